"""Model predictions of recorded experiments, whole or by subsystem.

The piston integrates its velocity and the recorded command of a closed-loop experiment would let
a replayed position wander off, so free-piston experiments are predicted over short horizons:
every ``horizon`` seconds the model restarts from the measured position, velocity and pressures,
after a short warm-up during which the valve sees the recorded command while chambers and piston
are held on the measurements (so the valve's own state is right at the restart). Measurements
that set the state are smoothed (zero phase) first, so sensor noise does not enter the restarts,
and pass back through the inverse of the model's own pressure-sensor model (bias, drift, lag) when
the sensor_dynamics effect is on, so a restart does not hand the sensor's error to the state. A
pressure the record did not measure (NaN) is restarted from the model's own estimate of it: its
chamber replayed from the measured motion and command (``mode="chambers"``), an observer that
stays with the hardware because the chamber is driven by what was measured. (Carried through the
restarts by the model instead, an unmeasured pressure drifts with every window's error, and even
a perfect model then misses by 3 % of the position's spread: a noise floor 100 times the
measured sensors', under which a 4.5 ms valve delay vanished.) The replay must start somewhere,
and nothing measured says where: :func:`unknown_start` finds how long that choice still matters,
and :func:`without_unknown_start` leaves those first samples out of the comparison.
Locked-piston experiments are stable and are predicted whole. Friction tests on the regulated rig
are predicted as the mechanics alone: their pressures are the regulators'.

The same kernel also replays one subsystem with its inputs held on the measurements: the valve
and chambers driven by the measured motion (``mode="chambers"``), or the mechanics driven by the
measured pressures (``mode="mechanics"``), so each can be judged apart.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from jetpipe_ros.diagnosis.data import MIN_HOLDOUT_S, MIN_SCALE, MIN_TRAIN_S, Prepared, Record
from jetpipe_ros.model import Actuator, ModelParams
from jetpipe_ros.model import kernel
from jetpipe_ros.model.flow import P_ATM, P_SUPPLY_NOMINAL

#: Default prediction horizon and warm-up [s].
HORIZON = 1.0
WARMUP = 0.05
MODES = ("full", "chambers", "mechanics")
#: Where the valve hysteresis's plays may stand when a record starts, as
#: :meth:`~jetpipe_ros.model.Actuator.preload_hysteresis` places them: after the command came
#: down to the record's start, midway, after it came up.
PLAY_STARTS = (1.0, 0.0, -1.0)
#: Where a chamber whose pressure no sensor measured may be when a record starts [Pa, absolute]:
#: anywhere between atmosphere and the supply of the valve's identification.
START_RANGE = (P_ATM, P_SUPPLY_NOMINAL)


@dataclass
class Prediction:
    """Predicted signals of one experiment, aligned with the record's samples."""

    y: np.ndarray  #: position [m]
    p1: np.ndarray  #: chamber 1 pressure, as the sensor reads it [Pa]
    p2: np.ndarray  #: chamber 2 pressure, as the sensor reads it [Pa]
    free: np.ndarray  #: bool mask of samples the model predicted (not held on measurements)

    def signal(self, name: str) -> np.ndarray:
        """A predicted signal by name (y, p1, p2)."""
        return getattr(self, name)


def windows(n: int, dt: float, horizon: float = HORIZON, warmup: float = WARMUP) -> np.ndarray:
    """Bool mask of the warm-up samples that start each prediction window of ``n`` samples."""
    held = np.zeros(n, dtype=bool)
    period = max(int(round(horizon / dt)), 2)
    lead = max(int(round(warmup / dt)), 1)
    for start in range(0, n, period):
        held[start:start + lead] = True
    return held


def sensor_inverse(params: ModelParams, p_meas: np.ndarray, t: np.ndarray,
                    chamber: int) -> np.ndarray:
    """Pressure [Pa] in chamber 1 or 2 that the model's pressure sensor would read as
    ``p_meas``."""
    if not params["effects.sensor_dynamics.enabled"]:
        return p_meas
    e = "effects.sensor_dynamics."
    offset = params[e + "bias"] + params[e + "drift"] * t
    if chamber == 2:
        offset = offset + params[e + "bias_difference"]
    p = (p_meas - offset) / (1.0 + params[e + "gain"])
    tau = params[e + "time_constant"]
    if tau > 0.0 and p.size > 2:
        p = p + tau * np.gradient(p, t)
    return p


