"""A dataset directory (docs/data.md): one CSV per experiment, indexed by ``dataset.yaml``.

``dataset.yaml`` lists the experiments with how each was run::

    experiments:
      - file: square_0p6V.csv
        piston: free        # free | locked (constant-volume test, Sec. 2.3)
        load_force: 0.0     # N, constant, optional
        role: train         # train | holdout, optional
        units: {u: mV}      # units of this CSV's columns, optional (overrides the top level)
        columns: {cmd: u}   # this CSV's own column names -> the contract's, optional
        measured: after_command  # the logger writes beside each command what it measured
                                 # after that command acted, optional (before_command)
    units: {t: ms, p1: bar gauge, p2: bar gauge, gauge_reference: 1013.25 hPa}  # optional,
                    # for every experiment; gauge_reference: the ambient gauge is relative to;
                    # position_zero: what the position sensor reads at mid-stroke (25 mm)
    columns: {time: t, position: y}  # optional, for every experiment (an entry's own override)
    measured: before_command   # optional, for every experiment (an entry's own overrides it)

Units (:mod:`jetpipe_ros.dataset.units`) are converted to SI when the experiments are read; each
experiment's notes, and :attr:`Dataset.notes`, say what was converted and what was done to its
time base (:mod:`jetpipe_ros.dataset.timebase`). Reading validates the index (errors name the
file, the entry and the field) and every CSV it lists, including physical plausibility
(:mod:`jetpipe_ros.dataset.plausibility`). Writing builds the whole directory beside the target
and renames it into place, so a failed write never leaves a half-written dataset behind; it
replaces an existing directory only if asked to and only if that directory is a dataset (its
``dataset.yaml`` and the files it lists, nothing else) that neither is nor contains the current
directory or a protected path (the bag being read).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from jetpipe_ros import fileio
from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.dataset.experiment import (COMPLETE, OPTIONAL, REQUIRED, Experiment,
                                            measured_later, read_experiment, write_experiment)
from jetpipe_ros.dataset.units import declared
from jetpipe_ros.fileio import load_yaml
from jetpipe_ros.model.limits import NOMINAL, Limits

INDEX = "dataset.yaml"
#: The contract's columns, what ``columns:`` may name.
CONTRACT = (*COMPLETE, *OPTIONAL)
PISTON = ("free", "locked")
ROLES = ("train", "holdout")
#: When a logger took the measurements on a row (``measured:`` of dataset.yaml): before the
#: command beside them acted (the contract: a sampled loop reads its sensors, then commands),
#: or after it acted (the other common convention: every measurement a row early).
MEASURED_WHEN = ("before_command", "after_command")
#: The note on an experiment read with ``measured: after_command``.
AFTER_COMMAND = ("measured after the command beside them acted, as dataset.yaml declares "
                 "(measured: after_command): moved a row later, so that each command is paired "
                 "with what was measured before it acted, as the contract reads; its last "
                 "command dropped")


@dataclass
class Entry:
    """How one experiment was run: its file and the dataset.yaml fields."""

    file: str  #: CSV file name, relative to the dataset directory
    piston: str = "free"  #: free | locked
    load_force: float = 0.0  #: constant external load [N]
    role: str | None = None  #: train | holdout | None (unassigned)
    extra: dict[str, Any] = field(default_factory=dict)  #: other fields, kept on rewrite
    #: Units of the CSV's columns (column -> unit), the top-level ``units:`` of dataset.yaml
    #: overridden by the entry's own; empty: SI. They describe the file: columns written with
    #: this entry must be in them (an experiment read back is in SI: write it with ``units={}``).
    units: dict[str, str] = field(default_factory=dict)
    #: The CSV's own column names -> the contract's (``columns:`` of dataset.yaml, the
    #: top level's overridden by the entry's own); units are declared by the contract's names.
    columns: dict[str, str] = field(default_factory=dict)
    #: When the logger took the measurements on a row against the command beside it
    #: (``measured:`` of dataset.yaml, the top level's overridden by the entry's own):
    #: ``before_command`` (the contract) or ``after_command`` (after that command acted: read
    #: a row later, :data:`AFTER_COMMAND`).
    measured: str = MEASURED_WHEN[0]

    @property
    def name(self) -> str:
        """The experiment's name: its file name without extension."""
        return Path(self.file).stem

    @property
    def locked(self) -> bool:
        """True for a constant-volume test (piston clamped)."""
        return self.piston == "locked"

    def to_yaml(self) -> dict[str, Any]:
        """The entry as a dataset.yaml mapping."""
        out: dict[str, Any] = {"file": self.file, "piston": self.piston,
                               "load_force": float(self.load_force)}
        if self.role is not None:
            out["role"] = self.role
        if self.units:
            out["units"] = dict(self.units)
        if self.columns:
            out["columns"] = dict(self.columns)
        if self.measured != MEASURED_WHEN[0]:
            out["measured"] = self.measured
        out.update(self.extra)
        return out


