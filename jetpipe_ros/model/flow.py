"""Mass flow map of the jet-pipe valve, Eq. 8, with the supply and atmosphere limits.

q(u, p) is the paper's fifth-order polynomial in the equivalent voltage u [V] and the chamber
pressure p [bar], evaluated with p clamped to its identified range [1, 10] bar. The valve vents to
atmosphere, so a chamber at or below atmospheric pressure has no outflow. A supply pressure other
than the 10 bar of the identification (supply_pressure effect) maps the chamber pressure affinely
from [p_atm, p_s] onto [1, 10] bar and scales the flow by (p_s - p_atm) / 9 bar: the jet-pipe's
pressure recovery is a fixed fraction of the supply-to-atmosphere span.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Atmospheric and identification supply pressures [Pa, absolute].
P_ATM = 1.0e5
P_SUPPLY_NOMINAL = 1.0e6


#: Eq. 8's coefficients give g/s; the model works in kg/s.
KG_PER_G = 1e-3


@njit(cache=True, error_model="numpy")
def flow_basis(u: float | np.ndarray, p_bar: float | np.ndarray) -> tuple[float | np.ndarray, ...]:
    """Eq. 8's 21 monomials u^i p^j (i + j <= 5) in the paper's order, for voltage ``u`` [V]
    and pressure ``p_bar`` [bar]: 1, u, p, u^2, u p, p^2, u^3, ..., u p^4, p^5.

    Floats (the kernel: a tuple of floats) or equal-shape arrays (the least-squares fit of
    :mod:`jetpipe_ros.identify.flow_map`: a tuple of arrays): the one definition of Eq. 8's
    terms that both the model and the identification use.
    """
    u2 = u * u
    u3 = u2 * u
    u4 = u3 * u
    p2 = p_bar * p_bar
    p3 = p2 * p_bar
    p4 = p3 * p_bar
    return (u * 0.0 + 1.0, u, p_bar, u2, u * p_bar, p2, u3, u2 * p_bar, u * p2, p3, u4,
            u3 * p_bar, u2 * p2, u * p3, p4, u4 * u, u4 * p_bar, u3 * p2, u2 * p3, u * p4,
            p4 * p_bar)


@njit(cache=True, error_model="numpy")
def flow_polynomial(coef: np.ndarray, u: float, p_bar: float) -> float:
    """Eq. 8: mass flow [kg/s] for voltage ``u`` [V] and pressure ``p_bar`` [bar].

    ``coef`` holds the 21 coefficients in the paper's order (result in g/s).
    """
    t = flow_basis(u, p_bar)
    # The dot product with constant indices: numba indexes a tuple at full speed only so (a
    # loop over the terms costs 8x in the kernel).
    g = (coef[0] * t[0] + coef[1] * t[1] + coef[2] * t[2] + coef[3] * t[3] + coef[4] * t[4]
         + coef[5] * t[5] + coef[6] * t[6] + coef[7] * t[7] + coef[8] * t[8] + coef[9] * t[9]
         + coef[10] * t[10] + coef[11] * t[11] + coef[12] * t[12] + coef[13] * t[13]
         + coef[14] * t[14] + coef[15] * t[15] + coef[16] * t[16] + coef[17] * t[17]
         + coef[18] * t[18] + coef[19] * t[19] + coef[20] * t[20])
    return g * KG_PER_G


def flow_matrix(u: np.ndarray | float, p_bar: np.ndarray | float) -> np.ndarray:
    """(n, 21) matrix of Eq. 8's monomials (:func:`flow_basis`) for voltages ``u`` [V] and
    pressures ``p_bar`` [bar] (broadcast against each other, flattened): the regressors of a
    least-squares fit of the coefficients [g/s]."""
    u, p = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(p_bar, dtype=float))
    return np.stack(flow_basis(np.ascontiguousarray(u.ravel()),
                               np.ascontiguousarray(p.ravel())), axis=-1)


def mass_flow(coef: np.ndarray, u: np.ndarray | float, p_bar: np.ndarray | float
              ) -> np.ndarray:
    """Eq. 8 over arrays: mass flow [kg/s] at voltages ``u`` [V] and pressures ``p_bar`` [bar]
    (broadcast, flattened), coefficients ``coef`` in the paper's order [g/s]."""
    return flow_matrix(u, p_bar) @ np.asarray(coef, dtype=float) * KG_PER_G


@njit(cache=True, error_model="numpy", inline="always")
def chamber_inflow(coef: np.ndarray, u: float, p: float, p_supply: float,
                   gain_charge: float = 1.0, gain_discharge: float = 1.0) -> float:
    """Mass flow [kg/s] into a chamber at pressure ``p`` [Pa] for equivalent voltage ``u`` [V].

    ``p_supply`` [Pa] is the actual supply; at 10 bar this is Eq. 8 with p clamped to [1, 10] bar
    and no outflow at or below atmospheric pressure. ``gain_charge`` and ``gain_discharge``
    multiply the flow where it fills (q > 0) and empties (q < 0) the chamber: an individual
    valve's flow map differs from the paper's by a factor per direction.
    """
    span = (p_supply - P_ATM) / (P_SUPPLY_NOMINAL - P_ATM)
    p_map = 1.0 + (p - P_ATM) * (1e-5 / span)
    p_map = min(max(p_map, 1.0), 10.0)
    q = span * flow_polynomial(coef, u, p_map)
    if q < 0.0:
        return 0.0 if p <= P_ATM else gain_discharge * q
    return gain_charge * q


#: Heat capacity ratio of air.
GAMMA_AIR = 1.4
_CRITICAL_RATIO = (2.0 / (GAMMA_AIR + 1.0)) ** (GAMMA_AIR / (GAMMA_AIR - 1.0))  # 0.528
_CHOKED = math.sqrt(GAMMA_AIR * (2.0 / (GAMMA_AIR + 1.0))
                    ** ((GAMMA_AIR + 1.0) / (GAMMA_AIR - 1.0)))  # 0.685
#: Above this downstream/upstream ratio the orifice law is linearised in the pressure
#: difference: the exact law's infinite slope at equal pressures would make explicit
#: integration chatter, and the flow there is negligible.
_LINEAR_RATIO = 0.995


@njit(cache=True, error_model="numpy")
def _orifice_function(ratio: float) -> float:
    if ratio <= _CRITICAL_RATIO:
        return _CHOKED
    g = GAMMA_AIR
    return math.sqrt(2.0 * g / (g - 1.0) * (ratio ** (2.0 / g) - ratio ** ((g + 1.0) / g)))


@njit(cache=True, error_model="numpy")
def orifice_flow(area: float, p_a: float, p_b: float, rt: float) -> float:
    """Compressible flow [kg/s] from ``p_a`` to ``p_b`` [Pa] through an orifice of effective
    area ``area`` [m^2] (ISO 6358 form, choked below the critical ratio 0.528); ``rt`` = r T of
    the upstream gas [J/kg]. Negative when the flow goes from b to a.
    """
    if area == 0.0 or p_a == p_b:
        return 0.0
    sign = 1.0 if p_a > p_b else -1.0
    p_up = max(p_a, p_b)
    ratio = min(p_a, p_b) / p_up
    if ratio > _LINEAR_RATIO:
        psi = _orifice_function(_LINEAR_RATIO) * (1.0 - ratio) / (1.0 - _LINEAR_RATIO)
    else:
        psi = _orifice_function(ratio)
    return sign * area * p_up / math.sqrt(rt) * psi
