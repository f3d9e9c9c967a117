"""The measurements as the diagnosis sees them: experiments, train/holdout split, noise and scales.

Each experiment becomes a :class:`Record` with its signals [SI units], a velocity estimated from
the measured position (Savitzky-Golay, zero phase) and the masks of samples used for fitting
(train) and for judging (holdout). When ``dataset.yaml`` assigns no holdout the split is chosen
here and stated (:attr:`Prepared.split_note`): every third experiment when there are at least
three, else the last 30 % of each experiment.

Records from real loggers need not have every sensor: the position, and none, one or both
chamber pressures (:attr:`Record.sensors`; a pressure not measured is NaN and the model carries
its own). Rows the logger lost were filled in on the regular grid by the dataset reader
(:attr:`jetpipe_ros.dataset.Experiment.valid`): they are never compared with the model, and an
experiment is split where more than :data:`SPLIT_GAP` s are missing in a row. A logger whose
measurements sit a whole number of rows off the command (:mod:`alignment`) is corrected here
(``shift_rows`` of :func:`prepare`). A record whose command follows the position's noise was
recorded in closed loop, declared so or not (:func:`feedback_share`); a signal logged on a
lattice (an encoder's counts) has its step counted in its noise (:func:`resolution`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import savgol_filter
from scipy.stats import median_abs_deviation

from jetpipe_ros.dataset import Dataset, DatasetError, Entry, Experiment, measured_later

SIGNALS = ("y", "p1", "p2")
#: Least total length of the training and of the holdout data [s].
MIN_TRAIN_S = 2.0
MIN_HOLDOUT_S = 1.0
#: Floors of the per-signal normalisation scales: 1 mm and 0.1 bar.
MIN_SCALE = {"y": 1e-3, "p1": 1e4, "p2": 1e4}
#: Least run of lost rows [s] at which an experiment is split in two. The command over lost rows
#: is unknown and held; after a command step the valve chain settles (5 %) in 25.5 ms, so past
#: that length the valve's state after the gap depends more on the commands lost than on those
#: recorded, and a fresh start (with the prediction warm-up) describes it better than the hold.
SPLIT_GAP = 0.0255
#: Fewest samples a record (or the part of a split one) needs to be predicted and scored.
MIN_SAMPLES = 50
#: Sample times [s] the diagnosis takes, 10 kHz to 100 Hz (docs/real_logs.md), bounds included.
SAMPLE_TIMES = (1e-4, 1e-2)
#: The data contract's nominal sample time [s] (1 kHz). A record logged slower is read as a
#: controller at its own rate, the command held from row to row; a controller faster than its
#: logger changed it between rows, which the record does not hold (:func:`slow_log_note`).
CONTRACT_SAMPLE_TIME = 1e-3
#: What the data note on a record logged slower than 1 kHz says (:func:`slow_log_note`).
SLOW_LOG = "slower than the contract's 1 kHz"
#: Share of its rows at which a record's command changes from the row before for the command to
#: count as varying between rows (a sweep, a closed loop), not a set of held steps.
VARYING_COMMAND = 0.5
#: Fewest changes between successive samples from which a signal's lattice is read
#: (:func:`resolution`).
MIN_MOVES = 20
#: How close to a whole number of steps every change must be for a lattice [steps].
LATTICE_TOLERANCE = 1e-6
#: A lattice is said in the data notes when its quantisation noise, step/sqrt(12), is at least
#: this share of the signal's noise (a printed value's last digit is a lattice too, but its
#: noise is nothing beside the sensor's).
MIN_LATTICE_SHARE = 0.1
#: Row lags at which a controller may react to the position it read: the command 0-3 rows after.
FEEDBACK_LAGS = range(0, 4)
#: Share of the command's high-frequency part that the position's noise, fed back, must carry
#: for a record to be taken as recorded in closed loop (:func:`feedback_share`): then most of
#: what the command holds above its smoothing is the controller's answer to sensor noise, and
#: the ratio of its cross-spectra with the measurements is the controller's inverse rather than
#: the actuator's response (:func:`localize.frequency_response`). Measured on the self-check's
#: records (twelve actuators, every sensor set, 1 kHz): 1.00 on each of 24 closed-loop records,
#: at most 0.04 on 84 open-loop ones; at 200 Hz at most 0.07 (a sweep whose fast part the
#: position answers), at 2 kHz, lossy or a row off, 0.02.
FEEDBACK_SHARE = 0.5


@dataclass
class Record:
    """One experiment prepared for replay and scoring."""

    name: str
    entry: Entry
    t: np.ndarray  #: time [s], starting at 0
    u: np.ndarray  #: valve command [V]
    y: np.ndarray  #: measured position [m]
    p1: np.ndarray  #: measured chamber 1 pressure [Pa] (NaN when not measured)
    p2: np.ndarray  #: measured chamber 2 pressure [Pa] (NaN when not measured)
    v: np.ndarray  #: velocity estimated from y [m/s]
    smooth: dict[str, np.ndarray]  #: y, p1, p2 smoothed (zero phase), to restart predictions
    f_load: np.ndarray  #: external load [N]
    train: np.ndarray  #: bool mask of training samples (measured rows only)
    holdout: np.ndarray  #: bool mask of held-out samples (measured rows only)
    sensors: tuple[str, ...] = SIGNALS  #: the signals the record measured
    #: the command follows the position's noise (:func:`feedback_share`), closed loop or not
    #: declared so
    feedback: bool = False

    @property
    def locked(self) -> bool:
        """Constant-volume test: the position is not a signal to explain."""
        return self.entry.locked

    @property
    def closed_loop(self) -> bool:
        """Recorded in closed loop, the command computed from the measured position: declared
        in ``dataset.yaml`` (``kind: closed_loop``), or found in the data (:attr:`feedback`)."""
        return self.feedback or self.entry.extra.get("kind") == "closed_loop"

    def high_frequency(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The command [V] and the position [m] less their zero-phase smoothing
        (:func:`smoothed`): at 1 kHz mostly the position's sensor noise and what a controller
        makes of it."""
        return self.u - smoothed(self.u, dt), self.y - self.smooth["y"]

    @property
    def regulated(self) -> bool:
        """Friction test on the regulated rig (``regulated: true``): regulators, not the valve,
        hold the chamber pressures, so only the motion is the model's to explain."""
        return self.entry.extra.get("regulated") is True

    def signal(self, name: str) -> np.ndarray:
        """A measured signal by name (y, p1, p2)."""
        return getattr(self, name)

    def signals(self) -> tuple[str, ...]:
        """The signals scored for this experiment: those it measured that the model explains."""
        if self.regulated:
            scored: tuple[str, ...] = ("y",)
        else:
            scored = ("p1", "p2") if self.locked else SIGNALS
        return tuple(s for s in scored if s in self.sensors)

    def measured(self, name: str) -> bool:
        """Whether the record has signal ``name`` (y, p1, p2)."""
        return name in self.sensors


