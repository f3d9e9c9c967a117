"""Mass flow map of the jet-pipe valve, Eq. 8, with the supply and atmosphere limits.

q(u, p) is the paper's fifth-order polynomial in the equivalent voltage u [V] and the chamber
pressure p [bar], evaluated with p clamped to its identified range [1, 10] bar. The valve vents to
atmosphere, so a chamber at or below atmospheric pressure has no outflow. A supply pressure other
than the 10 bar of the identification (supply_pressure effect) maps the chamber pressure affinely
from [p_ref, p_s] onto [p_ref, 10 bar] and scales the flow by (p_s - p_ref) / (10 bar - p_ref):
the map keeps its shape relative to a reference pressure p_ref. The physics admits a range: a
choked jet's mass flow grows with the absolute supply (p_ref = 0: similarity in absolute
pressure), the pressure a subsonic jet recovers in a receiver with the supply's excess over the
atmosphere (p_ref = p_atm, the default), a sonic jet's thrust in between (p_ref = p_atm / C_F,
about 0.79 bar with the thrust coefficient C_F = 1.27 of a convergent nozzle in air). At the
nominal supply every reference gives Eq. 8.

An individual valve's map departs from Eq. 8 by about the polynomial's fit error, in a shape it
cannot hold everywhere: an optional correction table (``flow.table``, zero by default) adds a
smooth surface through the values of a fixed grid of voltage and pressure, identified from the
constant-volume tests like Eq. 8 itself (:func:`table_flow`).

The leakage effect's laws are here too: the compressible orifice (:func:`orifice_flow`) and the
power law with a free exponent (:func:`power_leak`); the laminar one is a conductance times the
pressure difference. So is the valve_lag effect's ``flow`` form, a lag on each chamber's mass
flow after the map (:func:`flow_lag_matrix`, :func:`flow_lag_step`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.linalg import expm

#: Atmospheric and identification supply pressures [Pa, absolute].
P_ATM = 1.0e5
P_SUPPLY_NOMINAL = 1.0e6


#: Eq. 8's coefficients give g/s; the model works in kg/s.
KG_PER_G = 1e-3


#: Eq. 8's 21 terms u^i p^j (i + j <= 5) as (i, j), in the paper's order: 1, u, p, u^2, u p,
#: p^2, u^3, ..., u p^4, p^5. The one definition of the terms: the model evaluates them from it
#: (:func:`flow_polynomial`), the identification fits their coefficients (:func:`flow_matrix`).
FLOW_TERMS = tuple((degree - j, j) for degree in range(6) for j in range(degree + 1))

#: Number of Eq. 8's terms.
N_TERMS = len(FLOW_TERMS)

#: Position in the paper's order of the coefficient of u^i p^j, at [i, j] (-1: no such term).
_TERM_INDEX = np.full((6, 6), -1, dtype=np.int64)
for _k, (_i, _j) in enumerate(FLOW_TERMS):
    _TERM_INDEX[_i, _j] = _k


@njit(cache=True, error_model="numpy", inline="always")
def flow_polynomial(coef: np.ndarray, u: float, p_bar: float) -> float:
    """Eq. 8: mass flow [kg/s] for voltage ``u`` [V] and pressure ``p_bar`` [bar].

    ``coef`` holds the 21 coefficients in the paper's order (result in g/s). Evaluated by
    Horner's scheme, in p within each power of u (loops of constant length: they unroll, and
    the indices fold into constants).
    """
    g = 0.0
    for j in range(5, -1, -1):
        a = 0.0
        for i in range(5 - j, -1, -1):
            a = a * u + coef[_TERM_INDEX[i, j]]
        g = g * p_bar + a
    return g * KG_PER_G


#: The correction table's nodes: equivalent voltage [V] and chamber pressure [bar]. Fixed, so a
#: table is a plain list of numbers (a ROS parameter): value [g/s] at (TABLE_U[i], TABLE_P[j])
#: is entry i * len(TABLE_P) + j.
TABLE_U = np.linspace(-3.0, 3.0, 13)
TABLE_P = np.linspace(1.0, 10.0, 10)
#: Entries of the correction table.
TABLE_SIZE = TABLE_U.size * TABLE_P.size


@njit(cache=True, error_model="numpy", inline="always")
def _cell(x: float, first: float, step: float, n: int) -> tuple[int, float]:
    """Lower node index and fraction of a uniform grid's cell holding ``x`` (clamped)."""
    s = (x - first) / step
    s = min(max(s, 0.0), n - 1.0)
    i = min(int(s), n - 2)
    return i, s - i


