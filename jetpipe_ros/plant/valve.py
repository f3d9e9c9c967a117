"""The plant's servo valve: its own chain and flow map (the paper's equations evaluated by this
module's code, not the model's), and its real effects.

Signal path per sub-step of length h::

    u [V] -> clip -> delay tau (continuous) -> torque motor and jet pipe (Eq. 4) -> lead-lag
          (Eq. 9) -> weighted plays -> u_eq = clip(g u_h + u_0, -2.8, 3.0) -> flow map (Eq. 8)
          q(u_eq, p; p_s) with gain (1 + k ...) -> port volume and filter -> line -> chamber

- **Torque motor and jet pipe** (Eq. 4, Table 1, integrated in the physical states of its
  derivation): the coil current i [A], the rotor's rate w [rad/s] and angle theta [rad],

      L di/dt = u_d - R i - K_b w,   J dw/dt = K_t i - K_f w - K_s theta,   dtheta/dt = w,

  whose angle over the command is Eq. 4 divided by the jet-pipe length r. The equivalent voltage
  of the jet pipe is its angle at unit DC gain, u_jp = theta R K_s / K_t [V].
- **Lead-lag** (Eq. 9): (1 + s / w_z) / (1 + s / w_p) = w_p / w_z + (1 - w_p / w_z) / (1 + s /
  w_p), so u_f = (w_p / w_z) u_jp + (1 - w_p / w_z) l with dl/dt = w_p (u_jp - l).
- **Delay** (Eq. 10, ``valve.delay``): u_d(t) = u(t - tau) with the command held over each
  sample; a sub-step inside which the delayed command switches is integrated in two parts, up to
  the switch and after it. The four states advance by the classical Runge-Kutta rule in
  ``valve_steps`` steps per sub-step (the coil's pole R / L = 1.2e4 1/s sets the step: at 4
  steps per 125 us, |lambda h| = 0.38, well inside RK4's stability and accurate to ~1e-5 of a
  step's change). The model instead discretises the chain exactly.
- **Midpoint limits** (Eq. 5): the jet pipe saturates at +-1 mm, where Eq. 5's outer lines give
  u = -5 (1 - 1) - 2.8 = -2.8 V and u = -5.475 (-1 + 1) + 3 = 3.0 V: u_eq is clipped to them.
- **Flow map** (Eq. 8, its 21 coefficients typed below from the paper's text, in g/s for u in V
  and p in bar, summed term by term): p clamped to [1, 10] bar, no outflow from a chamber at or
  below atmospheric pressure, an individual valve's factor per direction (``flow.gain_charge``
  where it fills, ``flow.gain_discharge`` where it empties).
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
- **Flow map of another shape** (``flow_map_shape``, a bench's property, in no case cycle:
  ``jetpipe selfcheck --flow-map-shape``): a real valve's map departs from the fifth-order fit
  by up to its error, about 0.5 g/s at most (the paper, Sec. 2.3). Added to Eq. 8 before the
  direction factors, a smooth departure that keeps the nulls at u = 0,

      dq(u, p) = A sin(pi u / 2.9 V) cos(2 pi (p - 1 bar) / 9 bar + phi)   [kg/s],

  A [kg/s] at most 5e-4, phi [rad]; its RMS over the map's range is about A / 2.
- **What lies between the valve and each chamber** (``flow_lag``: a port volume behind a
  filter; ``transport_delay``: a pneumatic line with distributed dynamics): in
  :mod:`passages`, the map read at the port's pressure.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from jetpipe_ros.plant.air import P_ATM, P_SUPPLY

#: Eq. 8 as printed (u [V], p [bar], g/s): coefficient of u^i p^j at EQ8[i, j].
EQ8 = np.zeros((6, 6))
for (_i, _j), _c in {
        (0, 0): 3.562, (1, 0): 1.233, (0, 1): -2.037, (2, 0): 0.1701, (1, 1): -0.7901,
        (0, 2): 0.6697, (3, 0): 0.1335, (2, 1): -0.1801, (1, 2): 0.3379, (0, 3): -0.1243,
        (4, 0): 0.01195, (3, 1): -0.01784, (2, 2): 0.03335, (1, 3): -0.0413, (0, 4): 0.008227,
        (5, 0): -0.007284, (4, 1): -0.0005998, (3, 2): 0.0003319, (2, 3): -0.001838,
        (1, 4): 0.001729, (0, 5): -0.0001519}.items():
    EQ8[_i, _j] = _c
#: Eq. 8's terms in the order the paper prints them (u^i p^j as (i, j)): by degree, u first.
PAPER_TERMS = tuple((degree - j, j) for degree in range(6) for j in range(degree + 1))
#: The map's pressure range [bar]: where the paper identified it.
MAP_P_MIN, MAP_P_MAX = 1.0, 10.0
#: Equivalent-voltage limits [V]: Eq. 5 at the jet pipe's +-1 mm (module docstring).
U_EQ_LOW, U_EQ_HIGH = -5.0 * (1.0 - 1.0) - 2.8, -5.475 * (-1.0 + 1.0) + 3.0
#: Runge-Kutta steps of the valve chain per plant sub-step.
VALVE_STEPS = 4


@njit(cache=True, error_model="numpy")
def jet_flow(u: float, p_bar: float) -> float:
    """Eq. 8: mass flow [kg/s] at equivalent voltage ``u`` [V] and pressure ``p_bar`` [bar],
    summed term by term over :data:`EQ8`."""
    g = 0.0
    ui = 1.0
    for i in range(6):
        pj = 1.0
        for j in range(6 - i):
            g += EQ8[i, j] * ui * pj
            pj *= p_bar
        ui *= u
    return g / 1000.0


@njit(cache=True, error_model="numpy")
def valve_inflow(u_eq: float, p: float, p_supply: float, gain_charge: float,
                 gain_discharge: float, gain_slope: float, shape: float = 0.0,
                 shape_phase: float = 0.0) -> float:
    """Mass flow [kg/s] into a chamber at ``p`` [Pa] for equivalent voltage ``u_eq`` [V] from a
    supply at ``p_supply`` [Pa]: Eq. 8 (plus a departure of amplitude ``shape`` [kg/s] and
    phase ``shape_phase`` [rad]) by similarity in absolute pressure, the factor of its
    direction, times 1 + ``gain_slope`` (p - p_mid) / p_s (module docstring)."""
    s = p_supply / P_SUPPLY
    p_bar = min(max(p / s * 1e-5, MAP_P_MIN), MAP_P_MAX)
    q = jet_flow(u_eq, p_bar)
    if shape != 0.0:
        q += shape * math.sin(math.pi * u_eq / 2.9) * \
            math.cos(2.0 * math.pi * (p_bar - 1.0) / 9.0 + shape_phase)
    q *= s
    if q < 0.0:
        q = 0.0 if p <= P_ATM else gain_discharge * q
    else:
        q *= gain_charge
    if gain_slope != 0.0:
        q *= 1.0 + gain_slope * (p - 0.5 * (p_supply + P_ATM)) / p_supply
    return q


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def _rates(m: np.ndarray, x0: float, x1: float, x2: float, x3: float, u: float
           ) -> tuple[float, float, float, float]:
    """Time derivatives of (i, w, theta, l) under delayed command ``u`` [V]; ``m`` holds
    (R, L, K_t, K_b, J, K_f, K_s, w_p) (module docstring)."""
    u_jp = x2 * m[0] * m[6] / m[2]
    return ((u - m[0] * x0 - m[3] * x1) / m[1],
            (m[2] * x0 - m[5] * x1 - m[6] * x2) / m[4],
            x1,
            m[7] * (u_jp - x3))


@njit(cache=True, error_model="numpy")
def chain_rk4(m: np.ndarray, x: np.ndarray, u: float, span: float, steps: int) -> None:
    """Advance the chain's states ``x`` = (i, w, theta, l) in place over ``span`` [s] with the
    delayed command ``u`` [V] held, in ``steps`` classical Runge-Kutta steps."""
    h = span / steps
    x0, x1, x2, x3 = x[0], x[1], x[2], x[3]
    for _ in range(steps):
        a0, a1, a2, a3 = _rates(m, x0, x1, x2, x3, u)
        b0, b1, b2, b3 = _rates(m, x0 + 0.5 * h * a0, x1 + 0.5 * h * a1, x2 + 0.5 * h * a2,
                                x3 + 0.5 * h * a3, u)
        c0, c1, c2, c3 = _rates(m, x0 + 0.5 * h * b0, x1 + 0.5 * h * b1, x2 + 0.5 * h * b2,
                                x3 + 0.5 * h * b3, u)
        d0, d1, d2, d3 = _rates(m, x0 + h * c0, x1 + h * c1, x2 + h * c2, x3 + h * c3, u)
        x0 += h / 6.0 * (a0 + 2.0 * b0 + 2.0 * c0 + d0)
        x1 += h / 6.0 * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
        x2 += h / 6.0 * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
        x3 += h / 6.0 * (a3 + 2.0 * b3 + 2.0 * c3 + d3)
    x[0], x[1], x[2], x[3] = x0, x1, x2, x3


@njit(cache=True, error_model="numpy")
def chain_output(m: np.ndarray, lead: float, x: np.ndarray) -> float:
    """u_f [V]: the lead-lag's output (module docstring); ``lead`` = w_p / w_z."""
    u_jp = x[2] * m[0] * m[6] / m[2]
    return lead * u_jp + (1.0 - lead) * x[3]


