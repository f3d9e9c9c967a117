"""Where the measurements sit in time relative to the command: a logger's convention, measured.

The data contract pairs, on row k, the command u_k with the measurements taken at t_k, *before*
u_k acts (a sampled loop reads its sensors, then computes and applies the command). Another
common convention writes beside u_k the measurement taken *after* it acted: every measurement
then sits a row early, and a model compared with it looks too slow (an extra valve lag or delay,
a faster torque motor). This module measures the offset before anything is fitted, with two
pieces of evidence that do not share their assumptions:

- **The model's own delay** (open and closed loop). The valve cannot move the chambers or the
  piston sooner than its transport delay (Eq. 10, 2 ms) and its dynamics allow. The nominal model
  is fitted to the training records with one extra knob, a time offset of the measurements
  (continuous, +-:data:`MAX_OFFSET` s), beside the calibration knobs that also shape how soon
  the measurements answer (valve gain and natural frequency, flow gains, dead volumes);
  locked-piston records are used when there are enough (their pressures answer the valve
  directly), else all. No valve lag is fitted beside it: a lag at its vanishing corner (300 Hz)
  still delays by 0.5 ms, which the offset would then pay back, and a real lag looks like a
  delay of several ms anyway (which only the controller's reaction below sees through). A
  negative offset (the measurements answer sooner than the valve allows) is a logging
  convention, not physics; a positive one is the same, in open loop, as an extra valve delay
  (``valve_delay``): both readings fit.
- **The controller's reaction** (closed loop). A controller reacts at once to the sensor noise
  of the position it reads, while the plant cannot answer its command within the valve's delay.
  The high-frequency part of the command (less its zero-phase smoothing) is regressed on that
  of the position at row lags -1..3: the first lag at which the command follows the position's
  noise beyond :data:`Z_CONTROLLER` standard errors (and :data:`MINOR` of the strongest
  reaction) is where the controller read it. At lag 0 the log
  follows the contract; at lag 1 the measurements are a row early. This assumes the controller
  uses its newest sample (the sampled loop of the contract); a controller that computes from
  the previous sample looks like a log a row early, so when the model's delay disagrees the
  model is believed for negative offsets (physics forbids them) and the disagreement is said.

Which is believed depends on what the model's estimate is read through. With both pressures
measured, the chambers answer the valve within its delay, in opposite senses, and the offset is
pinned by the quickest part of the response (within 0.2 ms of the truth on aligned held-out
records, standard errors near 0.2 ms). With fewer sensors it is not, and its standard error,
computed as if the model were right, does not widen with what the model misses:

- with the position alone the offset is read through the piston, which integrates the chambers'
  flows twice, so any unmodelled effect of the chambers or the friction moves it by
  milliseconds (on 24 held-out records of the position alone logged aligned, 5 had an offset of
  -2 to -3 ms at about 3 standard errors);
- with one pressure it is read through one chamber, where a timing offset trades off with that
  chamber's own flow gains and dead volume (on 4 held-out records of chamber 1's pressure alone
  logged aligned, 3 had offsets of +-1.8 to 1.9 ms at 5 standard errors, on actuators whose
  offset with both pressures was within 0.2 ms).

The controller reacted on the logged row in all 8. So without both pressures the controller's
reaction, which needs no model, is believed whenever there is one, and the model's offset is only
said beside it. Without one nothing tells, and nothing is moved: the time base is said to be not
checked, and a logger's convention is for the user to declare (``measured: after_command`` in
dataset.yaml, which the reader applies).

Corrections are by whole rows (:func:`data.prepare`'s ``shift_rows``); what remains of the
estimate, under half a row, is left to the diagnosis like any other delay.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from jetpipe_ros.diagnosis.calibration import CALIBRATION, Calibration
from jetpipe_ros.diagnosis.candidates import Knob, KnobGroup
from jetpipe_ros.diagnosis.data import Prepared
from jetpipe_ros.diagnosis.fit import Fit, fit, uncertainty
from jetpipe_ros.model import ModelParams

#: Largest time offset searched either way [s] (a logger a few samples off at 1 kHz).
MAX_OFFSET = 3e-3
#: t statistic of the controller's reaction above which it is evidence (under no reaction
#: about standard normal; 5 leaves room for the five lags tried and the residuals' colour).
Z_CONTROLLER = 5.0
#: Fraction of the strongest reaction below which a lag's reaction is not the controller's.
MINOR = 0.1
#: Standard errors by which an offset must differ from zero before it is acted on.
Z_OFFSET = 3.0
#: Row lags of the controller test: the command following the position by -1..3 rows.
LAGS = range(-1, 4)
#: Least seconds of locked-piston training data for the offset fit to use those alone.
MIN_LOCKED_S = 2.0
#: Model evaluations of the offset fit.
BUDGET = 60
#: Knobs beside the offset that change how soon the measurements answer the command.
NUISANCE = ("flow_gain_charge", "flow_gain_discharge", "valve_gain", "valve_frequency",
            "dead_volume_1", "dead_volume_2")


@dataclass(frozen=True)
class _Offset(KnobGroup):
    """The time offset as a knob: the valve's whole transport delay [s] on records whose
    measurements were moved later by whole rows; offset = delay - ``zero``."""

    zero: float = 0.0  #: the delay at which the offset is nil [s]

    def apply(self, params: ModelParams, values: dict[str, float]) -> ModelParams:
        return params.with_values({"valve.delay": max(values["delay"], 0.0)})


@dataclass
class Alignment:
    """The measured offset of the measurements against the command and what was done."""

    offset_s: float  #: model estimate of the lag beyond the nominal valve's: the measurements'
    #: stamps minus when the nominal model would have them [s] (logger and extra delay together)
    stderr_s: float | None  #: its standard error [s]
    controller_rows: int | None  #: closed loop: row lag at which the command follows y
    controller_z: float  #: strength of that reaction [standard errors]
    shift_rows: int  #: correction applied: measurements moved this many rows later
    #: aligned | logging convention | extra delay or logging | extra delay | not checked
    reading: str
    words: str  #: the reading in a sentence
    used: str  #: which records the model estimate used

    def logger_offset(self, dt: float) -> float:
        """The offset attributed to the logger [s]: the measurements' stamps minus when they
        were taken (negative: written a row early), i.e. the correction undone."""
        return -self.shift_rows * dt

    def to_json(self, dt: float) -> dict:
        """The ``data.time_base`` section of diagnosis.json."""
        return {"time_offset_s": self.logger_offset(dt), "stderr_s": self.stderr_s,
                "corrected_rows": self.shift_rows,
                "model_offset_s": self.offset_s,
                "remaining_s": self.offset_s + self.shift_rows * dt,
                "controller_lag_rows": self.controller_rows,
                "controller_z": self.controller_z, "reading": self.reading,
                "explanation": self.words, "model_estimate_from": self.used}


def controller_reaction(prepared: Prepared) -> tuple[int | None, float]:
    """The first row lag (command after position) at which the command of the closed-loop
    records follows the position's noise beyond :data:`Z_CONTROLLER`, and its t statistic;
    (None, largest |t|) when nothing reacts (no position noise), (None, 0) without a
    closed-loop record, declared or found (:attr:`Record.closed_loop`).

    The high-frequency parts (each signal less its zero-phase smoothing) of the command are
    regressed on those of the position at every lag of :data:`LAGS` at once: the smoothing
    spreads each noise sample over its neighbours, so a lag tested alone would borrow the
    reaction of the next one. Only closed-loop records: a command written beforehand reacts to
    nothing, yet its sweeps and steps, which the position follows, are predicted by the
    position's past as well, with residuals too coloured for the t statistic (on the open-loop
    records of three plants of the self-check, aligned, a reaction stood out at 3 rows with
    t = 5.2, or at -1, and moved the records by as much)."""
    records = [r for r in prepared.records if r.closed_loop]
    width = max(LAGS) - min(LAGS)
    rows_x, rows_u = [], []
    for rec in records:
        if not rec.measured("y") or np.std(rec.u) < 1e-9 or rec.t.size <= 2 * width:
            continue
        eu, ey = rec.high_frequency(prepared.dt)
        ok = rec.train | rec.holdout
        k = np.arange(max(LAGS), rec.t.size + min(LAGS))  # rows with every lag inside
        cols = np.column_stack([ey[k - lag] for lag in LAGS])
        keep = ok[k] & np.all([ok[k - lag] for lag in LAGS], axis=0)
        rows_x.append(cols[keep])
        rows_u.append(eu[k][keep])
    if not rows_x or sum(len(u) for u in rows_u) <= 10 * len(LAGS):
        return None, 0.0
    x, u = np.concatenate(rows_x), np.concatenate(rows_u)
    coef, *_ = np.linalg.lstsq(x, u, rcond=None)
    resid = u - x @ coef
    sigma2 = float(resid @ resid) / max(u.size - len(LAGS), 1)
    cov = sigma2 * np.linalg.pinv(x.T @ x)
    t = {lag: abs(float(c)) / np.sqrt(max(cov[i, i], 1e-300))
         for i, (lag, c) in enumerate(zip(LAGS, coef))}
    # The first lag of a strong reaction: a derivative action reacts to two rows about
    # equally, and the first is the one read; a small fraction of the largest reaction is not
    # the controller's but what lost rows (held commands, interpolated positions) leave.
    strong = [lag for lag in LAGS if t[lag] > max(Z_CONTROLLER, MINOR * max(t.values()))]
    if not strong:
        return None, float(max(t.values()))
    return strong[0], float(t[strong[0]])


def _measured_later(prepared: Prepared, rows: int) -> Prepared:
    """The records with each measurement moved ``rows`` rows later (beside a later command),
    the first rows left without one (out of every comparison): every command is kept from the
    start, so the valve sees the record's beginning as it was."""
    if rows == 0:
        return prepared

    def later(x: np.ndarray) -> np.ndarray:
        return np.concatenate([np.repeat(x[:1], rows), x[:x.size - rows]])

    def none_first(m: np.ndarray) -> np.ndarray:
        return np.concatenate([np.zeros(rows, dtype=bool), m[:m.size - rows]])

    return dataclasses.replace(prepared, records=[dataclasses.replace(
        r, **{s: later(getattr(r, s)) for s in ("y", "p1", "p2", "v")},
        smooth={s: later(x) for s, x in r.smooth.items()},
        train=none_first(r.train), holdout=none_first(r.holdout)) for r in prepared.records])


