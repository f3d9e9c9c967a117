"""Where a gap starts: experiments on the records that hold one subsystem on the measurements
or change what one measured signal means.

The equation errors (:mod:`residuals`) describe the *shape* of what a model misses, but a shape
does not say where its cause lies: the force balance differentiates the measured position, so a
position transducer that lags reads there as a force. When no candidate explains a gap, the final
model (recalibrated, augmented) is therefore put through experiments on the records, each
changing one thing and asking how much of the held-out gap goes:

- **one sensor** (``sensors``): the model's prediction of one measured signal read through a
  first-order lag tau [s], a gain and an offset, ``s_meas = g lag_tau(s) + o``. tau is chosen on
  a grid from 0.5 to 20 ms, g and o by least squares on the training samples; the model's
  restarts take the measurement back through the same lag (``s + tau ds/dt``), as a lagging
  transducer needs;
- **the valve's null** (``valve``): the model driven by the recorded command plus an offset u_0
  [V] (within +-0.5 V, fitted on the training samples), a jet pipe whose null is off centre (the
  valve's gain is a calibration knob already);
- **the valve and chambers against the mechanics**: each replayed with its inputs held on the
  measurements (the chambers fed the measured motion and command, the piston the measured
  pressures: :func:`subsystem_gaps`), its own calibration knobs refitted on the training
  samples (the flow map, valve and dead volumes; the friction levels), since the whole model's
  recalibration may have moved one subsystem's knobs to make up for the other's missing physics;
  the replay that still misses by more holds the cause (the other one's gap falls when its inputs
  are right; both gaps are in per cent of the signals' spread beyond noise, so they compare).
  Between the valve and the chambers the equation errors decide (:mod:`residuals`): of
  the library terms that carry the two chamber balances' errors, the kind with the larger share
  of their variance (a valve offset or a flow gain that changes with pressure: ``valve``; a
  leak or compression term: ``chamber``); where no term of either kind carries a tenth,
  ``valve+chamber``. This is the weakest of the experiments: a shape, not a replay.

A one-signal experiment places the cause when it removes at least half of the held-out gap
beyond noise: more than all else together, so the signal it changes is where the gap starts. A
sensor fits first: a lag, gain or offset of one signal does not change what the actuator does,
so whatever else such a change explains (a valve delay on a position-only record is also a
position lag) is a candidate the diagnosis has already tried.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import optimize
from scipy import signal as sps

from jetpipe_ros.diagnosis.calibration import CALIBRATION
from jetpipe_ros.diagnosis.data import Prepared, Record
from jetpipe_ros.diagnosis.prediction import Prediction, predict
from jetpipe_ros.diagnosis.residuals import EquationError, sparse_terms
from jetpipe_ros.diagnosis.score import predict_all, score
from jetpipe_ros.model import ModelParams

#: Lags tried for one sensor [s]: a transducer's conditioning filter of a fraction of a sample
#: to a few tens of ms (docs/effects.md gives 1-10 ms for the pressure transducers).
SENSOR_LAGS = (5e-4, 1e-3, 2e-3, 3e-3, 4e-3, 6e-3, 8e-3, 1.2e-2, 1.6e-2, 2e-2)
#: Largest valve null offset tried [V] (the flow map's inputs span -2.8..3 V).
NULL_OFFSET = 0.5
#: A one-signal experiment that removes this share of the held-out gap places the cause.
PLACES = 0.5
#: Calibration knobs of each subsystem replayed apart (:mod:`calibration`), by replay mode.
OWN_KNOBS = {"chambers": ("flow_gain_charge", "flow_gain_discharge", "valve_gain",
                          "valve_frequency", "dead_volume_1", "dead_volume_2"),
             "mechanics": ("friction_entry", "friction_exit", "viscous_entry", "viscous_exit")}


def _replays(params: ModelParams, prepared: Prepared, mode: str) -> list[Prediction | None]:
    """Every record's replay of one subsystem (``mode``: chambers | mechanics); the mechanics
    only of free-piston records with both pressures measured (it is driven by them)."""
    if mode == "chambers":
        return predict_all(params, prepared, None, "chambers")
    return [predict(params, r, prepared.dt, "mechanics")
            if not r.locked and r.measured("p1") and r.measured("p2") else None
            for r in prepared.records]


def _refit(prepared: Prepared, params: ModelParams, mode: str,
           signals: tuple[str, ...]) -> ModelParams:
    """``params`` with the subsystem's own calibration knobs (:data:`OWN_KNOBS`) refitted to
    its replay's training samples (least squares on the log factors, within their ranges)."""
    knobs = [k for k in CALIBRATION.knobs if k.name in OWN_KNOBS[mode]]

    def moved(z: np.ndarray) -> ModelParams:
        return CALIBRATION.apply(params, {k.name: float(np.exp(zi)) for k, zi in zip(knobs, z)})

    def residuals(z: np.ndarray) -> np.ndarray:
        out = [(p.signal(s) - r.signal(s))[p.free & r.train] / prepared.scale[s]
               for r, p in zip(prepared.records, _replays(moved(z), prepared, mode))
               if p is not None for s in signals if s in r.signals()]
        return np.concatenate(out) if out else np.zeros(1)

    fit = optimize.least_squares(residuals, np.zeros(len(knobs)), diff_step=1e-3, max_nfev=60,
                                 bounds=([np.log(k.low) for k in knobs],
                                         [np.log(k.high) for k in knobs]))
    return moved(fit.x)