@dataclass
class Prepared:
    """All experiments with the split, sample time, noise levels and signal scales."""

    records: list[Record]
    dt: float  #: sample time [s]
    noise: dict[str, float]  #: estimated white sensor noise per signal [m or Pa]
    scale: dict[str, float]  #: normalisation scale per signal [m or Pa]
    split_note: str  #: how train and holdout were chosen
    notes: list[str] = field(default_factory=list)
    #: normalised mean square error a perfect model would still show per signal (sensor noise
    #: through the prediction restarts), set by :func:`noise_floor.calibrate`
    floor: dict[str, float] = field(default_factory=dict)
    #: the same per held-out prediction window (aligned with :func:`score.window_errors`)
    floor_windows: np.ndarray | None = None

    #: corrections made to the records (units, time base, lost rows, alignment), in words
    corrections: list[str] = field(default_factory=list)
    #: directions of the calibration knobs (columns, in the natural logs of their factors)
    #: that the training records leave free but the held-out predictions depend on: fitted on
    #: all records in every fit of the knobs (:mod:`nuisance`); None: none
    nuisance: np.ndarray | None = None
    #: what diagnosis.json says of them (``calibration.nuisance``)
    nuisance_report: dict = field(default_factory=dict)
    #: the step of the lattice each signal was logged on (:func:`resolution`) [m or Pa], for
    #: the signals logged on one; the noise twin logs on the same (:mod:`noise_floor`)
    resolution: dict[str, float] = field(default_factory=dict)

    def seconds(self, role: str) -> float:
        """Total length of the ``role`` samples [s]."""
        return sum(float(getattr(r, role).sum()) for r in self.records) * self.dt

    @property
    def sensors(self) -> tuple[str, ...]:
        """The signals measured in at least one record."""
        return tuple(s for s in SIGNALS if any(r.measured(s) for r in self.records))

    @property
    def unmeasured_pressures(self) -> tuple[str, ...]:
        """The chamber pressures (p1, p2) no record measured: sensors the bench lacks."""
        return tuple(s for s in ("p1", "p2") if s not in self.sensors)

    def has_both_pressures(self) -> bool:
        """Whether every record that is not a locked or regulated test measured both pressures
        (what the equation errors of the force balance and the mechanics replay need)."""
        return all(r.measured("p1") and r.measured("p2") for r in self.records)


