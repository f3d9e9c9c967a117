"""Chamber 1's time constant on a locked piston (for test_hose.py and test_port.py, which judge
the gas volume a passage adds before the chamber)."""

from __future__ import annotations

import numpy as np

from jetpipe_ros.model import ModelParams, simulate


def _area(x: np.ndarray, dt: float) -> float:
    """Area [s] between the normalised step response ``x`` and its final value."""
    return float(np.sum(x[-1] - x) * dt / (x[-1] - x[0]))


def chamber_time_constant(params: ModelParams, step: float = 0.05) -> float:
    """Piston locked, a small command step ``step`` [V] after 20 samples at rest: chamber 1
    settles as a first-order lag whose time constant [s] is its capacitance over the valve's
    flow slope; measured as the area over the normalised response of p1 less the valve's own
    mean delay (the same area over its u_eq: the delay and the chain's lags)."""
    locked = params.with_values({"mechanics.locked": True})
    u = np.concatenate([np.zeros(20), np.full(2500, step)])
    run = simulate(locked, u)
    dt = locked["integration.sample_time"]
    return _area(run.p1[20:], dt) - _area(run.u_eq[20:], dt)
