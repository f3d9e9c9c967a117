"""The plant's servo valve: the pinned chain behind a continuous delay, and its real effects.

Signal path per sub-step of length h (the pinned parts from :mod:`jetpipe_ros.model.valve` and
:mod:`jetpipe_ros.model.flow`, the rest this module's own)::

    u [V] -> clip -> delay tau (continuous) -> chain (exact) -> 2nd-order lag -> weighted plays
          -> u_eq = clip(g u_h + u_0, -2.8, 3.0) -> flow q(u_eq, p; p_s) with gain (1 + k ...)

- **Continuous transport delay** (``transport_delay``: the valve's own 2 ms plus ``delay``
  [s]): tau = (m + theta) h with m whole sub-steps and 0 <= theta < 1. The command is constant
  over each sub-step, so over sub-step j the delayed command is u_{j-m-1} for the first theta h
  and u_{j-m} for the rest, and the chain x' = A x + B u_d is advanced exactly:

      x_{j+1} = e^{Ah} x_j + e^{A(1-theta)h} Gamma(theta h) u_{j-m-1} + Gamma((1-theta)h) u_{j-m}

  with Gamma(s) = int_0^s e^{Ar} dr B, both taken from the pinned ``discretise_valve`` at the
  steps theta h and (1 - theta) h. The model instead rounds its delay to whole sub-steps.
- **Second-order lag** (``second_order_lag``): u_l'' = w_n^2 (u_f - u_l) - 2 zeta w_n u_l' on the
  chain's output (w_n = 2 pi f_n [rad/s], zeta [-]), discretised exactly (zero-order hold on
  u_f at the sub-step) with a matrix exponential. The model's candidate is a first-order lag.
- **Weighted play hysteresis** (``weighted_play_hysteresis``): three play operators
  P_i: z_i = min(max(z_i, u - r_i), u + r_i) with thresholds r_i [V] and weights w_i > 0,
  u_h = sum_i w_i z_i / sum_i w_i. A large loop's half-width is sum w_i r_i / sum w_i; a loop of
  amplitude A shows only the plays with r_i < A (each with vertical width 2 min(r_i, A - r_i) at
  the centre). The model's candidate spreads equal weights evenly around one half-width.
- **Null offset** (``null_offset``, on no list): u_eq = clip(g u_h + u_0) [V], a torque motor
  whose magnetic null is off by u_0: at 0 V each chamber settles at the null of Eq. 8 at +-u_0.
- **Supply through a drooping regulator and a hose** (``supply_droop``): the regulator's outlet
  p_r [Pa] follows its droop curve, set pressure p_set less R Q_h + S Q_h |Q_h| for the flow
  Q_h [kg/s] it delivers (R [Pa s/kg], S [Pa s^2/kg^2]: the droop steepens with flow), with
  its diaphragm's lag, tau_r dp_r/dt = p_set - R Q_h - S Q_h |Q_h| - p_r; the hose, of
  conductance G_h [kg/(s Pa)] and volume V_h [m^3], carries Q_h = G_h (p_r - p_s) to the
  valve, which draws Q = sum max(q_i, 0) [kg/s] to fill the chambers (from the previous
  sub-step): V_h dp_s/dt = r T (Q_h - Q). Each of the two states advances exactly over the
  sub-step with the other held. The flow map follows the supply by similarity in absolute
  pressure (choked jet flow and receiver recovery both scale with p_s): q(u, p; p_s) =
  s q_8(u, p / s) with s = p_s / 10 bar and no outflow at or below atmospheric pressure. The
  model's candidates: a constant supply, or one line (a linear conductance and a volume) fed
  from a constant set pressure, the flow map mapped affinely over [p_atm, p_s].
- **Pressure-dependent valve gain** (``pressure_dependent_gain``, on no list): the flow into a
  chamber at pressure p is scaled by 1 + k (p - p_mid) / p_s with p_mid = (p_s + p_atm) / 2
  (k [-]): the jet's recovery depends on the back pressure more than Eq. 8's fit says. The nulls
  of Eq. 8 stay; the flow around them grows or shrinks with the chamber pressure.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from jetpipe_ros.model.flow import P_ATM, P_SUPPLY_NOMINAL, chamber_inflow
from jetpipe_ros.model.valve import discretise_valve


@dataclass(frozen=True)
class DelayedChain:
    """The pinned valve chain advanced exactly behind a continuous delay (module docstring)."""

    a: np.ndarray  #: e^{Ah} (n, n)
    b_early: np.ndarray  #: e^{A(1-theta)h} Gamma(theta h) (n,): weight of u_{j-m-1}
    b_late: np.ndarray  #: Gamma((1-theta)h) (n,): weight of u_{j-m}
    c: np.ndarray  #: output row (n,)
    whole: int  #: m, whole sub-steps of the delay
    fraction: float  #: theta in [0, 1)


def delayed_chain(p: Mapping[str, Any], h: float, delay: float) -> DelayedChain:
    """The valve chain of parameters ``p`` at sub-step ``h`` [s] behind ``delay`` [s] in total."""
    steps = delay / h
    whole = int(np.floor(steps + 1e-9))
    fraction = max(steps - whole, 0.0)
    if fraction < 1e-9:
        fraction = 0.0
    full = discretise_valve(p, h)
    if full.d != 0.0:
        raise ValueError("the valve chain must be strictly proper (no feed-through)")
    if fraction == 0.0:
        b_early = np.zeros_like(full.b)
        b_late = full.b
    else:
        early = discretise_valve(p, fraction * h)
        late = discretise_valve(p, (1.0 - fraction) * h)
        b_early = late.a @ early.b
        b_late = late.b
    return DelayedChain(full.a, np.ascontiguousarray(b_early), np.ascontiguousarray(b_late),
                        full.c, whole, fraction)


@njit(cache=True, error_model="numpy", inline="always")
def weighted_plays(plays: np.ndarray, thresholds: np.ndarray, weights: np.ndarray,
                   u: float) -> float:
    """Advance the play operators ``plays`` [V] (in place) with input ``u`` [V]; return the
    weighted mean of their outputs [V] (``weights`` sum to 1)."""
    acc = 0.0
    for i in range(thresholds.shape[0]):
        r = thresholds[i]
        plays[i] = min(max(plays[i], u - r), u + r)
        acc += weights[i] * plays[i]
    return acc


@njit(cache=True, error_model="numpy", inline="always")
def valve_inflow(coef: np.ndarray, u_eq: float, p: float, p_supply: float, gain_charge: float,
                 gain_discharge: float, gain_slope: float) -> float:
    """Mass flow [kg/s] into a chamber at ``p`` [Pa] for equivalent voltage ``u_eq`` [V] from a
    supply at ``p_supply`` [Pa]: Eq. 8 (``chamber_inflow`` at the nominal supply) by similarity
    in absolute pressure, times 1 + ``gain_slope`` (p - p_mid) / p_s (module docstring)."""
    if p_supply == P_SUPPLY_NOMINAL:
        q = chamber_inflow(coef, u_eq, p, P_SUPPLY_NOMINAL, gain_charge, gain_discharge)
    else:
        s = p_supply / P_SUPPLY_NOMINAL
        q = s * chamber_inflow(coef, u_eq, p / s, P_SUPPLY_NOMINAL, gain_charge, gain_discharge)
        if q < 0.0 and p <= P_ATM:
            q = 0.0
    if gain_slope != 0.0:
        q *= 1.0 + gain_slope * (p - 0.5 * (p_supply + P_ATM)) / p_supply
    return q