def search_reach(dt: float) -> float:
    """How far [s] the offset is searched either way at sample time ``dt`` [s]."""
    return max(MAX_OFFSET, 1.5 * dt)


def at_edge(offset: float, dt: float) -> bool:
    """Whether an offset [s] lies at the edge of its search range (within 1 % of the range's
    width, as a knob at its bound, :meth:`KnobGroup.pinned`): the fit would have gone further,
    so it is not a measurement. Seen on records of the position alone, where the offset trades
    off with knobs the position does not pin: of 12 held-out records of seed 7919 whose log was
    aligned, 4 were moved 2-3 rows by mistake, 2 of them on an offset fitted at -3 ms."""
    reach = search_reach(dt)
    return abs(offset) >= reach - 0.02 * reach


def model_offset(prepared: Prepared, nominal: ModelParams) -> tuple[float, float | None, str]:
    """The time offset of the measurements [s] that fits the nominal model best, its standard
    error (marginal over the nuisance knobs), and which records were used. Searched over
    +-max(:data:`MAX_OFFSET`, 1.5 samples) through the valve's transport delay, the
    measurements moved later by whole rows where the delay alone cannot go that far below."""
    locked = [r for r in prepared.records if r.locked and r.signals()]
    use_locked = sum(float(r.train.sum()) for r in locked) * prepared.dt >= MIN_LOCKED_S
    records = locked if use_locked else [r for r in prepared.records if r.signals()]
    used = "locked-piston records" if use_locked else "all records"
    dt = prepared.dt
    reach = search_reach(dt)
    base = nominal["valve.delay"]
    rows = max(0, int(np.ceil((reach - base) / dt - 1e-9)))
    zero = base + rows * dt
    data = _measured_later(dataclasses.replace(prepared, records=records), rows)
    offset = _Offset("time_offset", (Knob("delay", zero - reach, zero + reach, zero),),
                     zero=zero)
    nuisance = Calibration("alignment", tuple(k for k in CALIBRATION.knobs
                                              if k.name in NUISANCE))
    groups: tuple[KnobGroup, ...] = (offset, nuisance)
    fitted: Fit = fit(data, nominal, groups, None, BUDGET)
    delay = fitted.values["time_offset"]["delay"]
    se = uncertainty(data, nominal, fitted, groups)["time_offset"]["delay"]
    return delay - zero, se, used