@njit(cache=True, error_model="numpy", inline="always")
def _cubic_weights(t: float) -> tuple[float, float, float, float]:
    """Weights of the nodes before, at the start of, at the end of and after a cell, at
    fraction ``t`` of it: cubic convolution (Keys 1981, a = -1/2, the Catmull-Rom spline)."""
    t2 = t * t
    t3 = t2 * t
    return ((-t3 + 2.0 * t2 - t) * 0.5, (3.0 * t3 - 5.0 * t2 + 2.0) * 0.5,
            (-3.0 * t3 + 4.0 * t2 + t) * 0.5, (t3 - t2) * 0.5)


@njit(cache=True, error_model="numpy", inline="always")
def table_flow(coef: np.ndarray, u: float, p_bar: float) -> float:
    """The flow map's correction [kg/s] at voltage ``u`` [V] and pressure ``p_bar`` [bar]:
    the table that follows Eq. 8's 21 coefficients in ``coef`` [g/s] on the nodes
    :data:`TABLE_U` x :data:`TABLE_P`, interpolated by cubic convolution in each direction
    (through the nodes' values, reproducing any quadratic surface inside the grid; a node
    beyond an edge repeats the edge's), constant beyond the outer nodes.

    A real valve's map departs from Eq. 8 by about its fit error (0.5 g/s at most in the paper)
    in a shape no fifth-order polynomial holds everywhere; the table, identified from the
    constant-volume tests (:mod:`jetpipe_ros.identify.flow_map`), carries that departure.
    Bilinear interpolation on the same nodes would miss a departure of the self-check's shape
    by a tenth of its size, enough to leave a held-out gap of about 1 % (docs/identification.md).
    """
    nu = TABLE_U.shape[0]
    npp = TABLE_P.shape[0]
    i, a = _cell(u, TABLE_U[0], TABLE_U[1] - TABLE_U[0], nu)
    j, b = _cell(p_bar, TABLE_P[0], TABLE_P[1] - TABLE_P[0], npp)
    wu = _cubic_weights(a)
    wp = _cubic_weights(b)
    g = 0.0
    for di in range(4):
        row = N_TERMS + min(max(i + di - 1, 0), nu - 1) * npp
        line = 0.0
        for dj in range(4):
            line += wp[dj] * coef[row + min(max(j + dj - 1, 0), npp - 1)]
        g += wu[di] * line
    return g * KG_PER_G


def table_matrix(u: np.ndarray, p_bar: np.ndarray) -> np.ndarray:
    """(n, :data:`TABLE_SIZE`) matrix whose product with a table [g/s] is :func:`table_flow`
    at voltages ``u`` [V] and pressures ``p_bar`` [bar] in g/s: the regressors of a fit of the
    table (the same weights, evaluated through :func:`table_flow` on unit tables)."""
    u, p = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(p_bar, dtype=float))
    u, p = u.ravel(), p.ravel()
    out = np.empty((u.size, TABLE_SIZE))
    _table_rows(u, p, out)
    return out


@njit(cache=True, error_model="numpy")
def _table_rows(u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    unit = np.zeros(N_TERMS + TABLE_SIZE)
    for m in range(TABLE_SIZE):
        unit[N_TERMS + m] = 1.0
        for n in range(u.shape[0]):
            out[n, m] = table_flow(unit, u[n], p[n]) / KG_PER_G
        unit[N_TERMS + m] = 0.0


def flow_matrix(u: np.ndarray | float, p_bar: np.ndarray | float) -> np.ndarray:
    """(n, 21) matrix of Eq. 8's terms (:data:`FLOW_TERMS`) for voltages ``u`` [V] and
    pressures ``p_bar`` [bar] (broadcast against each other, flattened): the regressors of a
    least-squares fit of the coefficients [g/s]."""
    u, p = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(p_bar, dtype=float))
    u, p = u.ravel(), p.ravel()
    return np.stack([u**i * p**j for i, j in FLOW_TERMS], axis=-1)


