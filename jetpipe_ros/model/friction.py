"""Pressure-dependent static friction of the piston, Eq. 15-18 with the planes of Eq. 20-27.

Each of the four friction parameters is a plane c0 + c1 p1 + c2 p2 over the chamber pressures in
bar, one set for the entry phase (v < 0, fitted where p2 > p1) and one for the exit phase
(v > 0, fitted where p1 > p2). Values are signed: in the entry phase forces and the Stribeck
velocity are negative, so F(v) carries the sign of v. Outside its fitted region a phase's planes
are evaluated at the mean pressure, and each parameter is kept on its physical side.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Rows of a plane array: breakaway F_S [N], Stribeck velocity v_s [m/s], viscous F_v [N s/m],
#: Coulomb F_C [N]; columns c0, c1, c2.
BREAKAWAY, STRIBECK, VISCOUS, COULOMB = 0, 1, 2, 3

#: Physical floors: |F_C| >= 1 N, |v_s| >= 1e-4 m/s (docs/model.md).
MIN_COULOMB = 1.0
MIN_STRIBECK = 1e-4


@njit(cache=True, error_model="numpy")
def plane_basis(p1_bar: float | np.ndarray, p2_bar: float | np.ndarray
                ) -> tuple[float | np.ndarray, ...]:
    """The terms (1, p1, p2) of a friction plane c0 + c1 p1 + c2 p2 (Eq. 20-27) at chamber
    pressures ``p1_bar``, ``p2_bar`` [bar]: floats or equal-shape arrays (the regressors of the
    planes' least-squares fit in :mod:`jetpipe_ros.identify.friction`)."""
    return (p1_bar * 0.0 + 1.0, p1_bar, p2_bar)


@njit(cache=True, error_model="numpy")
def plane(c: np.ndarray, p1_bar: float | np.ndarray, p2_bar: float | np.ndarray
          ) -> float | np.ndarray:
    """One of Eq. 20-27: c0 + c1 p1 + c2 p2 for coefficients ``c`` (3,) at chamber pressures
    ``p1_bar``, ``p2_bar`` [bar] (floats or arrays), in the unit of the parameter."""
    t = plane_basis(p1_bar, p2_bar)
    return c[0] * t[0] + c[1] * t[1] + c[2] * t[2]


@njit(cache=True, error_model="numpy")
def friction_parameters(planes: np.ndarray, direction: float, p1: float, p2: float
                        ) -> tuple[float, float, float, float]:
    """Signed (F_S, v_s, F_v, F_C) for motion in ``direction`` (+1 exit, -1 entry).

    ``planes`` has shape (2, 4, 3): [entry, exit] x [F_S, v_s, F_v, F_C] x [c0, c1, c2];
    ``p1``, ``p2`` are chamber pressures [Pa].
    """
    a = p1 * 1e-5
    b = p2 * 1e-5
    phase = 1 if direction > 0.0 else 0
    # Fitted region: exit where p1 > p2, entry where p2 > p1; elsewhere the mean pressure.
    if (phase == 1 and a <= b) or (phase == 0 and b <= a):
        a = b = 0.5 * (a + b)
    f_s = plane(planes[phase, BREAKAWAY], a, b)
    v_s = plane(planes[phase, STRIBECK], a, b)
    f_v = plane(planes[phase, VISCOUS], a, b)
    f_c = plane(planes[phase, COULOMB], a, b)
    s = 1.0 if phase == 1 else -1.0
    f_c = s * max(s * f_c, MIN_COULOMB)
    f_s = s * max(s * f_s, s * f_c)
    v_s = s * max(s * v_s, MIN_STRIBECK)
    f_v = max(f_v, 0.0)
    return f_s, v_s, f_v, f_c


@njit(cache=True, error_model="numpy")
def stribeck_force(v: float | np.ndarray, f_s: float, v_s: float, f_c: float) -> float | np.ndarray:
    """Eq. 18 without the viscous term: F_C + (F_S - F_C) exp(-(v/v_s)^2) [N] at velocity
    ``v`` [m/s] (a float, or an array). The kernel adds the viscous term F_v v implicitly."""
    r = v / v_s
    return f_c + (f_s - f_c) * np.exp(-r * r)


@njit(cache=True, error_model="numpy")
def sliding_friction(v: float | np.ndarray, f_s: float, v_s: float, f_v: float, f_c: float
                     ) -> float | np.ndarray:
    """Eq. 18: friction force [N] while sliding at velocity ``v`` [m/s] (a float, or an array:
    the identification fits it to the sliding samples of a friction test)."""
    return stribeck_force(v, f_s, v_s, f_c) + f_v * v


@njit(cache=True, error_model="numpy")
def static_friction(f_applied: float, f_s: float) -> float:
    """Eq. 15 at rest: the friction that balances ``f_applied``, at most the breakaway |F_S|."""
    lim = abs(f_s)
    return min(max(f_applied, -lim), lim)