def velocity(y: np.ndarray, dt: float, window_s: float = 0.021) -> np.ndarray:
    """Zero-phase velocity [m/s] of a position sampled every ``dt`` s (quadratic Savitzky-Golay)."""
    n = max(5, int(round(window_s / dt)) | 1)
    if y.size < n:
        return np.gradient(y, dt)
    return savgol_filter(y, n, 2, deriv=1, delta=dt)


def smoothed(x: np.ndarray, dt: float, window_s: float = 0.015) -> np.ndarray:
    """Zero-phase smoothing (quadratic Savitzky-Golay) that keeps steps sharp to ~``window_s``."""
    n = max(5, int(round(window_s / dt)) | 1)
    return savgol_filter(x, n, 2) if x.size >= n else x.copy()


def feedback_share(rec: Record, dt: float) -> float:
    """The share [-] of the command's high-frequency part (:meth:`Record.high_frequency`) that
    the position's, 0-3 rows earlier (:data:`FEEDBACK_LAGS`), explains by least squares over
    the measured rows: about 1 when a controller computed the command from the position and
    nothing else excites it, near 0 for a command written beforehand; 0 without a measured
    position or a moving command."""
    if not rec.measured("y") or rec.locked or np.std(rec.u) < 1e-9:
        return 0.0
    eu, ey = rec.high_frequency(dt)
    ok = rec.train | rec.holdout
    k = np.arange(max(FEEDBACK_LAGS), rec.t.size)
    keep = ok[k] & np.all([ok[k - lag] for lag in FEEDBACK_LAGS], axis=0)
    x = np.column_stack([ey[k - lag] for lag in FEEDBACK_LAGS])[keep]
    u = eu[k][keep]
    total = float(u @ u)
    if u.size <= 10 * len(FEEDBACK_LAGS) or total == 0.0:
        return 0.0
    coef, *_ = np.linalg.lstsq(x, u, rcond=None)
    resid = u - x @ coef
    return 1.0 - float(resid @ resid) / total


def resolution(x: np.ndarray) -> float:
    """The step of the lattice a signal was logged on (an encoder's count, a converter's least
    significant bit) [its unit], or 0 when its values lie on none: the smallest change between
    successive samples, when every change is a whole number of it (within
    :data:`LATTICE_TOLERANCE` of one; a float's rounding on values a million steps from zero is
    under 1e-9 of a step) and there are at least :data:`MIN_MOVES` changes. Noisy values
    written at full precision change by amounts that are not multiples of the smallest."""
    d = np.abs(np.diff(x[np.isfinite(x)]))
    moved = d[d > 0.0]
    if moved.size < MIN_MOVES:
        return 0.0
    k = moved / moved.min()
    if not np.all(np.abs(k - np.round(k)) <= LATTICE_TOLERANCE):
        return 0.0
    return float(np.median(moved / np.round(k)))  # the step, less the smallest's rounding


