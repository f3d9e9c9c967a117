"""One experiment as a CSV file: columns ``t,u,y,p1,p2`` [s, V, m, Pa absolute] (DESIGN.md s.5).

Optional columns ``v`` [m/s] and ``f_load`` [N] are read when present; other columns are ignored.
Reading checks what a wrong answer would otherwise hide: a header with the required columns,
numbers everywhere (errors give file, line and column), finite values, strictly increasing,
regularly sampled time, and physically possible values in the contract's units
(:mod:`jetpipe_ros.dataset.plausibility`: ranges, likely unit mistakes). Writing goes through a
temporary file renamed into place (:mod:`jetpipe_ros.fileio`), so a failed write never leaves a
half-written file behind.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jetpipe_ros import fileio
from jetpipe_ros.dataset import plausibility
from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.model.limits import NOMINAL, Limits

REQUIRED = ("t", "u", "y", "p1", "p2")
OPTIONAL = ("v", "f_load")
#: Allowed relative deviation of a sample interval from the median interval.
SAMPLING_TOLERANCE = 0.01


@dataclass
class Experiment:
    """Sampled signals of one experiment, each a 1-D float array of equal length [SI units]."""

    t: np.ndarray  #: time [s]
    u: np.ndarray  #: valve command [V]
    y: np.ndarray | None = None  #: piston position [m]
    p1: np.ndarray | None = None  #: chamber 1 pressure [Pa, absolute]
    p2: np.ndarray | None = None  #: chamber 2 pressure [Pa, absolute]
    v: np.ndarray | None = None  #: piston velocity [m/s]
    f_load: np.ndarray | None = None  #: external load [N]
    name: str = ""
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def dt(self) -> float:
        """Median sample interval [s]."""
        return float(np.median(np.diff(self.t))) if self.t.size > 1 else math.nan

    def columns(self) -> dict[str, np.ndarray]:
        """All present columns in contract order, then extras."""
        cols = {k: getattr(self, k) for k in (*REQUIRED, *OPTIONAL)}
        cols = {k: v for k, v in cols.items() if v is not None}
        cols.update(self.extra)
        return cols


def read_experiment(path: str | Path, required: Iterable[str] = REQUIRED,
                    limits: Limits = NOMINAL) -> Experiment:
    """Read and validate an experiment CSV; raise DatasetError naming file, line and column.

    Values outside ``limits`` (the nominal actuator's by default) are refused as physically
    impossible, with the likely unit mistake when a whole column is off.
    """
    path = Path(path)
    required = tuple(required)
    try:
        handle = path.open(newline="")
    except OSError as exc:
        raise DatasetError(f"{path}: cannot open: {exc.strerror}") from exc
    with handle:
        reader = csv.reader(handle)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise DatasetError(f"{path}: empty file, expected a header row") from None
        missing = [c for c in required if c not in header]
        if missing:
            raise DatasetError(f"{path}: line 1: missing column(s) {', '.join(missing)} "
                               f"(header has {', '.join(header)})")
        wanted = [c for c in (*REQUIRED, *OPTIONAL) if c in header]
        index = {c: header.index(c) for c in wanted}
        rows: list[list[float]] = []
        lines: list[int] = []
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue
            values = []
            for col in wanted:
                i = index[col]
                cell = row[i].strip() if i < len(row) else ""
                try:
                    value = float(cell)
                except ValueError:
                    raise DatasetError(f"{path}: line {line_no}, column {col!r}: "
                                       f"not a number: {cell!r}") from None
                if not math.isfinite(value):
                    raise DatasetError(f"{path}: line {line_no}, column {col!r}: "
                                       f"non-finite value {cell!r}")
                values.append(value)
            rows.append(values)
            lines.append(line_no)
    if len(rows) < 2:
        raise DatasetError(f"{path}: needs at least 2 data rows, has {len(rows)}")
    data = np.array(rows)
    cols = {c: np.ascontiguousarray(data[:, j]) for j, c in enumerate(wanted)}
    _check_time(path, cols["t"])
    plausibility.check(path, cols, limits, np.array(lines))
    return Experiment(name=path.stem, **cols)


def _check_time(path: Path, t: np.ndarray) -> None:
    dts = np.diff(t)
    bad = np.flatnonzero(dts <= 0.0)
    if bad.size:
        i = int(bad[0])
        raise DatasetError(f"{path}: line {i + 3}, column 't': time is not strictly increasing "
                           f"({t[i]:.6g} then {t[i + 1]:.6g} s)")
    med = float(np.median(dts))
    irregular = np.flatnonzero(np.abs(dts - med) > SAMPLING_TOLERANCE * med)
    if irregular.size:
        i = int(irregular[0])
        raise DatasetError(f"{path}: line {i + 3}, column 't': irregular sampling, step "
                           f"{dts[i]:.6g} s where the median step is {med:.6g} s")


def write_experiment(path: str | Path, columns: Mapping[str, np.ndarray]) -> None:
    """Write columns (``t`` first) to CSV atomically: a temporary file renamed into place."""
    path = Path(path)
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    if not np.all(np.isfinite(data)):
        raise DatasetError(f"{path}: refusing to write non-finite values")
    text = io.StringIO()
    text.write(",".join(names) + "\n")
    np.savetxt(text, data, delimiter=",", fmt="%.9g")
    fileio.write_text(path, text.getvalue())
