"""A hose between the valve and each chamber, lumped: the ``hose`` form of the valve_delay effect.

Real benches put a hose of length L [m] and bore d [m] (area A = pi d^2 / 4) between the valve's
port and each chamber. Its gas has a volume, the air in it an inertance, its wall a friction, and
a disturbance crosses it at the speed of sound c = sqrt(gamma r T) (346 m/s at 25 degC): L / c is
the one-way delay of the pure-delay ``line`` form. Here the hose is lumped into
:data:`SEGMENTS` equal segments of length l = L / N. Node k (k = 0 at the valve) holds the gas of
one segment, volume A l; segment k carries the mass flow w_k [kg/s] from node k to node k + 1, the
last one into the chamber:

    dp_k/dt = gamma r T / (A l) (w_(k-1) - w_k)         (w_(-1) = the valve's flow q(u_eq, p_0))
    dw_k/dt = A / (kappa l) (p_k - p_(k+1) - R(w_k) w_k)  (p_N = the chamber's pressure)

- **Gas of the hose: adiabatic.** Heat crosses the bore's radius in about d^2 / (4 alpha), alpha
  the air's thermal diffusivity (2e-5 m^2/s at 1 bar, less at higher density): 0.3 s for 5 mm at
  1 bar, over 1 s at 5 bar, slower than the campaign's signals; so the hose's compliance is
  A l / (gamma r T), and the waves travel at the adiabatic speed of sound.
- **The inertance's factor kappa.** A chain of N equal segments, closed at the valve (the jet
  pipe passes a flow, whatever the pressure behind it, to first order) and open at the chamber,
  has its first mode at (2 N c / (L sqrt(kappa))) sin(pi / (2 (2 N + 1))) [rad/s]; the hose's
  own is the quarter wave, pi c / (2 L). kappa = (4 N sin(pi / (2 (2 N + 1))) / pi)^2 (0.619
  for N = 2) makes them equal, keeping the hose's whole volume A L (its low-frequency
  signature, the volume the chamber seems to gain) and its whole friction; the total inertance
  is kappa L / A instead of L / A. Against the distributed line feeding a 160 cm^3 chamber (a
  transfer-function comparison at the design of this form), two segments so tuned stay within
  2 % of the gain up to 20 Hz and 18 % at the ring; one segment 4 % and 33 %.
- **Wall friction R(w) w.** Darcy's drop f (l / d) w |w| / (2 rho A^2), rho = p_m / (r T) the
  segment's mean density at the wall temperature, with a friction factor that blends the
  laminar (Hagen-Poiseuille, 64 / Re) and the turbulent (Blasius, 0.3164 Re^-0.25) laws as a
  fourth-power mean, f = ((64 / Re)^4 + (0.3164 Re^-0.25)^4)^(1/4), Re = |w| d / (A mu): smooth
  in w (the fit's gradients), within 1 % of the nearer law below Re = 410 and above Re = 3500,
  19 % above both where they cross (Re = 1187, a flow the transition makes uncertain anyway).
  Written out, R(w) = (K_lam^4 + K_turb^4 |w|^3)^(1/4) / p_m with K_lam = 32 mu l r T / (d^2 A)
  and K_turb = 0.3164 (A mu / d)^(1/4) l r T / (2 d A^2) (:func:`hose_constants`).

Integration (:func:`hose_step`, one inner step): the trapezoidal rule on the nodes, the flows and
the chamber's pressure together, with the friction's R and the map's slope dq/dp_0 frozen over
the step, so the hose is stable at any step (A-stable: a short hose's fast modes and the hose
against a small chamber do not blow up) and its ring keeps its damping (no numerical damping,
its frequency off by (w h)^2 / 12). Inner steps (:func:`inner_steps`) keep the quarter wave's
w h under :data:`STEP_LIMIT` (frequency error under 0.5 %), at most :data:`MAX_STEPS` of them.
"""

from __future__ import annotations

import math

from numba import njit

from jetpipe_ros.model.flow import GAMMA_AIR

#: Lumped segments of each hose.
SEGMENTS = 2
#: Factor on the segments' inertance that puts the chain's first mode on the quarter wave.
INERTANCE_FACTOR = (4.0 * SEGMENTS * math.sin(math.pi / (2.0 * (2 * SEGMENTS + 1)))
                    / math.pi) ** 2
#: Dynamic viscosity of air at 25 degC [Pa s].
VISCOSITY = 1.84e-5
#: Largest product of the quarter wave's angular frequency [rad/s] and the inner step [s].
STEP_LIMIT = 0.25
#: Most inner steps per sub-step: hoses shorter than 0.14 m (at 4 sub-steps of 1 ms) step their
#: quarter wave, above 600 Hz and ten times the valve's 50 Hz, more coarsely (w h = 0.68 at
#: 5 cm: frequency off by 4 %), which the trapezoid keeps stable; a fit that tries lengths near
#: 0 costs at most four times a sub-step's hose.
MAX_STEPS = 4
#: States of one hose: the nodes' pressures [Pa], then the segments' flows [kg/s].
HOSE_STATES = 2 * SEGMENTS


