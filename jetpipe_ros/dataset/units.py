"""Units declared in ``dataset.yaml``: which are accepted per column and their conversion to SI.

An experiment CSV is in the contract's units (``t`` [s], ``u`` [V], ``y`` [m], ``v`` [m/s],
``p1``/``p2`` [Pa, absolute], ``f_load`` [N]) unless ``dataset.yaml`` declares others::

    units: {t: ms, y: mm, p1: bar gauge, p2: bar gauge}   # every experiment
    experiments:
      - file: a.csv
        units: {u: mV}                                    # this one: overrides per column

The reader converts the declared columns to SI before any other check, so the plausibility
checks (:mod:`jetpipe_ros.dataset.plausibility`) run on SI values and a declared unit that is
still wrong is caught as if nothing had been declared. A conversion is ``x * factor + offset``;
the offset is only for gauge pressure, which is relative to the atmosphere: the reader adds
:data:`jetpipe_ros.model.flow.P_ATM` (the model's atmosphere) after scaling. Pressure units are
absolute unless spelled gauge: ``bar gauge``, ``barg``, ``kPa gauge``, ``psig``; ``bar``,
``bar absolute``, ``bara`` are absolute. Units are case-sensitive (``MPa`` is not ``mPa``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.model.flow import P_ATM

PSI = 6894.757293168361  #: Pa per psi (pound-force per square inch)

#: Per column: (its SI unit, {accepted unit: factor to SI}).
_SCALES: dict[str, tuple[str, dict[str, float]]] = {
    "t": ("s", {"s": 1.0, "ms": 1e-3, "us": 1e-6}),
    "u": ("V", {"V": 1.0, "mV": 1e-3}),
    "y": ("m", {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "um": 1e-6}),
    "v": ("m/s", {"m/s": 1.0, "mm/s": 1e-3}),
    "f_load": ("N", {"N": 1.0, "kN": 1e3}),
}
PRESSURES = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "bar": 1e5, "mbar": 1e2, "hPa": 1e2, "psi": PSI}
PRESSURE_COLUMNS = ("p1", "p2")
#: Columns a unit can be declared for, in contract order.
COLUMNS = ("t", "u", "y", "p1", "p2", "v", "f_load")


@dataclass(frozen=True)
class Unit:
    """A declared unit of one column and its conversion ``x * factor + offset`` to SI."""

    column: str
    name: str  #: as declared, e.g. ``bar gauge``
    si: str  #: the contract's unit, e.g. ``Pa absolute``
    factor: float
    offset: float = 0.0  #: [SI unit], added after scaling (gauge pressure: the atmosphere)

    @property
    def identity(self) -> bool:
        """True when the column is already in SI (nothing to convert)."""
        return self.factor == 1.0 and self.offset == 0.0

    def convert(self, x: np.ndarray) -> np.ndarray:
        """``x`` in SI."""
        return x * self.factor + self.offset if not self.identity else x

    def note(self) -> str:
        """The conversion as a sentence, e.g. ``p1: bar gauge -> Pa absolute (x 100000, +
        100000 Pa)``."""
        how = [f"x {self.factor:.10g}"] if self.factor != 1.0 else []
        if self.offset:
            how.append(f"+ {self.offset:.10g} Pa")
        return f"{self.column}: {self.name} -> {self.si} ({', '.join(how)})"


def accepted(column: str) -> str:
    """The units accepted for ``column``, for messages."""
    if column in PRESSURE_COLUMNS:
        return (f"{', '.join(PRESSURES)}, each absolute (e.g. 'bar', 'bar absolute', 'bara') "
                f"or gauge (e.g. 'bar gauge', 'barg', 'kPa gauge', 'psig')")
    return ", ".join(_SCALES[column][1])


def parse(column: str, text: Any) -> Unit:
    """The unit ``text`` declared for ``column``; ValueError (naming both and listing the
    accepted units) if either is unknown."""
    if column not in COLUMNS:
        raise ValueError(f"unknown column {column!r}; units can be declared for "
                         f"{', '.join(COLUMNS)}")
    name = " ".join(text.split()) if isinstance(text, str) else None
    if name:
        if column in PRESSURE_COLUMNS:
            unit = _pressure(column, name)
            if unit is not None:
                return unit
        else:
            si, scales = _SCALES[column]
            if name in scales:
                return Unit(column, name, si, scales[name])
    raise ValueError(f"column {column!r}: unknown unit {text!r}; accepted: {accepted(column)}")


def _pressure(column: str, name: str) -> Unit | None:
    """A pressure unit, absolute or gauge, or None if ``name`` is none of them."""
    for base, factor in PRESSURES.items():
        for gauge, spellings in ((False, (base, f"{base} absolute", f"{base} abs", f"{base}a")),
                                 (True, (f"{base} gauge", f"{base}g"))):
            if name in spellings:
                return Unit(column, name, "Pa absolute", factor, P_ATM if gauge else 0.0)
    return None


def declared(where: str, raw: Any) -> dict[str, str]:
    """Validate a ``units:`` mapping (column -> unit) read at ``where``; return it as a dict.
    Raise DatasetError naming ``where``, the column and the accepted units."""
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        raise DatasetError(f"{where}: expected a mapping of column to unit (e.g. "
                           f"{{p1: bar gauge}}), got {raw!r}")
    out: dict[str, str] = {}
    for column, text in raw.items():
        try:
            parse(column, text)
        except ValueError as exc:
            raise DatasetError(f"{where}: {exc}") from None
        out[column] = text
    return out


def to_si(where: str, cols: dict[str, np.ndarray], units: Mapping[str, str] | None) -> list[str]:
    """Convert the columns of ``cols`` (in place) from the declared ``units`` to SI; return one
    note per conversion. Columns declared but absent are ignored (a dataset-wide declaration
    covers experiments without that sensor)."""
    notes = []
    for column, text in declared(where, units).items():
        unit = parse(column, text)
        if column in cols and not unit.identity:
            cols[column] = unit.convert(cols[column])
            notes.append(unit.note())
    return notes
