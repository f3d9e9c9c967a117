"""The plant's piston: Eq. 14 with the paper's friction, stick-slip, bristles, a measured seal and
end-stop cushions.

M dv/dt = F_a - F_f - F_cushion - F_load, F_a = S (p1 - p2) - F_L - k_s (y - y_s) [N], M the
moving mass [kg]. The friction is this module's own evaluation of the paper's: each of F_S, v_s,
F_v, F_C a plane c0 + c1 p1 + c2 p2 over the chamber pressures in bar (Eq. 20-27, the
coefficients from ``friction.*`` of the model parameters), the entry planes for motion inward,
the exit planes outward, evaluated at the mean pressure outside the region each phase was fitted
in (entry where p2 > p1, exit where p1 > p2) and kept on its physical side (|F_C|, |F_S| >= 1 N,
|v_s| >= 1e-4 m/s, F_v >= 0); Eq. 18 sliding, F = F_C + (F_S - F_C) exp(-(v / v_s)^2) + F_v v,
and Eq. 15 at rest (the friction balances the applied force up to |F_S|). Each sub-step of
length h is implicit Euler in the velocity w,
the gas spring included (over the sub-step S (p1 - p2) falls by k_gas h w, k_gas = n S^2
(p1 / V1 + p2 / V2), n = 1 isothermal, gamma with the energy balance):

- **Stick-slip** (nominal): at rest the piston stays while |F_a| <= |F_S|; sliding, the new
  velocity w solves M (w - v) / h = F_a - F_st(w) - F_v w (Stribeck term implicit too) by Newton
  steps kept inside a bracket (bisection when a step leaves it); when no w of the sliding
  direction solves it (the force cannot carry the piston through the sub-step), it sticks.
  Sticking is a state, so the velocity is exactly zero at rest and cannot chatter.
- **Elasto-plastic bristles** (``elastoplastic_friction``; Dupont, Hayward, Armstrong and
  Altpeter 2002, with Olsson's velocity-dependent damping), replacing the stick logic:

      dz/dt = v (1 - alpha(z, v) sigma_0 z / g(v) sgn v),   g(v) = |F_st(v)| [N]
      F_f = sigma_0 z + sigma_1 exp(-(v / v_d)^2) dz/dt + F_v v

  with alpha = 0 for |z| <= z_ba or sgn z != sgn v (pure elastic pre-sliding, no drift below
  breakaway), 1 for |z| >= z_ss = g / sigma_0, and 1/2 + 1/2 sin(pi (|z| - (z_ss + z_ba) / 2) /
  (z_ss - z_ba)) between; z_ba = beta |F_C| / sigma_0. sigma_0 [N/m], sigma_1 [N s/m], v_d
  [m/s], beta [-]. A force F below beta |F_C| displaces the resting piston by exactly
  F / sigma_0. z is implicit (linearised in its rate) and coupled implicitly with v.
  The model's candidate is the LuGre model with constant damping, which creeps below breakaway.
- **Measured seal** (``measured_seal``), replacing the stick logic: a hysteresis with
  reversal-point memory over the Stribeck curves (Eq. 18) of both directions (:mod:`seal`; the
  levels g_exit, g_entry [N] and viscous coefficients from :func:`directional_levels`), its
  stiffness implicit in v.
- **End-stop cushions** (``end_stop_cushion``, on no list): within ``length`` d_c [m] of either
  end stop a spring-damper pushes the piston back, F = max(k_c e + c_c de/dt, 0) with the
  penetration e = |y| - (y_max - d_c) (k_c [N/m], c_c [N s/m]), implicit in v. The inelastic
  stop at +-y_max stays behind it.
- **Load on a compliance** (``extra_mass``): a load of mass m_x [kg] on the rod through a
  compliant coupling (a bracket, a flexible rod end) of stiffness k_x [N/m] and damping c_x
  [N s/m], given as the load's natural frequency on it f_x = sqrt(k_x / m_x) / (2 pi) [Hz] and
  damping ratio zeta_x = c_x / (2 sqrt(k_x m_x)):

      F_load = k_x (y - x_l) + c_x (v - v_l),   m_x dv_l/dt = F_load,   dx_l/dt = v_l,

  a two-mass load: at low frequency the rod carries M + m_x, near f_x the load resonates
  against the piston. The piston's sub-step takes F_load with the load held and its stiffness
  and damping implicit in w (as the gas spring); the load then follows implicitly in v_l from
  the piston's new position and velocity. The model's candidate is a rigid extra mass.
- **Load spring** (``load_spring``, on no list): a spring between the rod and the frame, k_s
  [N/m], relaxed at y_s [m], in F_a above and implicit in v like the gas spring.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Physical floors of the friction parameters: |F_C|, |F_S| >= 1 N, |v_s| >= 1e-4 m/s.
FLOOR_FORCE = 1.0
FLOOR_STRIBECK = 1e-4
#: Rows of the planes: breakaway, Stribeck velocity, viscous, Coulomb; phases: entry, exit.
F_S, V_S, F_V, F_C = range(4)


@njit(cache=True, error_model="numpy")
def friction_parameters(planes: np.ndarray, direction: float, p1: float, p2: float
                        ) -> tuple[float, float, float, float]:
    """Signed (F_S [N], v_s [m/s], F_v [N s/m], F_C [N]) for motion in ``direction`` (+1 exit,
    -1 entry) at chamber pressures ``p1``, ``p2`` [Pa]; ``planes`` (2, 4, 3) = [entry, exit] x
    [F_S, v_s, F_v, F_C] x [c0, c1, c2] (module docstring)."""
    exit_ = direction > 0.0
    a = p1 / 1e5
    b = p2 / 1e5
    if (exit_ and not a > b) or (not exit_ and not b > a):
        a = b = (a + b) / 2.0
    k = 1 if exit_ else 0
    sign = 1.0 if exit_ else -1.0
    c = planes[k]
    f_s = sign * max(sign * (c[F_S, 0] + c[F_S, 1] * a + c[F_S, 2] * b), FLOOR_FORCE)
    v_s = sign * max(sign * (c[V_S, 0] + c[V_S, 1] * a + c[V_S, 2] * b), FLOOR_STRIBECK)
    f_v = max(c[F_V, 0] + c[F_V, 1] * a + c[F_V, 2] * b, 0.0)
    f_c = sign * max(sign * (c[F_C, 0] + c[F_C, 1] * a + c[F_C, 2] * b), FLOOR_FORCE)
    return f_s, v_s, f_v, f_c


@njit(cache=True, error_model="numpy")
def stribeck_force(v: float, f_s: float, v_s: float, f_c: float) -> float:
    """Eq. 18 without its viscous term [N] at velocity ``v`` [m/s]."""
    return f_c + (f_s - f_c) * math.exp(-(v / v_s) ** 2)


@njit(cache=True, error_model="numpy")
def static_friction(f_applied: float, f_s: float) -> float:
    """Eq. 15 at rest [N]: what balances ``f_applied`` [N], at most |``f_s``|."""
    if f_applied > abs(f_s):
        return abs(f_s)
    if f_applied < -abs(f_s):
        return -abs(f_s)
    return f_applied


@njit(cache=True, error_model="numpy")
def stribeck_slope(v: float, f_s: float, v_s: float, f_c: float) -> float:
    """d F_st / dv of Eq. 18's Stribeck term [N s/m]."""
    r = v / v_s
    return -2.0 * r / v_s * (f_s - f_c) * math.exp(-r * r)


