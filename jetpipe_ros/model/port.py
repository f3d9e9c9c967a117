"""A port volume behind a restriction before each chamber: the valve_lag effect's ``port`` form.

Real benches put a volume between the valve and each chamber (the valve body's drilling, a
manifold, a fitting) and a restriction between that volume and the chamber (a filter, a
push-in fitting, a narrow port). The valve's map reads the port's pressure p_p [Pa]; the port
discharges into the chamber at p_c [Pa] through the restriction:

    V_p / (gamma r T) dp_p/dt = q(u_eq, p_p) - w,     w = w(p_p, p_c)

- **The restriction: ISO 6358 and Darcy**, as pneumatic catalogues describe filters and
  fittings: a sonic conductance C [m^3/(s Pa)] (choked flow C rho_0 p_up, at the standard
  reference atmosphere rho_0 = 1.185 kg/m^3, T_0 = 293.15 K of ISO 8778), a critical pressure
  ratio b and, since ISO 6358-1:2013, a subsonic index m: w = C rho_0 p_up
  [1 - ((r - b) / (1 - b))^2]^m below choking, r = p_down / p_up. The flow function is the
  model's one compressible orifice's
  (:func:`~jetpipe_ros.model.flow.orifice_function`, the leakage effect's): with Psi its value
  and Psi* = 0.685 choked, w = A_e p_up / sqrt(r T) Psi* (Psi(r) / Psi*)^(2 m)
  (:func:`~jetpipe_ros.model.flow.orifice_flow` with the index), the effective area
  A_e = C rho_0 sqrt(r T_0) / Psi* giving ISO 6358's choked flow (:func:`effective_area`).
  (Psi / Psi*)^2 and ISO's ellipse with b = 0.528 agree within 1 % at every ratio, so this is ISO
  6358 with b = 0.528 and m free; at m = 0.5 it is the orifice of the leakage effect. b is not a
  knob: catalogues give 0.2-0.5 for filters, but at the drops a port passes in use (a few % of the
  pressure) the law goes as (2 (1 - r) / (1 - b))^m, in which b only scales C; a free b would be a
  knob the records cannot tell from C. m is: 0.5 is an orifice or a fitting (the drop grows as the
  flow squared); a porous element (a sintered filter) passes gas by laminar flow through its
  pores, and a gas's density follows its pressure, so its law is Darcy's compressible one,
  w = K (p_up^2 - p_down^2) / (2 r T): linear in the drop, its conductance growing with the mean
  pressure. ISO's law at m = 1 is linear in the drop at a conductance that does not (at b = 0
  it is C rho_0 (p_up^2 - p_down^2) / p_up), so the law here is ISO's times
  (p_mean / p_0)^(2 m - 1), p_mean the mean of the two pressures and p_0 = 4.1648 bar where the
  chambers rest (:data:`POROUS_REFERENCE`): the orifice at m = 0.5, Darcy's law near equal
  pressures at m = 1 (conductance in proportion to p_mean), C the sonic conductance the element
  has at rest for any m. (A port of the self-check's plant, 40 cm^3 behind such a filter, was
  fitted with 2.0 % of the held-out gap left and confidence 0.15 by the ISO law, whose m went to
  0.5; with this one m went to 1 and 0.83 % was left, confidence 0.74.) Within 0.5 % of equal
  pressures the law is linear in the drop (the orifice's own rule), its conductance there G_0
  (:func:`small_drop_conductance`, at p_0): 34.2 C kg/(s Pa) at m = 0.5 and 25 degC, 5.0 C at
  m = 1.
- **Gas of the port: adiabatic.** Heat crosses a passage of diameter d in about d^2 / (4 alpha)
  (alpha = 2e-5 m^2/s at 1 bar, less at higher density): 0.3 s for 5 mm at 1 bar, over 1 s at
  5 bar, slower than the campaign's signals (as the hose's gas, :mod:`hose`); the port's
  compliance is V_p / (gamma r T) and at low frequency it shows as a dead volume V_p n / gamma.
- **Time constant.** Linearised (chamber large, map's slope K_v = -dq/dp_p):
  tau = V_p / (gamma r T (G + K_v)), G the restriction's slope at the flow it passes
  (G_0 at rest): 40 cm^3 behind C = 3e-9 m^3/(s Pa) (0.3 dm^3/(s bar), a push-in fitting)
  at m = 0.5 gives 3.0 ms at rest, 18 ms passing 1 g/s (its drop then 0.46 bar).

Integration (:func:`port_step`, one sub-step): the port and its chamber together by the linearly
implicit theta rule, the map's slope and the restriction's slopes frozen over the step (the slope in
p_c by a finite difference, that in p_p from it by Euler's identity for a law homogeneous of degree
1 in the two pressures), theta = max(1/2, 1 - 1/x), x = h (gamma r T / V_p (G + K_v) + g_c G) the
sum of the two modes' rates times the step (g_c the chamber's pressure rate per inflow): the
trapezoid (second order, no numerical damping) while x <= 2, i.e. down to a port of an eighth of a
sample at 4 sub-steps; above, theta rises continuously so that no mode changes sign over a step (a
port much faster than the step relaxes to its quasi-steady pressure instead of ringing), as a fit
that tries a tiny volume behind a wide restriction needs. Mass is conserved: what the port gains is
what the valve sent less what the chamber received over the step.
"""

from __future__ import annotations

import math

