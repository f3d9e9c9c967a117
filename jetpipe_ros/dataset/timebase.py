"""The time base of an experiment: every record read becomes a regular grid ``t = t_0 + k*dt``.

Times are in seconds (after any unit declared in ``dataset.yaml``); the notes give them in ms.
Loggers do not all sample like the simulator; the reader accepts what a logger does and says
what it did about it (the experiment's notes), instead of refusing:

* **Jitter** (each stamp near its slot on a regular grid): the stamps are snapped to the grid.
  The grid is fitted by least squares to the stamps against their slot indices
  ``n_k = round((t_k - t_0)/dt)``, from the step at which the first stamps' phases agree best,
  first on a prefix and then on longer ones (a clock a
  little off its nominal rate, e.g. 1.0001 ms, drifts by whole steps over a long record, which
  the median step alone would miss). The fitted step is replaced by a round value (the
  nominal rate, e.g. 1 ms or 1/300 s) when the difference is within the fit's uncertainty or
  moves no stamp by more than 1 % of a step, and likewise ``t_0`` by a multiple of the step.
  A stamp belongs to the grid when it lies within a third of a step of its slot and no other
  stamp shares that slot: the nearest wrong slot is then at least twice as far as the right
  one, so a slot is never taken by a stamp that belongs elsewhere, and snapping moves a sample
  by less than a third of a step (a phase error of at most 60 degrees at the Nyquist
  frequency, and of at most 6 degrees for signals below a tenth of it, which is where the
  model is fitted). Jitter below 1 % of a step is rounding of the written stamps and is
  snapped without a note.
* **Lost rows** (slots with no stamp): filled. The command ``u`` is held at the previous
  row's value (zero-order hold), because that is what the valve saw: the logger lost the row,
  not the controller's output, which stays in force until the next one. The load ``f_load``
  is a force on the piston, continuous in time (a weight released, a spring, a load cell's
  reading): interpolated linearly (the paper's friction tests release their load along a
  ramp; held over gaps of 30-79 ms, it had replayed their positions 60-120 um off, where the
  clean records' are 15 um). The measurements (``y``, ``p1``, ``p2``, ``v``) are
  interpolated linearly so that the signals stay continuous (a model started from them, a
  filter run over them, see no step), and the mask ``valid`` marks them False so that
  comparisons leave them out.
* **Irregular stamps** (beyond a third of a step from any regular grid, or two stamps in one
  slot): resampled at the median step from the first stamp on; measurements and the load
  interpolated linearly, the command held (the value in force at each grid time). Every row
  is then valid: no row was lost, the samples were only taken at other times.

Refused (DatasetError naming the file, the line and column ``t``): time not strictly
increasing (no order of the samples can be trusted), and a grid that would hold more than
:data:`MAX_GROWTH` times the rows read (more filled than measured: not a record with gaps,
and a memory hazard). Fewer than 2 rows and a median step outside the plausible range are
refused before (:mod:`jetpipe_ros.dataset.experiment`, :mod:`jetpipe_ros.dataset.plausibility`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from jetpipe_ros.dataset.errors import DatasetError

#: A stamp farther than this from its slot [steps] is not on the grid (see the module text).
JITTER_LIMIT = 1.0 / 3.0
#: Jitter up to this [steps] is rounding of the written stamps: snapped without a note.
SILENT_JITTER = 0.01
#: Most rows the regular grid may have per row read.
MAX_GROWTH = 2.0
#: Stamps whose phases find the step the grid's fit starts from (:func:`_coherent_step`), and
#: how far from the median interval it is searched [fraction]: a median within 5 % of the step
#: (fewer than about a third of the rows lost) keeps its multiples and fractions out.
COHERENT_STAMPS = 256
STEP_SEARCH = 0.05
#: Columns held between samples (zero-order hold); every other column is interpolated.
HELD = ("u",)
#: A live stream's sample time (the twin's, the recorder's): the median of its latest
#: :data:`STREAM_INTERVALS` stamp intervals, once there are :data:`MIN_INTERVALS`.
STREAM_INTERVALS = 200
MIN_INTERVALS = 20
#: Relative difference between that median and the set sample time beyond which the stream is
#: at another rate (:func:`another_rate`). The live twin rounds each interval to whole samples,
#: so a stream 5 % slower than the set sample time runs the model 5 % fast against the
#: hardware (its 2 ms valve delay read as 1.9 ms); the median of 200 intervals of a stream whose
#: stamps jitter by +-0.3 of a sample and that lost 1 % of them is within 2 % of the truth
#: (``test_twin.py``).
RATE_TOLERANCE = 0.05
#: Largest spacing of floats at a record's first stamp, as a share of its step, at which the
#: stamps are kept as written. Stamps of a clock's epoch (1.7e9 s, or 1.7e18 ns declared) lie
#: where floats are 0.24 us apart, 0.024 % of a 1 ms step: a grid built there has steps of two
#: sizes, and the sample time read from them is off by as much (0.99993 ms for 1 ms); such a
#: record is counted from its first stamp instead.
EPOCH_SPACING = 1e-6


def median_interval(intervals: Sequence[float]) -> float | None:
    """A live stream's sample time: the median of its latest stamp ``intervals`` (any unit),
    None before :data:`MIN_INTERVALS`."""
    return float(np.median(intervals)) if len(intervals) >= MIN_INTERVALS else None


def another_rate(interval: float, dt: float) -> bool:
    """True when a stream's sample time ``interval`` is more than :data:`RATE_TOLERANCE` off
    the set sample time ``dt`` (same unit)."""
    return abs(interval / dt - 1.0) > RATE_TOLERANCE


def check_increasing(path: Path, t: np.ndarray, lines: np.ndarray) -> None:
    """Refuse time that is not strictly increasing, naming the line where it goes back."""
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        i = int(bad[0])
        raise DatasetError(f"{path}: line {int(lines[i + 1])}, column 't': time is not strictly "
                           f"increasing ({t[i]:.6g} then {t[i + 1]:.6g} s)")


def regularise(path: Path, cols: Mapping[str, np.ndarray], lines: np.ndarray
               ) -> tuple[dict[str, np.ndarray], np.ndarray | None, list[str]]:
    """Put the columns ``cols`` (``t`` strictly increasing, at least 2 rows) on a regular grid.

    Returns the new columns, the mask of measured rows (None when every row was measured) and
    the notes saying what was done (none when the record was regular already).
    """
    t = cols["t"]
    step = float(np.median(np.diff(t)))
    origin = float(t[0])
    counted = np.spacing(abs(origin)) > EPOCH_SPACING * step
    if counted:
        t = t - origin
        cols = {**cols, "t": t}
    new, valid, notes = _regular(path, cols, lines, step)
    if counted:
        notes.insert(0, f"t counted from the first stamp, {origin:.10g} s (a clock's epoch, "
                        f"where floats are {np.spacing(abs(origin)) * 1e9:.3g} ns apart)")
    return new, valid, notes


def _regular(path: Path, cols: Mapping[str, np.ndarray], lines: np.ndarray, step: float
             ) -> tuple[dict[str, np.ndarray], np.ndarray | None, list[str]]:
    """:func:`regularise` on stamps ``cols['t']`` whose median interval is ``step`` [s]."""
    t = cols["t"]
    t0, dt, n = fit_grid(t, step)
    resid = t - (t0 + n * dt)
    worst = int(np.argmax(np.abs(resid)))
    shared = np.flatnonzero(np.diff(n) < 1)
    if abs(resid[worst]) < JITTER_LIMIT * dt and not shared.size:
        return _snap(path, cols, lines, t0, dt, n.astype(np.int64), resid)
    if shared.size:
        i = int(shared[0])
        why = (f"two stamps in one {dt * 1e3:.6g} ms slot at t = {t[i]:.6g} and "
               f"{t[i + 1]:.6g} s")
    else:
        why = (f"the stamp at t = {t[worst]:.6g} s is {abs(resid[worst]) / dt:.2f} steps from "
               f"the nearest grid time")
    return _resample(path, cols, lines, step, why)


def _coherent_step(tau: np.ndarray, step: float) -> float:
    """The step within :data:`STEP_SEARCH` of ``step`` at which the first
    :data:`COHERENT_STAMPS` stamps ``tau`` [s] (from 0) agree best in phase: the peak of
    ``|sum exp(2 pi i tau_k / dt)|``, on trial steps an eighth of the peak's width apart (the
    step found is then within a sixteenth of that width: the last of those stamps within 0.07
    of a step of its slot).

    A start for the grid's fit that neither lost rows nor jitter bias: the mean of the
    intervals of one step drifted by 1.1 % on a 200 Hz record with 1 % of its rows lost and
    stamps jittered by +-0.3 steps (the intervals' window, centred on their median, cut the
    jitter's tails unevenly), so the slots of the first 128 stamps were already off by one."""
    tau = tau[:COHERENT_STAMPS]
    width = step * step / max(float(tau[-1]), step)  # the last stamp moves a whole cycle
    trial = np.arange(step * (1.0 - STEP_SEARCH), step * (1.0 + STEP_SEARCH), 0.125 * width)
    power = np.abs(np.exp(2j * np.pi * tau[None, :] / trial[:, None]).sum(axis=1))
    return float(trial[int(np.argmax(power))])


def fit_grid(t: np.ndarray, step: float) -> tuple[float, float, np.ndarray]:
    """(t_0, dt, slot index of each stamp) of the regular grid nearest to the strictly
    increasing stamps ``t`` [s], searched from ``step`` [s] (their median interval)."""
    tau = t - t[0]  # fitted relative to the first stamp: absolute clocks (1.7e9 s) lose digits
    dt, m = _coherent_step(tau, step), min(t.size, COHERENT_STAMPS)
    while True:
        # the grid's phase: the circular mean of the stamps' (the first stamp's own jitter
        # would otherwise shift every slot boundary by up to a third of a step)
        a = dt / (2 * np.pi) * float(np.angle(np.sum(np.exp(2j * np.pi * tau[:m] / dt))))
        n = np.rint((tau[:m] - a) / dt)
        if np.ptp(n) > 0:
            a, dt, _ = _line(n, tau[:m])
        if m == t.size:
            break
        m = min(t.size, m + m // 2)
    n = np.rint((tau - a) / dt)
    if np.ptp(n) > 0:
        a, dt, se = _line(n, tau)
        dt = _round_step(dt, se, float(np.ptp(n)))
    n = np.rint((tau - a) / dt)
    a = float(np.mean(tau - n * dt))
    spread = float(np.std(tau - n * dt - a))
    t0 = float(t[0]) + a
    whole = round(t0 / dt) * dt
    if abs(whole - t0) <= max(SILENT_JITTER * dt, 3.0 * spread / math.sqrt(t.size)):
        t0 = whole
    n = np.rint((t - t0) / dt)
    t0 += float(n[0]) * dt
    return t0, dt, n - n[0]


def _line(n: np.ndarray, tau: np.ndarray) -> tuple[float, float, float]:
    """Least-squares ``tau = a + dt * n``: (a, dt, standard error of dt)."""
    nm, tm = float(n.mean()), float(tau.mean())
    sxx = float(np.sum((n - nm) ** 2))
    dt = float(np.sum((n - nm) * (tau - tm))) / sxx
    a = tm - dt * nm
    dof = n.size - 2
    se = math.sqrt(float(np.sum((tau - a - dt * n) ** 2)) / dof / sxx) if dof > 0 else 0.0
    return a, dt, se


def _round_step(dt: float, se: float, span: float) -> float:
    """The roundest step (fewest significant digits, of the step or of the rate) that the
    fitted ``dt`` cannot tell apart from: within 3 standard errors, or moving no stamp over the
    ``span`` [steps] by more than 1 % of a step."""
    tol = max(3.0 * se, SILENT_JITTER * dt / span)
    for digits in range(1, 8):
        for c in (_significant(dt, digits), 1.0 / _significant(1.0 / dt, digits)):
            if abs(c - dt) <= tol:
                return c
    return dt


def _significant(x: float, digits: int) -> float:
    return float(f"{x:.{digits}g}")


def _snap(path: Path, cols: Mapping[str, np.ndarray], lines: np.ndarray, t0: float, dt: float,
          n: np.ndarray, resid: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray | None,
                                                      list[str]]:
    """The stamps on the grid (t0, dt) at slots ``n``: snapped, lost rows filled."""
    notes = []
    worst = float(np.max(np.abs(resid)))
    if worst > SILENT_JITTER * dt:
        rms = float(np.sqrt(np.mean(resid ** 2)))
        notes.append(f"time stamps jitter around a regular {dt * 1e3:.6g} ms grid (RMS "
                     f"{rms * 1e3:.3g} ms, max {worst * 1e3:.3g} ms): snapped to the grid")
    size = int(n[-1]) + 1
    _check_growth(path, lines, cols["t"], size, n)
    grid = t0 + np.arange(size) * dt
    if size == n.size:
        out = dict(cols)
        out["t"] = grid
        return out, None, notes
    t_kept = grid[n]
    before = np.searchsorted(n, np.arange(size), side="right") - 1  # the row in force
    out = {"t": grid}
    for c, x in cols.items():
        if c == "t":
            continue
        if c in HELD:
            out[c] = x[before]
        else:
            out[c] = np.interp(grid, t_kept, x)
            out[c][n] = x
    valid = np.zeros(size, dtype=bool)
    valid[n] = True
    gaps = np.diff(n) - 1
    at = np.flatnonzero(gaps)
    longest = int(np.argmax(gaps))
    missing, length = int(gaps.sum()), int(gaps[longest])
    notes.append(f"{_count(missing, 'row')} missing in {_count(at.size, 'gap')} (longest "
                 f"{_count(length, 'row')}, {length * dt * 1e3:.6g} ms at t = "
                 f"{grid[n[longest] + 1]:.3f} s): command held, measurements interpolated and "
                 f"left out of comparisons")
    return out, valid, notes


def _resample(path: Path, cols: Mapping[str, np.ndarray], lines: np.ndarray, step: float,
              why: str) -> tuple[dict[str, np.ndarray], None, list[str]]:
    """Irregular stamps: everything resampled onto a grid at the median ``step``."""
    t = cols["t"]
    size = int(math.floor((t[-1] - t[0]) / step * (1 + 1e-12))) + 1
    _check_growth(path, lines, t, size, None)
    grid = t[0] + np.arange(size) * step
    before = np.searchsorted(t, grid, side="right") - 1  # the row in force at each grid time
    out = {"t": grid}
    for c, x in cols.items():
        if c != "t":
            out[c] = x[before] if c in HELD else np.interp(grid, t, x)
    note = (f"time stamps do not fit a regular grid ({why}): resampled onto a regular "
            f"{step * 1e3:.6g} ms grid (the median step), {size} rows from {t.size}: "
            f"measurements interpolated linearly, command held")
    return out, None, [note]


def _check_growth(path: Path, lines: np.ndarray, t: np.ndarray, size: int,
                  n: np.ndarray | None) -> None:
    """Refuse a grid of more than MAX_GROWTH times the rows read, naming the longest gap."""
    if size <= MAX_GROWTH * t.size:
        return
    i = int(np.argmax(np.diff(n) if n is not None else np.diff(t)))
    raise DatasetError(f"{path}: line {int(lines[i + 1])}, column 't': {t.size} rows span "
                       f"{size} steps of a regular grid (longest gap {t[i + 1] - t[i]:.6g} s, "
                       f"from t = {t[i]:.6g} s); more than half of the record would be filled "
                       f"in, so it is not read as a record with lost rows")


def _count(k: int, what: str) -> str:
    return f"{k} {what}" if k == 1 else f"{k} {what}s"
