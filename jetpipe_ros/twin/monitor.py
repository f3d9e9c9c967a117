"""The twin: the model beside the hardware, fed its measured samples, judging the gap live.

:class:`Twin` takes samples one at a time or in blocks (a stamp t [s], the command u [V] and load
[N] applied over the sample ending at t, the measurements y [m], p1, p2 [Pa] taken at t), steps
the model through them in step with the stamps (:class:`~jetpipe_ros.twin.stepper.Stepper`),
returns its predictions, and at the end of every horizon scores the horizon and its measured
noise floor (:mod:`jetpipe_ros.twin.gap`).

Inputs that are not a clean 1 kHz stream never stop it:

- a stamp not after the previous one (late, repeated or out of order) is dropped and counted;
- up to :data:`~jetpipe_ros.diagnosis.data.SPLIT_GAP` s of lost samples are filled on the grid
  with the command held and no measurement (never compared), as the dataset reader fills rows a
  logger lost;
- a longer gap pauses the comparison: the horizon in progress is scored as far as it went, and a
  new segment begins with the next sample (a restart and a warm-up), as the diagnosis splits an
  experiment there; :attr:`Counters.paused` and :attr:`Twin.paused_since` say so;
- stamps at another rate than the set sample time are said (:meth:`Twin.rate_mismatch`).

A chamber pressure the hardware does not measure (NaN at a segment's first sample) is carried by
the model, from wherever the model's chamber stood. Where the hardware's chamber started, nothing
measured says, and until that no longer matters the twin's position holds the model's guess,
not the hardware: on the model's own position-only closed-loop stream, its chambers started
at 2 and 8 bar where the model assumed 4.2, the first two judgements were ERROR with position
gaps of 92 % and 4 % (155 % and 3 % from 9 and 1.5 bar). So each segment is also followed by
two more copies of the model, its unmeasured chambers started at atmosphere and at supply
(every start a chamber can have: :data:`~jetpipe_ros.diagnosis.prediction.START_RANGE`, as the
diagnosis does for a record), and nothing is compared until the two hold every unmeasured
chamber within the pressure sensor's noise (``sensors.pressure_sigma``): from there the model
knows that pressure as well as a sensor would, whatever the start (:attr:`Twin.settling_since`,
:attr:`Counters.unsettled_s`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from jetpipe_ros.dataset.timebase import STREAM_INTERVALS, another_rate, median_interval
from jetpipe_ros.diagnosis.data import SIGNALS, SPLIT_GAP, noise_level
from jetpipe_ros.diagnosis.noise_floor import SEED
from jetpipe_ros.diagnosis.prediction import HORIZON, START_RANGE, WARMUP
from jetpipe_ros.model import Actuator, ModelParams, kernel
from jetpipe_ros.twin.gap import GapWindow, HorizonScore, Level, SignalGap
from jetpipe_ros.twin.stepper import OUT_COLUMNS, Stepper

#: Default rolling window of the gap [s] and history of the noise-only spread [s].
WINDOW = 5.0
HISTORY = 30.0


@dataclass(frozen=True)
class Settings:
    """How the twin compares (times in s)."""

    dt: float = 0.001  #: sample time of the measurements
    horizon: float = HORIZON  #: time between restarts from the measurements
    warmup: float = WARMUP  #: held part of each horizon
    window: float = WINDOW  #: the rolling gap's window
    history: float = HISTORY  #: horizons kept to measure the noise-only spread
    max_gap: float = SPLIT_GAP  #: longest run of lost samples filled; longer pauses
    seed: int = SEED  #: seed of the noisy model copies

    def __post_init__(self) -> None:
        checks = [("dt", self.dt > 0.0), ("horizon", self.horizon >= 10 * self.dt),
                  ("warmup", 0.0 < self.warmup < self.horizon),
                  ("window", self.window >= self.horizon),
                  ("history", self.history >= self.window), ("max_gap", self.max_gap >= 0.0)]
        for name, ok in checks:
            if not ok:
                raise ValueError(f"twin setting {name} = {getattr(self, name)!r} is invalid "
                                 f"(need dt > 0, horizon >= 10 dt, 0 < warmup < horizon, "
                                 f"window >= horizon, history >= window, max_gap >= 0)")


@dataclass
class Counters:
    """What happened to the inputs."""

    samples: int = 0  #: samples received and used
    late: int = 0  #: samples dropped: stamp not after the last one, or a non-finite input
    filled: int = 0  #: lost samples filled (short gaps)
    paused: int = 0  #: gaps long enough to pause the comparison
    paused_s: float = 0.0  #: time missing in those gaps [s]
    horizons: int = 0  #: horizons scored
    #: time not compared at segment starts, while an unmeasured chamber's start mattered [s]
    unsettled_s: float = 0.0


@dataclass
class _Horizon:
    """The samples of the horizon in progress and the state the twin started it from."""

    size: int
    t: np.ndarray = field(init=False)
    u: np.ndarray = field(init=False)
    f: np.ndarray = field(init=False)
    meas: np.ndarray = field(init=False)
    pred: np.ndarray = field(init=False)
    free: np.ndarray = field(init=False)
    n: int = 0
    start: tuple[np.ndarray, np.ndarray] | None = None
    segment_start: bool = False

    def __post_init__(self) -> None:
        self.t, self.u, self.f = (np.empty(self.size) for _ in range(3))
        self.meas, self.pred = np.empty((self.size, 3)), np.empty((self.size, 3))
        self.free = np.zeros(self.size, dtype=bool)


class Twin:
    """The model following an actuator's measurements and judging the gap.

    Args:
        params: the model (nominal, or recalibrated / augmented by a diagnosis).
        settings: sample time, horizon, window...
    """

    def __init__(self, params: ModelParams, settings: Settings | None = None) -> None:
        self.settings = s = settings if settings is not None else Settings()
        self.params = params
        self.stepper = Stepper(params, s.dt, s.horizon, s.warmup)
        self._copies = [Stepper(params, s.dt, s.horizon, s.warmup) for _ in range(2)]
        self._plant = Actuator(self.stepper.params)
        self._rng = np.random.default_rng(s.seed)
        period = self.stepper.period
        self.gaps = GapWindow(window=max(int(round(s.window / s.horizon)), 1),
                              history=max(int(round(s.history / s.horizon)), 1))
        self.counters = Counters()
        self.judged: list[SignalGap] = []
        self.paused_since: float | None = None  #: stamp after which data went missing [s]
        #: stamp of the segment's first sample while an unmeasured chamber's start still
        #: matters (nothing is compared), else None [s]
        self.settling_since: float | None = None
        self._brackets: list[Stepper] = []  # the model from atmosphere and from supply
        self._open: list[int] = []  # the unmeasured chambers' state indices
        self._compare_from = -math.inf  # stamp from which samples are compared [s]
        self.t_last: float | None = None  #: latest stamp used [s]
        #: stamp of the last sample of the horizon whose judgement set the present level [s]
        #: (None while nothing has been judged)
        self.level_since: float | None = None
        self._h = _Horizon(period)
        self._meas = np.empty(3)
        self._sigmas: deque[np.ndarray] = deque(maxlen=self.gaps.history)
        self._intervals: deque[float] = deque(maxlen=STREAM_INTERVALS)

    @property
    def level(self) -> Level:
        """The worst level over the signals judged (OK before any)."""
        return max((g.level for g in self.judged), default=Level.OK)

    def level_held(self) -> float:
        """How long the present level has held [s], in the samples' time: from
        :attr:`level_since` to the latest sample (0 before anything is judged)."""
        if self.level_since is None or self.t_last is None:
            return 0.0
        return self.t_last - self.level_since

    def feed(self, t: np.ndarray | float, u: np.ndarray | float, f_load: np.ndarray | float,
             y: np.ndarray | float, p1: np.ndarray | float,
             p2: np.ndarray | float) -> np.ndarray:
        """Take samples (scalars or equal-length arrays; see the module docstring for what each
        is); return the predicted y, p1, p2 (n, 3), NaN where nothing was predicted (a dropped
        sample, a segment's first)."""
        cols = np.broadcast_arrays(*(np.atleast_1d(np.asarray(x, dtype=float))
                                     for x in (t, u, f_load, y, p1, p2)))
        out = np.full((cols[0].size, 3), np.nan)
        for k in range(cols[0].size):
            out[k] = self.feed_one(*(float(c[k]) for c in cols))
        return out

    def feed_one(self, t: float, u: float, f: float, y: float, p1: float,
                 p2: float) -> np.ndarray:
        """:meth:`feed` for one sample given as floats; the predicted y, p1, p2 (3,)."""
        nan3 = np.full(3, np.nan)
        if not (math.isfinite(t) and math.isfinite(u) and math.isfinite(f)):
            self.counters.late += 1
            return nan3
        dt = self.settings.dt
        if self.t_last is not None:
            if t > self.t_last:
                self._intervals.append(t - self.t_last)
            steps = int(round((t - self.t_last) / dt))
            if steps < 1:
                self.counters.late += 1
                return nan3
            if steps > 1:
                if (steps - 1) * dt > self.settings.max_gap + 0.5 * dt:
                    self._pause(t)
                else:
                    for _ in range(1, steps):
                        self._sample(self.t_last + dt, u, f, np.full(3, np.nan))
                        self.counters.filled += 1
        self.counters.samples += 1
        meas = self._meas
        meas[0], meas[1], meas[2] = y, p1, p2
        return self._sample(t, u, f, meas)

    def interval(self) -> float | None:
        """The hardware's sample time [s]: the median of the latest stamp intervals
        (:func:`~jetpipe_ros.dataset.timebase.median_interval`; None before there are enough)."""
        return median_interval(self._intervals)

    def rate_mismatch(self) -> str | None:
        """In words, when the stamps come at another rate than the set sample time (by more than
        :data:`~jetpipe_ros.dataset.timebase.RATE_TOLERANCE`): samples then look lost (a stream
        at a multiple of it), late (a faster one), or the model runs at another speed than the
        hardware (any other)."""
        interval, dt = self.interval(), self.settings.dt
        if interval is None or not another_rate(interval, dt):
            return None
        return (f"the stamps come every {interval * 1e3:.3g} ms, but sample_time is "
                f"{dt * 1e3:.3g} ms: set it to the hardware's, {interval:.3g} s")

    def _pause(self, t: float) -> None:
        """A gap too long to fill: score what the horizon holds, restart at the next sample."""
        assert self.t_last is not None
        self.counters.paused += 1
        self.counters.paused_s += t - self.t_last - self.settings.dt
        self.paused_since = self.t_last
        self._close()
        self.stepper.restart()

    def _sample(self, t: float, u: float, f: float, meas: np.ndarray) -> np.ndarray:
        h = self._h
        if self.stepper.next_starts_horizon():
            if h.n:
                self._close()
            h.segment_start = self.stepper.index < 0
            h.start = self.stepper.snapshot()
            if h.segment_start:
                self._bracket(t, meas)
        pred, free = self.stepper.step_one(t, u, f, meas)
        if self._brackets:
            self._settle(t, u, f, meas)
        i = h.n
        h.t[i], h.u[i], h.f[i] = t, u, f
        h.meas[i], h.pred[i], h.free[i] = meas, pred, free
        h.n += 1
        self.t_last = t
        if free and self.paused_since is not None:
            self.paused_since = None
        return pred

    def _bracket(self, t: float, meas: np.ndarray) -> None:
        """At a segment's first sample (stamp ``t``, measurements ``meas``): start the two
        copies of the model whose unmeasured chambers bound every start, if there are any."""
        if self.settling_since is not None and self.t_last is not None:  # cut off by a pause
            self.counters.unsettled_s += self.t_last - self.settling_since
            self.settling_since = None
        self._open = [kernel.P1 + j for j in range(2) if not math.isfinite(meas[1 + j])]
        self._brackets = []
        self._compare_from = -math.inf
        if not self._open:
            return
        for p0 in START_RANGE:
            params = self.params.with_values({"chamber.initial_pressure_1": p0,
                                              "chamber.initial_pressure_2": p0})
            self._brackets.append(Stepper(params, self.settings.dt, self.settings.horizon,
                                          self.settings.warmup))
        self.settling_since, self._compare_from = t, math.inf

    def _settle(self, t: float, u: float, f: float, meas: np.ndarray) -> None:
        """Step the two bounding copies through the sample; once they agree on every
        unmeasured chamber within the pressure sensor's noise, compare from the next sample."""
        low, high = self._brackets
        low.step_one(t, u, f, meas)
        high.step_one(t, u, f, meas)
        sigma = self.params["sensors.pressure_sigma"]
        if all(abs(high.act.state[i] - low.act.state[i]) <= sigma for i in self._open):
            assert self.settling_since is not None
            self.counters.unsettled_s += t - self.settling_since
            self._brackets, self.settling_since, self._compare_from = [], None, t

    def _close(self) -> None:
        """Score the horizon in progress against its noise floor and judge the window."""
        h = self._h
        n = h.n
        h.n = 0
        if n == 0 or h.start is None:
            return
        meas, pred = h.meas[:n], h.pred[:n]
        free = h.free[:n] & (h.t[:n] > self._compare_from)
        if not free.any():
            return
        copies, noise_rel = self._noisy_copies(h, n)
        for j, s in enumerate(SIGNALS):
            x = meas[:, j]
            ok = np.isfinite(x)
            scored = free & ok
            if not ok.any():
                continue
            sse = [float(((p[scored, j] - m[scored, j]) ** 2).sum())
                   for p, m in [(pred, meas), *copies]]
            self.gaps.add(s, HorizonScore(sse[0], sse[1], sse[2], int(scored.sum()),
                                          int(ok.sum()), float(x[ok].sum()),
                                          float((x[ok] ** 2).sum()), 2.0 * noise_rel[j]))
        self.counters.horizons += 1
        before = self.level if self.judged else None
        self.judged = self.gaps.judge()
        if self.judged and self.level != before:
            self.level_since = float(h.t[n - 1])

    def _noisy_copies(self, h: _Horizon,
                      n: int) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
        """Two re-measurements of the horizon on the model itself with the measured sensor
        noise, each predicted with the twin's restarts: (prediction, noisy measurement); and
        the relative standard uncertainty of the noise used, per signal.

        The noise [m, Pa] is the median of the horizons' estimates over the history: one
        horizon's estimate strays by a few %, which would move the floor by twice as much. What
        is left of that error is measured from the estimates' own spread (that of a median of
        k normal draws: sqrt(pi / 2) sd / sqrt(k)); the floor, a variance, carries twice it."""
        assert h.start is not None
        self._plant.state, self._plant.ring = h.start[0].copy(), h.start[1].copy()
        first = 1 if h.segment_start else 0
        truth = np.empty((n, 3))
        truth[0] = self._plant.outputs()[OUT_COLUMNS]
        if n > first:
            truth[first:] = self._plant.run(h.u[first:n], h.f[first:n])[:, OUT_COLUMNS]
        meas = h.meas[:n]
        self._sigmas.append(np.array([noise_level(meas[np.isfinite(meas[:, j]), j])
                                      for j in range(3)]))
        history = np.array(self._sigmas)
        sigma = np.median(history, axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = np.sqrt(np.pi / 2) * history.std(axis=0) / sigma / np.sqrt(len(history))
        rel = np.where(np.isfinite(rel) & (len(history) > 1), rel, 1.0)
        out = []
        for copy in self._copies:
            noisy = truth + sigma * self._rng.standard_normal((n, 3))
            noisy[~np.isfinite(meas)] = np.nan
            copy.load(h.start)
            if h.segment_start:
                copy.restart()
            else:
                copy.align()
            pred, _ = copy.feed(h.t[:n], h.u[:n], h.f[:n], noisy)
            out.append((pred, noisy))
        return out, rel
