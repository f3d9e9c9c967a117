"""Cylinder chambers: volumes (Eq. 13) and pressure dynamics (Eq. 11-12).

Pressures are absolute [Pa]. The nominal gas is isothermal (polytropic index n = 1). The thermal
effect either sets n > 1, which multiplies both the flow and the volume-change terms, or gives
each chamber a gas temperature exchanging heat with the walls (energy balance).
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
    # By the reciprocal: it depends on the volumes only, so the kernel's sub-steps compute it
    # beside the flow map rather than after it (their chains of dependent operations set the
    # pace).
    dp1 = (rt * q1 - area * p1 * v) * (n / vol1)
    dp2 = (rt * q2 + area * p2 * v) * (n / vol2)
    return dp1, dp2


@njit(cache=True, error_model="numpy")
def pressure_temperature_rates(q: float, p: float, temp: float, dvol: float, vol: float,
                               r: float, t_wall: float, gamma: float,
                               conductance: float) -> tuple[float, float]:
    """Energy and mass balance of one chamber with wall heat exchange: dp/dt [Pa/s], dT/dt [K/s].

    ``q`` is the net mass inflow [kg/s] (inflow at the wall temperature ``t_wall`` [K], outflow
    at the gas temperature ``temp`` [K]), ``dvol`` the volume rate [m^3/s], ``r`` the gas
    constant [J/(kg K)], ``gamma`` the heat capacity ratio, ``conductance`` the wall heat
    conductance h A [W/K]. From d(p V)/dt / (gamma - 1) = c_p T_in q - p dV/dt + h A (T_w - T)
    and p V = m r T. Large h A tends to the isothermal Eq. 11-12.
    """
    t_in = t_wall if q > 0.0 else temp
    heat = conductance * (t_wall - temp)
    dp = (gamma * r * t_in * q + (gamma - 1.0) * heat - gamma * p * dvol) / vol
    dtemp = temp * (dp / p + dvol / vol - r * temp * q / (p * vol))
    return dp, dtemp
