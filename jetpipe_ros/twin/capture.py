"""The latest samples kept for a capture, and a capture written as a dataset.

:class:`Recent` keeps the last N seconds of the samples the twin received, in a ring of
preallocated rows, so a capture is one copy (:meth:`Recent.snapshot`) and never holds up the
stream. :func:`write_capture` writes such a copy in the layout ``jetpipe export`` writes (one CSV
per experiment ``t,u,y,p1,p2,f_load`` and ``dataset.yaml``), cut into pieces with the roles the
diagnosis judges by: every third piece held out, as the diagnosis itself chooses when a dataset
assigns none. A row of the dataset pairs the measurements at t_k with the command applied over
the next sample, [t_k, t_k+1), so the received rows, which carry the command applied over the
sample *ending* at their stamp, are shifted by one sample (the last one has no command yet and
is left out, as is one whose next sample never came); rows with a measurement missing are left
out (the dataset reader fills such holes). A chamber pressure the hardware does not measure
(``sensors``) is no column of the capture, as the dataset contract has it for a bench without
that sensor.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jetpipe_ros.dataset import DatasetError, Entry, write_dataset

#: Columns of a kept row: t [s], u [V] and load [N] applied over the sample ending at t,
#: y [m], p1, p2 [Pa].
COLUMNS = ("t", "u", "f_load", "y", "p1", "p2")
#: Length of a capture's pieces [s] (at least three pieces): the diagnosis wants 2 s to fit
#: and 1 s to judge at the least.
PIECE = 3.0


class Recent:
    """A ring of the latest ``seconds`` of samples at sample time ``dt`` [s]: as many rows as
    that holds without a sample lost; with samples lost they span longer, and a snapshot keeps
    the rows of the last ``seconds`` only."""

    def __init__(self, seconds: float, dt: float) -> None:
        self.seconds, self.dt = seconds, dt
        self.size = max(int(round(seconds / dt)), 1)
        self._rows = np.empty((self.size, len(COLUMNS)))
        self._next = 0
        self.count = 0  #: rows held

    def add(self, row: tuple[float, ...] | np.ndarray) -> None:
        """Keep one row (:data:`COLUMNS`), forgetting the oldest when full."""
        self._rows[self._next] = row
        self._next = (self._next + 1) % self.size
        self.count = min(self.count + 1, self.size)

    def snapshot(self) -> np.ndarray:
        """A copy of the rows of the last ``seconds`` (stamps within that of the latest's, to
        half a sample), oldest first, (count, 6)."""
        if self.count < self.size:
            rows = self._rows[:self.count].copy()
        else:
            rows = np.concatenate([self._rows[self._next:], self._rows[:self._next]])
        if rows.shape[0] == 0:
            return rows
        return rows[rows[:, 0] > rows[-1, 0] - self.seconds + 0.5 * self.dt]


#: The signals a capture may hold, as the twin has them (position, chamber pressures).
SENSORS = ("y", "p1", "p2")


def dataset_rows(rows: np.ndarray, sensors: tuple[str, ...] = SENSORS) -> np.ndarray:
    """Received rows (:data:`COLUMNS`) as dataset rows: each measurement with the command and
    load applied over the next sample, the last row dropped, and the rows where the command,
    the load or one of the ``sensors`` measured is not finite. A row whose next sample was not
    received (the following row more than half a sample from one sample later) has no known
    command: the next row's is that of a later sample, and it is left out too."""
    if rows.shape[0] < 2:
        return np.empty((0, len(COLUMNS)))
    out = rows[:-1].copy()
    out[:, 1:3] = rows[1:, 1:3]
    step = np.diff(rows[:, 0])
    dt = float(np.median(step))
    out[np.abs(step - dt) > 0.5 * dt, 1:3] = np.nan
    needed = [COLUMNS.index(c) for c in ("t", "u", "f_load", *sensors)]
    return out[np.isfinite(out[:, needed]).all(axis=1)]


def write_capture(rows: np.ndarray, root: str | Path, note: dict | None = None,
                  sensors: tuple[str, ...] = SENSORS) -> Path:
    """Write received rows (:data:`COLUMNS`) as a dataset directory ``root`` (new or empty);
    every third piece of about :data:`PIECE` s is held out; only the ``sensors`` the hardware
    measures (of :data:`SENSORS`) are columns. ``note`` is stored with each experiment in
    ``dataset.yaml``, with the rows received and those left out for a missing value
    (``received_rows``, ``incomplete_rows``). Raises DatasetError when there is too little to
    cut."""
    unknown = [s for s in sensors if s not in SENSORS]
    if unknown or "y" not in sensors:
        raise ValueError(f"capture sensors {', '.join(sensors)}: the position y and any of "
                         f"p1, p2")
    data = dataset_rows(rows, sensors)
    n = data.shape[0]
    if n < 2 or n * _dt(data) < PIECE:
        raise DatasetError(f"{root}: {n} of the {rows.shape[0]} rows received have the command, "
                           f"the load and every sensor ({', '.join(sensors)}) finite; a capture "
                           f"needs {PIECE:g} s of them (a sensor the hardware lacks is not in "
                           f"the monitor's 'pressure_sensors')")
    note = {**(note or {}), "received_rows": int(rows.shape[0]),
            "incomplete_rows": int(max(rows.shape[0] - 1 - n, 0))}
    pieces = max(int(n * _dt(data) / PIECE), 3)
    bounds = np.linspace(0, n, pieces + 1).astype(int)
    experiments = []
    for i, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
        part = data[lo:hi]
        entry = Entry(file=f"capture_{i:02d}.csv", piston="free", load_force=0.0,
                      role="holdout" if i % 3 == 2 else "train",
                      extra={"captured_from_s": float(part[0, 0]), **note})
        cols = {"t": part[:, 0] - part[0, 0],
                "u": part[:, 1], **{c: part[:, COLUMNS.index(c)] for c in SENSORS
                                    if c in sensors},
                "f_load": part[:, 2]}
        experiments.append((entry, cols))
    return write_dataset(root, experiments)


def _dt(data: np.ndarray) -> float:
    """Median sample time of rows [s] (0 for fewer than two)."""
    return float(np.median(np.diff(data[:, 0]))) if data.shape[0] > 1 else 0.0
