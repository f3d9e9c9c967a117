"""Physical plausibility of an experiment's columns: impossible values and likely unit mistakes.

A value outside :class:`~jetpipe_ros.model.limits.Limits` cannot come from this actuator: the
reader refuses it, naming the file, the line and the column. When a whole column is off by a
unit factor (pressures in bar or kPa, gauge instead of absolute pressure, position in mm or
measured from an end stop, time in ms) the message says which unit it likely is and how to
convert it, because such data would otherwise be fitted with a confident, wrong answer.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.model.flow import P_ATM
from jetpipe_ros.model.limits import NOMINAL, POSITION_MARGIN, Limits

#: Unit mistakes recognised per kind of column: (unit, factor to SI).
PRESSURE_UNITS = (("bar", 1e5), ("kPa", 1e3), ("MPa", 1e6), ("psi", 6894.757),
                  ("mbar (hPa)", 1e2))
POSITION_UNITS = (("mm", 1e-3), ("cm", 1e-2), ("um", 1e-6))
VELOCITY_UNITS = (("mm/s", 1e-3),)
VOLTAGE_UNITS = (("mV", 1e-3),)
TIME_UNITS = (("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9))


def check(path: Path, cols: Mapping[str, np.ndarray], limits: Limits = NOMINAL,
          lines: np.ndarray | None = None) -> None:
    """Raise DatasetError if a column of ``cols`` (read from ``path``) is physically
    impossible. ``lines`` gives each row's line number in the file (for the message)."""
    low, high = limits.pressure
    for c in ("p1", "p2"):
        if c in cols:
            _Column(path, c, cols[c], lines).check(
                low, high, "Pa", "an absolute pressure", PRESSURE_UNITS,
                typical=limits.pressure_typical, gauge=True)
    if "y" in cols:
        _Column(path, "y", cols["y"], lines).check(
            -limits.position, limits.position, "m", "a position within the stroke",
            POSITION_UNITS, least=0.1 * limits.position, end_stop=limits.position)
    for c, bound, unit, what, units, least in (
            ("v", limits.velocity, "m/s", "a piston velocity", VELOCITY_UNITS, 0.01),
            ("u", limits.voltage, "V", "a valve command", VOLTAGE_UNITS, 0.05),
            ("f_load", limits.load, "N", "an external load on this piston", (), 0.0)):
        if c in cols:
            _Column(path, c, cols[c], lines).check(-bound, bound, unit, what, units, least=least)
    if "t" in cols and cols["t"].size > 1:
        _sample_time(path, cols["t"], limits)


class _Column:
    """One column being checked: where it comes from, for the messages."""

    def __init__(self, path: Path, name: str, x: np.ndarray, lines: np.ndarray | None) -> None:
        self.path, self.name, self.x, self.lines = path, name, x, lines

    def check(self, low: float, high: float, unit: str, what: str,
              units: tuple[tuple[str, float], ...], typical: tuple[float, float] | None = None,
              least: float = 0.0, gauge: bool = False, end_stop: float | None = None) -> None:
        """Refuse values outside [low, high]; name a likely unit mistake.

        A column is off as a whole when its median (``typical`` given: a level such as a
        pressure) or its 99th percentile of magnitude (a signed signal) is out of range; a unit
        fits when every scaled value is plausible and the scaled median is ``typical`` (or the
        scaled 99th percentile magnitude at least ``least``).
        """
        x = self.x
        bad = np.flatnonzero((x < low) | (x > high))
        if not bad.size:
            return
        where = f"{self.path}: column {self.name!r}"
        span = f"{x.min():.6g} to {x.max():.6g}"
        plausible = f"[{low:.6g}, {high:.6g}] {unit}"
        level = np.median(x) if typical is not None else np.percentile(np.abs(x), 99)
        if not low <= level <= high:
            for name, factor in sorted(units, key=lambda u: abs(np.log10(u[1]))):
                y = x * factor
                size = np.median(y) if typical is not None else np.percentile(np.abs(y), 99)
                fits = (typical[0] <= size <= typical[1]) if typical is not None \
                    else size >= least
                if fits and np.all((y >= low) & (y <= high)):
                    raise DatasetError(f"{where}: values {span} are not {what} in {unit} "
                                       f"(plausible: {plausible}); they look like {name}: "
                                       f"multiply by {factor:g} to get {unit}")
        many = bad.size >= 0.01 * x.size
        if gauge and many and np.all((x + P_ATM >= low) & (x + P_ATM <= high)):
            raise DatasetError(f"{where}: values {span} look like gauge pressure (relative to "
                               f"the atmosphere); the dataset needs absolute pressure in Pa "
                               f"(plausible: {plausible}): add {P_ATM:g} Pa")
        if end_stop is not None and many and np.all((x >= -0.1 * end_stop)
                                                    & (x <= 2 * end_stop)):
            raise DatasetError(f"{where}: values {span} look measured from an end stop (0 to "
                               f"{2 * end_stop:.6g} {unit}); the dataset centres the stroke "
                               f"(plausible: {plausible}): declare what the sensor reads at "
                               f"mid-stroke in dataset.yaml (units: {{position_zero: "
                               f"{(end_stop - POSITION_MARGIN) * 1e3:g} mm}} for a zero at an "
                               f"end stop), or subtract half the stroke")
        first = int(bad[0])
        line = f"line {int(self.lines[first])}" if self.lines is not None \
            else f"data row {first + 1}"
        more = (f" ({bad.size} values outside, {bad.size / x.size:.1%} of the column)"
                if bad.size > 1 else "")
        raise DatasetError(f"{self.path}: {line}, column {self.name!r}: {x[first]:.6g} {unit} "
                           f"is not {what} (plausible: {plausible}){more}")


def _sample_time(path: Path, t: np.ndarray, limits: Limits) -> None:
    dt = float(np.median(np.diff(t)))
    low, high = limits.sample_time
    if low <= dt <= high:
        return
    where = f"{path}: column 't'"
    for name, factor in TIME_UNITS:
        if low <= dt * factor <= high:
            raise DatasetError(f"{where}: the median sample interval {dt:.6g} is not in "
                               f"seconds (plausible: [{low:g}, {high:g}] s); it looks like "
                               f"{name}: declare it in dataset.yaml (units: {{t: {name}}}) "
                               f"or multiply t by {factor:g}")
    raise DatasetError(f"{where}: the median sample interval {dt:.6g} s is outside the "
                       f"plausible [{low:g}, {high:g}] s")