def align(prepared: Prepared, nominal: ModelParams) -> Alignment:
    """Measure the offset and decide the correction (see the module text)."""
    dt = prepared.dt
    offset, se, used = model_offset(prepared, nominal)
    lag, z = controller_reaction(prepared)
    sig = se if se is not None else dt
    rows = int(np.round(offset / dt))
    edge = at_edge(offset, dt)
    significant = abs(offset) > Z_OFFSET * sig and rows != 0 and not edge
    est = f"{offset * 1e3:+.2f} ms (+-{sig * 1e3:.2f})"
    if edge:
        est += (f", at the edge of the +-{search_reach(dt) * 1e3:.1f} ms searched: not a "
                f"measurement")
    sooner = significant and rows < 0  # answers sooner than the valve allows: the logger
    pressures = [p for p in ("p1", "p2") if p in prepared.sensors]
    if len(pressures) < 2:
        through = f"the position and {pressures[0]}" if pressures else "the position alone"
        if lag is None:
            return _unchecked(offset, se, z, est, used, through)
        return _controller_believed(offset, se, lag, z, est, used, through)
    if lag:  # the controller reacts off the logged row: the logger, by the contract's loop
        shift = max(lag, -rows) if sooner else lag
        reading = "logging convention"
        words = f"{_controller_reading(lag)} (the model's delay says {est})"
        if shift != lag:
            words += (f"; the measurements answer sooner still than the valve allows, so "
                      f"{shift} row(s)")
        elif rows + lag > 0 and significant:
            words += (f"; what remains, {(offset + lag * dt) * 1e3:.2f} ms, is an extra delay "
                      f"of the actuator (or a controller that computes from its previous "
                      f"sample: then the log was right and this is all delay)")
        words += f"; corrected by moving them {abs(shift)} row(s) " \
                 f"{'later' if shift > 0 else 'earlier'}"
    elif sooner:
        shift = -rows
        reading = "logging convention"
        words = (f"the measurements answer the command {-offset * 1e3:.2f} ms sooner than the "
                 f"valve's delay allows ({est}): a logger that writes beside each command the "
                 f"measurement taken after it acted, not physics; corrected by moving them "
                 f"{shift} row(s) later")
        if lag == 0:
            words += ("; the closed-loop records' controller reacts on the same row, so it "
                      "may read its measurement a sample late")
    elif significant and rows > 0:
        shift = 0
        if lag == 0:
            reading = "extra delay"
            words = (f"the measurements answer {offset * 1e3:.2f} ms later than the nominal "
                     f"model ({est}), and the closed-loop records show the log aligned (the "
                     f"controller reacts on the same row): an extra delay of the actuator, "
                     f"left to the diagnosis")
        else:
            reading = "extra delay or logging"
            words = (f"the measurements answer {offset * 1e3:.2f} ms later than the nominal "
                     f"model ({est}): either the actuator has an extra valve delay or the "
                     f"logger writes its measurements late; these records cannot tell (a "
                     f"closed-loop record would), so the record is diagnosed as logged and a "
                     f"valve_delay verdict may be the logger's")
    else:
        shift = 0
        reading = "aligned"
        words = (f"the measurements sit where the contract puts them (offset {est}"
                 + (", and the closed-loop controller reacts on the same row" if lag == 0
                    else "") + ")")
    return Alignment(offset, se, lag, z, shift, reading, words, used)


