"""How many model samples are due at a timer tick: stepping by elapsed wall time.

rclpy skips timer ticks it misses rather than catching up, so a simulator that counted its
callbacks would lose simulated time. :class:`Pacer` instead compares the elapsed wall time,
scaled by the real-time factor, with the samples already issued, and caps the catch-up so that
a long stall (a suspended process, a slow machine) does not end in a burst of stale samples.
"""

from __future__ import annotations

import math


class Pacer:
    """Samples due per tick for a sample time ``dt`` [s] run at ``rate`` x real time.

    Args:
        dt: model sample time [s].
        rate: simulated seconds per wall second; 0 means as fast as possible (every tick gets
            ``max_batch`` samples).
        max_batch: most samples issued at one tick; a larger backlog is dropped and counted.
        now: wall time of the start [s], any monotonic origin.
    """

    def __init__(self, dt: float, rate: float, max_batch: int, now: float) -> None:
        if dt <= 0.0 or rate < 0.0 or max_batch < 1:
            raise ValueError(f"bad pacing: dt={dt} s, rate={rate}, max_batch={max_batch}")
        self.dt = dt
        self.max_batch = max_batch
        self.issued = 0  #: samples issued since the start
        self.ticks = 0  #: calls of :meth:`due` since the start
        self.dropped = 0  #: samples of backlog dropped since the start
        self.overruns = 0  #: ticks at which a backlog was dropped
        self.largest = 0  #: most samples issued at one tick (1: never behind)
        self._rate = rate
        self._origin = now
        self._base = 0

    @property
    def rate(self) -> float:
        """Target simulated seconds per wall second (0: as fast as possible)."""
        return self._rate

    def set_rate(self, rate: float, now: float) -> None:
        """Change the real-time factor from wall time ``now`` on [s]."""
        if rate < 0.0:
            raise ValueError(f"real-time factor must be >= 0, got {rate}")
        self._rate = rate
        self._origin = now
        self._base = self.issued

    def due(self, now: float) -> int:
        """Samples to step at wall time ``now`` [s]; counts them as issued."""
        self.ticks += 1
        if self._rate == 0.0:
            n = self.max_batch
        else:
            target = self._base + math.floor((now - self._origin) * self._rate / self.dt + 1e-9)
            n = target - self.issued
            if n > self.max_batch:
                backlog = n - self.max_batch
                self.dropped += backlog
                self.overruns += 1
                self._base -= backlog
                n = self.max_batch
        n = max(n, 0)
        self.issued += n
        if self._rate != 0.0:
            self.largest = max(self.largest, n)
        return n