@dataclass
class Dataset:
    """A loaded dataset: its directory, index entries and experiments (same order)."""

    root: Path
    entries: list[Entry]
    experiments: list[Experiment]

    def __iter__(self):
        return iter(zip(self.entries, self.experiments))

    def __len__(self) -> int:
        return len(self.entries)

    def with_role(self, role: str) -> list[tuple[Entry, Experiment]]:
        """The (entry, experiment) pairs whose role is ``role``."""
        return [(e, x) for e, x in self if e.role == role]

    @property
    def notes(self) -> list[str]:
        """Every experiment's notes (unit conversions, time-base repairs), each prefixed with
        its file name, e.g. ``square.csv: 12 rows missing in 3 gaps (...)``."""
        return [f"{e.file}: {note}" for e, x in self for note in x.notes]


def column_names(where: str, raw: Any, contract: Sequence[str] = CONTRACT) -> dict[str, str]:
    """A ``columns:`` mapping (the CSV's name -> the contract's, docs/data.md; ``contract``:
    the names a file of its kind has) validated; DatasetError naming ``where`` otherwise."""
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        raise DatasetError(f"{where}: expected a mapping of the CSV's column names to the "
                           f"contract's ({', '.join(contract)}), got {raw!r}")
    out: dict[str, str] = {}
    for source, target in raw.items():
        if not isinstance(source, str) or target not in contract:
            raise DatasetError(f"{where}: {source!r}: {target!r} is not a column of the "
                               f"contract (one of {', '.join(contract)})")
        if target in out.values():
            raise DatasetError(f"{where}: two columns named {target!r}")
        out[source] = target
    return out


def merged_columns(top: Mapping[str, str], own: Mapping[str, str]) -> dict[str, str]:
    """The top level's column names with the entry's own overriding them, per contract name."""
    return {**{s: t for s, t in top.items() if t not in own.values()}, **own}


def measured_when(where: str, raw: Any, default: str = MEASURED_WHEN[0]) -> str:
    """The ``measured:`` field at ``where``: one of :data:`MEASURED_WHEN` (``default`` when
    absent); DatasetError naming it otherwise."""
    if raw is None:
        return default
    if raw not in MEASURED_WHEN:
        raise DatasetError(f"{where}: must be one of {', '.join(MEASURED_WHEN)} (when the logger "
                           f"took the measurements on a row: before the command beside them "
                           f"acted, as the contract reads, or after), got {raw!r}")
    return raw


def parse_entry(index: Path, i: int, raw: Any, units: Mapping[str, str] | None = None,
                columns: Mapping[str, str] | None = None,
                measured: str = MEASURED_WHEN[0]) -> Entry:
    """Validate experiment ``i`` of ``index``; raise DatasetError naming entry and field.
    ``units``, ``columns`` and ``measured`` are the dataset's (top level), which the entry's
    own override."""
    where = f"{index}: experiments[{i}]"
    if not isinstance(raw, Mapping):
        raise DatasetError(f"{where}: expected a mapping with at least 'file', got {raw!r}")
    raw = dict(raw)
    file = raw.pop("file", None)
    if not isinstance(file, str) or not file.strip():
        raise DatasetError(f"{where}: field 'file' is missing or not a file name")
    if Path(file).is_absolute() or ".." in Path(file).parts:
        raise DatasetError(f"{where}: field 'file' must be a path inside the dataset: {file!r}")
    piston = raw.pop("piston", "free")
    if piston not in PISTON:
        raise DatasetError(f"{where} ({file}): field 'piston' must be one of "
                           f"{', '.join(PISTON)}, got {piston!r}")
    load = raw.pop("load_force", 0.0)
    if load is None:
        load = 0.0
    if isinstance(load, bool) or not isinstance(load, (int, float)) or not math.isfinite(load):
        raise DatasetError(f"{where} ({file}): field 'load_force' must be a finite number "
                           f"[N], got {load!r}")
    role = raw.pop("role", None)
    if role is not None and role not in ROLES:
        raise DatasetError(f"{where} ({file}): field 'role' must be one of "
                           f"{', '.join(ROLES)}, got {role!r}")
    own = declared(f"{where} ({file}): field 'units'", raw.pop("units", None))
    names = column_names(f"{where} ({file}): field 'columns'", raw.pop("columns", None))
    when = measured_when(f"{where} ({file}): field 'measured'", raw.pop("measured", None),
                         measured)
    return Entry(file=file, piston=piston, load_force=float(load), role=role, extra=raw,
                 units={**(units or {}), **own}, columns=merged_columns(columns or {}, names),
                 measured=when)


