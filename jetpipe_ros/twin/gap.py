"""The rolling gap per signal and its level (OK / WARN / ERROR), judged against noise.

The gap is the diagnosis' metric (:mod:`jetpipe_ros.diagnosis.score`): per signal, the mean
square of the prediction error over the free samples, normalised by the signal's spread over
the window (at least 1 mm or 0.1 bar), minus the *noise floor*, the normalised mean square error
a perfect model would show on the same samples; ``gap = 100 % * sqrt(excess)``.

**The noise floor is measured, not assumed.** As the diagnosis does for a dataset
(:mod:`jetpipe_ros.diagnosis.noise_floor`), each horizon is re-measured on the model itself:
from the twin's state at the horizon's start, the model is run on the horizon's measured command
and load, the sensor noise estimated from the horizon's own measurements
(:func:`jetpipe_ros.diagnosis.data.noise_level`) is added, and that noisy copy is predicted with
exactly the twin's restarts and scored like the data. Two such copies (independent noise) are
made per horizon: their mean is the floor, and their difference is a draw of what noise alone
makes two scores of the same horizon differ by, so its spread over the recent horizons measures
how far a perfect model's window score strays from the floor.

**Levels.** Over a window of W horizons the excess ``e = mse - floor`` is compared with its
standard error under "the model is right" (``se``: the measured spread above, scaled from one
horizon to the window). The two tests are the diagnosis' own for a gap beyond noise
(:func:`jetpipe_ros.diagnosis.verdict.left_beyond_noise`), with the paired t-test over windows
replaced by this ratio ``t = e / se``, whose spread is measured over a longer history than the
window (the standard error also holds the floor's own uncertainty, from that of the measured
noise). The spread is *estimated* from the k horizons of the history, so under a right model
``t`` follows Student's t with k degrees of freedom, not a normal law: its bar is the t quantile
with the false-alarm rate of :data:`~jetpipe_ros.diagnosis.verdict.MIN_T` standard errors of a
normal law (0.13 % of windows), :func:`bar`: 5.5 at the first judgement (k = 5), 4.0 at k = 10,
3.3 with the default 30 s history. (A flat bar of 3 raised false alarms in 1.5 % of windows at
k = 5 and 0.3 % at k = 30, and a nominal twin beside nominal hardware went WARN on a loaded
machine at t = 4.1 with 7 horizons.)

- WARN: ``t >= bar(k)`` and the gap at least
  :data:`~jetpipe_ros.diagnosis.verdict.NOISE_GAP` (0.5 % of the signal's spread, the least gap
  the diagnosis counts: about twice the pressure sensors' noise);
- ERROR: both, and the error beyond noise at least as large as the noise floor itself (the
  prediction's RMS error at least sqrt(2) times what noise explains), the diagnosis' test for a
  gap too concentrated for the t-test.

Before :data:`MIN_HISTORY` horizons are scored there is no measured spread, and nothing is
judged.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np
from scipy import stats

from jetpipe_ros.diagnosis.data import MIN_SCALE, SIGNALS
from jetpipe_ros.diagnosis.verdict import MIN_T, NOISE_GAP

#: Horizons scored before a level is given: enough draws of the noise-only difference to
#: estimate its spread.
MIN_HISTORY = 5
#: Fewest free samples of a signal for a horizon to be scored (as the diagnosis' windows).
MIN_SCORED = 10


class Level(IntEnum):
    """Diagnostic levels, numbered as ``diagnostic_msgs/DiagnosticStatus``."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass
class HorizonScore:
    """Sums over one horizon of one signal, in SI units squared [m^2 or Pa^2]."""

    sse: float  #: sum of squared prediction errors over the free samples
    sse_a: float  #: the same for the first noisy model copy
    sse_b: float  #: the same for the second one
    count: int  #: free samples scored
    n: int  #: measured samples (for the spread)
    total: float  #: sum of the measured values
    total_sq: float  #: sum of their squares
    floor_rel: float = 0.0  #: relative standard uncertainty of the floor (noise estimate)