def wave_speed(rt: float) -> float:
    """Adiabatic speed of sound [m/s] of air at r T = ``rt`` [J/kg]."""
    return math.sqrt(GAMMA_AIR * rt)


def hose_constants(length: float, bore: float, rt: float
                   ) -> tuple[float, float, float, float]:
    """A hose's constants per segment: the node's rate gamma r T / (A l) [Pa/kg], the segment's
    A / (kappa l) [1/m], K_lam [Pa^2 s/kg] and K_turb [Pa^2 s^0.75 / kg^0.75] (module docstring)
    for ``length`` [m] > 0 and ``bore`` [m] at r T = ``rt`` [J/kg]."""
    area = 0.25 * math.pi * bore * bore
    seg = length / SEGMENTS
    laminar = 32.0 * VISCOSITY * seg * rt / (bore * bore * area)
    turbulent = 0.3164 * (area * VISCOSITY / bore) ** 0.25 * seg * rt / (2.0 * bore * area * area)
    return GAMMA_AIR * rt / (area * seg), area / (INERTANCE_FACTOR * seg), laminar, turbulent


def inner_steps(length: float, rt: float, h: float) -> int:
    """Inner steps of a sub-step ``h`` [s] for a hose of ``length`` [m] > 0 at r T = ``rt``
    [J/kg]: the quarter wave pi c / (2 L) [rad/s] times the step under :data:`STEP_LIMIT`, at
    most :data:`MAX_STEPS`."""
    quarter = 0.5 * math.pi * wave_speed(rt) / length
    return int(min(max(math.ceil(quarter * h / STEP_LIMIT), 1), MAX_STEPS))


@njit(cache=True, error_model="numpy", inline="always")
def _resistance(w: float, p_a: float, p_b: float, laminar: float, turbulent: float) -> float:
    """R [Pa s/kg] of a segment carrying ``w`` [kg/s] between pressures ``p_a``, ``p_b`` [Pa]."""
    t = turbulent * turbulent
    return math.sqrt(math.sqrt(laminar ** 4 + t * t * abs(w) ** 3)) / (0.5 * (p_a + p_b))


@njit(cache=True, error_model="numpy", inline="always")
def hose_step(p0: float, p1: float, w0: float, w1: float, q: float, slope: float, p_c: float,
              rate_c: float, gain_c: float, node_rate: float, accel: float, laminar: float,
              turbulent: float, k: float) -> tuple[float, float, float, float, float, float]:
    """One trapezoidal step of length 2 ``k`` [s] of a two-segment hose and its chamber.

    From the nodes' pressures ``p0`` (valve end), ``p1`` [Pa] and the segments' flows ``w0``,
    ``w1`` [kg/s] (``w1`` into the chamber); the valve's flow into node 0 is
    ``q`` + ``slope`` (p_0' - p_0) [kg/s] (the map's slope dq/dp_0 <= 0 [kg/(s Pa)], implicit).
    The chamber's pressure ``p_c`` [Pa] moves at ``rate_c`` [Pa/s] (what the chamber does without
    the hose's flow) + ``gain_c`` [Pa/kg] times the flow w1 it receives; ``gain_c`` = 0 holds it
    (a measured pressure). Returns the new p0, p1, w0, w1, p_c and the mean of w1 over the step.
    """
    r0 = _resistance(w0, p0, p1, laminar, turbulent)
    r1 = _resistance(w1, p1, p_c, laminar, turbulent)
    ka = k * node_rate
    kb = k * accel
    g = 1.0 / (1.0 - ka * min(slope, 0.0))
    # p0' = big0 - g ka w0';  p1' = big1 + ka (w0' - w1');  p_c' = big_c + k gain_c w1'.
    big0 = p0 + g * ka * (2.0 * q - w0)
    big1 = p1 + ka * (w0 - w1)
    big_c = p_c + 2.0 * k * rate_c + k * gain_c * w1
    f0 = w0 + kb * (p0 - p1 - r0 * w0) + kb * (big0 - big1)
    f1 = w1 + kb * (p1 - p_c - r1 * w1) + kb * (big1 - big_c)
    e = kb * ka
    m00 = 1.0 + kb * r0 + kb * g * ka + e
    m11 = 1.0 + kb * r1 + e + kb * k * gain_c
    det = m00 * m11 - e * e
    w0_new = (f0 * m11 + e * f1) / det
    w1_new = (m00 * f1 + e * f0) / det
    return (big0 - g * ka * w0_new, big1 + ka * (w0_new - w1_new), w0_new, w1_new,
            big_c + k * gain_c * w1_new, 0.5 * (w1 + w1_new))