def noise_level(x: np.ndarray) -> float:
    """White-noise standard deviation of a sampled signal: robust (MAD, scaled to a normal
    standard deviation) spread of its second differences over sqrt(6). Smooth motion
    contributes little at 1 kHz; transients are outliers.
    """
    d2 = np.diff(x, 2)
    if d2.size < 10:
        return 0.0
    return float(median_abs_deviation(d2, scale="normal") / np.sqrt(6.0))


def prepare(dataset: Dataset, shift_rows: int = 0) -> Prepared:
    """Validate a dataset for the diagnosis and choose the split; raise DatasetError if unusable.

    ``shift_rows`` corrects a logger's time base (see :mod:`alignment`): positive when its
    measurements are that many rows early (row k holds the measurement taken k rows after the
    command beside it was applied), negative when late."""
    dts = [exp.dt for exp in dataset.experiments]
    dt = float(np.median(dts))
    for (entry, exp), d in zip(dataset, dts):
        if abs(d - dt) > 1e-3 * dt:
            raise DatasetError(f"{dataset.root / entry.file}: sample time {d * 1e3:.4g} ms differs "
                               f"from the other experiments' {dt * 1e3:.4g} ms")
        if exp.t.size < 50:
            raise DatasetError(f"{dataset.root / entry.file}: only {exp.t.size} samples; the "
                               f"diagnosis needs at least 50 per experiment")
    low, high = SAMPLE_TIMES
    if not low <= dt <= high:
        raise DatasetError(f"{dataset.root}: sample time {dt * 1e3:.4g} ms is outside "
                           f"{low * 1e3:g}-{high * 1e3:g} ms (10 kHz to 100 Hz)")
    roles = [e.role for e in dataset.entries]
    n = len(roles)
    by_time = False
    if "holdout" in roles and any(r != "holdout" for r in roles):
        holdout = [r == "holdout" for r in roles]
        note = "holdout as marked in dataset.yaml (unmarked experiments train)"
    elif "holdout" in roles:
        raise DatasetError(f"{dataset.root / 'dataset.yaml'}: every experiment is marked "
                           f"holdout; mark at least one 'role: train'")
    elif n >= 3:
        holdout = [i % 3 == 2 for i in range(n)]
        names = ", ".join(e.name for e, h in zip(dataset.entries, holdout) if h)
        note = (f"no holdout marked in dataset.yaml: held out every third experiment "
                f"({names})")
    else:
        holdout = [False] * n
        by_time = True
        note = ("no holdout marked in dataset.yaml and fewer than 3 experiments: the last 30 % "
                "of each experiment is held out")
    records = []
    notes = list(getattr(dataset, "notes", []))
    for (entry, exp), held in zip(dataset, holdout):
        exp = measured_later(exp, shift_rows)
        parts = _parts(exp, dt)
        if len(parts) > 1:
            notes.append(f"{entry.file}: split into {len(parts)} parts at runs of more than "
                         f"{SPLIT_GAP * 1e3:g} ms of lost rows")
        for i, (lo, hi) in enumerate(parts):
            name = entry.name if len(parts) == 1 else f"{entry.name}[{i + 1}]"
            if hi - lo < MIN_SAMPLES:
                notes.append(f"{entry.file}: part {name} left out: {hi - lo} samples, the "
                             f"diagnosis needs at least {MIN_SAMPLES}")
                continue
            rec = _record(entry, _slice(exp, lo, hi), dt, held, by_time, name)
            if not rec.signals():
                notes.append(f"{entry.file}: left out: a {entry.piston}-piston test without "
                             f"the signals it explains ({', '.join(rec.sensors) or 'none'} "
                             f"measured)")
                continue
            records.append(rec)
    if not records:
        raise DatasetError(f"{dataset.root}: no experiment the diagnosis can use "
                           f"({'; '.join(notes)})")
    steps = {s: max([resolution(_measured_rows(r, s)) for r in records
                     if s in r.signals()] or [0.0]) for s in SIGNALS}
    noise = {s: max(float(np.median([noise_level(_measured_rows(r, s)) for r in records
                                     if s in r.signals()] or [0.0])),
                    steps[s] / math.sqrt(12.0)) for s in SIGNALS}
    scale = {}
    for s in SIGNALS:
        values = [_measured_rows(r, s) for r in records if s in r.signals()]
        spread = float(np.std(np.concatenate(values))) if values else 0.0
        scale[s] = max(spread, MIN_SCALE[s])
    prepared = Prepared(records, dt, noise, scale, note, corrections=notes,
                        resolution={s: q for s, q in steps.items() if q > 0.0})
    for s, q in prepared.resolution.items():
        if q / math.sqrt(12.0) >= MIN_LATTICE_SHARE * noise[s]:
            unit, factor = ("um", 1e6) if s == "y" else ("Pa", 1.0)
            prepared.notes.append(
                f"{s} is logged in steps of {q * factor:.4g} {unit} (a sensor's or converter's "
                f"resolution): counted as noise of at least step/sqrt(12) = "
                f"{q / math.sqrt(12.0) * factor:.3g} {unit}, and the noise twin logs on the same "
                f"steps")
    missing = [s for s in SIGNALS if s not in prepared.sensors]
    if missing:
        prepared.notes.append(f"no {' or '.join(missing)} measured: the diagnosis compares "
                              f"{', '.join(prepared.sensors)} only")
    slow = slow_log_note(records, dt)
    if slow:
        prepared.notes.append(slow)
    for role, least in (("train", MIN_TRAIN_S), ("holdout", MIN_HOLDOUT_S)):
        have = prepared.seconds(role)
        if have < least:
            raise DatasetError(f"{dataset.root}: {have:.2f} s of {role} data; the diagnosis "
                               f"needs at least {least:g} s ({note})")
    if all(r.locked for r in records):
        prepared.notes.append("all experiments are locked-piston tests: the mechanics "
                              "(friction, mass) cannot be judged")
    found: dict[str, list[str]] = {}
    for rec in records:
        if rec.closed_loop or rec.regulated:
            continue
        share = feedback_share(rec, dt)
        if share >= FEEDBACK_SHARE:
            rec.feedback = True
            said = ("declares open_loop" if rec.entry.extra.get("kind") == "open_loop"
                    else "does not declare (kind: closed_loop)")
            found.setdefault(said, []).append(f"{rec.entry.file} ({share:.0%})")
    for said, files in found.items():
        prepared.notes.append(
            f"{', '.join(files)}: recorded in closed loop, which dataset.yaml {said}: that "
            f"share of the command's fast part follows the position's noise, a controller's "
            f"answer; left out of the frequency response")
    return prepared


