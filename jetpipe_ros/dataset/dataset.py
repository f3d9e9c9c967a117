"""A dataset directory (DESIGN.md s.5): one CSV per experiment, indexed by ``dataset.yaml``.

``dataset.yaml`` lists the experiments with how each was run::

    experiments:
      - file: square_0p6V.csv
        piston: free        # free | locked (constant-volume test, Sec. 2.3)
        load_force: 0.0     # N, constant, optional
        role: train         # train | holdout, optional

Reading validates the index (errors name the file, the entry and the field) and every CSV it
lists. Writing builds the whole directory beside the target and renames it into place, so a
failed write never leaves a half-written dataset behind.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.dataset.experiment import REQUIRED, Experiment, read_experiment, write_experiment

INDEX = "dataset.yaml"
PISTON = ("free", "locked")
ROLES = ("train", "holdout")


@dataclass
class Entry:
    """How one experiment was run: its file and the dataset.yaml fields."""

    file: str  #: CSV file name, relative to the dataset directory
    piston: str = "free"  #: free | locked
    load_force: float = 0.0  #: constant external load [N]
    role: str | None = None  #: train | holdout | None (unassigned)
    extra: dict[str, Any] = field(default_factory=dict)  #: other fields, kept on rewrite

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


def parse_entry(index: Path, i: int, raw: Any) -> Entry:
    """Validate experiment ``i`` of ``index``; raise DatasetError naming entry and field."""
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
    return Entry(file=file, piston=piston, load_force=float(load), role=role, extra=raw)


def read_index(root: str | Path) -> list[Entry]:
    """Read and validate ``root/dataset.yaml`` without loading the CSVs."""
    root = Path(root)
    index = root / INDEX
    if not root.is_dir():
        raise DatasetError(f"{root}: not a dataset directory (it does not exist or is a file)")
    try:
        doc = yaml.safe_load(index.read_text())
    except FileNotFoundError:
        raise DatasetError(f"{index}: missing; a dataset directory needs an index listing its "
                           f"experiments (DESIGN.md s.5)") from None
    except yaml.YAMLError as exc:
        raise DatasetError(f"{index}: not valid YAML: {exc}") from None
    if not isinstance(doc, Mapping) or not isinstance(doc.get("experiments"), list):
        raise DatasetError(f"{index}: expected a top-level 'experiments:' list")
    entries = [parse_entry(index, i, raw) for i, raw in enumerate(doc["experiments"])]
    if not entries:
        raise DatasetError(f"{index}: 'experiments' is empty")
    seen: set[str] = set()
    for e in entries:
        if e.name in seen:
            raise DatasetError(f"{index}: experiment {e.file!r} is listed twice")
        seen.add(e.name)
    return entries


def read_dataset(root: str | Path, required: Iterable[str] = REQUIRED) -> Dataset:
    """Read ``root/dataset.yaml`` and every experiment it lists, validating all of them."""
    root = Path(root)
    entries = read_index(root)
    experiments = [read_experiment(root / e.file, required) for e in entries]
    return Dataset(root=root, entries=entries, experiments=experiments)


def write_dataset(root: str | Path,
                  experiments: Sequence[tuple[Entry, Mapping[str, np.ndarray]]],
                  overwrite: bool = False) -> Path:
    """Write a dataset directory atomically and return its path.

    Args:
        root: target directory; it must not exist or be empty unless ``overwrite``.
        experiments: (entry, columns) pairs; columns start with ``t`` (see write_experiment).
        overwrite: replace an existing non-empty directory.
    """
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise DatasetError(f"{root}: exists and is not a directory")
    if root.is_dir() and any(root.iterdir()) and not overwrite:
        raise DatasetError(f"{root}: directory is not empty (pass overwrite to replace it)")
    names = [e.file for e, _ in experiments]
    if len(set(names)) != len(names):
        raise DatasetError(f"{root}: two experiments share a file name")
    root.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{root.name}.", suffix=".tmp", dir=root.parent))
    try:
        for entry, cols in experiments:
            write_experiment(tmp / entry.file, cols)
        index = {"experiments": [e.to_yaml() for e, _ in experiments]}
        (tmp / INDEX).write_text(yaml.safe_dump(index, sort_keys=False))
        if root.exists():
            shutil.rmtree(root)
        os.replace(tmp, root)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return root
