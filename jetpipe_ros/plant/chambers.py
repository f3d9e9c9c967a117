"""The plant's chambers: gas mass and internal energy, ISO 6358 and seal-gap leaks, wall heat
exchange.

Each chamber's gas is held as its mass m [kg] (and, with ``wall_heat_exchange``, its internal
energy U = m c_v T [J]); pressure follows from the ideal gas, p = m r T / V (isothermal) or
p = (gamma - 1) U / V, with V from Eq. 13 (:func:`volumes`: V_1 = S y + V_01, V_2 = -S y + V_02,
S the piston area [m^2], V_0i the volumes at y = 0 [m^3]). A sub-step applies,
in turn, the flows at fixed volume, the volume change of the piston's move, and the heat the
walls exchange: each part in closed form where it can be stiff. Units SI, pressures absolute.

- **Energy balance with wall heat exchange** (``wall_heat_exchange``):

      dm/dt = q_in - q_out
      dU/dt = c_p T_s q_in - c_p T q_out - p dV/dt + h_c A_w(V) (T_w - T)

  with the supply temperature T_s [K] (wall temperature T_w plus an offset), c_p = gamma r /
  (gamma - 1), c_v = r / (gamma - 1) [J/(kg K)], gamma = 1.4, the convective coefficient h_c
  [W/(m^2 K)] and the wetted wall area A_w = 2 S + P V / S [m^2] (piston face and end cap, plus
  the bore's perimeter P = 2 sqrt(pi S) along the gas column V / S, ports counted as bore): the
  conductance grows with the chamber as the piston uncovers wall. The volume change is
  isentropic over the sub-step, U' = U (V / V')^(gamma - 1), and the heat exchange exact at
  fixed mass and volume, U' = m c_v T_w + (U - m c_v T_w) exp(-h_c A_w h / (m c_v)), so a large
  h_c tends to the isothermal model. The model's candidates: a polytropic index, or one constant
  h A per chamber with the inflow at the wall temperature.
- **ISO 6358 orifice leaks** (``iso6358_leak``), across the piston and from each chamber to
  atmosphere, with sonic conductance C [m^3/(s Pa)] and critical pressure ratio b [-]:

      q = C rho_0 p_u sqrt(T_0 / T_u)                                   r = p_d / p_u <= b
      q = C rho_0 p_u sqrt(T_0 / T_u) sqrt(1 - ((r - b) / (1 - b))^2)   b < r <= 0.999
      q = linear in p_u - p_d through the value at r = 0.999           0.999 < r <= 1

  (ISO 6358-1:2013, reference air rho_0 = 1.185 kg/m^3 at T_0 = 293.15 K, p_u, T_u upstream).
  The model's candidates: laminar leaks, or an ideal-gas nozzle choked at 0.528. The laminar
  end of the law is stiff (a few 1e4 1/s at realistic C), so each leak moves, per sub-step,
  dm = q h (1 - e^-x) / x with x = K (q / dp) h and K the pressure the moved mass changes
  across the orifice per kg [Pa/kg]: exact where the flow is linear in dp, never overshooting.
- **Seal-gap leak** (``seal_gap_leak``) across the piston: a gap of width w, height delta and
  length L [m] (a scratched or worn seal) whose pressure drop is viscous (isothermal
  compressible flow between plates) plus an entrance and exit loss of zeta dynamic heads:

      dp = a q + b q^2,   a = 12 mu L / (rho_m w delta^3),   b = zeta / (2 rho_m (w delta)^2)

  with rho_m = (p_a + p_b) / (2 r T_u) the mean density [kg/m^3] and mu = 1.84e-5 Pa s, so
  q = 2 dp / (a + sqrt(a^2 + 4 b dp)): laminar at small dp, turbulent (q ~ sqrt(rho dp)) at
  large, the mean pressure in both. Moved per sub-step as the ISO 6358 leaks are. The model's
  candidates: laminar, orifice, or a power of dp alone.
"""

from __future__ import annotations

import math

from numba import njit

from jetpipe_ros.plant.air import GAMMA_AIR

#: ISO 6358 reference atmosphere (ISO 8778): density [kg/m^3] and temperature [K].
RHO_REF = 1.185
T_REF = 293.15
#: Pressure ratio above which ISO 6358-1:2013 takes the flow as laminar (linear in dp).
LAMINAR_RATIO = 0.999
#: Dynamic viscosity of air at 25 degC [Pa s].
AIR_VISCOSITY = 1.84e-5


@njit(cache=True, error_model="numpy")
def volumes(y: float, area: float, v01: float, v02: float) -> tuple[float, float]:
    """Eq. 13: the chambers' volumes [m^3] with the piston at ``y`` [m] (positive enlarges
    chamber 1), piston area ``area`` [m^2], volumes ``v01``, ``v02`` [m^3] at y = 0."""
    return v01 + area * y, v02 - area * y


