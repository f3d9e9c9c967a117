"""Excitation signals for identification experiments, sampled every ``dt`` [s].

Every generator takes the sample time ``dt`` [s], the duration [s] and its own parameters, and
returns a float array of ``samples(dt, duration)`` values: sample k is the value held over
[k dt, (k + 1) dt). Units are those of the quantity excited: volts for a valve command, metres
for a position setpoint. :data:`GENERATORS` maps the ``signal:`` names of a campaign YAML to the
generators.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy import signal as sps


def samples(dt: float, duration: float) -> int:
    """Number of samples of a signal lasting ``duration`` [s] at sample time ``dt`` [s]."""
    if dt <= 0.0 or duration <= 0.0:
        raise ValueError(f"need dt > 0 and duration > 0, got dt={dt}, duration={duration}")
    return max(1, round(duration / dt))


def _time(dt: float, duration: float) -> np.ndarray:
    return np.arange(samples(dt, duration)) * dt


def hold(dt: float, duration: float, level: float = 0.0) -> np.ndarray:
    """A constant ``level``."""
    return np.full(samples(dt, duration), float(level))


def steps(dt: float, duration: float, levels: Sequence[float],
          durations: Sequence[float]) -> np.ndarray:
    """Piecewise constant: ``levels[i]`` held for ``durations[i]`` [s], in order.

    The durations must add up to ``duration`` (to within one sample), e.g. the paper's
    charge/discharge test: levels [u, -u], durations [4.4, 1.8] s (Sec. 2.3).
    """
    if len(levels) != len(durations) or not levels:
        raise ValueError(f"steps: {len(levels)} levels but {len(durations)} durations")
    if any(d <= 0.0 for d in durations):
        raise ValueError(f"steps: durations must be > 0 s, got {list(durations)}")
    n = samples(dt, duration)
    ends = np.round(np.cumsum(durations) / dt).astype(int)
    if abs(ends[-1] - n) > 1:
        raise ValueError(f"steps: durations add up to {sum(durations):g} s, the experiment "
                         f"lasts {duration:g} s")
    index = np.searchsorted(ends, np.arange(n), side="right")
    return np.asarray(levels, dtype=float)[np.minimum(index, len(levels) - 1)]


def square(dt: float, duration: float, amplitude: float, frequency: float,
           offset: float = 0.0) -> np.ndarray:
    """Square wave ``offset +- amplitude`` at ``frequency`` [Hz], starting high (the paper's
    validation inputs: 0.6 V at 0.1122 Hz, 3 V at 0.97 Hz)."""
    return offset + amplitude * sps.square(2.0 * np.pi * frequency * _time(dt, duration))


def triangle(dt: float, duration: float, amplitude: float, frequency: float,
             offset: float = 0.0) -> np.ndarray:
    """Triangle wave ``offset +- amplitude`` at ``frequency`` [Hz], starting at ``offset``
    rising: constant-speed ramps (slow motion in the stick-slip regime, hysteresis loops)."""
    phase = 2.0 * np.pi * frequency * _time(dt, duration) + np.pi / 2.0
    return offset + amplitude * sps.sawtooth(phase, width=0.5)


def sine_sweep(dt: float, duration: float, amplitude: float, f0: float, f1: float,
               method: str = "logarithmic", offset: float = 0.0) -> np.ndarray:
    """Sine sweep from ``f0`` to ``f1`` [Hz] over the duration (scipy.signal.chirp), starting
    at zero phase: ``offset + amplitude sin(phase(t))``."""
    t = _time(dt, duration)
    return offset + amplitude * sps.chirp(t, f0, t[-1] if t.size > 1 else dt, f1,
                                          method=method, phi=-90.0)


def prbs(dt: float, duration: float, levels: Sequence[float], min_hold: float,
         max_hold: float, seed: int = 0) -> np.ndarray:
    """Multi-level pseudo-random sequence: levels drawn uniformly from ``levels``, each held
    for a random time in [``min_hold``, ``max_hold``] [s]; the same ``seed`` gives the same
    sequence. Consecutive levels differ, so every switch excites the system."""
    if len(levels) < 2:
        raise ValueError(f"prbs: needs at least 2 levels, got {list(levels)}")
    if not 0.0 < min_hold <= max_hold:
        raise ValueError(f"prbs: need 0 < min_hold <= max_hold, got {min_hold}, {max_hold} s")
    n = samples(dt, duration)
    rng = np.random.default_rng(seed)
    out = np.empty(n)
    k, last = 0, -1
    while k < n:
        choice = int(rng.integers(len(levels) - 1))
        last = choice + (choice >= last) if last >= 0 else int(rng.integers(len(levels)))
        length = max(1, round(rng.uniform(min_hold, max_hold) / dt))
        out[k:k + length] = levels[last]
        k += length
    return out


def release(dt: float, duration: float, level: float, rate: float) -> np.ndarray:
    """A held value released progressively: starts at ``level`` and ramps linearly to 0 at
    ``rate`` [units/s], then stays at 0 (the friction test's hydraulic load [N], Sec. 4.2:
    from S (p1 - p2) to 0 at about 1000 N/s)."""
    if rate <= 0.0:
        raise ValueError(f"release: rate must be > 0, got {rate}")
    return np.sign(level) * np.maximum(abs(level) - rate * _time(dt, duration), 0.0)


#: The generators by the name a campaign YAML gives in ``signal:``.
GENERATORS: dict[str, Callable[..., np.ndarray]] = {
    "hold": hold,
    "steps": steps,
    "square": square,
    "triangle": triangle,
    "sine_sweep": sine_sweep,
    "prbs": prbs,
    "release": release,
}