def mass_flow(coef: np.ndarray, u: np.ndarray | float, p_bar: np.ndarray | float
              ) -> np.ndarray:
    """The flow map over arrays: mass flow [kg/s] at voltages ``u`` [V] and pressures
    ``p_bar`` [bar] (broadcast, flattened); ``coef`` Eq. 8's coefficients in the paper's order
    [g/s], optionally followed by the correction table (:func:`table_flow`)."""
    coef = np.asarray(coef, dtype=float)
    g = flow_matrix(u, p_bar) @ coef[:N_TERMS]
    if coef.size > N_TERMS:
        g += table_matrix(u, p_bar) @ coef[N_TERMS:]
    return g * KG_PER_G


class FlowLaw(NamedTuple):
    """How an individual valve's flow follows Eq. 8 (numbers only, so that the compiled kernel
    passes it by value, without reference counting).

    ``reference`` [Pa] is the pressure the map keeps its shape relative to when the supply
    differs from 10 bar (0 to p_atm, module docstring); ``gain_charge`` and ``gain_discharge``
    multiply the flow where it fills (q > 0) and empties (q < 0) a chamber: an individual
    valve's map differs from the paper's by a factor per direction."""

    reference: float = P_ATM
    gain_charge: float = 1.0
    gain_discharge: float = 1.0


#: The paper's valve: Eq. 8 as identified.
PAPER_LAW = FlowLaw()


@njit(cache=True, error_model="numpy", inline="always")
def chamber_inflow(coef: np.ndarray, u: float, p: float, p_supply: float,
                   law: FlowLaw = PAPER_LAW) -> float:
    """Mass flow [kg/s] into a chamber at pressure ``p`` [Pa] for equivalent voltage ``u`` [V].

    ``p_supply`` [Pa] is the actual supply; ``law`` (:class:`FlowLaw`) how the map follows it
    and how this valve's flow differs from the paper's per direction. With the paper's law at
    10 bar this is Eq. 8 with p clamped to [1, 10] bar and no outflow at or below atmospheric
    pressure. ``coef`` is the flow map: Eq. 8's 21 coefficients, optionally followed by the
    correction table (:func:`table_flow`), added before the gains.
    """
    span = (p_supply - law.reference) / (P_SUPPLY_NOMINAL - law.reference)
    p_map = (law.reference + (p - law.reference) / span) * 1e-5
    p_map = min(max(p_map, 1.0), 10.0)
    q = flow_polynomial(coef, u, p_map)
    if coef.shape[0] > N_TERMS:
        q += table_flow(coef, u, p_map)
    q *= span
    if q < 0.0:
        return 0.0 if p <= P_ATM else law.gain_discharge * q
    return law.gain_charge * q


#: Heat capacity ratio of air.
GAMMA_AIR = 1.4
_CRITICAL_RATIO = (2.0 / (GAMMA_AIR + 1.0)) ** (GAMMA_AIR / (GAMMA_AIR - 1.0))  # 0.528
#: The flow function choked (at and below the critical ratio), Psi* [-].
CHOKED = math.sqrt(GAMMA_AIR * (2.0 / (GAMMA_AIR + 1.0))
                    ** ((GAMMA_AIR + 1.0) / (GAMMA_AIR - 1.0)))  # 0.685
#: Above this downstream/upstream ratio the orifice law is linearised in the pressure
#: difference: the exact law's infinite slope at equal pressures would make explicit
#: integration chatter, and the flow there is negligible.
LINEAR_RATIO = 0.995


@njit(cache=True, error_model="numpy")
def orifice_function(ratio: float, index: float = 0.5) -> float:
    """The orifice law's flow function Psi [-] at the downstream/upstream pressure ``ratio``:
    sqrt(2 gamma / (gamma - 1) (r^(2/gamma) - r^((gamma + 1)/gamma))), choked (0.685) at or below
    the critical ratio 0.528 (an isentropic nozzle's). With a subsonic ``index`` m other than
    0.5 (as ISO 6358-1:2013 writes its subsonic law; a porous element's m -> 1,
    :mod:`~jetpipe_ros.model.port`): Psi* (Psi / Psi*)^(2 m)."""
    if ratio <= _CRITICAL_RATIO:
        return CHOKED
    g = GAMMA_AIR
    psi = math.sqrt(2.0 * g / (g - 1.0) * (ratio ** (2.0 / g) - ratio ** ((g + 1.0) / g)))
    return psi if index == 0.5 else CHOKED * (psi / CHOKED) ** (2.0 * index)


