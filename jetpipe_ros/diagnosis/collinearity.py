"""Which candidates the calibration could imitate on these records: a local collinearity check.

A recalibration that closes the gap rules an effect out only if the knobs could not have taken
its place. Whether they could depends on what was measured: with both chamber pressures a
valve delay of 3 ms shows in how each pressure answers the command, which no knob changes; with
the position alone, the same delay is imitated to within a fraction of the noise bar by smaller
dead volumes and a little less friction (the air springs stiffen and the piston answers as
early as before), and `none` would then say nothing about the delay.

The check is linear, at the recalibrated model (a collinearity analysis in the sense of
identifiability studies of nonlinear models: an effect's sensitivity against the span of the
nuisance parameters' sensitivities). For each candidate visible at its typical size
(:func:`diagnose.visibility`), its *signature* s is the change of the normalised residuals
(:func:`score.residual_vector`, all compared samples, training and held-out) when it is switched
on at that size on the recalibrated model; J is the calibration knobs' Jacobian there, per
natural log of each factor (:func:`nuisance.calibration_jacobian`). The knobs' best imitation
delta minimises

    N / C |s + J delta|^2 + sum_k (delta_k / sigma_k)^2

with N and C the training records' independent evidence and noise (as :mod:`nuisance` weighs
them) and sigma the hardware's spread (:data:`calibration.SPREAD`): a move the spread makes
implausible costs as much as the data it buys; each knob stays within its search range
(:data:`calibration.CALIBRATION`: the recalibration could not go further). What is left,
|s + J delta| as a gap [%], is what the effect shows that no recalibration can. A candidate
whose leftover is below :data:`verdict.NOISE_GAP` although its signature is above it is one
these records cannot tell from parameters that are off: a verdict of no effect does not rule it
out, and the diagnosis says so.

Linear in the knobs' logs and in the effect's size: it asks whether the directions are
parallel, not whether a fit would land there (that is :mod:`separation`'s stand-ins, for the
knobs that did move). Where the linear leftover lies near the bar (within a factor
:data:`REFINE_BAND` either way) the linearisation's error could decide, so there the knobs are
moved for real: the model without the effect refitted to the model with it, as a recalibration
of records of the effect would, the same objective minimised by a bounded nonlinear
least-squares fit from the linear answer; the leftover is then the model's own. On two
development records of a drooping supply seen by the position alone (seeds 7103 and 6911, case
10, with both supply forms' law knob) the linear check left 0.86 % and 1.03 % of a lower
constant supply's signature and the refit 0.76 % and 0.93 %; of the supply line's 0.54 % and
0.61 %, refitted 0.48 % and 0.56 % (the first now under the bar: imitated); of a 25 Hz valve
lag's 0.51 % and 0.59 %, refitted 0.58 % and 0.60 % (the linearisation erred the other way).
A few tenths of a second per candidate refitted.

What a sensor the rig lacks would show (:func:`with_added_sensors`): for a candidate imitated on
records without one or both chamber pressures, the same check on the records as a rig with that
pressure sensor would have logged them. The pressure it would have read is the recalibrated
model's chambers replayed from the measured motion and command (:mod:`prediction`'s
``chambers`` mode, the observer that restarts an unmeasured pressure), its noise the model's
pressure sensor's (``sensors.pressure_sigma``), its scale the replayed pressure's spread, the
noise floor of every signal measured again on that rig. A
leftover above :data:`verdict.NOISE_GAP` there says which sensor would tell the effect from
parameters that are off on the same experiments: with the position alone a 3 ms valve delay is
imitated, with either chamber's pressure it is not.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares, lsq_linear

from jetpipe_ros.diagnosis.calibration import CALIBRATION, SPREAD
from jetpipe_ros.diagnosis.candidates import Candidate, effect_of
from jetpipe_ros.diagnosis.data import MIN_SCALE, Prepared, smoothed
from jetpipe_ros.diagnosis.fit import Fit
from jetpipe_ros.diagnosis.noise_floor import calibrate
from jetpipe_ros.diagnosis.nuisance import calibration_jacobian
from jetpipe_ros.diagnosis.prediction import predict
from jetpipe_ros.diagnosis.score import effective_samples, predict_all, residual_vector, score
from jetpipe_ros.diagnosis.verdict import NOISE_GAP
from jetpipe_ros.model import ModelParams

#: Knob moves [fraction] of an imitation that its description names.
NAMED_MOVE = 0.02
#: The linear check is refined (:meth:`Imitator.imitate`) where its leftover lies within this
#: factor of :data:`verdict.NOISE_GAP` either way: there the linearisation's error (up to a tenth
#: of the leftover either way where probed, the knobs moving 10-50 %) could carry it across,
#: with a margin for effects and records that bend more.
REFINE_BAND = 2.0
#: The refinement's budget of objective evaluations, each a model run (seven to nine sufficed
#: where probed). Its Jacobian is the linear check's, kept: recomputed by finite differences at
#: every step it changed the leftovers by at most 0.011 points on the development records below,
#: at ten times the cost.
REFINE_RUNS = 30


class Imitator:
    """The calibration knobs' best linear imitation of a model's change, at the recalibrated
    model ``recalibrated`` (the minimisation above, set up once for many signatures)."""

    def __init__(self, prepared: Prepared, nominal: ModelParams, recalibrated: Fit) -> None:
        self.prepared, self.params, self.nominal = prepared, recalibrated.params, nominal
        self.knobs = [k.name for k in CALIBRATION.knobs]
        self.factors = recalibrated.values[CALIBRATION.name]
        self.base = self._residuals(self.params)
        self.jac = calibration_jacobian(prepared, nominal, recalibrated.z, None)
        self.root = math.sqrt(effective_samples(recalibrated.train, prepared.dt) / max(
            recalibrated.train.noise_total, 1e-300))
        self.prior = np.array([1.0 / SPREAD[k] for k in self.knobs])  # per ln(factor)
        self.design = np.vstack([self.root * self.jac, np.diag(self.prior)])
        low = np.array([math.log(k.low / self.factors[k.name]) for k in CALIBRATION.knobs])
        high = np.array([math.log(k.high / self.factors[k.name]) for k in CALIBRATION.knobs])
        self.bounds = (np.minimum(low, 0.0), np.maximum(high, 0.0))  # round-off at a bound

    def _residuals(self, params: ModelParams) -> np.ndarray:
        return residual_vector(self.prepared, predict_all(params, self.prepared, None), None)

    def _step(self, sig: np.ndarray) -> np.ndarray:
        """The knobs' moves minimising the linearised objective for the signature ``sig``."""
        target = np.concatenate([-self.root * sig, np.zeros(len(self.knobs))])
        return lsq_linear(self.design, target, bounds=self.bounds).x

    def imitate(self, cand: Candidate, values: Mapping[str, float], refine: bool = False
                ) -> tuple[float, float, np.ndarray]:
        """``cand`` switched on at ``values`` on the recalibrated model: its signature's gap
        [%], the gap [%] the knobs' best imitation leaves of it, and the knobs' moves (natural
        logs of their factors) that cancel it. Linear unless ``refine`` and the signature shows
        while the linear leftover lies within :data:`REFINE_BAND` of :data:`verdict.NOISE_GAP`:
        then the model without the effect is refitted for real to the model with it, as a
        recalibration of records of the effect would move the knobs from the recalibration's
        values, the same objective minimised by a bounded trust-region least-squares fit
        (:func:`scipy.optimize.least_squares`, the linear check's Jacobian kept) from the linear
        answer; the gap left is the model's, not the linear prediction, and the moves that
        imitate the effect are returned negated (linearly, the moves that cancel an effect are
        the opposite of those that imitate it)."""
        on = self._residuals(cand.apply(self.params, dict(values)))
        sig = on - self.base
        delta = self._step(sig)
        shown = 100.0 * float(np.linalg.norm(sig))
        kept = 100.0 * float(np.linalg.norm(sig + self.jac @ delta))  # the linear prediction
        if refine and shown >= NOISE_GAP and (NOISE_GAP / REFINE_BAND <= kept
                                              <= NOISE_GAP * REFINE_BAND):

            def objective(d: np.ndarray) -> np.ndarray:
                moved = {k: self.factors[k] * math.exp(x) for k, x in zip(self.knobs, d)}
                off = self._residuals(CALIBRATION.apply(self.nominal, moved))
                return np.concatenate([self.root * (off - on), self.prior * d])

            start = np.clip(-delta, *self.bounds)  # the knobs stay in their search ranges
            delta = -least_squares(objective, start, jac=lambda d: self.design,
                                   bounds=self.bounds, xtol=1e-3, ftol=1e-4,
                                   max_nfev=REFINE_RUNS).x
            kept = 100.0 * float(np.linalg.norm(objective(-delta)[:len(sig)])) / self.root
        return shown, kept, delta