@njit(cache=True, error_model="numpy")
def chain_substep(m: np.ndarray, x: np.ndarray, ring: np.ndarray, head: int, j: int,
                  substeps: int, delay: float, h: float, steps: int) -> None:
    """Advance the chain one sub-step: sub-step ``j`` of the sample whose command is at
    ``ring[head]`` (one command per sample, older ones behind it), delayed by ``delay``
    samples; a switch of the delayed command inside the sub-step splits it (module
    docstring)."""
    n = ring.shape[0]
    start = j / substeps - delay  # in samples from the current sample's start
    back = math.floor(start + 1e-9)
    u_a = ring[(head + back + n) % n]
    split = (back + 1 - start) * substeps  # where in the sub-step the next command arrives
    if split >= 1.0 - 1e-9:
        chain_rk4(m, x, u_a, h, steps)
        return
    u_b = ring[(head + back + 1 + n) % n]
    first = max(1, int(math.ceil(split * steps)))
    chain_rk4(m, x, u_a, split * h, first)
    chain_rk4(m, x, u_b, (1.0 - split) * h, max(1, steps - first + 1))


def chain_parameters(p) -> tuple[np.ndarray, float]:
    """(R, L, K_t, K_b, J, K_f, K_s, w_p) and w_p / w_z of model parameters ``p``, SI units
    (Table 1, Eq. 9)."""
    m = np.array([p["valve.coil_resistance"], p["valve.coil_inductance"],
                  p["valve.torque_constant"], p["valve.back_emf_constant"],
                  p["valve.rotor_inertia"], p["valve.friction_coefficient"],
                  p["valve.magnetic_stiffness"], p["valve.lag_pole"]], dtype=float)
    return m, p["valve.lag_pole"] / p["valve.lag_zero"]