@njit(cache=True, error_model="numpy")
def sliding_velocity(v: float, f_a: float, inertia: float, damping: float, direction: float,
                     f_s: float, v_s: float, f_c: float) -> float:
    """Velocity [m/s] after a sub-step sliding in ``direction`` (+-1): the root w of
    G(w) = inertia (w - v) - f_a + F_st(w) + damping w with w on the sliding side, or 0 when
    G does not change sign there (the piston sticks). ``inertia`` = M / h [kg/s], ``damping``
    [N s/m] the implicit linear terms (F_v, the gas spring's k h, any cushion's), ``f_a`` [N]
    the other forces."""
    g0 = (-inertia * v - f_a + f_s) * direction
    if g0 >= 0.0:
        return 0.0
    # G(w) d > 0 once |w| > |v| + |f_a| / inertia: the bracket [0, hi] holds a root.
    lo = 0.0
    hi = abs(v) + abs(f_a) / inertia + 1e-12
    # Start from the step with the Stribeck term explicit.
    w = (inertia * v + f_a - stribeck_force(v, f_s, v_s, f_c)) * direction / (inertia + damping)
    if not lo < w < hi:
        w = 0.5 * hi
    for _ in range(100):
        s = w * direction
        g = (inertia * (s - v) - f_a + stribeck_force(s, f_s, v_s, f_c) + damping * s) * direction
        if g > 0.0:
            hi = w
        else:
            lo = w
        slope = inertia + damping + stribeck_slope(s, f_s, v_s, f_c)
        if slope > 0.0:
            step = g / slope
            if abs(step) <= 1e-12 * w + 1e-15:
                return (w - step) * direction
            nxt = w - step
        else:
            nxt = lo  # Newton has no direction here: bisect
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
            if hi - lo <= 1e-12 * hi + 1e-15:
                return nxt * direction
        w = nxt
    return w * direction


