"""One experiment as a CSV file: columns ``t,u,y,p1,p2`` [s, V, m, Pa absolute] (docs/data.md).

``t`` and ``u`` are required, and at least one measured column of ``y``, ``p1``, ``p2``: a
bench may have a position sensor only, or one pressure sensor. Optional columns ``v`` [m/s]
and ``f_load`` [N] are read when present; other columns are ignored. Row k pairs the command
``u_k`` with the measurements taken at ``t_k``. Columns in other units are converted to SI
when ``dataset.yaml`` declares them (:mod:`jetpipe_ros.dataset.units`). Reading checks what a
wrong answer would otherwise hide: a header with the required columns, numbers everywhere
(errors give file, line and column), finite values, strictly increasing time, and physically
possible values in the contract's units (:mod:`jetpipe_ros.dataset.plausibility`: ranges,
likely unit mistakes; run on the SI values, after any declared conversion). It then puts the
record on a regular grid (:mod:`jetpipe_ros.dataset.timebase`: jitter snapped, lost rows
filled and marked in ``valid``, irregular stamps resampled) and says in the experiment's notes
what it converted or changed. Writing goes through a temporary file renamed into place
(:mod:`jetpipe_ros.fileio`), so a failed write never leaves a half-written file behind.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import numpy as np

from jetpipe_ros import fileio
from jetpipe_ros.dataset import plausibility, timebase
from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.dataset.units import contract_unit, declared, parse, to_si
from jetpipe_ros.model.limits import NOMINAL, Limits

#: Significant digits a record's sample time is read to: the step between stamps carries their
#: rounding (0.01 s read as 0.010000000000000009 s from stamps printed to 10 ms), which is no
#: part of the logger's rate and put a 100 Hz record outside the model's range of sample
#: times; a clock off its nominal rate by 1 ppm still shows.
SAMPLE_TIME_DIGITS = 9
#: Column separators a header is searched for, in order (a comma first: a comma-separated
#: file has no other), with their names.
DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab"}
#: Byte-order marks of UTF-16 text (little- and big-endian).
UTF16_MARKS = (b"\xff\xfe", b"\xfe\xff")
#: Columns every experiment needs.
REQUIRED = ("t", "u")
#: Measured columns, optional each; an experiment needs at least one of them.
MEASURED = ("y", "p1", "p2")
#: Every sensor: what identification needs (``required=COMPLETE``).
COMPLETE = (*REQUIRED, *MEASURED)
OPTIONAL = ("v", "f_load")


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
    #: True where the row was measured, False where it was filled in (a row lost by the
    #: logger); None when every row was measured.
    valid: np.ndarray | None = None
    #: What the reader converted or changed, one plain sentence each (no file name).
    notes: list[str] = field(default_factory=list)

    @property
    def measured(self) -> np.ndarray:
        """True at each measured row, False where a row was filled in (:attr:`valid`; every
        row True when that is None)."""
        return self.valid if self.valid is not None else np.ones(self.t.size, dtype=bool)

    @property
    def dt(self) -> float:
        """Median sample interval [s], to :data:`SAMPLE_TIME_DIGITS` significant digits."""
        if self.t.size < 2:
            return math.nan
        return float(f"{np.median(np.diff(self.t)):.{SAMPLE_TIME_DIGITS}g}")

    def columns(self) -> dict[str, np.ndarray]:
        """All present columns in contract order, then extras."""
        cols = {k: getattr(self, k) for k in (*COMPLETE, *OPTIONAL)}
        cols = {k: v for k, v in cols.items() if v is not None}
        cols.update(self.extra)
        return cols


def measured_later(exp: Experiment, rows: int) -> Experiment:
    """The experiment with its measured columns moved ``rows`` rows later relative to the
    command (``rows`` > 0: the logger wrote each measurement that many rows early, beside a
    command that had already acted; < 0: late), the rows left without a partner dropped at
    each end; extra columns are not kept."""
    if rows == 0:
        return exp
    n = exp.t.size - abs(rows)
    cmd = slice(rows, None) if rows > 0 else slice(0, n)
    meas = slice(0, n) if rows > 0 else slice(-rows, None)
    out = dataclasses.replace(exp, t=exp.t[cmd], u=exp.u[cmd], extra={},
                              notes=list(exp.notes))
    if exp.f_load is not None:
        out.f_load = exp.f_load[cmd]
    for c in (*MEASURED, "v"):
        x = getattr(exp, c)
        setattr(out, c, None if x is None else x[meas])
    if exp.valid is not None:
        out.valid = exp.valid[meas]
    return out


def read_experiment(path: str | Path, required: Iterable[str] = REQUIRED,
                    limits: Limits = NOMINAL, units: Mapping[str, str] | None = None, *,
                    any_of: Iterable[str] = MEASURED,
                    columns: Mapping[str, str] | None = None) -> Experiment:
    """Read and validate an experiment CSV; raise DatasetError naming file, line and column.

    ``required`` columns must all be present, and at least one of ``any_of`` (the measured
    columns by default; ``()`` for a command-only file, as ``jetpipe simulate`` reads).
    ``columns`` (the file's column name -> the contract's, as declared in dataset.yaml) are
    renamed first; ``units`` (column -> unit, as declared in dataset.yaml, by the contract's
    names) are converted to SI then. Values
    outside ``limits`` (the nominal actuator's by default) are refused as physically
    impossible, with the likely unit mistake when a whole column is off. The experiment
    returned is on a regular grid (:mod:`jetpipe_ros.dataset.timebase`).
    """
    path = Path(path)
    required, any_of = tuple(required), tuple(any_of)
    declared(f"{path}: units", units)  # a bad declaration before the file
    cols, line_nos, read = read_columns(
        path, required, (*COMPLETE, *OPTIONAL), any_of=any_of, rename=columns,
        hint="; the contract's names are t, u, y, p1, p2 (docs/data.md): name the file's own "
             "in dataset.yaml, e.g. columns: {Time: t, Command: u}",
        declared_units=units or {})
    notes = read + to_si(f"{path}: units", cols, units)
    timebase.check_increasing(path, cols["t"], line_nos)
    plausibility.check(path, cols, limits, line_nos)
    cols, valid, changes = timebase.regularise(path, cols, line_nos)
    return Experiment(name=path.stem, **cols, valid=valid, notes=notes + changes)


def read_columns(path: Path, required: Sequence[str], known: Sequence[str], *,
                 any_of: Sequence[str] = (), least: int = 2, hint: str = "",
                 rename: Mapping[str, str] | None = None, index: str = "dataset.yaml",
                 declared_units: Mapping[str, str] | None = None
                 ) -> tuple[dict[str, np.ndarray], np.ndarray, list[str]]:
    """The numeric columns ``known`` that a CSV with a header row has (``required`` all of
    them, at least one of ``any_of``), each as a float array, the file's line number of every
    data row kept, and what reading changed, one plain sentence each. ``rename`` maps the
    file's own column names to those (each must be in the header; ``index`` names the file
    that declared them, for the message).

    Blank lines and comment lines (``#`` first: a logger's metadata) are skipped, a
    spreadsheet's byte-order mark too; the separator is the header's (a comma, else a semicolon
    or a tab, which then allow a decimal comma: a European spreadsheet's export), and said.
    What loggers write for a reading they did not get (an empty cell,
    or NaN) is a lost sample: its row is left out, as a row the logger lost (the grid fills
    it: :mod:`jetpipe_ros.dataset.timebase`), and said; a column of ``known`` with no reading
    in any row is a sensor the bench does not have (a logger with a fixed layout), read as
    absent unless ``required``. A row repeated exactly (every value the same as the row
    before, stamp included: a logger that wrote it twice) is read once. With
    ``declared_units`` (column -> the unit declared for it; a column not in it is in the
    contract's: :func:`_units_row`), a first row under the header with no number in any column
    read is the logger's row of units: read as such, not as data. Anything else
    unreadable raises DatasetError naming the file, the line and the column (``hint`` says
    what the columns should hold); so does an infinite value."""
    try:
        with path.open("rb") as raw:
            utf16 = raw.read(2) in UTF16_MARKS
        # utf-8-sig: a spreadsheet's byte-order mark is not part of the first column's name;
        # the numbers are ASCII, so an undecodable byte in a comment or label harms nothing.
        # A UTF-16 mark: a spreadsheet's "Unicode text" (Excel's, tab-separated).
        handle = path.open(newline="", encoding="utf-16" if utf16 else "utf-8-sig",
                           errors="replace")
    except OSError as exc:
        raise DatasetError(f"{path}: cannot open: {exc.strerror}") from exc
    notes: list[str] = ["read as UTF-16 text (a spreadsheet's Unicode text)"] if utf16 else []
    with handle:
        first, head = 0, ""
        for first, head in enumerate(handle, start=1):
            if head.strip() and not head.lstrip().startswith("#"):
                break
        else:
            raise DatasetError(f"{path}: empty file, expected a header row")
        delimiter = next((d for d in DELIMITERS if d in head), ",")
        decimal_comma = delimiter != ","
        if decimal_comma:
            notes.append(f"read as {DELIMITERS[delimiter]}-separated, a decimal comma "
                         f"accepted")
        header = [h.strip() for h in next(csv.reader([head], delimiter=delimiter))]
        reader = csv.reader(handle, delimiter=delimiter)  # the lines after the header
        if rename:
            notes.append("column" + ("s " if len(rename) > 1 else " ") + ", ".join(
                f"{a} read as {rename[a]}" for a in header if a in rename))
            header = _renamed(path, first, header, rename, index)
        missing = [c for c in required if c not in header]
        if missing:
            raise DatasetError(f"{path}: line {first}: missing column(s) {', '.join(missing)} "
                               f"(header has {', '.join(header)}{hint})")
        wanted = [c for c in known if c in header]
        index = {c: header.index(c) for c in wanted}
        rows: list[list[float]] = []
        lines: list[int] = []
        clock = _Clock()
        first_row = declared_units is not None  # only it may be a row of units
        for row in reader:
            if (not row or row[0].lstrip().startswith("#")
                    or all(not cell.strip() for cell in row)):
                continue
            line_no = first + reader.line_num
            if first_row:
                first_row = False
                cells = {c: row[index[c]].strip() if index[c] < len(row) else "" for c in wanted}
                if all(_unit_like(cell) for cell in cells.values()):
                    notes.append(_units_row(path, line_no, cells, declared_units))
                    continue
            values = []
            for col in wanted:
                i = index[col]
                cell = row[i].strip() if i < len(row) else ""
                if decimal_comma:
                    cell = cell.replace(",", ".")
                if col == "t" and cell and (clock.start is not None or not rows
                                            and not _number(cell, False)):
                    values.append(clock.seconds(path, line_no, cell))
                    continue
                try:
                    value = float(cell) if cell else math.nan
                except ValueError:
                    raise DatasetError(f"{path}: line {line_no}, column {col!r}: "
                                       f"not a number: {cell!r}") from None
                if math.isinf(value):
                    raise DatasetError(f"{path}: line {line_no}, column {col!r}: "
                                       f"non-finite value {cell!r}")
                values.append(value)
            rows.append(values)
            lines.append(line_no)
    if clock.start is not None:
        if (declared_units or {}).get("t") is not None:
            raise DatasetError(f"{path}: column 't' holds dates and times, which carry their "
                               f"unit: remove the unit dataset.yaml declares for t")
        notes.append(f"t read as dates and times (ISO 8601): seconds from the first row's, "
                     f"{clock.start.isoformat(sep=' ')}")
    data = np.array(rows, dtype=float).reshape(len(rows), len(wanted))
    line_nos = np.array(lines, dtype=np.int64)
    empty = [c for j, c in enumerate(wanted) if rows and np.isnan(data[:, j]).all()]
    for col in empty:
        if col in required:
            raise DatasetError(f"{path}: column {col!r} holds no value in any row")
    if empty:
        notes.append(f"column{'s' if len(empty) > 1 else ''} {', '.join(empty)} hold"
                     f"{'' if len(empty) > 1 else 's'} no value in any row: read as not "
                     f"measured")
        keep = [j for j, c in enumerate(wanted) if c not in empty]
        wanted, data = [wanted[j] for j in keep], data[:, keep]
    if any_of and not any(c in wanted for c in any_of):
        raise DatasetError(f"{path}: no measured column: needs at least one of "
                           f"{', '.join(any_of)} with values (header has {', '.join(header)})")
    lost = np.isnan(data).any(axis=1)
    if lost.any():
        shown = [f"{line_nos[i]} ({', '.join(c for c, x in zip(wanted, data[i]) if np.isnan(x))})"
                 for i in np.flatnonzero(lost)[:3]]
        notes.append(_rows_said(lost, "with an empty or NaN reading left out as lost", shown))
        data, line_nos = data[~lost], line_nos[~lost]
    repeated = np.r_[False, (data[1:] == data[:-1]).all(axis=1)] if data.size else \
        np.zeros(0, dtype=bool)
    if repeated.any():
        notes.append(_rows_said(repeated, "repeating the row before exactly read once",
                                [str(n) for n in line_nos[repeated][:3]]))
        data, line_nos = data[~repeated], line_nos[~repeated]
    if len(data) < least:
        raise DatasetError(f"{path}: needs at least {least} data rows, has {len(data)}")
    return ({c: np.ascontiguousarray(data[:, j]) for j, c in enumerate(wanted)}, line_nos,
            notes)


class _Clock:
    """A time column written as dates and times (ISO 8601, e.g. ``2026-12-05 12:00:00.001``:
    what a logger with a wall clock, or pandas with a time index, writes), read as seconds
    from the first row's, to the microsecond."""

    def __init__(self) -> None:
        self.start: datetime | None = None

    def seconds(self, path: Path, line: int, cell: str) -> float:
        """Seconds of ``cell`` (at ``line``) from the first row's date and time; DatasetError
        when it is no date and time, or mixes a time zone with none."""
        try:
            stamp = datetime.fromisoformat(cell)
        except ValueError:
            raise DatasetError(f"{path}: line {line}, column 't': neither a number nor a date "
                               f"and time (ISO 8601, e.g. 2026-12-05 12:00:00.001): "
                               f"{cell!r}") from None
        if self.start is None:
            self.start = stamp
        if (stamp.tzinfo is None) != (self.start.tzinfo is None):
            raise DatasetError(f"{path}: line {line}, column 't': {cell!r} and the first row's "
                               f"{self.start.isoformat(sep=' ')} differ in giving a time zone")
        return (stamp - self.start).total_seconds()


def _unit_like(cell: str) -> bool:
    """Whether ``cell`` reads as a unit (``mm``, ``[Pa]``, ``m/s^2``, ``bar gauge``): a letter
    first, no digit but an exponent's or a leading ``1/``, no parenthesis or quote within. A
    first row of such cells is a logger's row of units; one of other text (``np.float64(0.0)``,
    a label) is refused as not a number, naming the cell."""
    inner = re.sub(r"\^-?\d+", "", cell.strip().strip("[]()").strip())
    inner = inner[2:] if inner.startswith("1/") else inner
    return bool(inner) and (inner[0].isalpha() or inner[0] in "%°µ") and not re.search(
        r"[\d()\[\]{}=,;:'\"]", inner)


def _number(cell: str, decimal_comma: bool) -> bool:
    """True when ``cell`` reads as a number (NaN included)."""
    try:
        float(cell.replace(",", ".") if decimal_comma else cell)
    except ValueError:
        return False
    return True


def _units_row(path: Path, line: int, cells: Mapping[str, str],
               declared: Mapping[str, str]) -> str:
    """The note on a logger's row of units ``cells`` (column -> its cell, brackets allowed:
    ``[mm]``) at ``line``; DatasetError when it gives a column in a unit other than the
    contract's that dataset.yaml does not declare (``declared``: column -> the declared unit):
    a row of units is read, never acted on, so nothing is converted unseen."""
    named = {c: cell.strip("[]() ") for c, cell in cells.items()}
    for column, unit in named.items():
        if declared.get(column) is None and not _contract(column, unit):
            raise DatasetError(
                f"{path}: line {line}: a row of units ({', '.join(named.values())}) gives "
                f"column {column!r} in {unit!r}, where the contract reads "
                f"{contract_unit(column)}: declare it in dataset.yaml (units: "
                f"{{{column}: {unit}}}; a pressure says gauge or absolute, e.g. 'bar gauge'; "
                f"docs/data.md) or convert the column")
    return (f"line {line} read as the columns' units ("
            f"{', '.join(f'{c} {u}' for c, u in named.items())}), not as data; the units used "
            f"are the contract's and those declared in dataset.yaml")


def _contract(column: str, unit: str) -> bool:
    """Whether a row of units' ``unit`` for ``column`` is the contract's, in any spelling the
    declarations take (``Pa absolute``, ``Pa abs`` and ``Paa`` are ``Pa``). ``bar`` is not,
    though declared it reads as absolute: a logger's row saying bar says neither gauge nor
    absolute, which only a declaration settles."""
    try:
        return parse(column, unit).identity
    except ValueError:
        return False


def _rows_said(rows: np.ndarray, what: str, first: list[str]) -> str:
    """A note on the ``rows`` (a mask) that reading changed: how many, ``what`` was done, and
    the ``first`` few of them (their lines)."""
    n = int(rows.sum())
    return (f"{n} row{'s' if n > 1 else ''} {what} (line{'s' if n > 1 else ''} "
            f"{', '.join(first)}{', ...' if n > len(first) else ''})")


def _renamed(path: Path, line: int, header: list[str], rename: Mapping[str, str], index: str
             ) -> list[str]:
    """``header`` with the file's names in ``rename`` (declared in ``index``) replaced by the
    contract's."""
    absent = [a for a in rename if a not in header]
    if absent:
        raise DatasetError(f"{path}: line {line}: column(s) {', '.join(absent)} named in "
                           f"{index}'s 'columns' not in the header (header has "
                           f"{', '.join(header)})")
    out = [rename.get(h, h) for h in header]
    twice = sorted({c for c in out if out.count(c) > 1 and c in rename.values()})
    if twice:
        raise DatasetError(f"{path}: line {line}: two columns would be {', '.join(twice)} "
                           f"(the header has it besides the one 'columns' renames)")
    return out


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