@njit(cache=True, error_model="numpy")
def iso6358_flow(conductance: float, critical: float, p_up: float, p_down: float,
                 t_up: float) -> float:
    """ISO 6358 mass flow [kg/s] from ``p_up`` to ``p_down`` [Pa] through sonic conductance
    ``conductance`` [m^3/(s Pa)] with critical ratio ``critical``, upstream gas at ``t_up`` [K];
    ``p_up`` >= ``p_down`` (module docstring)."""
    ratio = p_down / p_up
    choked = conductance * RHO_REF * p_up * math.sqrt(T_REF / t_up)
    if ratio <= critical:
        return choked
    if ratio <= LAMINAR_RATIO:
        x = (ratio - critical) / (1.0 - critical)
        return choked * math.sqrt(1.0 - x * x)
    x = (LAMINAR_RATIO - critical) / (1.0 - critical)
    return choked * math.sqrt(1.0 - x * x) * (1.0 - ratio) / (1.0 - LAMINAR_RATIO)


@njit(cache=True, error_model="numpy")
def leak_mass(conductance: float, critical: float, p_a: float, p_b: float, t_a: float,
              t_b: float, stiffness: float, h: float) -> float:
    """Mass [kg] an ISO 6358 leak moves from side a to side b over a sub-step ``h`` [s]
    (negative from b to a): q h (1 - e^-x) / x with x = ``stiffness`` (q / |p_a - p_b|) h,
    ``stiffness`` [Pa/kg] the pressure difference one kg moved removes (module docstring)."""
    if conductance == 0.0 or p_a == p_b:
        return 0.0
    if p_a > p_b:
        q = iso6358_flow(conductance, critical, p_a, p_b, t_a)
    else:
        q = -iso6358_flow(conductance, critical, p_b, p_a, t_b)
    return _moved(q, abs(p_a - p_b), stiffness, h)


@njit(cache=True, error_model="numpy")
def _moved(q: float, dp: float, stiffness: float, h: float) -> float:
    """Mass [kg] a leak of flow ``q`` [kg/s] at pressure difference ``dp`` > 0 [Pa] moves over
    ``h`` [s]: q h (1 - e^-x) / x, x = ``stiffness`` [Pa/kg] (q / dp) h."""
    x = stiffness * abs(q) / dp * h
    if x < 1e-9:
        return q * h
    return q * h * (1.0 - math.exp(-x)) / x


@njit(cache=True, error_model="numpy")
def gap_flow(width: float, height: float, length: float, loss: float, p_a: float, p_b: float,
             rt_up: float) -> float:
    """Mass flow [kg/s] from ``p_a`` to ``p_b`` [Pa] through a seal gap of ``width``,
    ``height`` and ``length`` [m] with loss coefficient ``loss`` [-], ``rt_up`` = r T of the
    upstream gas [J/kg] (module docstring); negative from b to a."""
    dp = abs(p_a - p_b)
    if width == 0.0 or dp == 0.0:
        return 0.0
    rho = 0.5 * (p_a + p_b) / rt_up
    a = 12.0 * AIR_VISCOSITY * length / (rho * width * height ** 3)
    b = loss / (2.0 * rho * (width * height) ** 2)
    q = 2.0 * dp / (a + math.sqrt(a * a + 4.0 * b * dp))
    return q if p_a > p_b else -q


@njit(cache=True, error_model="numpy")
def gap_leak_mass(width: float, height: float, length: float, loss: float, p_a: float,
                  p_b: float, rt_up: float, stiffness: float, h: float) -> float:
    """Mass [kg] a seal-gap leak moves from side a to side b over a sub-step ``h`` [s], as
    :func:`leak_mass` moves an ISO 6358 leak's."""
    if width == 0.0 or p_a == p_b:
        return 0.0
    return _moved(gap_flow(width, height, length, loss, p_a, p_b, rt_up), abs(p_a - p_b),
                  stiffness, h)


@njit(cache=True, error_model="numpy")
def wetted_area(volume: float, area: float) -> float:
    """Wall area [m^2] the gas of a chamber of ``volume`` [m^3] touches: piston face and end cap
    2 S plus the bore's perimeter 2 sqrt(pi S) along the gas column ``volume`` / S."""
    return 2.0 * area + 2.0 * math.sqrt(math.pi * area) * volume / area


@njit(cache=True, error_model="numpy")
def exchange_heat(energy: float, mass: float, volume: float, area: float, coefficient: float,
                  t_wall: float, cv: float, h: float) -> float:
    """Internal energy [J] after ``h`` [s] of exact heat exchange with the wall at ``t_wall``
    [K] at fixed mass [kg] and volume [m^3]; ``coefficient`` h_c [W/(m^2 K)], ``cv`` [J/(kg K)].
    """
    settled = mass * cv * t_wall
    rate = coefficient * wetted_area(volume, area) / (mass * cv)
    return settled + (energy - settled) * math.exp(-rate * h)


@njit(cache=True, error_model="numpy")
def isentropic_energy(energy: float, volume_before: float, volume_after: float) -> float:
    """Internal energy [J] after an isentropic volume change (p V^gamma constant)."""
    return energy * (volume_before / volume_after) ** (GAMMA_AIR - 1.0)