def imitations(imitator: Imitator, candidates: Sequence[Candidate]) -> dict[str, dict]:
    """For each of ``candidates`` (on the recalibrated model of ``imitator``, a fit of the
    calibration knobs alone): its signature's gap [%], the gap [%] the knobs' best imitation
    leaves of it (linear, refitted near the bar: :meth:`Imitator.imitate`), whether that is
    below :data:`verdict.NOISE_GAP` (``imitated``) and the factors the imitation moves the
    knobs to (those moved by :data:`NAMED_MOVE` or more)."""
    out = {}
    for cand in candidates:
        shown, kept, delta = imitator.imitate(cand, cand.typical, refine=True)
        out[cand.name] = {
            "signature_gap_pct": shown, "left_gap_pct": kept,
            "imitated": shown >= NOISE_GAP > kept,
            "knobs": {k: math.exp(d) for k, d in zip(imitator.knobs, delta)
                      if abs(math.exp(d) - 1.0) >= NAMED_MOVE},
        }
    return out


def with_added_sensors(prepared: Prepared, nominal: ModelParams, recalibrated: Fit,
                       candidates: Sequence[Candidate], found: dict[str, dict]) -> None:
    """For each of ``candidates`` that :func:`imitations` found imitated (``found``), on records
    that lack a chamber pressure: the gap [%] the knobs' best imitation would leave on the same
    experiments with each pressure sensor the records lack added, and with both where both are
    missing, in ``found[name]["with_sensors"]`` (by the signals added, joined by ``+``)."""
    hidden = [c for c in candidates if found.get(c.name, {}).get("imitated")]
    missing = prepared.unmeasured_pressures
    if not hidden or not missing:
        return
    for added in [(s,) for s in missing] + ([missing] if len(missing) > 1 else []):
        rig = _as_logged_with(prepared, recalibrated.params, added,
                              nominal["sensors.pressure_sigma"])
        train = score(rig, predict_all(recalibrated.params, rig, "train"), "train")
        seen = imitations(Imitator(rig, nominal, dataclasses.replace(recalibrated, train=train)),
                          hidden)
        for c in hidden:
            found[c.name].setdefault("with_sensors", {})["+".join(added)] = \
                seen[c.name]["left_gap_pct"]


