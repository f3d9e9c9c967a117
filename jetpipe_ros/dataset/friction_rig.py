"""Friction-rig records: a rod driven back and forth by an external drive, one chamber pressurised.

A friction-rig folder holds ``records.yaml`` and one CSV per record::

    records:
      - file: seal_5bar.csv
        bore: 0.025          # m; or area: 4.909e-4 (m^2)
        gauge_bar: 5         # set pressure [bar gauge], optional (the CSV's p is what is used)
        seal: NAPN           # optional: records of one seal are fitted together
        role: holdout        # train | holdout, optional: holdout records are not fitted
        units: {F: kN}       # optional: this CSV's units (overrides the top level)
        columns: {Force: F}  # optional: this CSV's own column names -> t, x, p, F
    units: {t: ms, x: mm, p: bar gauge}   # optional, for every record
    columns: {time: t}                    # optional, for every record

Each CSV has the columns ``t,x,p,F`` (s, m, Pa absolute, N, unless ``units:`` declares others,
as ``dataset.yaml`` does: :mod:`jetpipe_ros.dataset.units`): time, rod position, the chamber
pressure acting on the bore (the other side at atmosphere) and the force measured on the rod.
The friction is F - (p - p_atm) A, positive in the direction of motion.

Loggers lose rows and jitter. A record is put on a regular grid at its median sample time by
linear interpolation; grid points farther than 0.6 sample from any logged row are marked
invalid (gaps are masked, never refused). Only what cannot be read is refused, with a message
naming the file, the line or the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from jetpipe_ros.dataset.dataset import column_names, merged_columns
from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.dataset.experiment import read_columns
from jetpipe_ros.dataset.timebase import check_increasing
from jetpipe_ros.dataset.units import REFERENCE, declared, to_si
from jetpipe_ros.fileio import load_yaml
from jetpipe_ros.model.flow import P_ATM

INDEX = "records.yaml"
COLUMNS = ("t", "x", "p", "F")
#: The quantity of each column, for the units a record may declare.
QUANTITIES = {"t": "time", "x": "length", "p": "pressure", "F": "force"}
ROLES = ("train", "holdout")
#: A grid point farther than this many sample times from any logged row is a gap.
GAP_TOLERANCE = 0.6
MIN_ROWS = 50
#: How far a record's logged pressure (median) may lie from its declared ``gauge_bar`` before
#: it is said: 10 % of the set pressure, at least 0.2 bar [Pa]. A regulator holds its set point
#: within a few percent (the twelve public records: within 0.05 bar, 1.5 %); a file under
#: another file's entry, or a pressure in other units, lies far beyond.
SET_TOLERANCE = 0.1
SET_TOLERANCE_PA = 0.2e5
#: Longest median sample time [s] read as seconds: a friction record needs samples within the
#: build-up after a reversal (about 1 mm, a tenth of a second at 10 mm/s); a larger step is a
#: time column in ms (the public records: 10 ms).
MAX_SAMPLE_TIME = 1.0
#: Most travel [m] read as metres: a rig strokes centimetres (the public records: 36 mm), so
#: more is a position in mm or um.
MAX_TRAVEL = 10.0


@dataclass
class RigRecord:
    """One friction-rig record on a regular time grid [SI units]."""

    name: str  #: file stem
    file: str  #: CSV file name
    seal: str  #: seal (records of one seal are fitted together)
    area: float  #: area the pressure acts on [m^2]
    role: str | None  #: train | holdout | None
    set_pressure: float | None  #: set pressure [Pa absolute], as declared
    t: np.ndarray  #: time [s], regular
    x: np.ndarray  #: rod position [m]
    p: np.ndarray  #: chamber pressure [Pa absolute]
    force: np.ndarray  #: force on the rod [N]
    valid: np.ndarray  #: bool: a logged row near this grid point (False in the logger's gaps)
    notes: list[str]  #: what was done to the time base

    @property
    def dt(self) -> float:
        """Sample time of the grid [s]."""
        return float(self.t[1] - self.t[0])

    @property
    def friction(self) -> np.ndarray:
        """Friction force F - (p - p_atm) A [N], positive in the direction of motion."""
        return self.force - (self.p - P_ATM) * self.area


def _number(where: str, key: str, value: Any, low: float, high: float, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or not low <= value <= high:
        raise DatasetError(f"{where}: field {key!r} must be a number in [{low:g}, {high:g}] "
                           f"{unit}, got {value!r}")
    return float(value)


def read_records(root: str | Path) -> list[RigRecord]:
    """Read and check a friction-rig folder; DatasetError naming the file and field."""
    root = Path(root)
    index = root / INDEX
    if not index.is_file():
        raise DatasetError(f"{index}: no {INDEX} (a friction-rig folder lists its records "
                           f"there: file, bore or area, optional seal, gauge_bar, role)")
    try:
        tree = load_yaml(index)
    except yaml.YAMLError as exc:
        raise DatasetError(f"{index}: not valid YAML: {exc}") from None
    raw = tree.get("records") if isinstance(tree, dict) else None
    if not isinstance(raw, list) or not raw:
        raise DatasetError(f"{index}: expected a non-empty list 'records:'")
    unknown = set(tree) - {"records", "units", "columns"}
    if unknown:
        raise DatasetError(f"{index}: unknown field(s) {', '.join(sorted(unknown))} (known: "
                           f"records, units, columns)")
    units = _units(f"{index}: units", tree.get("units"))
    columns = column_names(f"{index}: columns", tree.get("columns"), COLUMNS)
    records, seen = [], set()
    for i, entry in enumerate(raw, 1):
        where = f"{index}: record {i}"
        if not isinstance(entry, dict) or not isinstance(entry.get("file"), str):
            raise DatasetError(f"{where}: expected a mapping with a 'file:' name")
        where = f"{index}: record {i} ({entry['file']})"
        unknown = set(entry) - {"file", "bore", "area", "gauge_bar", "seal", "role", "units",
                                "columns"}
        if unknown:
            raise DatasetError(f"{where}: unknown field(s) {', '.join(sorted(unknown))}")
        if entry["file"] in seen:
            raise DatasetError(f"{where}: listed twice")
        seen.add(entry["file"])
        if ("bore" in entry) == ("area" in entry):
            raise DatasetError(f"{where}: give exactly one of 'bore' [m] or 'area' [m^2]")
        if "bore" in entry:
            area = math.pi * (_number(where, "bore", entry["bore"], 1e-4, 1.0, "m") / 2) ** 2
        else:
            area = _number(where, "area", entry["area"], 1e-8, 1.0, "m^2")
        role = entry.get("role")
        if role is not None and role not in ROLES:
            raise DatasetError(f"{where}: field 'role' must be one of {', '.join(ROLES)}, "
                               f"got {role!r}")
        gauge = entry.get("gauge_bar")
        set_pressure = None if gauge is None else \
            P_ATM + 1e5 * _number(where, "gauge_bar", gauge, 0.0, 100.0, "bar")
        own = _units(f"{where}: field 'units'", entry.get("units"))
        names = column_names(f"{where}: field 'columns'", entry.get("columns"), COLUMNS)
        t, x, p, force, valid, notes = _read_csv(root / entry["file"], {**units, **own},
                                                 merged_columns(columns, names))
        if set_pressure is not None:
            held = float(np.median(p[valid]))
            if abs(held - set_pressure) > max(SET_TOLERANCE_PA,
                                              SET_TOLERANCE * (set_pressure - P_ATM)):
                notes.append(f"{entry['file']}: gauge_bar {gauge:g} declared, but the pressure "
                             f"logged is {(held - P_ATM) * 1e-5:.2f} bar gauge (median): the "
                             f"logged one is used; check the file and its entry")
        records.append(RigRecord(
            name=Path(entry["file"]).stem, file=entry["file"], seal=str(entry.get("seal", "")),
            area=area, role=role, set_pressure=set_pressure, t=t, x=x, p=p, force=force,
            valid=valid, notes=notes))
    return records


def _units(where: str, raw: Any) -> dict[str, str]:
    """A record's ``units:`` mapping, validated; DatasetError naming ``where`` otherwise. No
    ``gauge_reference``: the friction takes the pressure against the atmosphere on the rod's
    other side, which is what a gauge reads, whatever the ambient pressure."""
    units = declared(where, raw, QUANTITIES)
    if REFERENCE in units:
        raise DatasetError(f"{where}: {REFERENCE} is not needed on a friction rig (the "
                           f"pressure acts against the atmosphere on the rod's other side, "
                           f"which is what a gauge reads): leave it out")
    return units


def _read_csv(path: Path, units: dict[str, str], columns: dict[str, str]
              ) -> tuple[np.ndarray, ...]:
    """(t, x, p, F on a regular grid [SI], valid mask, notes) of one record CSV whose columns
    are named ``columns`` (the file's name -> the contract's) and in ``units`` (declared)."""
    cols, lines, read = read_columns(path, COLUMNS, COLUMNS, least=MIN_ROWS, rename=columns,
                                     index=INDEX,
                                     hint="; needs t,x,p,F in s, m, Pa absolute, N, or units "
                                          "declared in records.yaml")
    # A gauge reading becomes p_atm + gauge, and the friction takes p - p_atm: the gauge
    # reading itself, the pressure against the atmosphere on the other side.
    read += to_si(f"{path}: units", cols, units, QUANTITIES, reference_matters=False)
    t, x, p, force = (cols[c] for c in COLUMNS)
    check_increasing(path, t, lines)
    step = np.diff(t)
    if np.median(p) < 0.5 * P_ATM:
        raise DatasetError(f"{path}: column 'p' has median {np.median(p):g} Pa: it must be the "
                           f"absolute pressure in Pa (gauge bar x 1e5 + 1e5), or its unit "
                           f"declared in records.yaml (e.g. units: {{p: bar gauge}})")
    dt = float(np.median(step))
    if dt > MAX_SAMPLE_TIME:
        raise DatasetError(f"{path}: column 't' has a median step of {dt:g}: a rig logs far "
                           f"faster than one row per {MAX_SAMPLE_TIME:g} s; t must be in "
                           f"seconds, or its unit declared (units: {{t: ms}})")
    if np.ptp(x) > MAX_TRAVEL:
        raise DatasetError(f"{path}: column 'x' spans {np.ptp(x):g}: more than "
                           f"{MAX_TRAVEL:g} m of travel; x must be in metres, or its unit "
                           f"declared (units: {{x: mm}})")
    grid = t[0] + dt * np.arange(int(round((t[-1] - t[0]) / dt)) + 1)
    after = np.clip(np.searchsorted(t, grid), 1, t.size - 1)
    nearest = np.minimum(np.abs(t[after] - grid), np.abs(t[after - 1] - grid))
    valid = nearest <= GAP_TOLERANCE * dt
    notes = [f"{path.name}: {note}" for note in read]
    notes.append(f"{path.name}: {t.size} rows put on a {dt * 1e3:.3g} ms grid of {grid.size} "
                 f"points")
    if not valid.all():
        notes.append(f"{path.name}: {int((~valid).sum())} grid points in the logger's gaps "
                     f"masked (longest gap {step.max():.3g} s)")
    return (grid, np.interp(grid, t, x), np.interp(grid, t, p), np.interp(grid, t, force),
            valid, notes)
