"""Units declared in ``dataset.yaml`` (and a friction rig's ``records.yaml``): which are accepted
per column and their conversion to SI.

An experiment CSV is in the contract's units (``t`` [s], ``u`` [V], ``y`` [m], ``v`` [m/s],
``p1``/``p2`` [Pa, absolute], ``f_load`` [N]) unless ``dataset.yaml`` declares others::

    units: {t: ms, y: mm, p1: bar gauge, p2: bar gauge}   # every experiment
    experiments:
      - file: a.csv
        units: {u: mV}                                    # this one: overrides per column

The reader converts the declared columns to SI before any other check, so the plausibility
checks (:mod:`jetpipe_ros.dataset.plausibility`) run on SI values and a declared unit that is
still wrong is caught as if nothing had been declared. A conversion is ``x * factor + offset``;
the offset is for a gauge pressure and for a position sensor zeroed elsewhere than mid-stroke
(``position_zero``: what it reads with the piston at the model's y = 0, e.g. ``25 mm`` for one
zeroed at the retracted end stop, subtracted after scaling). A gauge pressure is relative to
the atmosphere: the reader adds the
reference declared as ``gauge_reference`` (an absolute pressure with its unit, e.g. ``101325
Pa`` or ``1013.25 hPa``: the barometer's reading, or the standard atmosphere a logger that
converts absolute readings to gauge subtracted), else :data:`jetpipe_ros.model.flow.P_ATM` (the
model's atmosphere, 1 bar), after scaling. The ambient pressure varies by several kPa with the
weather and the altitude, and a reference that is off shifts both pressures alike, as a common
bias of the pressure sensors would (the diagnosis reads it as one, ``sensor_dynamics``): declare
it where it is known. Pressure units are absolute unless spelled gauge: ``bar gauge``,
``barg``, ``kPa gauge``, ``psig``; ``bar``, ``bar absolute``, ``bara`` are absolute. Units are
case-sensitive (``MPa`` is not ``mPa``). A friction rig's ``records.yaml`` declares units the
same way for its columns ``t``, ``x`` (a length), ``p`` and ``F`` (a force):
:mod:`jetpipe_ros.dataset.friction_rig`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.model.flow import P_ATM

PSI = 6894.757293168361  #: Pa per psi (pound-force per square inch)

#: Per quantity but pressure: (its SI unit, {accepted unit: factor to SI}).
_SCALES: dict[str, tuple[str, dict[str, float]]] = {
    "time": ("s", {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}),
    "voltage": ("V", {"V": 1.0, "mV": 1e-3}),
    "length": ("m", {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "um": 1e-6}),
    "velocity": ("m/s", {"m/s": 1.0, "mm/s": 1e-3}),
    "force": ("N", {"N": 1.0, "kN": 1e3}),
}
PRESSURES = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "bar": 1e5, "mbar": 1e2, "hPa": 1e2, "psi": PSI}
#: The quantity of each column of an experiment CSV, in contract order: the columns a unit can
#: be declared for. Other files name their own (a friction rig's: ``t, x, p, F``).
EXPERIMENT = {"t": "time", "u": "voltage", "y": "length", "p1": "pressure", "p2": "pressure",
              "v": "velocity", "f_load": "force"}
#: The key of a ``units:`` mapping that gives the absolute pressure gauge pressures are relative
#: to, and the range accepted for it [Pa] (sea level's extremes and 9 km of altitude).
REFERENCE = "gauge_reference"
REFERENCE_RANGE = (3.0e4, 1.2e5)
#: Words of the note of a gauge pressure converted with the reference assumed.
ASSUMED = f"assumed, not declared ({REFERENCE})"
#: The key of a ``units:`` mapping that gives what the position sensor reads with the piston at
#: mid-stroke (the model's y = 0), a length with its unit; subtracted after scaling. The most
#: it may be [m]: a sensor zeroed at an end stop of a long stroke.
ZERO = "position_zero"
ZERO_LIMIT = 0.5
#: Quantities with a direction: their units may be declared reversed (``-mm``).
SIGNED = ("voltage", "length", "velocity", "force")
REVERSED = "-"


@dataclass(frozen=True)
class Unit:
    """A declared unit of one column and its conversion ``x * factor + offset`` to SI."""

    column: str
    name: str  #: as declared, e.g. ``bar gauge``
    si: str  #: the contract's unit, e.g. ``Pa absolute``
    factor: float
    offset: float = 0.0  #: [SI unit], added after scaling (gauge: the atmosphere; y: -its zero)

    @property
    def identity(self) -> bool:
        """True when the column is already in SI (nothing to convert)."""
        return self.factor == 1.0 and self.offset == 0.0

    def convert(self, x: np.ndarray) -> np.ndarray:
        """``x`` in SI."""
        return x * self.factor + self.offset if not self.identity else x

    def note(self) -> str:
        """The conversion as a sentence, e.g. ``p1: bar gauge -> Pa absolute (x 100000, +
        100000 Pa)``, ``y: mm -> m (x 0.001, - 0.025 m)``."""
        how = [f"x {self.factor:.10g}"] if self.factor != 1.0 else []
        if self.factor < 0:
            how[0] += ": counted the other way round"
        if self.offset:
            sign = "+" if self.offset > 0 else "-"
            how.append(f"{sign} {abs(self.offset):.10g} {self.si.split()[0]}")
        return f"{self.column}: {self.name} -> {self.si} ({', '.join(how)})"


def contract_unit(column: str, quantities: Mapping[str, str] = EXPERIMENT) -> str:
    """The unit the contract reads ``column`` in (of the file whose columns are
    ``quantities``): the SI unit of its quantity, absolute Pa for a pressure."""
    return "Pa" if quantities[column] == "pressure" else _SCALES[quantities[column]][0]


def accepted(column: str, quantities: Mapping[str, str] = EXPERIMENT) -> str:
    """The units accepted for ``column`` (of the file whose columns are ``quantities``: column
    -> quantity), for messages."""
    if quantities[column] == "pressure":
        return (f"{', '.join(PRESSURES)}, each absolute (e.g. 'bar', 'bar absolute', 'bara') "
                f"or gauge (e.g. 'bar gauge', 'barg', 'kPa gauge', 'psig')")
    names = list(_SCALES[quantities[column]][1])
    if quantities[column] not in SIGNED:
        return ", ".join(names)
    return (f"{', '.join(names)}; with a minus before the unit (e.g. '{REVERSED}{names[0]}') "
            f"when the column counts the other way round")


def parse(column: str, text: Any, reference: float = P_ATM,
          quantities: Mapping[str, str] = EXPERIMENT) -> Unit:
    """The unit ``text`` declared for ``column`` (a gauge pressure relative to ``reference``
    [Pa]) of a file whose columns are ``quantities`` (column -> quantity); ValueError (naming
    both and listing the accepted units) if either is unknown."""
    if column not in quantities:
        raise ValueError(f"unknown column {column!r}; units can be declared for "
                         f"{', '.join(quantities)} (and {REFERENCE}, the absolute pressure "
                         f"gauge pressures are relative to"
                         + (f"; {ZERO}, what the position sensor reads at mid-stroke"
                            if "y" in quantities else "") + ")")
    name = " ".join(text.split()) if isinstance(text, str) else None
    if name:
        if quantities[column] == "pressure":
            unit = _pressure(column, name, reference)
            if unit is not None:
                return unit
        else:
            si, scales = _SCALES[quantities[column]]
            sign, bare = ((-1.0, name[1:].strip()) if name.startswith(REVERSED)
                          and quantities[column] in SIGNED else (1.0, name))
            if bare in scales:
                return Unit(column, name, si, sign * scales[bare])
    if name and name.startswith(REVERSED) and quantities[column] in ("time", "pressure"):
        raise ValueError(f"column {column!r}: {text!r}: a {quantities[column]} has no direction "
                         f"to reverse" + (f"; chamber pressures logged under each other's "
                                          f"names are renamed with columns: {{p1: p2, p2: p1}}"
                                          if column in ("p1", "p2") else ""))
    raise ValueError(f"column {column!r}: unknown unit {text!r}; accepted: "
                     f"{accepted(column, quantities)}")


def _spelling(name: str) -> tuple[float, bool] | None:
    """The factor to Pa of pressure unit ``name`` and whether it is gauge, or None if ``name``
    is no pressure unit."""
    for base, factor in PRESSURES.items():
        for gauge, spellings in ((False, (base, f"{base} absolute", f"{base} abs", f"{base}a")),
                                 (True, (f"{base} gauge", f"{base}g"))):
            if name in spellings:
                return factor, gauge
    return None


def _pressure(column: str, name: str, reference: float) -> Unit | None:
    """A pressure unit, absolute or gauge (relative to ``reference`` [Pa]), or None if
    ``name`` is none of them."""
    found = _spelling(name)
    if found is None:
        return None
    factor, gauge = found
    return Unit(column, name, "Pa absolute", factor, reference if gauge else 0.0)


def gauge_reference(text: Any) -> float:
    """The absolute pressure [Pa] that ``gauge_reference: text`` declares (a number and an
    absolute pressure unit, e.g. ``101325 Pa``, ``1013.25 hPa``, ``1.01325 bar``); ValueError
    naming the key, the value and what is accepted."""
    words = text.split() if isinstance(text, str) else []
    found = _spelling(words[1]) if len(words) == 2 else None
    try:
        value = float(words[0]) * found[0] if found is not None and not found[1] else None
    except ValueError:
        value = None
    if value is None:
        raise ValueError(f"{REFERENCE}: expected an absolute pressure and its unit (e.g. "
                         f"'101325 Pa', '1013.25 hPa'), got {text!r}")
    low, high = REFERENCE_RANGE
    if not low <= value <= high:
        raise ValueError(f"{REFERENCE}: {text!r} is {value:g} Pa, outside the "
                         f"{low:g}-{high:g} Pa an ambient pressure can have")
    return value


def position_zero(text: Any) -> float:
    """The reading [m] that ``position_zero: text`` declares (a number and a length unit, e.g.
    ``25 mm``, ``-0.025 m``); ValueError naming the key, the value and what is accepted."""
    words = text.split() if isinstance(text, str) else []
    scales = _SCALES["length"][1]
    try:
        value = float(words[0]) * scales[words[1]] if len(words) == 2 else None
    except (ValueError, KeyError):
        value = None
    if value is None:
        raise ValueError(f"{ZERO}: expected a length and its unit ({', '.join(scales)}; e.g. "
                         f"'25 mm'), got {text!r}")
    if not abs(value) <= ZERO_LIMIT:
        raise ValueError(f"{ZERO}: {text!r} is {value:g} m, more than the {ZERO_LIMIT:g} m a "
                         f"position sensor's zero can lie from mid-stroke")
    return value


def declared(where: str, raw: Any, quantities: Mapping[str, str] = EXPERIMENT
             ) -> dict[str, str]:
    """Validate a ``units:`` mapping (column -> unit) read at ``where`` for a file whose columns
    are ``quantities``; return it as a dict. Raise DatasetError naming ``where``, the column and
    the accepted units."""
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        raise DatasetError(f"{where}: expected a mapping of column to unit (e.g. "
                           f"{{p1: bar gauge}}), got {raw!r}")
    out: dict[str, str] = {}
    for column, text in raw.items():
        try:
            if column == REFERENCE:
                gauge_reference(text)
            elif column == ZERO and "y" in quantities:
                position_zero(text)
            else:
                parse(column, text, quantities=quantities)
        except ValueError as exc:
            raise DatasetError(f"{where}: {exc}") from None
        out[column] = text
    return out


def to_si(where: str, cols: dict[str, np.ndarray], units: Mapping[str, str] | None,
          quantities: Mapping[str, str] = EXPERIMENT, *, reference_matters: bool = True
          ) -> list[str]:
    """Convert the columns of ``cols`` (in place) from the declared ``units`` to SI (the
    columns' quantities: ``quantities``); return one note per conversion. Columns declared but
    absent are ignored (a dataset-wide declaration covers experiments without that sensor). A
    gauge pressure without a declared ``gauge_reference`` gets the model's atmosphere, and its
    note says so unless ``reference_matters`` is False (a file whose pressure is only used
    against that same atmosphere, as a friction rig's is: the reference cancels)."""
    units = declared(where, units, quantities)
    given = REFERENCE in units
    reference = gauge_reference(units[REFERENCE]) if given else P_ATM
    per_column = {c: t for c, t in units.items() if c not in (REFERENCE, ZERO)}
    if ZERO in units:
        per_column.setdefault("y", "m")
    notes = []
    for column, text in per_column.items():
        unit = parse(column, text, reference, quantities)
        if column == "y" and ZERO in units:
            # the reading at mid-stroke, counted as the column counts
            unit = dataclasses.replace(
                unit, offset=-math.copysign(1.0, unit.factor) * position_zero(units[ZERO]))
        if column in cols and not unit.identity:
            cols[column] = unit.convert(cols[column])
            gauge = unit.offset and quantities[column] == "pressure"
            assumed = (f"; the ambient pressure the gauge is relative to {ASSUMED}: a "
                       f"reference off by some kPa reads as a common bias of the pressure "
                       f"sensors") if gauge and not given and reference_matters else ""
            notes.append(unit.note() + assumed)
    return notes
