"""The measurements as the diagnosis sees them: experiments, train/holdout split, noise and scales.

Each experiment becomes a :class:`Record` with its signals [SI units], a velocity estimated from
the measured position (Savitzky-Golay, zero phase) and the masks of samples used for fitting
(train) and for judging (holdout). When ``dataset.yaml`` assigns no holdout the split is chosen
here and stated (:attr:`Prepared.split_note`): every third experiment when there are at least
three, else the last 30 % of each experiment.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import savgol_filter
from scipy.stats import median_abs_deviation

from jetpipe_ros.dataset import Dataset, DatasetError, Entry, Experiment

SIGNALS = ("y", "p1", "p2")
#: Least total length of the training and of the holdout data [s].
MIN_TRAIN_S = 2.0
MIN_HOLDOUT_S = 1.0
#: Floors of the per-signal normalisation scales: 1 mm and 0.1 bar.
MIN_SCALE = {"y": 1e-3, "p1": 1e4, "p2": 1e4}


@dataclass
class Record:
    """One experiment prepared for replay and scoring."""

    name: str
    entry: Entry
    t: np.ndarray  #: time [s], starting at 0
    u: np.ndarray  #: valve command [V]
    y: np.ndarray  #: measured position [m]
    p1: np.ndarray  #: measured chamber 1 pressure [Pa]
    p2: np.ndarray  #: measured chamber 2 pressure [Pa]
    v: np.ndarray  #: velocity estimated from y [m/s]
    smooth: dict[str, np.ndarray]  #: y, p1, p2 smoothed (zero phase), to restart predictions
    f_load: np.ndarray  #: external load [N]
    train: np.ndarray  #: bool mask of training samples
    holdout: np.ndarray  #: bool mask of held-out samples

    @property
    def locked(self) -> bool:
        """Constant-volume test: the position is not a signal to explain."""
        return self.entry.locked

    @property
    def regulated(self) -> bool:
        """Friction test on the regulated rig (``regulated: true``): regulators, not the valve,
        hold the chamber pressures, so only the motion is the model's to explain."""
        return self.entry.extra.get("regulated") is True

    def signal(self, name: str) -> np.ndarray:
        """A measured signal by name (y, p1, p2)."""
        return getattr(self, name)

    def signals(self) -> tuple[str, ...]:
        """The signals scored for this experiment."""
        if self.regulated:
            return ("y",)
        return ("p1", "p2") if self.locked else SIGNALS


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

    def seconds(self, role: str) -> float:
        """Total length of the ``role`` samples [s]."""
        return sum(float(getattr(r, role).sum()) for r in self.records) * self.dt


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


def noise_level(x: np.ndarray) -> float:
    """White-noise standard deviation of a sampled signal: robust (MAD, scaled to a normal
    standard deviation) spread of its second differences over sqrt(6). Smooth motion
    contributes little at 1 kHz; transients are outliers.
    """
    d2 = np.diff(x, 2)
    if d2.size < 10:
        return 0.0
    return float(median_abs_deviation(d2, scale="normal") / np.sqrt(6.0))


def prepare(dataset: Dataset) -> Prepared:
    """Validate a dataset for the diagnosis and choose the split; raise DatasetError if unusable."""
    dts = [exp.dt for exp in dataset.experiments]
    dt = float(np.median(dts))
    for (entry, exp), d in zip(dataset, dts):
        if abs(d - dt) > 1e-3 * dt:
            raise DatasetError(f"{dataset.root / entry.file}: sample time {d * 1e3:.4g} ms differs "
                               f"from the other experiments' {dt * 1e3:.4g} ms")
        if exp.t.size < 50:
            raise DatasetError(f"{dataset.root / entry.file}: only {exp.t.size} samples; the "
                               f"diagnosis needs at least 50 per experiment")
    if not 1e-4 <= dt <= 1e-2:
        raise DatasetError(f"{dataset.root}: sample time {dt:g} s is outside 0.1-10 ms")
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
    for (entry, exp), held in zip(dataset, holdout):
        records.append(_record(entry, exp, dt, held, by_time))
    noise = {s: float(np.median([noise_level(r.signal(s)) for r in records
                                 if s in r.signals()] or [0.0])) for s in SIGNALS}
    scale = {}
    for s in SIGNALS:
        values = [r.signal(s) for r in records if s in r.signals()]
        spread = float(np.std(np.concatenate(values))) if values else 0.0
        scale[s] = max(spread, MIN_SCALE[s])
    prepared = Prepared(records, dt, noise, scale, note)
    for role, least in (("train", MIN_TRAIN_S), ("holdout", MIN_HOLDOUT_S)):
        have = prepared.seconds(role)
        if have < least:
            raise DatasetError(f"{dataset.root}: {have:.2f} s of {role} data; the diagnosis "
                               f"needs at least {least:g} s ({note})")
    if all(r.locked for r in records):
        prepared.notes.append("all experiments are locked-piston tests: the mechanics "
                              "(friction, mass) cannot be judged")
    return prepared


def swapped(prepared: Prepared) -> Prepared:
    """The same data with the roles exchanged: fit on the holdout, judge on the training data
    (the second fold of a two-fold cross-validation). The noise floor is not carried over."""
    records = [dataclasses.replace(r, train=r.holdout, holdout=r.train)
               for r in prepared.records]
    return dataclasses.replace(prepared, records=records, floor={}, floor_windows=None,
                               split_note=f"roles exchanged ({prepared.split_note})")


def _record(entry: Entry, exp: Experiment, dt: float, held: bool, by_time: bool) -> Record:
    n = exp.t.size
    if by_time:
        holdout = np.arange(n) >= int(0.7 * n)
    else:
        holdout = np.full(n, held)
    f_load = exp.f_load if exp.f_load is not None else np.full(n, entry.load_force)
    y = exp.y
    smooth = {"y": smoothed(y, dt), "p1": smoothed(exp.p1, dt), "p2": smoothed(exp.p2, dt)}
    return Record(name=entry.name, entry=entry, t=exp.t - exp.t[0], u=exp.u, y=y, p1=exp.p1,
                  p2=exp.p2, v=np.zeros(n) if entry.locked else velocity(y, dt), smooth=smooth,
                  f_load=np.ascontiguousarray(f_load, dtype=float), train=~holdout,
                  holdout=holdout)
