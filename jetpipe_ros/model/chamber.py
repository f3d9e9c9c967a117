"""Cylinder chambers: volumes (Eq. 13) and pressure dynamics (Eq. 11-12).

Pressures are absolute [Pa]. The nominal gas is isothermal (polytropic index n = 1); the thermal
effect sets n > 1, which multiplies both the flow and the volume-change terms.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, error_model="numpy")
def chamber_volumes(y: float, area: float, v01: float, v02: float) -> tuple[float, float]:
    """Eq. 13: chamber volumes [m^3] at piston position ``y`` [m]."""
    return area * y + v01, -area * y + v02


@njit(cache=True, error_model="numpy")
def pressure_rates(q1: float, q2: float, p1: float, p2: float, v: float, vol1: float,
                   vol2: float, area: float, rt: float, n: float) -> tuple[float, float]:
    """Eq. 11-12 (times the polytropic index n): dp1/dt, dp2/dt [Pa/s].

    ``q1``, ``q2`` are the net mass flows into each chamber [kg/s], ``v`` the piston velocity
    [m/s] (positive enlarges chamber 1), ``rt`` the product r T [J/kg].
    """
    dp1 = n * (rt * q1 - area * p1 * v) / vol1
    dp2 = n * (rt * q2 + area * p2 * v) / vol2
    return dp1, dp2