def subsystem_gaps(prepared: Prepared, params: ModelParams, role: str | None = None,
                   refit: bool = False) -> dict:
    """Gap [%] of each subsystem replayed with its inputs held on the measurements (``role``
    samples; all for None), with its own calibration knobs refitted on the training samples
    when ``refit``; and the steady pressure offset and noise the sensors show."""
    own = {mode: _refit(prepared, params, mode, signals) if refit else params
           for mode, signals in (("chambers", ("p1", "p2")), ("mechanics", ("y",)))}
    chambers = score(prepared, _replays(own["chambers"], prepared, "chambers"), role,
                     ("p1", "p2"))
    mechanics = score(prepared, _replays(own["mechanics"], prepared, "mechanics"), role, ("y",))
    offsets = []
    for rec in prepared.records:
        if rec.regulated or not rec.measured("p1"):
            continue
        pred = predict(params, rec, prepared.dt, "chambers")
        steady = np.abs(np.gradient(rec.p1, prepared.dt)) < 2e4
        steady[: rec.t.size // 10] = False
        steady &= rec.train | rec.holdout
        if steady.sum() > 100:
            offsets.append(float(np.median((rec.p1 - pred.p1)[steady])))
    return {
        "valve_and_chambers": {"driven_by": "measured command and piston motion",
                               **chambers.to_json()},
        "mechanics": {"driven_by": "measured chamber pressures", **mechanics.to_json()}
        if mechanics.mse else None,
        "sensors": {"steady_pressure_offset_pa": float(np.median(offsets)) if offsets else None,
                    "noise": {"y_m": prepared.noise["y"], "p1_pa": prepared.noise["p1"],
                              "p2_pa": prepared.noise["p2"]}},
    }


def _lag(x: np.ndarray, tau: float, dt: float) -> np.ndarray:
    """``x`` through a first-order lag of time constant ``tau`` [s], exact for ``x`` linear
    between samples, starting at rest at x[0]."""
    num, den, _ = sps.cont2discrete(([1.0], [tau, 1.0]), dt, method="foh")
    num = np.ravel(num)
    zi = sps.lfilter_zi(num, den) * x[0]
    return sps.lfilter(num, den, x, zi=zi)[0]


def _restarted(rec: Record, name: str, tau: float, dt: float) -> Record:
    """``rec`` whose restart values of signal ``name`` are taken back through a lag ``tau``."""
    smooth = dict(rec.smooth)
    smooth[name] = smooth[name] + tau * np.gradient(smooth[name], dt)
    v = rec.v + tau * np.gradient(rec.v, dt) if name == "y" else rec.v
    return dataclasses.replace(rec, smooth=smooth, v=v)


def _sensor(prepared: Prepared, params: ModelParams, name: str) -> dict:
    """The best lag, gain and offset of sensor ``name`` and the held-out gap it leaves."""
    dt = prepared.dt
    best = None
    for tau in SENSOR_LAGS:
        records = [_restarted(r, name, tau, dt) if r.measured(name) else r
                   for r in prepared.records]
        moved = dataclasses.replace(prepared, records=records)
        preds = predict_all(params, moved, None)
        lagged = [_lag(p.signal(name), tau, dt) for p in preds]
        rows = [(lg[m], r.signal(name)[m]) for r, p, lg in zip(prepared.records, preds, lagged)
                if r.measured(name) and name in r.signals()
                for m in [p.free & r.train] if m.any()]
        if not rows:
            return {}
        x = np.concatenate([a for a, _ in rows])
        target = np.concatenate([b for _, b in rows])
        (gain, offset), *_ = np.linalg.lstsq(np.column_stack([x, np.ones_like(x)]), target,
                                             rcond=None)
        changed = [dataclasses.replace(p, **{name: gain * lg + offset})
                   for p, lg in zip(preds, lagged)]
        train = score(prepared, changed, "train")
        if best is None or train.total < best[0]:
            best = (train.total, tau, float(gain), float(offset), changed)
    _, tau, gain, offset, changed = best
    return {"subsystem": "sensors", "signal": name, "time_constant_s": tau, "gain": gain,
            "offset": offset, "holdout_gap": score(prepared, changed, "holdout").gap}


def _null(prepared: Prepared, params: ModelParams) -> dict:
    """The valve null offset [V] that fits the training samples, and the held-out gap left."""

    def preds(u0: float) -> list[Prediction]:
        moved = dataclasses.replace(prepared, records=[
            dataclasses.replace(r, u=r.u + u0) for r in prepared.records])
        return predict_all(params, moved, None)

    fit = optimize.minimize_scalar(lambda u0: score(prepared, preds(u0), "train").total,
                                   bounds=(-NULL_OFFSET, NULL_OFFSET), method="bounded",
                                   options={"xatol": 2e-3})
    return {"subsystem": "valve", "signal": "u", "null_offset_v": float(fit.x),
            "holdout_gap": score(prepared, preds(float(fit.x)), "holdout").gap}


def place(prepared: Prepared, params: ModelParams,
          remainders: dict[str, EquationError]) -> dict:
    """Where the gap of ``params`` on the held-out data starts (module docstring): the
    subsystem, in words why, and every experiment's held-out gap and share removed.
    ``remainders``: what each equation of ``params`` leaves beyond calibration, by equation
    (:func:`residuals.locate`)."""
    base = score(prepared, predict_all(params, prepared, None), "holdout")
    experiments = [_sensor(prepared, params, s) for s in prepared.sensors]
    experiments = [e for e in experiments if e] + [_null(prepared, params)]
    for e in experiments:
        e["removed"] = 1.0 - e["holdout_gap"] / base.gap if base.gap > 0 else 0.0
    best = max(experiments, key=lambda e: e["removed"])
    replays = subsystem_gaps(prepared, params, "holdout", refit=True)
    out = {"holdout_gap": base.gap, "experiments": experiments, "replays": replays,
           "places_at": PLACES}
    if best["removed"] >= PLACES:
        what = (f"a lag of {1e3 * best['time_constant_s']:g} ms, gain {best['gain']:.3f} and "
                f"offset of the {best['signal']} sensor alone" if best["subsystem"] == "sensors"
                else f"a valve null offset of {best['null_offset_v']:+.3f} V alone")
        return {**out, "subsystem": best["subsystem"],
                "words": f"{what} removes {100 * best['removed']:.0f} % of the held-out gap"}
    words = (f"no one measured signal explains it (best: {best['signal']}, "
             f"{100 * best['removed']:.0f} %)")
    chambers = replays["valve_and_chambers"]["gap"]
    if replays["mechanics"] is None:
        subsystem = "valve+chamber"
        words += "; the mechanics cannot be replayed apart (it needs both pressures measured)"
    else:
        mechanics = replays["mechanics"]["gap"]
        subsystem = "mechanics" if mechanics > chambers else "valve+chamber"
        words += (f"; replayed with their inputs measured, the mechanics miss by "
                  f"{mechanics:.2f} %, the valve and chambers by {chambers:.2f} %")
    if subsystem == "valve+chamber":
        shares = _term_shares(remainders)
        out["chamber_balance_shares"] = shares
        kind = max(shares, key=shares.get)
        if shares[kind] > 0.0 and shares[kind] > min(shares.values()):
            subsystem = kind
        words += (f"; the chamber balances' error is shaped by the valve's terms "
                  f"({100 * shares['valve']:.0f} % of its variance) and the chambers' "
                  f"({100 * shares['chamber']:.0f} %)")
    return {**out, "subsystem": subsystem, "words": words}


def _term_shares(remainders: dict[str, EquationError]) -> dict[str, float]:
    """Share of the chamber balances' error variance carried by the valve's and by the
    chambers' library terms (:func:`residuals.sparse_terms`), averaged over the balances."""
    balances = [e for name, e in remainders.items() if name.startswith("chamber")]
    shares = {"valve": 0.0, "chamber": 0.0}
    for err in balances:
        for term in sparse_terms(err):
            if term["subsystem"] in shares:
                shares[term["subsystem"]] += term["share"] / len(balances)
    return shares