@dataclass
class SignalGap:
    """The judged gap of one signal over the window."""

    signal: str
    gap: float  #: excess NRMSE [%]
    mse: float  #: normalised mean square error of the model
    floor: float  #: normalised mean square error noise alone explains
    z: float  #: excess over its standard error under a right model
    bar: float  #: the z at which the gap counts (:func:`bar` of the history's horizons)
    level: Level
    horizons: int  #: horizons in the window
    scale: float  #: normalisation scale [m or Pa]

    def describe(self) -> str:
        """One line for a person."""
        return (f"{self.signal}: gap {self.gap:.2f} % (model {100 * math.sqrt(self.mse):.2f} %, "
                f"noise {100 * math.sqrt(self.floor):.2f} %, z {self.z:.1f} of {self.bar:.1f}) "
                f"{self.level.name}")


@dataclass
class GapWindow:
    """The latest scored horizons of each signal, and their judgement."""

    window: int  #: horizons in the rolling window
    history: int  #: horizons kept for the noise-only spread
    scores: dict[str, deque[HorizonScore]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.window < 1 or self.history < self.window:
            raise ValueError(f"need 1 <= window ({self.window}) <= history ({self.history})")
        self.scores = {s: deque(maxlen=self.history) for s in SIGNALS}

    def add(self, signal: str, score: HorizonScore) -> None:
        """Keep one horizon's score of ``signal`` (ignored with under :data:`MIN_SCORED`
        samples)."""
        if score.count >= MIN_SCORED:
            self.scores[signal].append(score)

    def judge(self) -> list[SignalGap]:
        """The gap and level of each signal with enough history."""
        return [g for g in (self._judge(s) for s in SIGNALS) if g is not None]

    def _judge(self, signal: str) -> SignalGap | None:
        hist = list(self.scores[signal])
        if len(hist) < MIN_HISTORY:
            return None
        win = hist[-self.window:]
        n = sum(h.n for h in win)
        mean = sum(h.total for h in win) / n
        var = max(sum(h.total_sq for h in win) / n - mean * mean, 0.0)
        scale2 = max(math.sqrt(var), MIN_SCALE[signal]) ** 2
        count = sum(h.count for h in win)
        mse = sum(h.sse for h in win) / count / scale2
        floor = sum(h.sse_a + h.sse_b for h in win) / (2 * count) / scale2
        se = math.hypot(_standard_error(hist, win, scale2), win[-1].floor_rel * floor)
        excess = mse - floor
        z = excess / se if se > 0.0 else (math.inf if excess > 0.0 else 0.0)
        gap = 100.0 * math.sqrt(max(excess, 0.0))
        level = Level.OK
        limit = bar(len(hist))
        if z >= limit and gap >= NOISE_GAP:
            level = Level.ERROR if excess >= floor else Level.WARN
        return SignalGap(signal, gap, mse, floor, z, limit, level, len(win), math.sqrt(scale2))


def bar(history: int) -> float:
    """The excess' bar in standard errors when its spread is measured on ``history``
    horizons: the Student t quantile (``history`` degrees of freedom) whose one-sided tail
    equals that of a normal law beyond :data:`~jetpipe_ros.diagnosis.verdict.MIN_T`."""
    return float(stats.t.isf(stats.norm.sf(MIN_T), history))


def _standard_error(hist: Sequence[HorizonScore], win: Sequence[HorizonScore],
                    scale2: float) -> float:
    """Standard error of the window's excess when the model is right.

    Per horizon, the two noisy copies' scores a, b differ by noise alone: var(a - b) = 2 s^2,
    where s^2 is the variance of one horizon's score. The data's excess over a horizon,
    ``d = m - (a + b) / 2``, then has variance 1.5 s^2 = 0.75 var(a - b); over the window the
    horizons are weighted by their sample counts. ``var(a - b)`` is measured over the whole
    history (its mean is zero, so the mean square is its variance).
    """
    diffs = np.array([(h.sse_a - h.sse_b) / h.count / scale2 for h in hist])
    var_one = 0.75 * float(np.mean(diffs ** 2))
    counts = np.array([h.count for h in win], dtype=float)
    return math.sqrt(var_one * float((counts ** 2).sum())) / float(counts.sum())
