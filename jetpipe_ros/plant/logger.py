"""Other data loggers: what the plant measured, written the way other benches log it.

The plant's campaign is recorded in the package's own convention (row k: the command u_k beside
the measurements taken at t_k, before u_k acts; 1 kHz; every sensor; SI units). Real benches log
otherwise. Each logger here rewrites a recorded dataset directory as one of them would have:

- ``shifted``: the other common pairing, u_k beside the measurements taken *after* u_k acted
  (at t_k+1): every measurement column moves one row up, the last row is dropped;
- ``lossy``: a logger on a non-real-time host: 1 % of the rows lost at random and every stamp
  taken from a clock with jitter (uniform, +-0.3 of a sample);
- ``gauge_mm``: pressures in bar gauge and the position in mm from the retracted end stop (a
  linear sensor zeroed there), declared in ``dataset.yaml`` with what the sensor reads at
  mid-stroke (``position_zero``), the gauge relative to the standard atmosphere (101325 Pa),
  which it declares too: the plant's ambient is 1 bar, so a reader that took the model's 1 bar
  for the reference would see both pressures 1.3 kPa low;
- ``one_pressure``: a bench with one pressure sensor (chamber 1): column ``p2`` dropped;
- ``position_only``: no pressure sensors: ``p1`` and ``p2`` dropped;
- ``reversed_position``: a position sensor mounted the other way round: the position (and
  velocity) logged with the opposite sign, nothing declared;
- ``crossed_pressures``: the two pressure sensors wired to each other's channels: chamber 1's
  pressure logged as ``p2`` and chamber 2's as ``p1``, nothing declared;
- ``bench``: what a real bench's logger does all at once: ``shifted``, then ``lossy``, then
  ``gauge_mm``, then exported from a European spreadsheet (:func:`spreadsheet`): a metadata
  line, semicolons and decimal commas, the time in ms, the bench's own column names declared
  in ``dataset.yaml`` beside the units, and no experiment declared closed loop.

Every one of them, the package's own included, logs no velocity (:func:`without_velocity`): a
rig has no sensor for it.

This is the self-check's "real" logger: written apart from the reader that corrects these
artefacts (:mod:`jetpipe_ros.dataset`, :mod:`jetpipe_ros.diagnosis.alignment`,
:mod:`jetpipe_ros.diagnosis.signs`), with the csv
module and its own ``dataset.yaml`` edit, so the check is not the reader against itself. Other
sample rates are not a rewrite: the campaign is recorded at that rate (``rate``).
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

#: Columns that hold measurements (what a logger pairs with the command).
MEASURED = ("y", "p1", "p2", "v")
P_ATM_LOGGER = 101325.0  #: the logger's idea of the atmosphere for gauge pressure [Pa]
#: What a position sensor zeroed at the retracted end stop reads at mid-stroke [mm] (the
#: plant's stroke is 50 mm, centred).
HALF_STROKE_MM = 25.0
LOST_FRACTION = 0.01  #: rows a lossy logger loses
JITTER = 0.3  #: a lossy logger's stamp jitter, half-width [samples]


def _read(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def _write(path: Path, header: list[str], data: np.ndarray) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows([[repr(float(x)) for x in row] for row in data])


def _files(root: Path) -> list[Path]:
    doc = yaml.safe_load((root / "dataset.yaml").read_text())
    return [root / e["file"] for e in doc["experiments"]]


def shifted(root: Path, rng: np.random.Generator) -> None:
    """Row k: the command u_k beside the measurements taken after it acted (row k+1's)."""
    for path in _files(root):
        header, data = _read(path)
        cols = [header.index(c) for c in MEASURED if c in header]
        out = data[:-1].copy()
        out[:, cols] = data[1:, cols]
        _write(path, header, out)


def lossy(root: Path, rng: np.random.Generator) -> None:
    """1 % of the rows (never the first or last) lost, the stamps jittered +-0.3 samples."""
    for path in _files(root):
        header, data = _read(path)
        n = data.shape[0]
        dt = float(np.median(np.diff(data[:, 0])))
        lost = rng.choice(np.arange(1, n - 1), size=int(LOST_FRACTION * n), replace=False)
        keep = np.setdiff1d(np.arange(n), lost)
        out = data[keep].copy()
        out[:, 0] += rng.uniform(-JITTER, JITTER, keep.size) * dt
        _write(path, header, out)


def _rescaled(root: Path, scale: dict[str, tuple[float, float]]) -> None:
    """Every CSV's columns of ``scale`` (column -> (factor, offset)) logged as x * factor +
    offset."""
    for path in _files(root):
        header, data = _read(path)
        for c, (factor, offset) in scale.items():
            if c in header:
                i = header.index(c)
                data[:, i] = data[:, i] * factor + offset
        _write(path, header, data)


def gauge_mm(root: Path, rng: np.random.Generator) -> None:
    """Pressures in bar gauge, the position in mm from the retracted end stop (and velocity in
    mm/s), declared."""
    _rescaled(root, {"y": (1e3, HALF_STROKE_MM), "v": (1e3, 0.0),
                     "p1": (1e-5, -P_ATM_LOGGER * 1e-5), "p2": (1e-5, -P_ATM_LOGGER * 1e-5)})
    index = root / "dataset.yaml"
    doc = yaml.safe_load(index.read_text())
    doc["units"] = {"y": "mm", "v": "mm/s", "p1": "bar gauge", "p2": "bar gauge",
                    "gauge_reference": f"{P_ATM_LOGGER:.0f} Pa",
                    "position_zero": f"{HALF_STROKE_MM:g} mm"}
    index.write_text(yaml.safe_dump(doc, sort_keys=False))


def _drop(columns: tuple[str, ...]) -> Callable[[Path, np.random.Generator], None]:
    def drop(root: Path, rng: np.random.Generator) -> None:
        for path in _files(root):
            header, data = _read(path)
            keep = [i for i, c in enumerate(header) if c not in columns]
            _write(path, [header[i] for i in keep], data[:, keep])
    return drop


def reversed_position(root: Path, rng: np.random.Generator) -> None:
    """The position (and velocity) with the opposite sign: a sensor mounted the other way."""
    _rescaled(root, {"y": (-1.0, 0.0), "v": (-1.0, 0.0)})


def crossed_pressures(root: Path, rng: np.random.Generator) -> None:
    """Chamber 1's pressure under the name p2 and chamber 2's under p1."""
    for path in _files(root):
        header, data = _read(path)
        _write(path, [{"p1": "p2", "p2": "p1"}.get(c, c) for c in header], data)


#: The bench's own column names (:func:`spreadsheet`), by the contract's.
BENCH_COLUMNS = {"t": "Zeit_ms", "u": "Ventil_V", "y": "Weg", "v": "Geschw", "p1": "Druck_A",
                 "p2": "Druck_B", "f_load": "Last_N"}


def spreadsheet(root: Path, rng: np.random.Generator) -> None:
    """Every CSV as a European spreadsheet exports it: a metadata line first, semicolons and
    decimal commas, the time in ms, the contract's columns under the bench's names
    (:data:`BENCH_COLUMNS`; other columns keep theirs); ``dataset.yaml`` declares the names
    and the time's unit beside any units already declared, and drops every experiment's
    ``kind``."""
    logged: set[str] = set()
    for path in _files(root):
        header, data = _read(path)
        logged.update(header)
        data[:, header.index("t")] *= 1e3
        with path.open("w", newline="") as f:
            f.write("# exported from bench logger, channels as configured\n")
            w = csv.writer(f, delimiter=";")
            w.writerow([BENCH_COLUMNS.get(c, c) for c in header])
            w.writerows([[repr(float(x)).replace(".", ",") for x in row] for row in data])
    index = root / "dataset.yaml"
    doc = yaml.safe_load(index.read_text())
    doc["units"] = {**doc.get("units", {}), "t": "ms"}
    doc["columns"] = {name: c for c, name in BENCH_COLUMNS.items() if c in logged}
    for entry in doc["experiments"]:
        entry.pop("kind", None)
    index.write_text(yaml.safe_dump(doc, sort_keys=False))


def bench(root: Path, rng: np.random.Generator) -> None:
    """:func:`shifted`, :func:`lossy`, :func:`gauge_mm` and :func:`spreadsheet`, in turn."""
    for step in (shifted, lossy, gauge_mm, spreadsheet):
        step(root, rng)


one_pressure = _drop(("p2",))
position_only = _drop(("p1", "p2"))


def without_velocity(root: Path) -> None:
    """Drop column ``v`` (the simulation's true velocity) from every CSV at ``root``: no rig
    measures it, and every logger starts from this."""
    _drop(("v",))(Path(root), np.random.default_rng(0))

#: Logger name -> rewrite of a dataset directory in place.
LOGGERS: dict[str, Callable[[Path, np.random.Generator], None]] = {
    "shifted": shifted, "lossy": lossy, "gauge_mm": gauge_mm, "one_pressure": one_pressure,
    "position_only": position_only, "reversed_position": reversed_position,
    "crossed_pressures": crossed_pressures, "bench": bench,
}
#: Sensors each logger leaves (None: all three).
SENSORS = {"one_pressure": ("y", "p1"), "position_only": ("y",)}


def log(name: str, root: Path, seed: int) -> None:
    """Rewrite the dataset at ``root`` as logger ``name`` would have written it."""
    if name not in LOGGERS:
        raise ValueError(f"unknown logger {name!r}: one of {', '.join(LOGGERS)}")
    LOGGERS[name](Path(root), np.random.default_rng(seed))