def _as_logged_with(prepared: Prepared, params: ModelParams, added: Sequence[str],
                    sigma: float) -> Prepared:
    """``prepared`` as a rig that also logged the pressures ``added`` would have recorded it:
    each the chambers of ``params`` replayed from the measured motion and command, with noise
    ``sigma`` [Pa] and the replayed pressure's spread as its scale; the noise floor of every
    signal measured again (:func:`noise_floor.calibrate`): a pressure that restarts each
    prediction lowers the position's too."""
    records, read = [], {s: [] for s in added}
    for rec in prepared.records:
        new = [s for s in added if not rec.measured(s)]
        if not new or rec.regulated:  # a regulated test's pressures are the regulators'
            records.append(rec)
            continue
        replay = predict(params, rec, prepared.dt, "chambers", scale=prepared.scale)
        logged = {s: replay.signal(s) for s in new}
        for s, x in logged.items():
            read[s].append(x)
        records.append(dataclasses.replace(
            rec, **logged, smooth={**rec.smooth, **{s: smoothed(x, prepared.dt)
                                                    for s, x in logged.items()}},
            sensors=(*rec.sensors, *new)))
    scale, noise = dict(prepared.scale), dict(prepared.noise)
    for s, xs in read.items():
        if xs:
            scale[s] = max(float(np.std(np.concatenate(xs))), MIN_SCALE[s])
            noise[s] = sigma
    rig = dataclasses.replace(prepared, records=records, scale=scale, noise=noise)
    rig.floor, rig.floor_windows = calibrate(rig, params)  # the position's floor falls too
    return rig


def imitated_effects(found: dict[str, dict]) -> dict[str, dict]:
    """The imitated candidates of :func:`imitations`, one per effect (its form the knobs
    imitate best), by effect name."""
    out: dict[str, dict] = {}
    for name, row in found.items():
        effect = effect_of(name)
        if row["imitated"] and (effect not in out
                                or row["left_gap_pct"] < out[effect]["left_gap_pct"]):
            out[effect] = {"candidate": name, **row}
    return out


#: The pressure sensors a rig may add, in words (keys of ``with_sensors``).
ADDED = {"p1": "chamber 1's", "p2": "chamber 2's", "p1+p2": "both"}


def telling(with_sensors: Mapping[str, float]) -> list[str]:
    """The sensor sets of ``with_sensors`` (:func:`with_added_sensors`) that would tell an
    effect from parameters that are off, their leftover at least :data:`verdict.NOISE_GAP`:
    the single sensors that would, else both together; none when not even both would."""
    tell = [k for k, v in with_sensors.items() if v >= NOISE_GAP]
    return [k for k in tell if "+" not in k] or tell


def sensor_words(hidden: Mapping[str, dict]) -> str:
    """Words for what a pressure sensor the records lack would tell of the effects ``hidden``
    (:func:`imitated_effects` after :func:`with_added_sensors`): the leftover of each
    imitation with each sensor added, and the effects that not even all the missing pressures
    would tell from parameters that are off."""
    rows = {e: r["with_sensors"] for e, r in sorted(hidden.items()) if r.get("with_sensors")}
    if not rows:
        return ""
    keys = list(next(iter(rows.values())))
    told = [e for e, added in rows.items() if telling(added)]
    words = ""
    if told:
        words = (f"; logged with a chamber pressure as well, the same experiments would tell "
                 f"{', '.join(told)} (left after the imitation with "
                 f"{' / '.join(ADDED[k] for k in keys)}: "
                 + ", ".join(f"{e} {' / '.join(f'{rows[e][k]:.2f}' for k in keys)} %"
                             for e in told) + ")")
    if len(told) < len(rows):
        most = keys[-1]  # both, or the one missing
        words += (f"; not even {ADDED[most]} {'pressures' if '+' in most else 'pressure'} "
                  f"would tell {', '.join(e for e in rows if e not in told)}")
    return words