def slow_log_note(records: list[Record], dt: float) -> str | None:
    """What a record logged slower than the contract's 1 kHz (sample time ``dt`` [s]) leaves
    open, when its command varies from row to row in some experiment; else None.

    Such a record is read as a controller at its own rate holds its command: from each row to
    the next. A controller faster than its logger changed the command between rows, which the
    record does not hold, and nothing in the record tells the two apart. Measured on the
    model's own 1 kHz records logged every 5th row (200 Hz): a plant with no effect answered
    ``unlisted`` (1.3 % left), a 25 Hz valve lag named with a natural frequency of the valve
    24 % off (docs/real_logs.md, *A logger slower than its controller*)."""
    if dt <= CONTRACT_SAMPLE_TIME * (1.0 + 1e-6):
        return None
    varying = sorted({r.entry.file for r in records
                      if np.mean(np.diff(r.u) != 0.0) > VARYING_COMMAND})
    if not varying:
        return None
    return (f"logged at {1.0 / dt:.4g} Hz, {SLOW_LOG}: the command is "
            f"read as held from each row to the next, as a controller at that rate holds it. "
            f"It changes at most rows of {_few(varying)}: if the controller ran faster than "
            f"its logger, the valve saw commands between the rows that the record does not "
            f"hold, and part of any gap left is theirs; log the command at the controller's "
            f"rate")


