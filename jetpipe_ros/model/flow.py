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


@njit(cache=True, error_model="numpy")
def flow_polynomial(coef: np.ndarray, u: float, p_bar: float) -> float:
    """Eq. 8: mass flow [kg/s] for voltage ``u`` [V] and pressure ``p_bar`` [bar].

    ``coef`` holds the 21 coefficients in the paper's order (result in g/s): by total degree,
    and within a degree by falling power of u (1; u, p; u^2, u p, p^2; ...; u p^4, p^5).
    Evaluated as a polynomial in p whose coefficients are polynomials in u, both by Horner's
    scheme: the 21 terms summed one after the other (a chain of 20 dependent additions) made
    the integration kernel about 10 % slower.
    """
    c = coef
    a0 = c[0] + u * (c[1] + u * (c[3] + u * (c[6] + u * (c[10] + u * c[15]))))
    a1 = c[2] + u * (c[4] + u * (c[7] + u * (c[11] + u * c[16])))
    a2 = c[5] + u * (c[8] + u * (c[12] + u * c[17]))
    a3 = c[9] + u * (c[13] + u * c[18])
    a4 = c[14] + u * c[19]
    p = p_bar
    return (a0 + p * (a1 + p * (a2 + p * (a3 + p * (a4 + p * c[20]))))) * 1e-3


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
