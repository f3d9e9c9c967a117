"""How a seal's sliding level moves over a record, which no friction form describes.

A real seal's friction is not stationary: as it warms, runs in and spreads its lubricant, its
sliding level moves over a record (on the twelve public records it rises on the O-ring and
NAPN seals, by up to 40 % over 80 s, and barely moves on PK: docs/friction.md). A fit on a
record's first half then meets another level in the held-out second half, a miss no form
can mend. This module measures it from the data alone, before and apart from any fit:

- a *pass* is the motion between two reversals; its *level* is the median of its friction,
  signed as the motion, over the samples at least :data:`~jetpipe_ros.identify.seal.SETTLED`
  past the reversal (where the friction has reached its level) and moving with a clean
  velocity window. A pass covers the stroke, so the bore profile averages out of it alike
  in every pass;
- per direction, a straight line through the passes' levels against their median times, each
  pass one sample (the samples within a pass are correlated, separate passes nearly
  independent): the Theil-Sen line (the median of the slopes between pairs of passes), so one
  odd pass (a stall, a logger's gap) does not tilt it, with the 95 % interval of its slope
  from Kendall's tau (no assumption on the levels' scatter). The drift is the line's change
  over the record relative to the passes' mean level.

A direction with fewer than :data:`MIN_PASSES` passes (an actuator's friction test slides once)
has no drift.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from jetpipe_ros.identify.seal import DIRECTIONS, SETTLED, Prepared, reversals, since_reversal

#: Fewest passes a direction needs for a line with an interval: with fewer than 4 the 95 %
#: interval of a Theil-Sen slope spans every pairwise slope.
MIN_PASSES = 4
#: Fewest settled samples a pass needs for its median to be its level (0.2 s at 100 Hz).
MIN_SAMPLES = 20
#: Confidence of the slope's interval.
CONFIDENCE = 0.95


@dataclass(frozen=True)
class Drift:
    """One direction's sliding level over a record."""

    direction: str  #: exit (v > 0) or entry (v < 0)
    times: np.ndarray  #: each pass's median time [s]
    levels: np.ndarray  #: each pass's level [N], positive
    slope: float  #: the line's slope [N/s]
    intercept: float  #: the line's level at t = 0 [N]
    interval: tuple[float, float]  #: the slope's 95 % interval [N/s]

    @property
    def mean(self) -> float:
        """The passes' mean level [N]."""
        return float(np.mean(self.levels))

    @property
    def span(self) -> float:
        """Time from the first pass to the last [s]."""
        return float(self.times[-1] - self.times[0])

    @property
    def change(self) -> float:
        """The line's change over the record relative to the mean level [-]."""
        return self.slope * self.span / self.mean

    @property
    def change_interval(self) -> tuple[float, float]:
        """The 95 % interval of :attr:`change` [-]."""
        lo, hi = self.interval
        return lo * self.span / self.mean, hi * self.span / self.mean

    @property
    def significant(self) -> bool:
        """True when the 95 % interval excludes 0 (a drift beyond the passes' scatter)."""
        lo, hi = self.interval
        return lo > 0.0 or hi < 0.0

    def to_json(self) -> dict[str, Any]:
        """The direction's entry in ``friction.json``."""
        return {"passes": int(self.times.size), "mean_level_n": self.mean,
                "slope_n_per_s": self.slope, "slope_ci95_n_per_s": list(self.interval),
                "change_over_record": self.change,
                "change_ci95": list(self.change_interval), "significant": self.significant,
                "pass_time_s": self.times.tolist(), "pass_level_n": self.levels.tolist()}


def pass_levels(prep: Prepared, friction: np.ndarray | None = None
                ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per direction, each pass's median time [s] and level [N] (see the module text) of the
    record's measured friction, or of ``friction`` [N] along it (a model's prediction: the
    same statistic of both)."""
    friction = prep.friction if friction is None else friction
    rec = prep.record
    moving = prep.train | prep.test
    since = since_reversal(rec.x, prep.v)
    settled = moving & (np.abs(np.nan_to_num(since)) >= SETTLED)
    turns = reversals(prep.v)
    bounds = zip(np.concatenate([[0], turns]), np.concatenate([turns, [prep.v.size]]))
    out: dict[str, tuple[list[float], list[float]]] = {d: ([], []) for d in DIRECTIONS}
    for start, end in bounds:
        k = np.arange(start, end)[settled[start:end]]
        if k.size < MIN_SAMPLES:
            continue
        sign = float(np.sign(np.median(prep.v[k])))
        times, levels = out["exit" if sign > 0 else "entry"]
        times.append(float(np.median(rec.t[k])))
        levels.append(float(np.median(sign * friction[k])))
    return {d: (np.array(t), np.array(f)) for d, (t, f) in out.items()}


def level_drift(prep: Prepared) -> dict[str, Drift]:
    """Per direction with :data:`MIN_PASSES` passes or more, the line of its level over the
    record (:class:`Drift`)."""
    out = {}
    for direction, (times, levels) in pass_levels(prep).items():
        if times.size < MIN_PASSES:
            continue
        fit = stats.theilslopes(levels, times, alpha=CONFIDENCE)
        out[direction] = Drift(direction, times, levels, float(fit.slope),
                               float(fit.intercept),
                               (float(fit.low_slope), float(fit.high_slope)))
    return out


def describe(drifts: dict[str, dict[str, Drift]]) -> str | None:
    """One line on the drifts of a seal's records (record name -> direction -> drift), e.g.
    "level over each record: exit +3.6 to +7.2 %, entry -0.1 to +23.5 % (6 of 8 beyond their
    95 % interval)"; None without a drift measured."""
    ranges = []
    for direction in DIRECTIONS:
        changes = sorted(100 * d[direction].change for d in drifts.values() if direction in d)
        if changes:
            ranges.append(f"{direction} {changes[0]:+.1f}" + (
                f" to {changes[-1]:+.1f} %" if len(changes) > 1 else " %"))
    every = [x for d in drifts.values() for x in d.values()]
    if not every:
        return None
    moved = sum(x.significant for x in every)
    return (f"level over each record: {', '.join(ranges)} ({moved} of {len(every)} beyond "
            f"their 95 % interval)")
