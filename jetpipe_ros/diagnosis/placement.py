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
- each of these judged with the calibration knobs refitted beside it (a few Gauss-Newton steps
  from the recalibration's values): the whole model's recalibration may have made up for part
  of what the experiment changes (a lagging position read as more viscous friction); and
  against the same refit without it, so the knobs' own share is no experiment's;
- **the valve and chambers against the mechanics**: each replayed with its inputs held on the
  measurements (the chambers fed the measured motion and command, the piston the measured
  pressures: :func:`subsystem_gaps`), its own calibration knobs refitted on the training
  samples (the flow map, valve and dead volumes; the friction levels), since the whole model's
  recalibration may have moved one subsystem's knobs to make up for the other's missing physics;
  the replay that still misses by more holds the cause (the other one's gap falls when its inputs
  are right; both gaps are in per cent of the signals' spread beyond noise, so they compare).
  Between the valve and the chambers, the valve's static flow map is identified afresh
  (Eq. 8 times a gain that is a smooth function of command and pressure, fitted to the
  chambers' replay on the training samples, as the paper identifies Eq. 8 from the pressure
  rate of a chamber, Sec. 2.3): when it removes at least half of the chambers' held-out replay
  gap, the valve holds the cause (a static function of command and pressure: a null or gain
  that moves with pressure);
  when it does not, the chambers do (what the gas does beyond a flow that depends on them:
  heat, leaks across the piston, volumes in motion);
- **fewer sensors**: the mechanics replays only with both pressures measured, the chambers
  only against a measured pressure. With one pressure, the chambers' replay is set against the
  whole model on the same signal: fed the measured motion, the valve and chambers keep a gap
  of their own (beyond noise, and at least half the whole model's on that pressure) when the
  cause is theirs, and go on to the flow-map test above; when most of the pressure's gap goes
  once the motion is the measured one, the motion carried the error, and the mechanics holds
  the cause by elimination (said so). With no pressure measured (the position alone), or
  nothing beyond noise in the pressure either way, no replay can judge: the candidate that
  explains the largest share of the gap (on top of the recalibration, significantly) places it
  where it acts, said as such; with no candidate explaining any of it, the answer is that these
  records cannot place it (subsystem ``none``), not a default.

A one-signal experiment places the cause when it removes at least half of the held-out gap
beyond noise: more than all else together, so the signal it changes is where the gap starts. A
sensor fits first: a lag, gain or offset of one signal does not change what the actuator does,
so whatever else such a change explains (a valve delay on a position-only record is also a
position lag) is a candidate the diagnosis has already tried.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np
from scipy import optimize
from scipy import signal as sps

from jetpipe_ros.diagnosis.calibration import CALIBRATION
from jetpipe_ros.diagnosis.data import SIGNALS, Prepared, Record
from jetpipe_ros.diagnosis.prediction import Prediction, predict
from jetpipe_ros.diagnosis.score import predict_all, score
from jetpipe_ros.diagnosis.verdict import NOISE_GAP
from jetpipe_ros.model import ModelParams
from jetpipe_ros.model.flow import flow_matrix

#: Lags tried for one sensor [s]: a transducer's conditioning filter of a fraction of a sample
#: to a few tens of ms (docs/effects.md gives 1-10 ms for the pressure transducers).
SENSOR_LAGS = (5e-4, 1e-3, 2e-3, 3e-3, 4e-3, 6e-3, 8e-3, 1.2e-2, 1.6e-2, 2e-2)
#: Largest valve null offset tried [V] (the flow map's inputs span -2.8..3 V).
NULL_OFFSET = 0.5
#: A one-signal experiment that removes this share of the held-out gap places the cause.
PLACES = 0.5
#: Gauss-Newton steps of the calibration knobs refitted beside a one-signal experiment (they
#: start where the whole model's recalibration left them, near their optimum).
RECALIBRATION_STEPS = 3
#: Calibration knobs of each subsystem replayed apart (:mod:`calibration`), by replay mode.
OWN_KNOBS = {"chambers": ("flow_gain_charge", "flow_gain_discharge", "valve_gain",
                          "valve_frequency", "dead_volume_1", "dead_volume_2"),
             "mechanics": ("friction_entry", "friction_exit", "viscous_entry", "viscous_exit")}
#: The valve's flow map identified afresh: Eq. 8 times a gain that is a smooth function of
#: command and pressure, these powers (i, j) of u and p (the constant is the calibration's).
MAP_GAINS = ((1, 0), (0, 1), (1, 1), (2, 0), (0, 2))
#: Largest coefficient of each power in that gain (u and p scaled to within +-1 and +-0.5).
MAP_RANGE = 1.0


def _replays(params: ModelParams, prepared: Prepared, mode: str) -> list[Prediction | None]:
    """Every record's replay of one subsystem (``mode``: chambers | mechanics); the mechanics
    only of free-piston records with both pressures measured (it is driven by them)."""
    if mode == "chambers":
        return predict_all(params, prepared, None, "chambers")
    return [predict(params, r, prepared.dt, "mechanics")
            if not r.locked and r.measured("p1") and r.measured("p2") else None
            for r in prepared.records]


def _fit(prepared: Prepared, signals: tuple[str, ...],
         predictions: Callable[[np.ndarray], Sequence[Prediction | None]], n: int,
         bounds: tuple[np.ndarray, np.ndarray], evaluations: int | None = None) -> np.ndarray:
    """``z`` (n values within ``bounds``, starting at 0) whose ``predictions(z)`` fit the
    training samples of ``signals`` best (least squares; at most ``evaluations`` predictions,
    default ten per unknown and one)."""

    def residuals(z: np.ndarray) -> np.ndarray:
        out = [(p.signal(s) - r.signal(s))[p.free & r.train] / prepared.scale[s]
               for r, p in zip(prepared.records, predictions(z))
               if p is not None for s in signals if s in r.signals()]
        return np.concatenate(out) if out else np.zeros(1)

    return optimize.least_squares(residuals, np.zeros(n), diff_step=1e-3,
                                  max_nfev=evaluations or 10 * (n + 1), bounds=bounds).x


def _fit_replay(prepared: Prepared, mode: str, signals: tuple[str, ...],
                moved: Callable[[np.ndarray], ModelParams], n: int,
                bounds: tuple[np.ndarray, np.ndarray]) -> ModelParams:
    """``moved(z)`` with ``z`` fitted to the ``mode`` replay's training samples of
    ``signals`` (:func:`_fit`)."""
    return moved(_fit(prepared, signals, lambda z: _replays(moved(z), prepared, mode), n,
                      bounds))


def _recalibrated(prepared: Prepared, params: ModelParams,
                  predictions: Callable[[ModelParams, np.ndarray], Sequence[Prediction]],
                  extra: tuple[tuple[float, float], ...] = ()) -> float:
    """Held-out gap [%] of ``predictions(params', e)`` (an experiment's changed predictions)
    once every calibration knob is refitted with it on the training samples (factors on
    ``params``, a few Gauss-Newton steps from where the whole model's recalibration left
    them), and the experiment's ``extra`` unknowns (their bounds) with them: the
    recalibration may have made up for part of what the experiment changes."""
    knobs = CALIBRATION.knobs
    n = len(knobs)

    def run(z: np.ndarray) -> Sequence[Prediction]:
        q = CALIBRATION.apply(params, {k.name: float(np.exp(zi)) for k, zi in zip(knobs, z)})
        return predictions(q, z[n:])

    low = np.r_[np.log([k.low for k in knobs]), [b[0] for b in extra]]
    high = np.r_[np.log([k.high for k in knobs]), [b[1] for b in extra]]
    z = _fit(prepared, SIGNALS, run, n + len(extra), (low, high),
             evaluations=RECALIBRATION_STEPS * (n + len(extra) + 1))
    return score(prepared, run(z), "holdout").gap


def _refit(prepared: Prepared, params: ModelParams, mode: str,
           signals: tuple[str, ...]) -> ModelParams:
    """``params`` with the subsystem's own calibration knobs (:data:`OWN_KNOBS`) refitted to
    its replay's training samples (least squares on the log factors, within their ranges)."""
    knobs = [k for k in CALIBRATION.knobs if k.name in OWN_KNOBS[mode]]

    def moved(z: np.ndarray) -> ModelParams:
        return CALIBRATION.apply(params, {k.name: float(np.exp(zi)) for k, zi in zip(knobs, z)})

    return _fit_replay(prepared, mode, signals, moved, len(knobs),
                       (np.log([k.low for k in knobs]), np.log([k.high for k in knobs])))


def _flow_map(prepared: Prepared, params: ModelParams) -> ModelParams:
    """``params`` with the valve's flow map identified afresh in a smooth gain: Eq. 8 times
    ``1 + sum a_k b_k(u, p)`` over :data:`MAP_GAINS` (u / 3 V and (p - 5.5 bar) / 9 bar to the
    powers given), each ``a_k`` within +-``MAP_RANGE``, fitted to the chambers' replay on the
    training samples jointly with the chambers' own calibration knobs (the whole model's
    recalibration may have moved them to make up for the map). The product is carried into
    Eq. 8's own 21 coefficients by least squares over the map's domain (-3.4..3.4 V, 1..10 bar),
    so the model runs it as it runs Eq. 8."""
    base = np.array(params["flow.coefficients"], dtype=float)
    u, p = (g.ravel() for g in np.meshgrid(np.linspace(-3.4, 3.4, 35), np.linspace(1, 10, 37)))
    terms = flow_matrix(u, p)
    flow = terms @ base
    shapes = np.column_stack([flow * (u / 3.0) ** i * ((p - 5.5) / 9.0) ** j
                              for i, j in MAP_GAINS])
    per_gain, *_ = np.linalg.lstsq(terms, shapes, rcond=None)  # (21, gains)
    knobs = [k for k in CALIBRATION.knobs if k.name in OWN_KNOBS["chambers"]]
    n = len(knobs)

    def moved(z: np.ndarray) -> ModelParams:
        remapped = params.with_values({"flow.coefficients": (base + per_gain @ z[n:]).tolist()})
        return CALIBRATION.apply(remapped, {k.name: float(np.exp(zi))
                                            for k, zi in zip(knobs, z[:n])})

    gains = len(MAP_GAINS)
    return _fit_replay(prepared, "chambers", ("p1", "p2"), moved, n + gains,
                       (np.r_[np.log([k.low for k in knobs]), np.full(gains, -MAP_RANGE)],
                        np.r_[np.log([k.high for k in knobs]), np.full(gains, MAP_RANGE)]))


def subsystem_gaps(prepared: Prepared, params: ModelParams, role: str | None = None,
                   own: dict[str, ModelParams] | None = None) -> dict:
    """Gap [%] of each subsystem replayed with its inputs held on the measurements (``role``
    samples; all for None), each on ``params`` or on its own parameters in ``own`` (by replay
    mode: chambers, mechanics); and the steady pressure offset and noise the sensors show. A
    replay with nothing measured to compare it with is None, not a gap of zero: the valve and
    chambers without a pressure sensor, the mechanics without both (it is fed both)."""
    own = {"chambers": params, "mechanics": params, **(own or {})}
    chambers = score(prepared, _replays(own["chambers"], prepared, "chambers"), role,
                     ("p1", "p2"))
    mechanics = score(prepared, _replays(own["mechanics"], prepared, "mechanics"), role, ("y",))
    offsets = []
    for rec in prepared.records:
        if rec.regulated or not rec.measured("p1"):
            continue
        pred = predict(params, rec, prepared.dt, "chambers", scale=prepared.scale)
        steady = np.abs(np.gradient(rec.p1, prepared.dt)) < 2e4
        steady[: rec.t.size // 10] = False
        steady &= rec.train | rec.holdout
        if steady.sum() > 100:
            offsets.append(float(np.median((rec.p1 - pred.p1)[steady])))
    return {
        "valve_and_chambers": {"driven_by": "measured command and piston motion",
                               **chambers.to_json()} if chambers.mse else None,
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


def _sensor_predictions(prepared: Prepared, params: ModelParams, name: str,
                        tau: float) -> tuple[list[Prediction], float, float]:
    """Predictions of every record with sensor ``name`` read through a lag ``tau`` [s] and the
    gain and offset that fit its training samples best (least squares), and those two."""
    dt = prepared.dt
    records = [_restarted(r, name, tau, dt) if r.measured(name) else r for r in prepared.records]
    preds = predict_all(params, dataclasses.replace(prepared, records=records), None)
    lagged = [_lag(p.signal(name), tau, dt) for p in preds]
    rows = [(lg[m], r.signal(name)[m]) for r, p, lg in zip(prepared.records, preds, lagged)
            if r.measured(name) and name in r.signals() for m in [p.free & r.train] if m.any()]
    if not rows:
        return preds, 1.0, 0.0
    x = np.concatenate([a for a, _ in rows])
    target = np.concatenate([b for _, b in rows])
    (gain, offset), *_ = np.linalg.lstsq(np.column_stack([x, np.ones_like(x)]), target,
                                         rcond=None)
    changed = [dataclasses.replace(p, **{name: gain * lg + offset})
               for p, lg in zip(preds, lagged)]
    return changed, float(gain), float(offset)


def _sensor(prepared: Prepared, params: ModelParams, name: str) -> dict:
    """The lag (on :data:`SENSOR_LAGS`), gain and offset of sensor ``name`` that fit the
    training samples best, and the held-out gap left with the calibration knobs refitted."""
    if not any(r.measured(name) and name in r.signals() for r in prepared.records):
        return {}
    fits = [(score(prepared, preds, "train").total, tau, gain, offset)
            for tau in SENSOR_LAGS
            for preds, gain, offset in [_sensor_predictions(prepared, params, name, tau)]]
    _, tau, gain, offset = min(fits)
    gap = _recalibrated(prepared, params,
                        lambda q, _: _sensor_predictions(prepared, q, name, tau)[0])
    return {"subsystem": "sensors", "signal": name, "time_constant_s": tau, "gain": gain,
            "offset": offset, "holdout_gap": gap}


def _null(prepared: Prepared, params: ModelParams) -> dict:
    """The valve null offset [V] that fits the training samples, and the held-out gap left
    with it refitted jointly with the calibration knobs."""

    def preds(q: ModelParams, u0: float) -> list[Prediction]:
        moved = dataclasses.replace(prepared, records=[
            dataclasses.replace(r, u=r.u + u0) for r in prepared.records])
        return predict_all(q, moved, None)

    fit = optimize.minimize_scalar(lambda u0: score(prepared, preds(params, u0), "train").total,
                                   bounds=(-NULL_OFFSET, NULL_OFFSET), method="bounded",
                                   options={"xatol": 2e-3})
    u0 = float(fit.x)
    gap = _recalibrated(prepared, params, lambda q, e: preds(q, u0 + e[0]),
                        ((-NULL_OFFSET - u0, NULL_OFFSET - u0),))
    return {"subsystem": "valve", "signal": "u", "null_offset_v": u0, "holdout_gap": gap}


def by_candidates(leads: Sequence[tuple[str, str, float]], words: str) -> dict:
    """The subsystem of the candidate that removes the largest share of the gap, of ``leads``
    (candidate, its subsystem, held-out share removed; only those that explain part of the
    gap), placed so when no replay can judge; "none" when no candidate explains any of it."""
    if not leads:
        return {"subsystem": "none", "words": words + "; no candidate explains part of it: "
                "these records cannot place it"}
    name, subsystem, share = max(leads, key=lambda lead: lead[2])
    return {"subsystem": subsystem, "placed_by": name,
            "words": words + f"; of the candidates, {name} explains most of it "
                             f"({100 * share:.0f} %), so it is placed where that one acts"}


def place(prepared: Prepared, params: ModelParams,
          leads: Sequence[tuple[str, str, float]] = ()) -> dict:
    """Where the gap of ``params`` on the held-out data starts (module docstring): the
    subsystem, in words why, and every experiment's held-out gap and share removed.
    ``leads`` are the candidates that explain part of the gap (name, subsystem, held-out
    share removed): where the records hold too few signals for any replay to judge, the
    largest of them places it."""
    whole = predict_all(params, prepared, None)
    base = score(prepared, whole, "holdout")
    # What the same refit of the knobs leaves without any experiment: the bar each one is
    # judged against, so that no experiment gets credit for what the knobs alone remove.
    knobs_alone = _recalibrated(prepared, params, lambda q, _: predict_all(q, prepared, None))
    reference = min(base.gap, knobs_alone)
    experiments = [_sensor(prepared, params, s) for s in prepared.sensors]
    experiments = [e for e in experiments if e] + [_null(prepared, params)]
    for e in experiments:
        e["removed"] = 1.0 - e["holdout_gap"] / reference if reference > 0 else 0.0
    best = max(experiments, key=lambda e: e["removed"])
    own = {mode: _refit(prepared, params, mode, signals)
           for mode, signals in (("chambers", ("p1", "p2")), ("mechanics", ("y",)))}
    replays = subsystem_gaps(prepared, params, "holdout", own)
    out = {"holdout_gap": base.gap, "knobs_refitted_gap": knobs_alone,
           "experiments": experiments, "replays": replays,
           "places_at": PLACES}
    if best["removed"] >= PLACES:
        what = (f"a lag of {1e3 * best['time_constant_s']:g} ms, gain {best['gain']:.3f} and "
                f"offset of the {best['signal']} sensor alone" if best["subsystem"] == "sensors"
                else f"a valve null offset of {best['null_offset_v']:+.3f} V alone")
        return {**out, "subsystem": best["subsystem"],
                "words": f"{what} removes {100 * best['removed']:.0f} % of the held-out gap"}
    words = (f"no one measured signal explains it (best: {best['signal']}, "
             f"{100 * best['removed']:.0f} %)")
    if replays["mechanics"] is None:
        words += "; the mechanics cannot be replayed apart (it needs both pressures measured)"
        if replays["valve_and_chambers"] is None:
            words += "; nor can the chambers (no chamber pressure is measured)"
            return {**out, **by_candidates(leads, words)}
        chambers = replays["valve_and_chambers"]["gap"]
        # One replay against the whole model on the same signals: fed the measured motion,
        # the valve and chambers keep a gap of their own if the cause is theirs; if the
        # motion was what the whole model got wrong, most of the pressure's gap goes.
        pressures = score(prepared, whole, "holdout", ("p1", "p2")).gap
        words += (f"; fed the measured motion, the valve and chambers miss the measured "
                  f"pressure by {chambers:.2f} %, the whole model by {pressures:.2f} %")
        if chambers >= max(NOISE_GAP, PLACES * pressures):
            subsystem = "valve+chamber"
        elif pressures >= NOISE_GAP:
            return {**out, "subsystem": "mechanics",
                    "words": words + ": the motion carries the error, so it starts in the "
                                     "mechanics (by elimination: not replayed apart)"}
        else:
            return {**out, **by_candidates(leads, words + ", both within noise")}
    else:
        mechanics = replays["mechanics"]["gap"]
        chambers = replays["valve_and_chambers"]["gap"]
        subsystem = "mechanics" if mechanics > chambers else "valve+chamber"
        words += (f"; replayed with their inputs measured, the mechanics miss by "
                  f"{mechanics:.2f} %, the valve and chambers by {chambers:.2f} %")
    if subsystem == "valve+chamber":
        remapped = score(prepared, _replays(_flow_map(prepared, own["chambers"]), prepared,
                                            "chambers"), "holdout", ("p1", "p2")).gap
        share = 1.0 - remapped / chambers if chambers > 0 else 0.0
        out["flow_map_removed"] = share
        subsystem = "valve" if share >= PLACES else "chamber"
        removed = (f"{100 * share:.0f} % of the chambers' replay gap" if share > 0.0 else
                   f"none of the chambers' replay gap (it leaves {remapped:.2f} %)")
        words += (f"; the valve's flow map identified afresh (Eq. 8 times a smooth gain) removes "
                  f"{removed}")
    return {**out, "subsystem": subsystem, "words": words}