def initial_state(params: ModelParams, y: np.ndarray, p1: np.ndarray,
                  p2: np.ndarray) -> dict[str, float]:
    """The model's initial position and pressures taken from the first samples of the
    (smoothed) measurements; a signal not measured (NaN) keeps the parameters' own value (the
    pressures' default is the valve's null equilibrium), and the model carries it from there."""
    out = {}
    for key, x, low, high in (("mechanics.initial_position", y, -0.5, 0.5),
                              ("chamber.initial_pressure_1", p1, 1e4, 1.2e6),
                              ("chamber.initial_pressure_2", p2, 1e4, 1.2e6)):
        if np.isfinite(x[0]):
            out[key] = float(np.clip(x[0], low, high))
    return out


def predict(params: ModelParams, rec: Record, dt: float, mode: str = "full",
            horizon: float = HORIZON, warmup: float = WARMUP,
            scale: Mapping[str, float] | None = None) -> Prediction:
    """Predict experiment ``rec`` with ``params`` (noise-free) at sample time ``dt``.

    With the valve's hysteresis on, where its plays stand when the record starts is set by
    commands the record does not show, and it matters for the whole record where the command
    never sweeps past the widest play: a closed-loop record near the valve's null keeps it
    throughout (a play of 0.58 V weighing 6 % of a three-play loop, started from the middle
    where the hardware had it at one side, missed slow closed-loop motion by 2.9 % of its
    spread; from that side by 0.3 %). So the record is predicted from each start of
    :data:`PLAY_STARTS` and the prediction closest to the record kept, as its first samples set
    the pressures and position the model starts from: each measured signal's mean square error
    over the predicted samples, over its ``scale`` [m or Pa] squared (default: its spread in
    the record, at least :data:`data.MIN_SCALE`)."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if rec.regulated:
        mode = "mechanics"
    hysteresis = (params["effects.valve_hysteresis.enabled"]
                  and params["effects.valve_hysteresis.half_width"] > 0.0)
    if mode == "mechanics" or not hysteresis:
        return _predict(params, rec, dt, mode, horizon, warmup, 0.0)
    preds = [_predict(params, rec, dt, mode, horizon, warmup, side) for side in PLAY_STARTS]
    return min(preds, key=lambda pred: misfit(pred, rec, scale))


def misfit(pred: Prediction, rec: Record, scale: Mapping[str, float] | None = None) -> float:
    """Sum over the record's scored signals of the mean square error of ``pred`` over the
    predicted samples where the record measured, over ``scale`` [m or Pa] squared (default:
    the signal's spread in the record, at least :data:`data.MIN_SCALE`)."""
    total = 0.0
    for s in rec.signals():
        measured = rec.signal(s)
        mask = pred.free & np.isfinite(measured)
        if not mask.any():
            continue
        norm = scale[s] if scale is not None else max(float(np.std(measured[mask])),
                                                      MIN_SCALE[s])
        total += float(np.mean((pred.signal(s)[mask] - measured[mask]) ** 2)) / norm ** 2
    return total


def _predict(params: ModelParams, rec: Record, dt: float, mode: str, horizon: float,
             warmup: float, side: float) -> Prediction:
    """:func:`predict` from the hysteresis's plays at ``side``
    (:meth:`~jetpipe_ros.model.Actuator.preload_hysteresis`)."""
    y = rec.smooth["y"]
    p1, p2 = (sensor_inverse(params, rec.smooth[s], rec.t, i)
              for i, s in ((1, "p1"), (2, "p2")))
    changes = {"mechanics.locked": rec.locked, "sensors.noise": False,
               **initial_state(params, y, p1, p2)}
    n = rec.t.size
    if mode == "full" and not rec.locked and not (rec.measured("p1") and rec.measured("p2")) \
            and rec.measured("y"):
        # The unmeasured pressures, replayed from the measured motion: what restarts them.
        replayed = _run(params.at_sample_time(dt).with_values(changes), rec,
                        _motion_drive(rec, y, dt), side)
        p1 = p1 if rec.measured("p1") else replayed[:, kernel.OUT_P1]
        p2 = p2 if rec.measured("p2") else replayed[:, kernel.OUT_P2]
    act = Actuator(params.at_sample_time(dt).with_values(changes))
    act.preload_hysteresis(side)
    drive = np.full((n - 1, kernel.N_DRIVE), np.nan)
    held = np.zeros(n, dtype=bool)
    if mode == "chambers" and not rec.locked:
        drive = _motion_drive(rec, y, dt)
    elif mode == "mechanics":
        # A driven step holds the pressures: at their mean over the step, so the force on the
        # piston is not half a sample late.
        drive[:, kernel.DRIVE_P1] = 0.5 * (p1[:-1] + p1[1:])
        drive[:, kernel.DRIVE_P2] = 0.5 * (p2[:-1] + p2[1:])
        if not rec.locked:
            held = windows(n, dt, horizon, warmup)
            _drive_to_next(drive, held, y, rec.v, dt)
    elif mode == "full" and not rec.locked:
        held = windows(n, dt, horizon, warmup)
        _drive_to_next(drive, held, y, rec.v, dt, p1, p2)
    out = _run_actuator(act, rec, drive)
    free = ~held
    free[0] = False
    return Prediction(y=out[:, kernel.OUT_Y_MEAS], p1=out[:, kernel.OUT_P1_MEAS],
                      p2=out[:, kernel.OUT_P2_MEAS], free=free)


def unknown_start(params: ModelParams, rec: Record, dt: float) -> int:
    """Samples at the start of ``rec`` over which the replay of a pressure it did not measure
    still depends on where that chamber started (0 when there is none to replay).

    The chambers are replayed from the measured motion (:func:`predict`) twice, from the two
    ends of :data:`START_RANGE`. Each chamber is then driven by the command and the measured
    motion alone, so its replay is monotone in its start and every other start lies between the
    two: from the first sample after which they stay within the pressure sensor's noise
    (``sensors.pressure_sigma`` [Pa]) the replay knows the pressure as well as a sensor would,
    whatever the start. Before it, a position-only record holds the replay's guess, not the
    hardware: on the model's own records with a noise-free position that first stretch made
    the held-out error 7 times the noise twin's, which, simulated from the very state the
    replay assumes, showed nothing of it.
    """
    unmeasured = [s for s in ("p1", "p2") if not rec.measured(s)]
    if not unmeasured or rec.locked or rec.regulated or not rec.measured("y"):
        return 0
    out = {"p1": kernel.OUT_P1, "p2": kernel.OUT_P2}
    drive = _motion_drive(rec, rec.smooth["y"], dt)
    base = params.at_sample_time(dt).with_values({
        "mechanics.locked": False, "sensors.noise": False,
        **initial_state(params, rec.smooth["y"], rec.smooth["p1"], rec.smooth["p2"])})
    ends = [_run(base.with_values({"chamber.initial_pressure_1": p0,
                                   "chamber.initial_pressure_2": p0}), rec, drive)
            for p0 in START_RANGE]
    spread = np.max([np.abs(ends[1][:, out[s]] - ends[0][:, out[s]]) for s in unmeasured],
                    axis=0)
    apart = np.flatnonzero(~(spread <= params["sensors.pressure_sigma"]))
    return int(apart[-1]) + 1 if apart.size else 0


def without_unknown_start(prepared: Prepared, params: ModelParams) -> Prepared:
    """``prepared`` with the samples :func:`unknown_start` finds left out of training and
    held-out comparison (a note says how much), unless that would leave less than the
    diagnosis needs (then a note says the start is compared unsettled)."""
    cut = [unknown_start(params, rec, prepared.dt) for rec in prepared.records]
    if not any(cut):
        return prepared
    records = []
    for rec, k in zip(prepared.records, cut):
        train, holdout = rec.train.copy(), rec.holdout.copy()
        train[:k] = holdout[:k] = False
        records.append(dataclasses.replace(rec, train=train, holdout=holdout))
    out = dataclasses.replace(prepared, records=records, notes=list(prepared.notes))
    seconds = [k * prepared.dt for k in cut if k]
    share = 1.0 - sum(out.seconds(r) for r in ("train", "holdout")) / \
        sum(prepared.seconds(r) for r in ("train", "holdout"))
    words = (f"a pressure no sensor measured is replayed from the measured motion, and where "
             f"its chamber started is unknown: the first {min(seconds):.2f}-{max(seconds):.2f} "
             f"s of {len(seconds)} records, until the replay is the same from any start "
             f"between atmosphere and supply")
    if out.seconds("train") < MIN_TRAIN_S or out.seconds("holdout") < MIN_HOLDOUT_S:
        prepared.notes.append(f"{words}, are compared all the same: without them too little "
                              f"data would be left")
        return prepared
    out.notes.append(f"{words}, are not compared ({share:.0%} of the compared samples)")
    return out


def _drive_to_next(drive: np.ndarray, held: np.ndarray, y: np.ndarray, v: np.ndarray,
                   dt: float, p1: np.ndarray | None = None,
                   p2: np.ndarray | None = None) -> None:
    """Fill ``drive`` so that each step that starts on a ``held`` sample ends on the measured
    state of the sample after it: the free run after a warm-up then starts from the state
    measured where it starts. A driven step moves the piston at the driven velocity and holds
    the pressures, so the position is driven to y_{k+1} - v_{k+1} dt, the velocity and the
    pressures to those of sample k+1. (Driven with sample k's, every restart began with the
    pressures a sample old and the velocity a sample late: the model, predicting its own
    noise-free records, missed them by 230 um and 6.6 kPa RMS at 200 Hz, 45 um and 0.9 kPa at
    1 kHz, on a 3 V square wave into the end stops.)"""
    rows = held[:-1]
    drive[rows, kernel.DRIVE_Y] = (y[1:] - v[1:] * dt)[rows]
    drive[rows, kernel.DRIVE_V] = v[1:][rows]
    if p1 is not None and p2 is not None:
        drive[rows, kernel.DRIVE_P1] = p1[1:][rows]
        drive[rows, kernel.DRIVE_P2] = p2[1:][rows]


def _motion_drive(rec: Record, y: np.ndarray, dt: float) -> np.ndarray:
    """The kernel's drive that holds the piston on the measured (smoothed) motion ``y`` [m]: each
    step from y_k at the secant velocity (y_{k+1} - y_k) / dt (``dt`` [s], the step the kernel
    takes), so that it ends on y_{k+1} and the chambers see the volume swept over the step. (At
    the velocity estimated at y_k the chambers' replay of the model's own noise-free 200 Hz
    records missed them by 1-5 kPa RMS.)"""
    drive = np.full((rec.t.size - 1, kernel.N_DRIVE), np.nan)
    drive[:, kernel.DRIVE_Y] = y[:-1]
    drive[:, kernel.DRIVE_V] = np.diff(y) / dt
    return drive


def _run(params: ModelParams, rec: Record, drive: np.ndarray, side: float = 0.0) -> np.ndarray:
    """The model ``params`` (at the record's sample time) over the record's command and load
    with ``drive``, the hysteresis's plays started at ``side``: the kernel's outputs, one row
    per sample."""
    act = Actuator(params)
    act.preload_hysteresis(side)
    return _run_actuator(act, rec, drive)


def _run_actuator(act: Actuator, rec: Record, drive: np.ndarray) -> np.ndarray:
    out = np.empty((rec.t.size, kernel.N_OUT))
    out[0] = act.outputs()
    if rec.t.size > 1:
        out[1:] = act.run(rec.u[:-1], rec.f_load[:-1], drive)
    return out


def persistence(rec: Record, dt: float, horizon: float = HORIZON,
                warmup: float = WARMUP) -> Prediction:
    """The forecast that knows nothing of the actuator: each signal held, over every prediction
    window, at its (smoothed) measured value where the model restarts (for a locked-piston
    test, predicted whole, its first value). Scored like a model's prediction: a model no
    better than this describes nothing of the hardware."""
    n = rec.t.size
    starts = np.zeros(n, dtype=int)
    held = np.zeros(n, dtype=bool)
    if not rec.locked:
        held = windows(n, dt, horizon, warmup)
        lead = held & ~np.concatenate([[False], held[:-1]])  # first warm-up sample of a window
        starts = np.maximum.accumulate(np.where(lead, np.arange(n), 0))
        ends = np.flatnonzero(held & ~np.concatenate([held[1:], [False]]))  # last warm-up
        for end in ends:  # held at the restart value: the end of the warm-up
            starts[starts == starts[end]] = end
    free = ~held
    free[0] = False
    return Prediction(**{s: rec.smooth[s][starts] for s in ("y", "p1", "p2")}, free=free)

