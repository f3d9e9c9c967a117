"""From fitted candidates to an answer: ranking, significance, pairs, confidence, ambiguity.

A candidate *explains* the gap when, on the held-out data, it removes at least
:data:`MIN_SHRINKAGE` of the gap (the excess error beyond noise, :mod:`score`) and its
improvement is significant, so fitting noise is not mistaken for an effect: either a paired
t-test over the prediction windows (the errors of one window are correlated, different windows
nearly independent) gives t >= :data:`MIN_T`, or the error removed exceeds the whole noise floor
(an improvement concentrated in a few windows, e.g. the locked-piston tests, is real when it is
larger than anything noise could produce), or, when the holdout is too short to tell, a cross-check
confirms it: the candidate refitted on the holdout and judged on the training data (the second
fold of a two-fold cross-validation, both judgements out of sample) gives a t that, combined with
the first by Stouffer's rule, (t + t_cross) / sqrt(2) >= :data:`MIN_T`. Candidates are ranked
by a Bayesian information criterion over the held-out error with one sample per signal and
window, so an extra parameter must pay for itself; a pair must also remove :data:`MIN_SHRINKAGE`
of what its better member leaves (:data:`MOSTLY` when the pair still leaves a gap beyond noise),
with significance, and its second effect must not sit at the edge of its search range
(:func:`left_out`), or the single effect is preferred. A single effect
whose knob sits at the far edge of its search range is not named either (:func:`pinned_single`):
fitted there it measures nothing, it stands in for a cause outside its form.

The answer is ``none`` when no candidate explains the gap: either the nominal gap is within
noise, or its cause is not among the candidates, or (a gap within noise) the winner removes less
than :data:`MOSTLY` of it and an unrelated candidate, not told apart from it, about as much
(:func:`decide`). Two
candidates are *indistinguishable* when the runner-up also explains the gap and either leaves
at most :data:`AMBIGUOUS` times the gap the winner leaves, or the winner's held-out advantage
over it is not significant by the same test (paired t over the windows, or more than the noise
floor); then the answer
keeps the winner, lowers the confidence and names the experiment that separates them best (and
the diagnosis lets both folds of a two-fold cross-validation choose between the two:
:func:`jetpipe_ros.diagnosis.diagnose.second_fold`).
Confidence is the winner's shrinkage times its margin over the runner-up, ln(runner-up's gap /
winner's gap) / ln(4) capped at 1 (full when the runner-up leaves four times the winner's gap),
or for ``none`` one minus the strongest evidence against it: the largest shrinkage any candidate
achieved, weighted by how significant it was.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from jetpipe_ros.diagnosis.calibration import NAME as CALIBRATION
from jetpipe_ros.diagnosis.calibration import describe
from jetpipe_ros.diagnosis.candidates import CANDIDATES, effect_of
from jetpipe_ros.diagnosis.fit import Fit
from jetpipe_ros.diagnosis.score import Score, effective_samples
from jetpipe_ros.model import EFFECTS

MIN_SHRINKAGE = 0.3
#: An effect that leaves a gap beyond noise is the cause only if it removes at least this much
#: of the gap: one that leaves more than it removes is at most part of the cause.
MOSTLY = 0.5
MIN_T = 3.0
AMBIGUOUS = 1.25
#: The least gap [%] that counts as beyond noise: 0.5 % of each signal's spread is about twice
#: the pressure sensor's noise (0.9-1 kPa of 1.7-2 bar) and four times the position sensor's
#: (63 um of 12.6 mm) on the default campaign; a systematic error smaller than that is below
#: what a controller designer could see in the recordings.
NOISE_GAP = 0.5
#: How the reason of a ``none`` whose recalibration explains the gap begins (:func:`settle`).
NO_EFFECT = "no unmodelled effect: "


@dataclass
class Ranked:
    """A fit with its held-out figures relative to a base model (the nominal one, or the
    recalibrated one for effects fitted on top of it)."""

    fit: Fit
    base_gap: float  #: the base model's held-out gap [%]
    shrinkage: float  #: 1 - gap_augmented / gap_base (held out)
    improvement: float  #: relative reduction of the held-out mean square error
    t: float  #: paired t statistic of the improvement over the prediction windows
    removed_over_floor: float  #: held-out error removed / the noise floor's error
    bic: float
    #: paired t of the cross-check (fitted on the holdout, judged on the training data), if run
    t_cross: float | None = None
    #: held-out gap of its second fold (fitted on the holdout, judged on the training data) [%],
    #: if run (:func:`jetpipe_ros.diagnosis.diagnose.second_fold`)
    second_fold: float | None = None
    #: a pair's fit with each member back where it changes nothing, every other knob as
    #: fitted (:func:`jetpipe_ros.diagnosis.fit.switched_off`), by member; empty if not scored
    switched_off: dict[str, Fit] = field(default_factory=dict)

    @property
    def significant(self) -> bool:
        """True when the held-out improvement is more than noise (see the module text)."""
        combined = (self.t + self.t_cross) / math.sqrt(2.0) if self.t_cross is not None else 0.0
        return self.t >= MIN_T or self.removed_over_floor >= 1.0 or combined >= MIN_T

    @property
    def needs_cross_check(self) -> bool:
        """True when the candidate removes enough of the gap but the holdout alone cannot show
        that the improvement is more than noise."""
        return (self.shrinkage >= MIN_SHRINKAGE and not self.significant and self.t > 0.0
                and self.t_cross is None)

    @property
    def explains(self) -> bool:
        """True when the fit removes a significant part of the gap."""
        return self.shrinkage >= MIN_SHRINKAGE and self.significant

    def to_json(self, nominal: Score) -> dict:
        """The ranking row of diagnosis.json."""
        effects = list(self.fit.effect_names)
        values = self.fit.effect_values()
        if self.fit.calibrated:
            values = {**values, CALIBRATION: self.fit.values[CALIBRATION]}
        return {"effect": self.fit.effect, "effects": effects, "candidate": self.fit.name,
                "forms": self.fit.forms,
                "subsystem": "+".join(dict.fromkeys(EFFECTS[e] for e in effects)),
                "params": values if len(values) > 1 else values[effects[0]],
                "train_gap": self.fit.train.gap, "holdout_gap": self.fit.holdout.gap,
                "shrinkage": self.shrinkage, "explains": self.explains, "t": self.t,
                "t_cross_check": self.t_cross, "second_fold_gap": self.second_fold,
                "removed_over_noise_floor": self.removed_over_floor,
                "holdout_by_signal": self.fit.holdout.to_json(), "bic": self.bic,
                "evaluations": self.fit.evaluations, "fit_seconds": self.fit.seconds,
                **({"switched_off_gap": {effect_of(g): f.holdout.gap
                                         for g, f in self.switched_off.items()}}
                   if self.switched_off else {})}


def paired_t(before: np.ndarray, after: np.ndarray) -> float:
    """t statistic of the mean reduction from ``before`` to ``after`` (paired samples,
    :func:`scipy.stats.ttest_rel`); +-inf for a reduction without spread, 0 for none."""
    d = before - after
    if d.size < 2:
        return 0.0
    if float(np.std(d)) <= 1e-12 * float(np.max(np.abs(before))):  # no spread but round-off
        mean = float(np.mean(d))
        return 0.0 if mean == 0.0 else math.copysign(math.inf, mean)
    return float(stats.ttest_rel(before, after).statistic)


def rank(fits: Sequence[Fit], nominal: Score, nominal_windows: np.ndarray,
         dt: float) -> list[Ranked]:
    """Rank fits by held-out BIC (best first)."""
    n = effective_samples(nominal, dt)
    out = []
    for f in fits:
        k = sum(len(v) for v in f.values.values())
        shrink = 1.0 - f.holdout.gap / nominal.gap if nominal.gap > 0 else 0.0
        imp = 1.0 - f.holdout.total / nominal.total if nominal.total > 0 else 0.0
        bic = n * math.log(max(f.holdout.total, 1e-300)) + k * math.log(n)
        removed = (nominal.total - f.holdout.total) / max(nominal.noise_total, 1e-300)
        out.append(Ranked(f, nominal.gap, shrink, imp,
                          paired_t(nominal_windows, f.holdout_windows), removed, bic))
    return sorted(out, key=lambda r: r.bic)


def left_beyond_noise(held: Score, windows: np.ndarray,
                      floor_windows: np.ndarray | None) -> bool:
    """True when a model leaves a held-out gap beyond noise: at least :data:`NOISE_GAP`, and
    significantly so: its error per prediction window above what noise alone leaves in the same
    window (paired t >= :data:`MIN_T` against the noise floor's twin, :mod:`noise_floor`), or
    its error beyond noise larger than the whole noise floor (an error concentrated in a few
    windows, which the t-test cannot see)."""
    if held.gap < NOISE_GAP:
        return False
    if floor_windows is None or floor_windows.shape != windows.shape:
        return True
    return (paired_t(windows, floor_windows) >= MIN_T
            or held.total - held.noise_total >= held.noise_total)


def needs_pairs(best: Ranked, floor_windows: np.ndarray | None) -> bool:
    """True when the best single effect leaves a gap beyond noise."""
    return left_beyond_noise(best.fit.holdout, best.fit.holdout_windows, floor_windows)


def _better_single(pair: Ranked, ranking: Sequence[Ranked]) -> Ranked | None:
    singles = [r for r in ranking if len(r.fit.effects) == 1 and r.fit.effects[0] in
               pair.fit.effects]
    return min(singles, key=lambda r: r.fit.holdout.total) if singles else None


def idle_single(single: Ranked) -> bool:
    """True when a single effect fitted jointly with the calibration does not carry the
    held-out improvement it is credited with: scored again with the effect switched off, the
    calibration as fitted beside it (:attr:`Ranked.switched_off`, nothing refitted), the fit
    loses less than :data:`MOSTLY` of what it gains over its base (the recalibration alone).

    The joint fit then found a better calibration, and the effect took the credit for it: the
    pairs' idle member (:func:`idle_second`) met by a single effect. Seen with the position
    alone on an actuator with nothing a position sensor can see (seed 9437, a campaign with a
    2.6 V square wave trained on, development): a polytropic index of 1.002 took 43 % of a
    0.079 % gap, leaving 0.045 %; switched off, 0.048 %. Effects that were right there carried
    most of theirs: an elasto-plastic friction 0.17 % (0.24 % switched off, base 0.25 %), a
    measured seal 0.33 % (0.52 %, base 0.48 %), a drooping supply 0.23 % (1.26 %, base 0.53 %).
    False when it was not scored switched off (an effect fitted on the recalibration with
    its knobs held loses all of its gain when switched off)."""
    if len(single.fit.effects) != 1:
        return False
    off = single.switched_off.get(single.fit.effects[0])
    gained = single.base_gap - single.fit.holdout.gap
    if off is None or gained <= 0.0:
        return False
    return off.holdout.gap - single.fit.holdout.gap < MOSTLY * gained


def pinned_second(pair: Ranked, ranking: Sequence[Ranked]) -> list[str]:
    """The knobs of the pair's second effect (the member beside its better single one) that
    sit at the far edge of their search range (:meth:`KnobGroup.pinned`), as
    ``candidate.knob``.

    The ranges reach several times beyond the largest typical size of docs/effects.md, and the
    second effect of a pair is the weaker one: fitted at such an edge it measures nothing, it
    compensates what the first effect's form misses (seen on a plant whose supply droops with
    the flow drawn: the pressure sensors' gain error driven to the range's 5 %, where the
    plant's sensors are exact)."""
    best = _better_single(pair, ranking)
    first = best.fit.effects if best is not None else ()
    return [f"{g}.{k}" for g in pair.fit.effects if g not in first
            for k in CANDIDATES[g].pinned(pair.fit.values[g])]


def pinned_single(single: Ranked) -> list[str]:
    """The knobs of a single effect that sit at the far edge of their search range
    (:meth:`KnobGroup.pinned`), as ``candidate.knob``.

    The ranges reach beyond the largest typical sizes of docs/effects.md (a delay to 8 ms for
    1-5 ms, a mass to 10 kg for 0.5-5 kg); an effect fitted at such an edge is not measured
    (its value is the bound, its standard error meaningless): it stands in for a cause its form
    does not hold (seen on the plant: a lag of the chamber flows after the flow map, before the
    candidates had that form, taken as a command delay pinned at 8 ms, removing 71 %), as the
    second effect of a pair does (:func:`pinned_second`)."""
    if len(single.fit.effects) != 1:
        return []
    (g,) = single.fit.effects
    return [f"{g}.{k}" for k in CANDIDATES[g].pinned(single.fit.values[g])]


def idle_second(pair: Ranked, ranking: Sequence[Ranked],
                floor_windows: np.ndarray | None) -> list[str]:
    """The pair's second effect (the member beside its better single one) when the pair does
    not pay for it against itself with that member switched off (:attr:`Ranked.switched_off`:
    every other knob as fitted, nothing refitted), by the rule of :func:`left_out`.

    A member that carries the pair's held-out improvement loses it when switched off. One that
    does not only moved the other knobs in training, soaking up there what the first effect's
    form misses; the improvement held out is the other knobs' new values, not the member's.
    Seen with one chamber pressure on a wall heat exchange whose conductance grows with the
    wetted wall, three seeds of three (6563, 2477, 2203): the heat alone left 0.67-0.76 % held
    out; beside a supply 1.4 kPa low, a leak of 2e-6 kg/s or a pressure sensor's 0.3 % gain
    error, 0.45-0.51 %; each pair with its second member switched off, 0.41-0.48 %."""
    best = _better_single(pair, ranking)
    first = best.fit.effects if best is not None else ()
    return [g for g in pair.fit.effects if g not in first and g in pair.switched_off
            and not _pays(pair.fit, pair.switched_off[g], floor_windows)]


def _pays(fitted: Fit, against: Fit, floor_windows: np.ndarray | None) -> bool:
    """``fitted`` removes at least :data:`MIN_SHRINKAGE` of the held-out gap ``against``
    leaves (:data:`MOSTLY` when ``fitted`` still leaves a gap beyond noise), significantly
    (paired t >= :data:`MIN_T` over the windows, or more than the whole noise floor)."""
    left = against.holdout
    shrink = 1.0 - fitted.holdout.gap / left.gap if left.gap > 0 else 0.0
    enough = MOSTLY if left_beyond_noise(fitted.holdout, fitted.holdout_windows,
                                         floor_windows) else MIN_SHRINKAGE
    return shrink >= enough and significantly_better(fitted, against, left.noise_total)


def significantly_better(fitted: Fit, against: Fit, noise_total: float) -> bool:
    """True when ``fitted``'s held-out advantage over ``against`` is itself significant: paired
    t >= :data:`MIN_T` over the windows, or more error removed than the whole noise floor
    (``noise_total``, the mean normalised noise variance)."""
    t = paired_t(against.holdout_windows, fitted.holdout_windows)
    return t >= MIN_T or against.holdout.total - fitted.holdout.total >= noise_total


def left_out(r: Ranked, ranking: Sequence[Ranked], floor_windows: np.ndarray | None
             ) -> str | None:
    """Why a candidate that explains the gap (:attr:`Ranked.explains`) is not named all the
    same, in a few words, or None when no rule leaves it out.

    A single effect is left out with a knob at the far edge of its search range
    (:func:`pinned_single`), or when, switched off with the calibration as fitted beside it, it
    loses less than :data:`MOSTLY` of its gain (:func:`idle_single`). A pair is named only when
    its second effect pays for itself on held-out data: the pair removes at least
    :data:`MIN_SHRINKAGE` of what its better single member leaves, and that improvement is
    significant (paired t >= :data:`MIN_T` over the windows, or more than the whole noise
    floor), with the second effect's knobs inside their search ranges (:func:`pinned_second`),
    and the same improvement over the pair with its second effect switched off
    (:func:`idle_second`). When the pair still leaves a gap beyond noise, the second effect must
    remove :data:`MOSTLY` of what the first leaves, the rule a single effect meets against its
    base: one that leaves more of the rest than it removes is at most part of the rest's cause,
    and the single effect is named with the gap it leaves (seen on the plant's supply behind a
    drooping regulator, four seeds of four: a sensor lag or a leak beside the supply took
    32-34 % of what the supply left, and 1.5-5.4 % beyond noise remained). A pair neither of
    whose members was fitted alone is not judged so."""
    why = left_out_rule(r, ranking, floor_windows)
    if why is None:
        return None
    rule, names = why
    if rule == "gains little":
        return f"gains too little over {names[0]} alone"
    if rule == "pinned":
        return f"{', '.join(names)} at the edge of its search range"
    return f"{', '.join(names)} switched off leaves as little"


def left_out_rule(r: Ranked, ranking: Sequence[Ranked], floor_windows: np.ndarray | None
                  ) -> tuple[str, list[str]] | None:
    """The rule of :func:`left_out` that leaves ``r`` out and what it names: ``"pinned"`` with
    the knobs at an edge, ``"gains little"`` with the better single member, ``"idle"`` with the
    second effects that switched off leave as little; None when no rule does."""
    if not r.explains:
        return None
    if len(r.fit.effects) == 1:
        if pinned := pinned_single(r):
            return "pinned", pinned
        return ("idle", list(r.fit.effects)) if idle_single(r) else None
    best = _better_single(r, ranking)
    if best is None:
        return None
    if not _gains_over_first(r, ranking, floor_windows):
        return "gains little", [best.fit.name]
    if pinned := pinned_second(r, ranking):
        return "pinned", pinned
    if idle := idle_second(r, ranking, floor_windows):
        return "idle", idle
    return None


def _gains_over_first(pair: Ranked, ranking: Sequence[Ranked],
                      floor_windows: np.ndarray | None) -> bool:
    """The pair pays (:func:`_pays`) against its better single member refitted alone (False
    when neither member was fitted alone)."""
    best = _better_single(pair, ranking)
    return best is not None and _pays(pair.fit, best.fit, floor_windows)


@dataclass
class Verdict:
    """The answer: an effect (or pair) or none, why, and how sure."""

    winner: Ranked | None
    confidence: float
    reason: str
    runner_up: Ranked | None = None
    ambiguous: bool = False
    #: with no winner: the best candidate that explains part of the gap, not most of it
    partial: Ranked | None = None
    #: with no winner: the base model leaves a gap beyond noise that no candidate explains
    unexplained: bool = False


def decide(ranking: Sequence[Ranked], base: Score, base_windows: np.ndarray,
           floor_windows: np.ndarray | None) -> Verdict:
    """Choose the answer from a ranking (singles and pairs together) against its base model
    (the nominal or the recalibrated one; ``base_windows`` its held-out window errors).

    An effect that explains the gap (:attr:`Ranked.explains`: a significant part of it, beyond
    noise) is named even when the gap is under :data:`NOISE_GAP`, the size at which it shows in
    a plot of the records: the reason then says it is small. On the recalibrated model this was
    refused until issue 24's seal stop (an earlier version saw a 0.4 ms valve delay take 38 % of
    a 0.21 % gap left by recalibrating an actuator whose torque motor differed from nominal);
    measured since on the self-check's held-out seeds 3571, 4243, 6449, 7919, 8447 and 6733 with
    every logger, no candidate explained any of 30 effect-free actuators' sub-bar gaps (the
    most: 17 % of a gap with 0.9 of the noise floor removed, or 74 % of a 0.12 % gap without
    significance), while one of the two friction-dynamics forms explained 3 of 8 measured
    seals' (37-52 %, 0.9-1.3 noise floors), and on records of the position alone a leak
    explained a seal-gap leak's, a valve lag a port lag's and two lines' (the wrong form of the
    right subsystem). Those cases are this rule's development data.

    Under that bar, a winner that removes less than :data:`MOSTLY` of the gap is not named when
    an effect it does not share leaves within :data:`AMBIGUOUS` times its gap and the winner's
    advantage is not significant (:func:`significantly_better`): what unrelated effects take
    alike is a part of the remainder any added freedom bends to, evidence for none of them. Seen
    with the position alone on seed 2609's parameters-only actuator: after recalibration a hose
    took 35 % of a 0.13 % gap (significant only with its cross-check), an orifice leak 32 %, a
    second-order valve lag 29 %, a power-law leak 22 %. The right namings of small gaps on the same
    development records (seeds 2609, 3137, 4099, 7103: elasto-plastic friction, the measured
    seal, a drooping supply with the position alone) had no unrelated rival within 1.5 times the
    winner's gap. Above the bar a minority is named only when it leaves the gap within noise,
    and the rule is not applied."""
    best_shrink = max((_clip(r.shrinkage) * (1.0 if r.significant else
                                             _clip(max(r.t / MIN_T, r.removed_over_floor)))
                       for r in ranking), default=0.0)
    explaining = [r for r in ranking if r.explains and left_out(r, ranking, floor_windows) is None]
    stand_in = next((r for r in ranking if r.explains and pinned_single(r)), None)
    gap_left = left_beyond_noise(base, base_windows, floor_windows)
    named = [r for r in explaining if r.shrinkage >= MOSTLY or not left_beyond_noise(
        r.fit.holdout, r.fit.holdout_windows, floor_windows)]
    if not named:
        partial = explaining[0] if explaining else None
        idle = next((r for r in ranking if r.explains and idle_single(r)), None)
        idle_words = "" if idle is None else (
            f"; {idle.fit.name} removes {idle.shrinkage:.0%} of it, but switched off, the "
            f"calibration as fitted beside it, the fit leaves "
            f"{idle.switched_off[idle.fit.effects[0]].holdout.gap:.2f} %: the improvement is "
            f"that calibration's, not the effect's")
        if not gap_left:
            return Verdict(None, _clip(1.0 - best_shrink),
                           f"the held-out gap ({base.gap:.2f} %) is within what sensor noise "
                           f"explains{idle_words}", partial=partial)
        part = (f"{partial.fit.name} explains only {partial.shrinkage:.0%} of it"
                if partial is not None else
                f"no candidate removes {MIN_SHRINKAGE:.0%} of it with significance (best "
                f"{max((r.shrinkage for r in ranking), default=0.0):.0%})")
        if stand_in is not None:
            part += (f"; {stand_in.fit.name} removes {stand_in.shrinkage:.0%}, but with "
                     f"{', '.join(pinned_single(stand_in))} at the edge of its search range: "
                     f"taken as standing in for a cause outside its form, not named")
        return Verdict(None, _clip(1.0 - best_shrink),
                       f"a held-out gap of {base.gap:.2f} % beyond noise remains and {part}: "
                       f"its cause is not among the candidates{idle_words}", partial=partial,
                       unexplained=True)
    win = named[0]
    rivals = [r for r in ranking if r is not win
              and not set(r.fit.effect_names) & set(win.fit.effect_names)
              and r.improvement > 0]
    runner = rivals[0] if rivals else None
    ambiguous = False
    if runner is not None:
        close = runner.fit.holdout.gap <= AMBIGUOUS * max(win.fit.holdout.gap, 1e-6)
        apart = significantly_better(win.fit, runner.fit, base.noise_total)
        if not gap_left and win.shrinkage < MOSTLY and close and not apart:
            return Verdict(None, _clip(1.0 - best_shrink),
                           f"the held-out gap ({base.gap:.2f} %) is within what sensor noise "
                           f"explains; {win.fit.name} removes {win.shrinkage:.0%} of it, but "
                           f"{runner.fit.name}, another effect, removes about as much "
                           f"({runner.shrinkage:.0%}), and neither is told from the other: a "
                           f"part of the gap unrelated effects take alike is evidence for "
                           f"none of them", partial=win)
        ambiguous = runner.explains and (close or not apart)
    confidence = confidence_of(win, runner.fit.holdout.gap if runner is not None else None)
    reason = (f"{win.fit.name} removes {win.shrinkage:.0%} of the held-out gap "
              f"({base.gap:.2f} % -> {win.fit.holdout.gap:.2f} %)")
    if base.gap < NOISE_GAP:
        reason += (f", a small gap (under the {NOISE_GAP} % at which it shows in a plot of the "
                   f"records) but beyond noise")
    beside = [r for r in ranking if len(r.fit.effects) > len(win.fit.effects)
              and set(win.fit.effects) <= set(r.fit.effects) and r.explains
              and r.fit.holdout.gap < win.fit.holdout.gap]
    compensating = [(r, pinned) for r in beside if (pinned := pinned_second(r, ranking))]
    if compensating:
        r, pinned = compensating[0]
        reason += (f"; {r.fit.name} leaves less ({r.fit.holdout.gap:.2f} %), but with "
                   f"{', '.join(pinned)} at the edge of its range: taken as compensating what "
                   f"the form of {win.fit.name} misses, not named")
    # Said only where it decided: the pair would be named but for its idle second effect.
    idle = [(r, why[1]) for r in beside
            if (why := left_out_rule(r, ranking, floor_windows)) and why[0] == "idle"]
    if idle:
        r, (off, *_) = idle[0]
        reason += (f"; {r.fit.name} leaves less ({r.fit.holdout.gap:.2f} %), but with {off} "
                   f"switched off, the rest as fitted, it leaves "
                   f"{r.switched_off[off].holdout.gap:.2f} %: {off} does not carry the "
                   f"improvement, not named")
    if stand_in is not None and ranking.index(stand_in) < ranking.index(win):
        reason += (f"; {stand_in.fit.name} leaves less ({stand_in.fit.holdout.gap:.2f} %), but "
                   f"with {', '.join(pinned_single(stand_in))} at the edge of its search "
                   f"range: taken as standing in for a cause outside its form, not named")
    if ambiguous and runner is not None:
        reason += (f"; {runner.fit.name} explains the data almost as well "
                   f"({runner.shrinkage:.0%}): these experiments cannot tell them apart")
    return Verdict(win, confidence, reason, runner, ambiguous)


def confidence_of(win: Ranked, runner_gap: float | None) -> float:
    """The winner's shrinkage times its margin over the runner-up's held-out gap,
    ln(runner-up's gap / winner's gap) / ln(4) capped at 1 (1 without a runner-up)."""
    margin = 1.0
    if runner_gap is not None:
        gap = max(win.fit.holdout.gap, 1e-6)
        margin = min(1.0, max(0.0, math.log(max(runner_gap, gap) / gap) / math.log(4.0)))
    return _clip(win.shrinkage) * margin


def _clip(x: float) -> float:
    return float(min(max(x, 0.0), 1.0))


@dataclass
class Settled:
    """What the data need: calibration, an effect, both or neither, and in plain words why."""

    final: Fit | None  #: the fit of the final model (None: the nominal model)
    calibrated: bool  #: the final model includes the recalibration
    verdict: Verdict  #: the unmodelled-effect answer
    reason: str
    #: calibration given the effect: the effect with the calibration against the effect alone
    given: Ranked | None = None
    #: another explanation as good as the final one (an effect alone against the calibration)
    alternative: Ranked | None = None
    #: a gap beyond noise remains that no candidate and no recalibration explains
    unlisted: bool = False


def settle(calibration: Ranked, on_cal: Verdict, alone: Verdict, given: Ranked | None,
           effect_alone: Ranked | None, floor_windows: np.ndarray | None) -> Settled:
    """Decide which of calibration and unmodelled effect the data need.

    ``calibration`` is the recalibrated model against the nominal one; ``on_cal`` the effect
    verdict on top of the recalibrated model; ``alone`` the effect verdict on the nominal model;
    ``given`` the winner of ``on_cal`` against the same effect fitted without the calibration,
    and ``effect_alone`` that fit against the nominal model. Each part must pay for itself given
    the other:

    - an effect that explains the gap left after recalibration is the answer; the calibration
      stays in the model when it explains a significant part of what the effect alone leaves,
      else the effect alone is kept (its mis-set parameters were not needed), unless the
      recalibration explains nothing alone either and the winner on the nominal model predicts
      the holdout better than that effect alone: then that winner is the answer;
    - with no such effect, a significant recalibration is kept; if an effect alone explains the
      nominal gap too, the two are alternatives: the one with the lower held-out information
      criterion is kept, the other reported; but when both leave a gap beyond noise
      (``floor_windows``: the noise floor's held-out window errors), neither reading is the
      cause: the effect does what mis-set parameters also do, which real hardware always has,
      and what both leave is a cause on no list, ``unlisted`` (seed 5347's load spring, a force
      on no list, was named a supply restriction of zero volume that left 2.34 % of a 6.41 %
      gap where the recalibration left 3.48 %);
    - with neither, an effect that explains the nominal gap alone is the answer;
    - with no effect in the end, a gap beyond noise that remains is ``unlisted``: its cause is
      on no list (nor a mis-set parameter).
    """
    cal_words = _knob_words(calibration.fit.values)
    if on_cal.winner is not None and given is not None:
        win = on_cal.winner
        if given.explains or effect_alone is None or not effect_alone.explains:
            reason = (f"the nominal parameters were off ({_knob_words(win.fit.values)}); on "
                      f"top of the recalibration, {on_cal.reason}; the recalibration removes "
                      f"{given.shrinkage:.0%} of what {win.fit.name} alone leaves")
            return Settled(win.fit, True, on_cal, reason, given)
        best = alone.winner
        if (not calibration.explains and best is not None
                and set(best.fit.effect_names) != set(win.fit.effect_names)):
            # Neither the recalibration nor its help beside the effect pays for itself: the
            # ranking on top of it was made beside knobs the data do not pin (a record of the
            # position alone leaves the dead volumes and flow gains free to overfit). The
            # ranking on the nominal model decides when its winner, another effect (forms of
            # one effect are judged as before), predicts the holdout better,
            # or when it is one member of the pair that won and the other, without the knobs,
            # removes less than MIN_SHRINKAGE of what it leaves (a second effect by the rule
            # of decide(), judged without the knobs).
            member = set(best.fit.effect_names) < set(win.fit.effect_names)
            rest = 1.0 - effect_alone.fit.holdout.gap / max(best.fit.holdout.gap, 1e-12)
            if best.fit.holdout.gap < effect_alone.fit.holdout.gap or (
                    member and rest < MIN_SHRINKAGE):
                reason = alone.reason
                if member:
                    reason += (f"; without the recalibration (not significant), "
                               f"{win.fit.name} leaves only {rest:.0%} less than "
                               f"{best.fit.name} alone")
                return Settled(best.fit, False, alone, reason)
        verdict = Verdict(effect_alone, on_cal.confidence, on_cal.reason, on_cal.runner_up,
                          on_cal.ambiguous)
        reason = (f"{win.fit.name} explains the gap: alone it removes "
                  f"{effect_alone.shrinkage:.0%} of the held-out gap; recalibrating the nominal "
                  f"parameters as well is not significant (removes {given.shrinkage:.0%} of "
                  f"what is left, t = {given.t:.1f})")
        return Settled(effect_alone.fit, False, verdict, reason, given)
    if calibration.explains:
        alt = alone.winner
        both_leave = (alt is not None and on_cal.unexplained and left_beyond_noise(
            alt.fit.holdout, alt.fit.holdout_windows, floor_windows))
        if alt is not None and alt.bic < calibration.bic and not both_leave:
            verdict = Verdict(alt, alone.confidence, alone.reason)
            return Settled(alt.fit, False, verdict,
                           f"{alone.reason}; recalibrating the nominal parameters instead "
                           f"({cal_words}) explains the data almost as well (held-out gap "
                           f"{calibration.fit.holdout.gap:.2f} % against "
                           f"{alt.fit.holdout.gap:.2f} %): these experiments cannot tell "
                           f"them apart", alternative=calibration)
        if on_cal.unexplained:
            reason = (f"the nominal parameters are off ({cal_words}; recalibrated, the held-out "
                      f"gap shrinks from {calibration.base_gap:.2f} % to "
                      f"{calibration.fit.holdout.gap:.2f} %), but {on_cal.reason}")
            if both_leave:
                reason += (f"; {alt.fit.name} alone, instead of the recalibration, leaves "
                           f"{alt.fit.holdout.gap:.2f} %, beyond noise too: it does what "
                           f"mis-set parameters do, not what is left")
            return Settled(calibration.fit, True, on_cal, reason, unlisted=True)
        reason = (f"{NO_EFFECT}the nominal parameters are off ({cal_words}); "
                  f"recalibrated, the held-out gap shrinks from {calibration.base_gap:.2f} % "
                  f"to {calibration.fit.holdout.gap:.2f} %")
        if on_cal.partial is not None:  # a candidate took part of it, not named (decide)
            reason += f"; on top of the recalibration, {on_cal.reason}"
        if alt is not None and alt.fit.holdout.gap <= AMBIGUOUS * calibration.fit.holdout.gap:
            reason += (f"; {alt.fit.name} alone explains the data almost as well (held-out "
                       f"gap {alt.fit.holdout.gap:.2f} % against "
                       f"{calibration.fit.holdout.gap:.2f} %): these experiments cannot tell "
                       f"them apart")
            return Settled(calibration.fit, True, on_cal, reason, alternative=alt)
        return Settled(calibration.fit, True, on_cal, reason)
    if alone.winner is not None:
        return Settled(alone.winner.fit, False, alone, alone.reason)
    return Settled(None, False, alone, alone.reason, unlisted=alone.unexplained)


def _knob_words(values: dict) -> str:
    words = describe(values[CALIBRATION]) if CALIBRATION in values else []
    return ", ".join(words) if words else "all within 2 % of nominal"
