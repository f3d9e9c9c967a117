"""What lies between the plant's valve and each chamber: a port volume behind a porous filter
(``flow_lag``) and a pneumatic line with distributed dynamics (``transport_delay``).

Both are written here apart from the model's candidate forms (a lag of the map's flow, a pure
delay of flow and pressure): neither is a delay or a linear lag of a flow; each fills and
empties by its own flow law. Units SI, pressures absolute, gas at the wall temperature T [K],
r [J/(kg K)] the gas constant.

- **Port volume behind a filter** (``flow_lag``): the valve discharges into a port volume V_p
  [m^3] (valve body, manifold, fittings), isothermal, from which a porous element (a sintered
  filter) passes gas to the chamber by isothermal compressible Darcy flow,

      V_p / (r T) dp_p/dt = q(u_eq, p_p) - q_f,   q_f = K (p_p^2 - p_d^2) / (2 r T),

  q the valve's map read at the port's pressure p_p, p_d the pressure downstream (the chamber,
  or the line's first node when a line is on too), K [m^3/(s Pa)] the filter's conductance
  (q_f = K rho_m (p_p - p_d), rho_m the mean density). A nonlinear first-order lag: linearised
  at rest at pressure p, dp_p/dt = -(G + K_v) / C_p dp_p + ..., with C_p = V_p / (r T)
  [kg/Pa], the filter's G = K p / (r T) [kg/(s Pa)] and the valve's K_v = -dq/dp [kg/(s Pa)];
  its time constant

      tau = V_p / (K p + r T K_v)

  shortens as the pressure rises, and a flow through it leaves a drop q_f / G across it.
- **Pneumatic line** (``transport_delay``): a tube of length L [m] and bore d [m] (area
  A = pi d^2 / 4) from the valve's port to the chamber, in N_SEGMENTS lumped segments of
  length l_s = L / N: node k (k = 0 at the valve) holds a volume V_s = A l_s (half of it at
  node 0; the far half-segment lies in the chamber), the gas in it adiabatic (acoustic waves
  are faster than the wall's heat), and each segment's mass flow w_k [kg/s] from node k to
  node k + 1 (node N the chamber) has the air's inertance l_s / A and wall friction:

      V_k / (gamma r T) dp_k/dt = w_(k-1) - w_k        (w_(-1) = the valve's flow)
      (l_s / A) dw_k/dt = p_k - p_(k+1) - f (l_s / d) w_k |w_k| / (2 rho A^2)

  with rho the segment's mean density, the Darcy factor f = max(64 / Re, 0.3164 Re^-0.25)
  (Hagen-Poiseuille laminar, Blasius turbulent), Re = |w| d / (A mu). Waves travel at
  c = sqrt(gamma r T) (346 m/s at 25 degC): a step of flow reaches the chamber L / c late and
  rings at the quarter-wave frequency c / (4 L) (the valve's end nearly closed, the chamber's
  open), (2 c N / L) sin(pi / (4 N)) / (2 pi) for the lumped chain (within 0.2 % at N = 8);
  friction damps it and drops pressure with the flow; the line's volume adds to the chamber's.

Time steps: each plant sub-step is split into ``steps`` equal inner steps (:func:`inner_steps`);
the line advances by the symplectic Euler rule (the nodes' pressures from the flows, then the
flows from the new pressures, friction implicit), stable while the chain's highest frequency
times the step stays under 2 (held under 0.5); the port by Heun's rule.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Segments of each line.
N_SEGMENTS = 8
#: Dynamic viscosity of air at 25 degC [Pa s].
VISCOSITY = 1.84e-5
#: Largest product of the line chain's highest frequency [rad/s] and the inner step [s].
LINE_STEP_LIMIT = 0.5
#: Largest product of the port's rate (G + K_v) / C_p [1/s] and the inner step [s].
PORT_STEP_LIMIT = 0.1


def inner_steps(h: float, line_length: float, wave_speed: float, port_rate: float) -> int:
    """Inner steps per sub-step ``h`` [s]: enough for a line of ``line_length`` [m] (0: none)
    with waves at ``wave_speed`` [m/s] (the half-volume node's frequency, 2 sqrt(2) c N / L
    [rad/s], times the step under :data:`LINE_STEP_LIMIT`) and for a port whose fastest rate
    is ``port_rate`` [1/s] (0: none; times the step under :data:`PORT_STEP_LIMIT`)."""
    steps = 1
    if line_length > 0.0:
        top = 2.0 * math.sqrt(2.0) * wave_speed * N_SEGMENTS / line_length
        steps = max(steps, math.ceil(top * h / LINE_STEP_LIMIT))
    if port_rate > 0.0:
        steps = max(steps, math.ceil(port_rate * h / PORT_STEP_LIMIT))
    return int(steps)


@njit(cache=True, error_model="numpy")
def filter_flow(conductance: float, p_up: float, p_down: float, rt: float) -> float:
    """Mass flow [kg/s] through a porous filter of ``conductance`` K [m^3/(s Pa)] from
    ``p_up`` to ``p_down`` [Pa] (negative backwards), isothermal Darcy flow, ``rt`` = r T
    [J/kg]: K (p_up^2 - p_down^2) / (2 r T)."""
    return conductance * (p_up * p_up - p_down * p_down) / (2.0 * rt)


@njit(cache=True, error_model="numpy")
def friction_resistance(w: float, p_a: float, p_b: float, bore: float, area: float,
                        length: float, rt: float) -> float:
    """R [1/(m s)] with the wall's pressure drop R w [Pa] for a segment of ``length`` [m],
    ``bore`` [m] and ``area`` [m^2] carrying ``w`` [kg/s] between ``p_a`` and ``p_b`` [Pa]:
    f (l / d) |w| / (2 rho A^2), f = max(64 / Re, 0.3164 Re^-0.25) (module docstring)."""
    rho = 0.5 * (p_a + p_b) / rt
    laminar = 32.0 * VISCOSITY * length / (rho * bore * bore * area)  # 64 / Re of the above
    reynolds = abs(w) * bore / (area * VISCOSITY)
    if reynolds < 1.0:
        return laminar
    return max(laminar, 0.3164 * reynolds ** -0.25 * length * abs(w)
               / (2.0 * rho * bore * area * area))


@njit(cache=True, error_model="numpy")
def line_step(x: np.ndarray, base: int, q_in: float, p_end: float, wave: float,
              inertance: float, bore: float, area: float, length: float, rt: float,
              dt: float) -> float:
    """Advance one line by ``dt`` [s] (symplectic Euler, friction implicit); its node pressures
    [Pa] at ``x[base:base + N]``, segment flows [kg/s] at ``x[base + N:base + 2 N]``.
    ``q_in`` [kg/s] enters node 0 (the valve's side), ``p_end`` [Pa] is the chamber's;
    ``wave`` = gamma r T / V_s [Pa/kg] (node 0 has half V_s), ``inertance`` = l_s / A [1/m],
    ``length`` = l_s. Returns the flow delivered to the chamber over the step [kg/s] (the
    last segment's flow the nodes were advanced with: every kg leaving the valve arrives)."""
    n = N_SEGMENTS
    f = base + n
    delivered = x[f + n - 1]
    x[base] += dt * 2.0 * wave * (q_in - x[f])
    for k in range(1, n):
        x[base + k] += dt * wave * (x[f + k - 1] - x[f + k])
    for k in range(n):
        p_a = x[base + k]
        p_b = x[base + k + 1] if k < n - 1 else p_end
        w = x[f + k]
        r = friction_resistance(w, p_a, p_b, bore, area, length, rt)
        x[f + k] = (w + dt / inertance * (p_a - p_b)) / (1.0 + dt / inertance * r)
    return delivered
