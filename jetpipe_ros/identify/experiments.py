"""Which recorded experiment feeds which procedure, read from ``dataset.yaml`` and the command.

The procedures take their experiments from the dataset the way the paper's bench ran them:

- **charge/discharge** (flow map, Sec. 2.3): ``piston: locked`` and a piecewise-constant
  command (levels held, e.g. +|u| for 4.4 s then -|u| for 1.8 s).
- **valve sweep** (valve dynamics, Sec. 2.4): ``piston: locked`` and an oscillating command
  (a sine sweep, e.g. 1-70 Hz), many reversals per second.
- **slow ramps** (hysteresis, Sec. 2.2): ``piston: locked`` and a command ramped up and down
  slowly (e.g. a triangle wave over +-3.4 V at 0.05-0.1 Hz), few reversals per second.
- **friction test** (Sec. 4.2): ``piston: free`` with ``regulated: true`` (chamber pressures held
  by regulators, Fig. 15) and the hydraulic load recorded in the ``f_load`` column.

Free-piston experiments without ``regulated`` are the validation runs of Sec. 6: not used to
identify, but replayed by the report as a check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jetpipe_ros.dataset import Dataset, Entry, Experiment

CHARGE, SWEEP, RAMP, FRICTION, VALIDATION = ("charge", "sweep", "ramp", "friction", "validation")

#: A command is piecewise constant when at least this fraction of its steps are zero.
_HELD_FRACTION = 0.95
#: Locked tests reversing their command slower than this are ramps; faster, sweeps [1/s].
_RAMP_REVERSALS_PER_S = 2.0


@dataclass(frozen=True)
class Recording:
    """One experiment with its index entry and the test it is recognised as."""

    entry: Entry
    experiment: Experiment
    kind: str  #: charge | sweep | ramp | friction | validation

    @property
    def name(self) -> str:
        """The experiment's name (its file name without extension)."""
        return self.entry.name


def reversals_per_second(u: np.ndarray, dt: float) -> float:
    """Sign changes of the command's slope per second (steps without change are skipped)."""
    du = np.diff(u)
    signs = np.sign(du[np.abs(du) > 1e-9])
    return float(np.count_nonzero(np.diff(signs))) / (u.size * dt)


def classify(entry: Entry, exp: Experiment) -> str:
    """The kind of test ``exp`` is (module docstring), from its entry and its command."""
    if not entry.locked:
        return FRICTION if entry.extra.get("regulated") is True else VALIDATION
    du = np.abs(np.diff(exp.u))
    if np.mean(du < 1e-9) >= _HELD_FRACTION:
        return CHARGE
    if reversals_per_second(exp.u, exp.dt) < _RAMP_REVERSALS_PER_S:
        return RAMP
    return SWEEP


def recordings(dataset: Dataset) -> list[Recording]:
    """Every experiment of ``dataset`` with its kind, in index order."""
    return [Recording(e, x, classify(e, x)) for e, x in dataset]


def of_kind(recs: list[Recording], kind: str) -> list[Recording]:
    """The recordings of one kind."""
    return [r for r in recs if r.kind == kind]