@njit(cache=True, error_model="numpy")
def stick_slip(v: float, stuck: bool, f_a: float, planes: np.ndarray, p1: float, p2: float,
               inertia: float, damping: float) -> tuple[float, bool, float]:
    """One sub-step of the nominal friction: (velocity [m/s], stuck, friction [N]) from
    velocity ``v``, the stuck flag and the applied force ``f_a`` [N] (module docstring)."""
    if stuck or v == 0.0:
        direction = math.copysign(1.0, f_a)
        f_s, v_s, f_v, f_c = friction_parameters(planes, direction, p1, p2)
        if stuck and abs(f_a) <= abs(f_s):
            return 0.0, True, f_a
    else:
        direction = math.copysign(1.0, v)
        f_s, v_s, f_v, f_c = friction_parameters(planes, direction, p1, p2)
    w = sliding_velocity(v, f_a, inertia, damping + f_v, direction, f_s, v_s, f_c)
    if w == 0.0:
        return 0.0, True, static_friction(f_a, f_s)
    return w, False, stribeck_force(w, f_s, v_s, f_c) + f_v * w


@njit(cache=True, error_model="numpy")
def plasticity(z: float, v: float, z_ba: float, z_ss: float) -> float:
    """alpha(z, v) of the elasto-plastic model [-] (module docstring)."""
    if v == 0.0 or z * v <= 0.0:
        return 0.0
    a = abs(z)
    if a <= z_ba:
        return 0.0
    if a >= z_ss:
        return 1.0
    return 0.5 + 0.5 * math.sin(math.pi * (a - 0.5 * (z_ss + z_ba)) / (z_ss - z_ba))


@njit(cache=True, error_model="numpy")
def bristles(v: float, z: float, f_a: float, planes: np.ndarray, p1: float, p2: float,
             inertia: float, damping: float, h: float, sigma0: float, sigma1: float,
             v_damp: float, fraction: float) -> tuple[float, float, float]:
    """One sub-step of the elasto-plastic friction: (velocity [m/s], bristle deflection z [m],
    friction [N]); ``inertia`` = M / h [kg/s], ``damping`` [N s/m] implicit linear terms besides
    F_v, ``fraction`` beta (module docstring)."""
    if v != 0.0:
        direction = math.copysign(1.0, v)
    elif f_a != 0.0:
        direction = math.copysign(1.0, f_a)
    else:
        direction = math.copysign(1.0, z)
    f_s, v_s, f_v, f_c = friction_parameters(planes, direction, p1, p2)
    g = abs(stribeck_force(v, f_s, v_s, f_c))
    z_ss = g / sigma0
    alpha = plasticity(z, v, fraction * abs(f_c) / sigma0, z_ss)
    rate = alpha * sigma0 * abs(v) / g  # dz/dt = v - rate z
    s1 = sigma1 * math.exp(-(v / v_damp) ** 2)
    d = 1.0 + h * rate
    # z' = (z + h w) / d, dz/dt = (w - rate z) / d, F_f = sigma0 z' + s1 dz/dt + F_v w.
    w = (inertia * v + f_a - (sigma0 - s1 * rate) * z / d) / \
        (inertia + (sigma0 * h + s1) / d + f_v + damping)
    z_new = (z + h * w) / d
    friction = sigma0 * z_new + s1 * (w - rate * z) / d + f_v * w
    return w, z_new, friction


@njit(cache=True, error_model="numpy")
def directional_levels(planes: np.ndarray, v: float, p1: float, p2: float
                       ) -> tuple[float, float, float, float]:
    """The Stribeck curve (Eq. 18)'s magnitude |F_st(v)| [N] in the exit and the entry direction
    at velocity ``v`` [m/s] and pressures ``p1``, ``p2`` [Pa], and both directions' viscous
    coefficients F_v [N s/m]: (g_exit, g_entry, f_v_exit, f_v_entry)."""
    f_s, v_s, f_v_exit, f_c = friction_parameters(planes, 1.0, p1, p2)
    g_exit = abs(stribeck_force(v, f_s, v_s, f_c))
    f_s, v_s, f_v_entry, f_c = friction_parameters(planes, -1.0, p1, p2)
    g_entry = abs(stribeck_force(v, f_s, v_s, f_c))
    return g_exit, g_entry, f_v_exit, f_v_entry