from numba import njit

from jetpipe_ros.model.flow import CHOKED, LINEAR_RATIO, orifice_flow, orifice_function

#: Density [kg/m^3] and temperature [K] of the standard reference atmosphere (ISO 8778) in
#: which ISO 6358 gives the sonic conductance.
RHO_0 = 1.185
T_0 = 293.15
#: Mean pressure [Pa] at which the restriction passes, at any index m, what ISO 6358's law of
#: the same C and m passes: 4.1648 bar, where both chambers rest with the valve at its null (the
#: model's initial state), so the time constants "at rest" hold for every m.
POROUS_REFERENCE = 4.1648e5
#: Pressure step [Pa] of the finite difference giving the restriction's slope in p_c.
SLOPE_STEP = 10.0


def effective_area(conductance: float, r_gas: float) -> float:
    """Effective area A_e [m^2] of the model's orifice law with the choked flow of ISO 6358's
    sonic ``conductance`` C [m^3/(s Pa)], gas constant ``r_gas`` [J/(kg K)]:
    C rho_0 sqrt(r T_0) / Psi* (module docstring)."""
    return conductance * RHO_0 * math.sqrt(r_gas * T_0) / CHOKED


def small_drop_conductance(area: float, index: float, rt: float) -> float:
    """Slope [kg/(s Pa)] of the restriction of effective ``area`` [m^2] and subsonic ``index``
    within 0.5 % of equal pressures at :data:`POROUS_REFERENCE` (at another mean pressure p,
    times (p / POROUS_REFERENCE)^(2 m - 1)), where it is linear in the drop; ``rt`` = r T
    [J/kg]."""
    return area * orifice_function(LINEAR_RATIO, index) / ((1.0 - LINEAR_RATIO) * math.sqrt(rt))


@njit(cache=True, error_model="numpy", inline="always")
def restriction_flow(area: float, p_a: float, p_b: float, rt: float, index: float) -> float:
    """Mass flow [kg/s] through the port's restriction of effective ``area`` [m^2] and index
    ``index`` from ``p_a`` to ``p_b`` [Pa] (negative backwards), ``rt`` = r T [J/kg]: the
    orifice law with ISO 6358's subsonic index (:func:`~jetpipe_ros.model.flow.orifice_flow`)
    times (p_mean / :data:`POROUS_REFERENCE`)^(2 m - 1), p_mean = (p_a + p_b) / 2 (module
    docstring): at m = 0.5 the orifice, at m = 1 Darcy's compressible law."""
    w = orifice_flow(area, p_a, p_b, rt, index)
    if index == 0.5:
        return w
    return w * (0.5 * (p_a + p_b) / POROUS_REFERENCE) ** (2.0 * index - 1.0)


@njit(cache=True, error_model="numpy", inline="always")
def port_step(p_p: float, p_c: float, q: float, slope: float, rate_c: float, gain_c: float,
              port_rate: float, area: float, index: float, rt: float, h: float
              ) -> tuple[float, float, float, float]:
    """One step ``h`` [s] of a port and its chamber (module docstring).

    From the port's pressure ``p_p`` and the chamber's ``p_c`` [Pa]; the valve's flow into the
    port is ``q`` + ``slope`` (p_p' - p_p) [kg/s] (``slope`` = dq/dp_p <= 0 [kg/(s Pa)]); the
    chamber's pressure moves at ``rate_c`` [Pa/s] (what it does without the port's flow) +
    ``gain_c`` [Pa/kg] times the flow it receives (``gain_c`` = 0 holds it: a measured
    pressure); ``port_rate`` = gamma r T / V_p [Pa/kg]; ``area`` the restriction's effective
    area [m^2], ``index`` its subsonic index, ``rt`` = r T [J/kg]. Returns the new p_p, p_c,
    the mean flow into the chamber and the mean flow leaving the valve [kg/s] over the step."""
    w = restriction_flow(area, p_p, p_c, rt, index)
    g_b = (w - restriction_flow(area, p_p, p_c + SLOPE_STEP, rt, index)) / SLOPE_STEP
    # The law is homogeneous of degree 2 m in the two pressures (Euler: p_p dw/dp_p
    # + p_c dw/dp_c = 2 m w), which gives the other slope without another evaluation.
    g_a = (2.0 * index * w + p_c * g_b) / p_p
    s = min(slope, 0.0)
    a_pp = port_rate * (g_a - s)  # -d(dp_p/dt)/dp_p
    a_pc = port_rate * g_b  # d(dp_p/dt)/dp_c
    a_cp = gain_c * g_a  # d(dp_c/dt)/dp_p
    a_cc = gain_c * g_b  # -d(dp_c/dt)/dp_c
    x = h * (a_pp + a_cc)
    theta = max(0.5, 1.0 - 1.0 / x) if x > 0.0 else 0.5
    k = theta * h
    f_p = h * port_rate * (q - w)
    f_c = h * (rate_c + gain_c * w)
    m00 = 1.0 + k * a_pp
    m01 = -k * a_pc
    m10 = -k * a_cp
    m11 = 1.0 + k * a_cc
    det = m00 * m11 - m01 * m10
    d_p = (f_p * m11 - m01 * f_c) / det
    d_c = (m00 * f_c - m10 * f_p) / det
    into = w + theta * (g_a * d_p - g_b * d_c)
    return p_p + d_p, p_c + d_c, into, q + theta * s * d_p
