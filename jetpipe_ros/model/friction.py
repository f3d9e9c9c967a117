"""Friction of the piston: the static Eq. 15-18 with the planes of Eq. 20-27, and its dynamic
forms (LuGre bristles, Maxwell-slip elements) over the same planes.

Each of the four friction parameters is a plane c0 + c1 p1 + c2 p2 over the chamber pressures in
bar, one set for the entry phase (v < 0, fitted where p2 > p1) and one for the exit phase
(v > 0, fitted where p1 > p2). Values are signed: in the entry phase forces and the Stribeck
velocity are negative, so F(v) carries the sign of v. Outside its fitted region a phase's planes
are evaluated at the mean pressure, and each parameter is kept on its physical side. The
breakaway F_S may lie below the Coulomb level F_C (no Stribeck dip: friction rising with speed,
as real seals show at low speed); it is used as fitted.

A seal's level also varies along the bore (its diameter and finish vary along a printed or
honed bore, and the seal's squeeze with them): an optional **bore profile** scales the Stribeck
curve of each direction by a factor that varies with the piston position, linearly between knots
and held beyond them (:func:`level_factors`); without one the factor is 1. The viscous term is
not scaled (it is the lubricant film's shear, not the seal's contact force).

The dynamic forms replace Eq. 15's stick logic with a state that carries the friction through a
reversal (pre-sliding) and that the kernel and the friction-rig fit advance with the same
functions (:func:`lugre_step`, :func:`maxwell_slip_step`, :func:`prescribed_friction`):

- **LuGre** (Canudas de Wit et al. 1995): one bristle deflection z [m],
  dz/dt = v - sigma_0 |v| z / g(v), F = sigma_0 z + sigma_1 dz/dt + F_v v, with g(v) the
  Stribeck curve of Eq. 18 (without its viscous term) of the direction of motion.
- **Maxwell-slip** (Lampaert, Al-Bender and Swevers 2003, generalised Maxwell-slip without its
  rate law): n elasto-plastic elements in parallel, element i slipping once its deflection
  reaches delta_i. With s_i = deflection / delta_i in [-1, 1], ds_i/dx = 1/delta_i until
  |s_i| = 1, and F = (1/n) sum_i s_i g_{sign s_i}(v) + F_v v: each element carries an equal
  share of the Stribeck level of the direction it is deflected in. The delta_i lie geometrically
  between spread * delta and delta (:func:`element_slips`), so the friction changes sign soon
  after a reversal and reaches its level only after about 2 delta.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Rows of a plane array: breakaway F_S [N], Stribeck velocity v_s [m/s], viscous F_v [N s/m],
#: Coulomb F_C [N]; columns c0, c1, c2.
BREAKAWAY, STRIBECK, VISCOUS, COULOMB = 0, 1, 2, 3

#: The floor on the Stribeck levels |F_C|, |F_S| [N] of the paper's planes (``friction.floor``'s
#: default): the planes are fitted over the tests' pressures and extrapolate linearly, and the
#: exit Coulomb plane reaches 0 near p1 = p2 = 8.3 bar. A seal fitted on a friction rig has
#: levels of a few N or less, some under 1 N, and writes its own floor (LEVEL_FLOOR).
PAPER_FLOOR = 1.0
#: The floor a rig-fitted seal is written with [N]: far under any level a load cell resolves,
#: and above 0, which keeps LuGre's sigma_0 |v| / g finite.
LEVEL_FLOOR = 1e-3
#: Floor on the Stribeck velocity |v_s| [m/s].
MIN_STRIBECK = 1e-4


@njit(cache=True, error_model="numpy")
def plane_basis(p1_bar: float | np.ndarray, p2_bar: float | np.ndarray
                ) -> tuple[float | np.ndarray, ...]:
    """The terms (1, p1, p2) of a friction plane c0 + c1 p1 + c2 p2 (Eq. 20-27) at chamber
    pressures ``p1_bar``, ``p2_bar`` [bar]: floats or equal-shape arrays (the regressors of the
    planes' least-squares fit in :mod:`jetpipe_ros.identify.friction`)."""
    return (p1_bar * 0.0 + 1.0, p1_bar, p2_bar)


@njit(cache=True, error_model="numpy")
def plane(c: np.ndarray, p1_bar: float | np.ndarray, p2_bar: float | np.ndarray
          ) -> float | np.ndarray:
    """One of Eq. 20-27: c0 + c1 p1 + c2 p2 for coefficients ``c`` (3,) at chamber pressures
    ``p1_bar``, ``p2_bar`` [bar] (floats or arrays), in the unit of the parameter."""
    t = plane_basis(p1_bar, p2_bar)
    return c[0] * t[0] + c[1] * t[1] + c[2] * t[2]


@njit(cache=True, error_model="numpy")
def friction_parameters(planes: np.ndarray, direction: float, p1: float, p2: float,
                        floor: float = PAPER_FLOOR) -> tuple[float, float, float, float]:
    """Signed (F_S, v_s, F_v, F_C) for motion in ``direction`` (+1 exit, -1 entry).

    ``planes`` has shape (2, 4, 3): [entry, exit] x [F_S, v_s, F_v, F_C] x [c0, c1, c2];
    ``p1``, ``p2`` are chamber pressures [Pa]; |F_S| and |F_C| are held at ``floor`` [N] or
    more (``friction.floor``), |v_s| at :data:`MIN_STRIBECK`, F_v at 0.
    """
    a = p1 * 1e-5
    b = p2 * 1e-5
    phase = 1 if direction > 0.0 else 0
    # Fitted region: exit where p1 > p2, entry where p2 > p1; elsewhere the mean pressure.
    if (phase == 1 and a <= b) or (phase == 0 and b <= a):
        a = b = 0.5 * (a + b)
    f_s = plane(planes[phase, BREAKAWAY], a, b)
    v_s = plane(planes[phase, STRIBECK], a, b)
    f_v = plane(planes[phase, VISCOUS], a, b)
    f_c = plane(planes[phase, COULOMB], a, b)
    s = 1.0 if phase == 1 else -1.0
    f_c = s * max(s * f_c, floor)
    f_s = s * max(s * f_s, floor)
    v_s = s * max(s * v_s, MIN_STRIBECK)
    f_v = max(f_v, 0.0)
    return f_s, v_s, f_v, f_c


@njit(cache=True, error_model="numpy")
def level_factors(profile: np.ndarray, y: float) -> tuple[float, float]:
    """Factors (exit, entry) on the Stribeck levels at piston position ``y`` [m] of a bore
    profile (3, K): row 0 the knots' positions [m], increasing, rows 1 and 2 the exit and entry
    factors there; linear between the knots, held beyond them. K = 0: no profile, (1, 1)."""
    if profile.shape[1] == 0:
        return 1.0, 1.0
    return np.interp(y, profile[0], profile[1]), np.interp(y, profile[0], profile[2])


@njit(cache=True, error_model="numpy")
def scaled_parameters(planes: np.ndarray, profile: np.ndarray, direction: float, y: float,
                      p1: float, p2: float, floor: float) -> tuple[float, float, float, float]:
    """:func:`friction_parameters` (levels held at ``floor`` [N] or more) with F_S and F_C
    scaled by the bore profile's factor of ``direction`` at piston position ``y`` [m]
    (:func:`level_factors`)."""
    f_s, v_s, f_v, f_c = friction_parameters(planes, direction, p1, p2, floor)
    exit_factor, entry_factor = level_factors(profile, y)
    factor = exit_factor if direction > 0.0 else entry_factor
    return factor * f_s, v_s, f_v, factor * f_c


@njit(cache=True, error_model="numpy")
def stribeck_force(v: float | np.ndarray, f_s: float, v_s: float, f_c: float) -> float | np.ndarray:
    """Eq. 18 without the viscous term: F_C + (F_S - F_C) exp(-(v/v_s)^2) [N] at velocity
    ``v`` [m/s] (a float, or an array). The kernel adds the viscous term F_v v implicitly."""
    r = v / v_s
    return f_c + (f_s - f_c) * np.exp(-r * r)


@njit(cache=True, error_model="numpy")
def sliding_friction(v: float | np.ndarray, f_s: float, v_s: float, f_v: float, f_c: float
                     ) -> float | np.ndarray:
    """Eq. 18: friction force [N] while sliding at velocity ``v`` [m/s] (a float, or an array:
    the identification fits it to the sliding samples of a friction test)."""
    return stribeck_force(v, f_s, v_s, f_c) + f_v * v


@njit(cache=True, error_model="numpy")
def static_friction(f_applied: float, f_s: float) -> float:
    """Eq. 15 at rest: the friction that balances ``f_applied``, at most the breakaway |F_S|."""
    lim = abs(f_s)
    return min(max(f_applied, -lim), lim)


#: Friction forms: Eq. 15's stick logic over Eq. 18, LuGre bristles, Maxwell-slip elements.
STATIC, LUGRE, MAXWELL_SLIP = 0, 1, 2
#: The friction_dynamics effect's forms by name.
FRICTION_FORMS = {"lugre": LUGRE, "maxwell_slip": MAXWELL_SLIP}
#: Most Maxwell-slip elements the kernel's state holds.
MAX_ELEMENTS = 8


def element_slips(displacement: float, spread: float, elements: int) -> np.ndarray:
    """Slip displacements delta_i [m] of ``elements`` Maxwell-slip elements, geometrically
    from ``spread * displacement`` to ``displacement`` [m] (one element: ``displacement``)."""
    if elements == 1:
        return np.array([displacement])
    return displacement * np.geomspace(spread, 1.0, elements)


def presliding_displacement(slips: np.ndarray, fraction: float = 0.9) -> float:
    """Displacement after a reversal [m] at which Maxwell-slip elements with slip displacements
    ``slips`` [m] have covered ``fraction`` of the swing from one sliding level to the other
    (equal levels, constant speed): the mean of min(u / (2 delta_i), 1) reaches ``fraction``."""
    lo, hi = 0.0, 2.0 * float(np.max(slips))
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if np.mean(np.minimum(mid / (2.0 * slips), 1.0)) < fraction:
            lo = mid
        else:
            hi = mid
    return hi


@njit(cache=True, error_model="numpy")
def sliding_levels(planes: np.ndarray, profile: np.ndarray, v: float, y: float, p1: float,
                   p2: float, floor: float) -> tuple[float, float, float, float]:
    """Magnitudes of the Stribeck curve (Eq. 18 without its viscous term) [N] of the exit and
    entry directions at velocity ``v`` [m/s], piston position ``y`` [m] (the bore ``profile``,
    :func:`level_factors`) and pressures ``p1``, ``p2`` [Pa] (levels held at ``floor`` [N] or
    more), and the viscous coefficients F_v [N s/m] of both: (g_exit, g_entry, f_v_exit,
    f_v_entry)."""
    f_s, v_s, f_v_exit, f_c = scaled_parameters(planes, profile, 1.0, y, p1, p2, floor)
    g_exit = abs(stribeck_force(v, f_s, v_s, f_c))
    f_s, v_s, f_v_entry, f_c = scaled_parameters(planes, profile, -1.0, y, p1, p2, floor)
    g_entry = abs(stribeck_force(v, f_s, v_s, f_c))
    return g_exit, g_entry, f_v_exit, f_v_entry


@njit(cache=True, error_model="numpy")
def lugre_step(z: float, v: float, g: float, sigma0: float, h: float) -> tuple[float, float]:
    """Advance the LuGre bristle deflection ``z`` [m] over ``h`` [s] at velocity ``v`` [m/s]
    (held) with Stribeck level ``g`` [N] and stiffness ``sigma0`` [N/m], exactly for the
    linear ODE dz/dt = v - a z, a = sigma0 |v| / g [1/s]. Returns (z_new [m], a [1/s])."""
    a = sigma0 * abs(v) / g
    if a * h < 1e-12:
        return z + h * v, a
    return v / a + (z - v / a) * math.exp(-a * h), a


@njit(cache=True, error_model="numpy")
def maxwell_slip_step(s: np.ndarray, dx: float, slips: np.ndarray) -> None:
    """Advance the normalised deflections ``s`` (in place, each in [-1, 1]) of Maxwell-slip
    elements with slip displacements ``slips`` [m] by a displacement ``dx`` [m]."""
    for i in range(slips.shape[0]):
        s[i] = min(max(s[i] + dx / slips[i], -1.0), 1.0)


@njit(cache=True, error_model="numpy")
def maxwell_slip_force(s: np.ndarray, g_exit: float, g_entry: float) -> float:
    """Friction [N] of Maxwell-slip elements at normalised deflections ``s``: each an equal
    share of the Stribeck level [N] of the direction it is deflected in (without F_v v)."""
    f = 0.0
    for i in range(s.shape[0]):
        f += s[i] * (g_exit if s[i] > 0.0 else g_entry)
    return f / s.shape[0]


@njit(cache=True, error_model="numpy")
def prescribed_friction(form: int, planes: np.ndarray, profile: np.ndarray, v: np.ndarray,
                        y: np.ndarray, p1: np.ndarray, p2: np.ndarray, h: float, sigma0: float,
                        sigma1: float, slips: np.ndarray, floor: float) -> np.ndarray:
    """Friction force [N] along a prescribed motion (a friction rig drives the rod): velocity
    ``v`` [m/s], position ``y`` [m] (for the bore ``profile``, :func:`level_factors`) and
    pressures ``p1``, ``p2`` [Pa] sampled every ``h`` [s], levels held at ``floor`` [N] or
    more; the dynamic
    forms' state starts relaxed and is integrated from the velocity. ``form`` is
    :data:`STATIC` (Eq. 18 in the direction of ``v``; 0 where v = 0), :data:`LUGRE`
    (``sigma0`` [N/m], ``sigma1`` [N s/m]) or :data:`MAXWELL_SLIP` (``slips`` [m])."""
    n = v.shape[0]
    out = np.empty(n)
    z = 0.0
    s = np.zeros(slips.shape[0])
    for k in range(n):
        g_exit, g_entry, f_v_exit, f_v_entry = sliding_levels(planes, profile, v[k], y[k],
                                                              p1[k], p2[k], floor)
        f_v = f_v_exit if v[k] > 0.0 else f_v_entry
        if form == LUGRE:
            d = v[k] if v[k] != 0.0 else z
            g = g_exit if d > 0.0 else g_entry
            z, a = lugre_step(z, v[k], g, sigma0, h)
            out[k] = sigma0 * z + sigma1 * (v[k] - a * z) + f_v * v[k]
        elif form == MAXWELL_SLIP:
            maxwell_slip_step(s, h * v[k], slips)
            out[k] = maxwell_slip_force(s, g_exit, g_entry) + f_v * v[k]
        elif v[k] > 0.0:
            out[k] = g_exit + f_v * v[k]
        elif v[k] < 0.0:
            out[k] = -g_entry + f_v * v[k]
        else:
            out[k] = 0.0
    return out