def _controller_believed(offset: float, se: float | None, lag: int, z: float, est: str,
                         used: str, through: str) -> Alignment:
    """The reading of records without both pressures that hold a closed loop: the controller's
    reaction decides the correction, the model's offset, read ``through`` the sensors there
    are, is only reported (module text)."""
    why = (f"the model's offset ({est}) is read through {through}, which an unmodelled "
           f"effect or a miscalibrated chamber moves by milliseconds, so the controller's "
           f"reaction, which needs no model, is believed")
    if lag == 0:
        words = (f"the closed-loop records' controller reacts to the position on the row it "
                 f"is logged on, so the measurements sit where the contract puts them; {why}")
        return Alignment(offset, se, lag, z, 0, "aligned", words, used)
    words = (f"{_controller_reading(lag)}; {why}; corrected by moving them {abs(lag)} row(s) "
             f"{'later' if lag > 0 else 'earlier'}")
    return Alignment(offset, se, lag, z, lag, "logging convention", words, used)


def _unchecked(offset: float, se: float | None, z: float, est: str, used: str,
               through: str) -> Alignment:
    """The reading of records without both pressures and without a closed loop whose
    controller reacts: nothing to act on. The model's offset, read ``through`` the sensors
    there are, is said, not acted on: on aligned records it was off by 2-3 ms at about 3
    standard errors (the position alone: 5 of 24, seeds 7919 and 8447; one pressure: 1.5-2.1 ms
    on 7 of 16, seeds 4243 and 6449), and a record a row early gave -2.75 ms (+-0.77) with the
    position alone (module text)."""
    words = (f"not checked: no closed-loop record whose controller reacts to the position, "
             f"and the model's offset ({est}) is read through {through}, which an unmodelled "
             f"effect or a miscalibrated chamber moves by milliseconds; the records are "
             f"diagnosed as logged. A logger that writes beside each command the measurements "
             f"taken after it acted is declared in dataset.yaml (measured: after_command)")
    return Alignment(offset, se, None, z, 0, "not checked", words, used)


def _controller_reading(lag: int) -> str:
    """What a controller reacting ``lag`` (non-zero) rows off its logged row says of the log."""
    return (f"the controller in the closed-loop records reacts to the position {abs(lag)} "
            f"row(s) {'after' if lag > 0 else 'before'} the row it is logged on, so the logger "
            f"writes its measurements {abs(lag)} row(s) {'early' if lag > 0 else 'late'}")
