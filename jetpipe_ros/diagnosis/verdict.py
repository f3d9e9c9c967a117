"""From fitted candidates to an answer: ranking, significance, pairs, confidence, ambiguity.

A candidate *explains* the gap when, on the held-out data, it removes at least
:data:`MIN_SHRINKAGE` of the gap (the excess error beyond noise, :mod:`score`) and at least
:data:`MIN_IMPROVEMENT` of the mean square error itself, so that fitting noise is not mistaken for
an effect. Candidates are ranked by a Bayesian information criterion over the held-out error with
one sample per signal and prediction window (the residuals within a window are correlated), so an
extra parameter must pay for itself.

The answer is ``none`` when the nominal gap is within noise or no candidate explains it. Two
candidates are *indistinguishable* when the gap the runner-up leaves is within
:data:`AMBIGUOUS` times (plus :data:`NOISE_GAP` / 5) the gap the winner leaves; then the answer
keeps the winner, lowers the confidence and names the experiment that separates them best.
Confidence is the winner's shrinkage times its margin over the runner-up, ln(runner-up's gap /
winner's gap) / ln(4) capped at 1 (full when the runner-up leaves four times the winner's gap),
or for ``none`` one minus the best shrinkage any candidate achieved.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from jetpipe_ros.diagnosis.fit import Fit
from jetpipe_ros.diagnosis.prediction import HORIZON
from jetpipe_ros.diagnosis.score import Score
from jetpipe_ros.model import EFFECTS

MIN_SHRINKAGE = 0.3
MIN_IMPROVEMENT = 0.01
AMBIGUOUS = 1.25
#: A winner leaving more than this fraction of the gap (and a gap above NOISE_GAP) tries pairs.
PAIR_IF_LEFT = 0.3
#: Gaps below this [%] are treated as within noise.
NOISE_GAP = 0.5


@dataclass
class Ranked:
    """A fit with its held-out figures relative to the nominal model."""

    fit: Fit
    shrinkage: float  #: 1 - gap_augmented / gap_nominal (held out)
    improvement: float  #: relative reduction of the held-out mean square error
    bic: float

    @property
    def explains(self) -> bool:
        """True when the fit removes a significant part of the gap."""
        return self.shrinkage >= MIN_SHRINKAGE and self.improvement >= MIN_IMPROVEMENT

    def to_json(self, nominal: Score) -> dict:
        """The ranking row of diagnosis.json."""
        effects = list(self.fit.effects)
        return {"effect": self.fit.name, "effects": effects,
                "subsystem": "+".join(dict.fromkeys(EFFECTS[e] for e in effects)),
                "params": self.fit.values if len(effects) > 1 else self.fit.values[effects[0]],
                "train_gap": self.fit.train.gap, "holdout_gap": self.fit.holdout.gap,
                "shrinkage": self.shrinkage, "explains": self.explains,
                "holdout_by_signal": self.fit.holdout.to_json(), "bic": self.bic,
                "evaluations": self.fit.evaluations, "fit_seconds": self.fit.seconds}


def effective_samples(s: Score, dt: float) -> float:
    """Independent pieces of evidence in a score: one per signal and prediction window."""
    return max(sum(s.count.values()) * dt / HORIZON, 1.0)


def rank(fits: Sequence[Fit], nominal: Score, dt: float) -> list[Ranked]:
    """Rank fits by held-out BIC (best first)."""
    n = effective_samples(nominal, dt)
    out = []
    for f in fits:
        k = sum(len(v) for v in f.values.values())
        shrink = 1.0 - f.holdout.gap / nominal.gap if nominal.gap > 0 else 0.0
        imp = 1.0 - f.holdout.total / nominal.total if nominal.total > 0 else 0.0
        bic = n * math.log(max(f.holdout.total, 1e-300)) + k * math.log(n)
        out.append(Ranked(f, shrink, imp, bic))
    return sorted(out, key=lambda r: r.bic)


def needs_pairs(best: Ranked, nominal: Score) -> bool:
    """True when the best single effect leaves a significant part of the gap."""
    left = best.fit.holdout.gap
    return left > NOISE_GAP and left > PAIR_IF_LEFT * nominal.gap


@dataclass
class Verdict:
    """The answer: an effect (or pair) or none, why, and how sure."""

    winner: Ranked | None
    confidence: float
    reason: str
    runner_up: Ranked | None = None
    ambiguous: bool = False


def decide(ranking: Sequence[Ranked], nominal: Score) -> Verdict:
    """Choose the answer from a ranking (singles and pairs together)."""
    best_shrink = max((r.shrinkage for r in ranking), default=0.0)
    if nominal.gap <= NOISE_GAP:
        return Verdict(None, _clip(1.0 - best_shrink),
                       f"the nominal model's held-out gap ({nominal.gap:.2f} %) is within what "
                       f"sensor noise explains")
    explaining = [r for r in ranking if r.explains]
    if not explaining:
        return Verdict(None, _clip(1.0 - best_shrink),
                       f"a gap of {nominal.gap:.2f} % remains but no candidate removes "
                       f"{MIN_SHRINKAGE:.0%} of it on held-out data (best "
                       f"{best_shrink:.0%}): the cause is not among the candidates")
    win = explaining[0]
    rivals = [r for r in ranking if r is not win and not set(r.fit.effects) & set(win.fit.effects)
              and r.improvement > 0]
    runner = rivals[0] if rivals else None
    margin = 1.0
    ambiguous = False
    if runner is not None:
        g_win = max(win.fit.holdout.gap, 1e-6)
        g_run = runner.fit.holdout.gap
        margin = min(1.0, max(0.0, math.log(max(g_run, g_win) / g_win) / math.log(4.0)))
        ambiguous = g_run <= AMBIGUOUS * g_win + NOISE_GAP / 5
    confidence = _clip(win.shrinkage) * margin
    reason = (f"{win.fit.name} removes {win.shrinkage:.0%} of the held-out gap "
              f"({nominal.gap:.2f} % -> {win.fit.holdout.gap:.2f} %)")
    if ambiguous and runner is not None:
        reason += (f"; {runner.fit.name} explains the data almost as well "
                   f"({runner.shrinkage:.0%}): these experiments cannot tell them apart")
    return Verdict(win, confidence, reason, runner, ambiguous)


def _clip(x: float) -> float:
    return float(min(max(x, 0.0), 1.0))