#: A number in a note (not the digit of a name such as ``p1``).
_NUMBER = re.compile(r"(?<![A-Za-z_\d.])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def grouped_notes(notes: Sequence[str]) -> list[str]:
    """Notes ``file: what``, one line for each ``what`` with the files it is said of (a unit
    converted in every file is one line, not fifteen), in the order first said. Notes that
    differ in their numbers only are one line too, each number that differs given as its range
    over the files (stamps that jitter by 0.171 ms in one file and 0.176 ms in another:
    "0.171-0.176 ms")."""
    groups: dict[str, list[tuple[str, str]]] = {}
    for note in notes:
        name, sep, what = note.partition(": ")
        what = what if sep else note
        groups.setdefault(_NUMBER.sub("#", what), []).append((name if sep else "", what))
    out = []
    for said in groups.values():
        names = [n for n, _ in said if n]
        what = _ranges([w for _, w in said])
        if len(names) > 1:
            shown = ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")
            out.append(f"{len(names)} files ({shown}): {what}")
        else:
            out.append(f"{names[0]}: {what}" if names else what)
    return out


def _ranges(texts: Sequence[str]) -> str:
    """``texts`` (alike but for their numbers) as one, each number that differs as its range."""
    numbers = [_NUMBER.findall(t) for t in texts]
    parts = _NUMBER.split(texts[0])
    out = [parts[0]]
    for i, part in enumerate(parts[1:]):
        column = [n[i] for n in numbers]
        low, high = min(column, key=float), max(column, key=float)
        out.append(low if float(low) == float(high) else
                   f"{low} to {high}" if float(low) < 0 else f"{low}-{high}")
        out.append(part)
    return "".join(out)


def read_index(root: str | Path) -> list[Entry]:
    """Read and validate ``root/dataset.yaml`` without loading the CSVs."""
    root = Path(root)
    index = root / INDEX
    if not root.is_dir():
        raise DatasetError(f"{root}: not a dataset directory (it does not exist or is a file)")
    try:
        doc = load_yaml(index)
    except FileNotFoundError:
        found = sorted(f.name for f in root.glob("*.csv"))
        sketch = "".join(f"\n  - file: {name}\n    piston: free" for name in found[:20])
        raise DatasetError(
            f"{index}: missing; a dataset directory needs an index listing its experiments "
            f"(docs/data.md)" + (f". For the {len(found)} CSV file(s) here, with every piston "
                                 f"free (mark a clamped one 'locked'), it would read:"
                                 f"\nexperiments:{sketch}" if found else "")) from None
    except yaml.YAMLError as exc:
        raise DatasetError(f"{index}: not valid YAML: {exc}") from None
    if not isinstance(doc, Mapping) or not isinstance(doc.get("experiments"), list):
        raise DatasetError(f"{index}: expected a top-level 'experiments:' list")
    units = declared(f"{index}: units", doc.get("units"))
    columns = column_names(f"{index}: columns", doc.get("columns"))
    measured = measured_when(f"{index}: measured", doc.get("measured"))
    entries = [parse_entry(index, i, raw, units, columns, measured)
               for i, raw in enumerate(doc["experiments"])]
    if not entries:
        raise DatasetError(f"{index}: 'experiments' is empty")
    seen: set[str] = set()
    for e in entries:
        if e.name in seen:
            raise DatasetError(f"{index}: experiment {e.file!r} is listed twice")
        seen.add(e.name)
    return entries


def read_dataset(root: str | Path, required: Iterable[str] = REQUIRED,
                 limits: Limits = NOMINAL) -> Dataset:
    """Read ``root/dataset.yaml`` and every experiment it lists, validating all of them
    (values outside ``limits``, the nominal actuator's by default, are refused), converting
    declared units to SI and putting each on a regular grid (see :attr:`Dataset.notes`)."""
    root = Path(root)
    entries = read_index(root)
    experiments = [read_experiment(root / e.file, required, limits, e.units,
                                   columns=e.columns) for e in entries]
    for i, e in enumerate(entries):
        if e.measured == MEASURED_WHEN[1]:
            experiments[i] = measured_later(experiments[i], 1)
            experiments[i].notes.append(AFTER_COMMAND)
    return Dataset(root=root, entries=entries, experiments=experiments)


def _within(path: Path, other: Path) -> bool:
    """True if ``path`` is ``other`` or inside it (both resolved)."""
    return path == other or other in path.parents


def check_target(root: str | Path, overwrite: bool = False,
                 protect: Iterable[str | Path] = ()) -> Path:
    """Check, before any work, that a dataset can be written to ``root``; return it.

    ``root`` must be absent or an empty directory, or (``overwrite``) a dataset directory: its
    ``dataset.yaml`` and the files that lists, nothing else. It must never be, contain or lie
    inside a path in ``protect`` (e.g. the bag being exported), nor be or contain the current
    directory. Raises DatasetError (or fileio.FileError if it cannot be written) naming it.
    """
    root = fileio.output_dir(root, "dataset directory")
    real = root.resolve()
    for keep in protect:
        keep = Path(keep).resolve()
        relation = ("is" if real == keep else "contains" if _within(keep, real)
                    else "lies inside" if _within(real, keep) else None)
        if relation:
            raise DatasetError(f"{root}: refusing to write the dataset there: it {relation} "
                               f"{keep}, which is being read")
    if _within(Path.cwd().resolve(), real):
        raise DatasetError(f"{root}: refusing to write the dataset there: it is or contains the "
                           f"current directory; give a new directory")
    if not root.is_dir() or not any(root.iterdir()):
        return root
    if not overwrite:
        raise DatasetError(f"{root}: directory is not empty (pass overwrite to replace a "
                           f"dataset written before)")
    problem = _not_a_dataset(root)
    if problem:
        raise DatasetError(f"{root}: refusing to overwrite: {problem}; only a dataset directory "
                           f"(dataset.yaml and the files it lists) is replaced")
    return root


def _not_a_dataset(root: Path) -> str | None:
    """Why directory ``root`` is not a dataset directory (None if it is one)."""
    if not (root / INDEX).is_file():
        return f"it has no {INDEX}, so it is not a dataset"
    try:
        listed = {Path(e.file).as_posix() for e in read_index(root)}
    except DatasetError as exc:
        return f"its {INDEX} is not a dataset index ({exc})"
    for item in sorted(root.rglob("*")):
        name = item.relative_to(root).as_posix()
        if item.is_symlink() or not (item.is_file() or item.is_dir()):
            return f"it holds {name!r}, which is not a plain file"
        if item.is_file() and name != INDEX and name not in listed:
            return f"it holds {name!r}, which {INDEX} does not list"
    return None


def write_dataset(root: str | Path,
                  experiments: Sequence[tuple[Entry, Mapping[str, np.ndarray]]],
                  overwrite: bool = False, protect: Iterable[str | Path] = ()) -> Path:
    """Write a dataset directory atomically and return its path.

    Args:
        root: target directory; see :func:`check_target`.
        experiments: (entry, columns) pairs; columns start with ``t`` (see write_experiment).
        overwrite: replace an existing dataset directory.
        protect: paths the dataset must neither replace nor contain (see check_target).
    """
    root = check_target(root, overwrite, protect)
    names = [e.file for e, _ in experiments]
    if len(set(names)) != len(names):
        raise DatasetError(f"{root}: two experiments share a file name")
    with fileio.staged_directory(root, replace=overwrite) as tmp:
        for entry, cols in experiments:
            write_experiment(tmp / entry.file, cols)
        index = {"experiments": [e.to_yaml() for e, _ in experiments]}
        fileio.write_text(tmp / INDEX, yaml.safe_dump(index, sort_keys=False))
    return root