def _few(names: list[str], most: int = 3) -> str:
    """Up to ``most`` names, and how many more."""
    return ", ".join(names[:most]) + (f" and {len(names) - most} more" if len(names) > most
                                      else "")


def swapped(prepared: Prepared) -> Prepared:
    """The same data with the roles exchanged: fit on the holdout, judge on the training data
    (the second fold of a two-fold cross-validation). The noise floor is not carried over."""
    records = [dataclasses.replace(r, train=r.holdout, holdout=r.train)
               for r in prepared.records]
    return dataclasses.replace(prepared, records=records, floor={}, floor_windows=None,
                               split_note=f"roles exchanged ({prepared.split_note})")


def _measured_rows(rec: Record, signal: str) -> np.ndarray:
    """The rows of a signal that were measured (not filled in over lost rows)."""
    x = rec.signal(signal)
    return x[rec.train | rec.holdout] if (rec.train | rec.holdout).any() else x


def shifted(dataset: Dataset, rows: int) -> Dataset:
    """``dataset`` with every experiment's measured columns moved ``rows`` rows later relative
    to its command, as :func:`prepare`'s ``shift_rows`` moves them (for tools that read the
    experiments themselves)."""
    return dataclasses.replace(dataset, experiments=[measured_later(exp, rows)
                                                     for exp in dataset.experiments])


def _slice(exp: Experiment, lo: int, hi: int) -> Experiment:
    """Rows lo..hi-1 of an experiment."""
    if lo == 0 and hi == exp.t.size:
        return exp
    out = dataclasses.replace(exp, extra={})
    for c in ("t", "u", "y", "p1", "p2", "v", "f_load", "valid"):
        x = getattr(exp, c, None)
        if x is not None:
            setattr(out, c, x[lo:hi])
    return out


def _parts(exp: Experiment, dt: float) -> list[tuple[int, int]]:
    """Row ranges of an experiment between runs of more than :data:`SPLIT_GAP` lost rows."""
    valid = getattr(exp, "valid", None)
    n = exp.t.size
    if valid is None or valid.all():
        return [(0, n)]
    longest = int(np.ceil(SPLIT_GAP / dt - 1e-9))
    lost = np.flatnonzero(~valid)
    runs = np.split(lost, np.flatnonzero(np.diff(lost) > 1) + 1)
    parts, start = [], 0
    for run in runs:
        if run.size > longest:
            parts.append((start, int(run[0])))
            start = int(run[-1]) + 1
    parts.append((start, n))
    return [(lo, hi) for lo, hi in parts if hi > lo]


def _record(entry: Entry, exp: Experiment, dt: float, held: bool, by_time: bool,
            name: str) -> Record:
    n = exp.t.size
    if by_time:
        holdout = np.arange(n) >= int(0.7 * n)
    else:
        holdout = np.full(n, held)
    valid = getattr(exp, "valid", None)
    measured = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    f_load = exp.f_load if exp.f_load is not None else np.full(n, entry.load_force)
    sensors = tuple(s for s in SIGNALS if getattr(exp, s) is not None)
    signals = {s: (np.asarray(getattr(exp, s), dtype=float) if s in sensors
                   else np.full(n, np.nan)) for s in SIGNALS}
    y = signals["y"]
    smooth = {s: smoothed(x, dt) if s in sensors else x for s, x in signals.items()}
    v = np.zeros(n) if entry.locked or "y" not in sensors else velocity(y, dt)
    return Record(name=name, entry=entry, t=exp.t - exp.t[0], u=exp.u, y=y, p1=signals["p1"],
                  p2=signals["p2"], v=v, smooth=smooth,
                  f_load=np.ascontiguousarray(f_load, dtype=float), train=~holdout & measured,
                  holdout=holdout & measured, sensors=sensors)