@njit(cache=True, error_model="numpy")
def orifice_flow(area: float, p_a: float, p_b: float, rt: float, index: float = 0.5) -> float:
    """Compressible flow [kg/s] from ``p_a`` to ``p_b`` [Pa] through an orifice of effective
    area ``area`` [m^2] (the isentropic nozzle law, choked below the critical ratio 0.528:
    within 1 % of ISO 6358's ellipse with b = 0.528; subsonic ``index`` as
    :func:`orifice_function`); ``rt`` = r T of the upstream gas [J/kg]. Negative
    when the flow goes from b to a; linear in the drop within 0.5 % of equal pressures
    (through the law's value there).
    """
    if area == 0.0 or p_a == p_b:
        return 0.0
    sign = 1.0 if p_a > p_b else -1.0
    p_up = max(p_a, p_b)
    ratio = min(p_a, p_b) / p_up
    if ratio > LINEAR_RATIO:
        psi = orifice_function(LINEAR_RATIO, index) * (1.0 - ratio) / (1.0 - LINEAR_RATIO)
    else:
        psi = orifice_function(ratio, index)
    return sign * area * p_up / math.sqrt(rt) * psi


#: Pressure difference [Pa] at which the power-law leak's flow is given (1 bar).
LEAK_REFERENCE = 1.0e5
#: Below this pressure difference [Pa] the power-law leak is linear in it (through the law's
#: value there): a law with n < 1 has an infinite slope at equal pressures, which would make
#: explicit integration chatter, and the flow there is negligible.
LEAK_LINEAR = 1.0e3


@njit(cache=True, error_model="numpy")
def power_leak(flow: float, exponent: float, p_a: float, p_b: float) -> float:
    """Leak mass flow [kg/s] from ``p_a`` to ``p_b`` [Pa] with a free exponent:
    q = flow sign(dp) (|dp| / 1 bar)^n, dp = p_a - p_b, ``flow`` [kg/s] the leak at 1 bar,
    ``exponent`` n in [0.5, 1] (1: laminar, 0.5: turbulent); linear in dp below
    :data:`LEAK_LINEAR`. Negative when the flow goes from b to a."""
    dp = p_a - p_b
    if flow == 0.0 or dp == 0.0:
        return 0.0
    if abs(dp) < LEAK_LINEAR:
        return flow * (LEAK_LINEAR / LEAK_REFERENCE) ** exponent * (dp / LEAK_LINEAR)
    return math.copysign(flow * (abs(dp) / LEAK_REFERENCE) ** exponent, dp)


def flow_lag_matrix(frequency: float, damping: float, h: float) -> np.ndarray:
    """The valve_lag effect's ``flow`` form over one step of ``h`` [s]: the flow q_c [kg/s]
    reaching a chamber follows the map's flow q_v through the second-order lag

        q_c'' = w^2 (q_v - q_c) - 2 zeta w q_c',   w = 2 pi ``frequency`` [Hz], zeta = ``damping``

    (the gas in a port or a line between the valve and the chamber: its inertia and its
    compressibility). Discretised exactly with q_v held over the step: a (3, 3) array whose rows
    give, from (q_c, q_c', q_v) at the start of the step, the new q_c, the new q_c' and the mean
    of q_c over the step (exact too: integrating the equation over the step,
    mean q_c = q_v - (dq_c' + 2 zeta w dq_c) / (w^2 h), d the change over the step).
    """
    w = 2.0 * math.pi * frequency
    z = np.zeros((3, 3))
    z[0, 1] = 1.0
    z[1] = (-w * w, -2.0 * damping * w, w * w)
    step = expm(z * h)
    out = np.zeros((3, 3))
    out[:2] = step[:2]
    change = step[:2] - np.eye(3)[:2]
    out[2] = np.array([0.0, 0.0, 1.0]) - (change[1] + 2.0 * damping * w * change[0]) / (w * w * h)
    return out


@njit(cache=True, error_model="numpy", inline="always")
def flow_lag_step(lag: np.ndarray, q: float, rate: float, q_v: float
                  ) -> tuple[float, float, float]:
    """One step of the flow lag (:func:`flow_lag_matrix` ``lag``) from the lagged flow ``q``
    [kg/s] and its rate ``rate`` [kg/s^2] with the map's flow ``q_v`` [kg/s] held: the mean
    lagged flow over the step, the new flow and the new rate."""
    mean = lag[2, 0] * q + lag[2, 1] * rate + lag[2, 2] * q_v
    return (mean, lag[0, 0] * q + lag[0, 1] * rate + lag[0, 2] * q_v,
            lag[1, 0] * q + lag[1, 1] * rate + lag[1, 2] * q_v)
