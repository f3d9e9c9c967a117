"""Second-order linear blocks of the plant (the pressure and position transducers):
exact zero-order-hold discretisation and the per-sub-step update."""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.linalg import expm


def second_order_lag(frequency: float, damping: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation (A_d (2, 2), B_d (2,)) at ``h`` [s] of the unit-gain
    lag w^2 / (s^2 + 2 zeta w s + w^2), w = 2 pi ``frequency`` [Hz], zeta = ``damping``; state
    (output, its time derivative)."""
    w = 2.0 * np.pi * frequency
    m = np.zeros((3, 3))
    m[0, 1] = 1.0
    m[1, 0] = -w * w
    m[1, 1] = -2.0 * damping * w
    m[1, 2] = w * w
    e = expm(m * h)
    return np.ascontiguousarray(e[:2, :2]), np.ascontiguousarray(e[:2, 2])


@njit(cache=True, error_model="numpy")
def second_order_step(a: np.ndarray, b: np.ndarray, x: np.ndarray, i: int, u: float) -> None:
    """Advance the block whose state is ``x[i], x[i + 1]`` by one step with input ``u`` held."""
    x0 = x[i]
    x1 = x[i + 1]
    x[i] = a[0, 0] * x0 + a[0, 1] * x1 + b[0] * u
    x[i + 1] = a[1, 0] * x0 + a[1, 1] * x1 + b[1] * u
