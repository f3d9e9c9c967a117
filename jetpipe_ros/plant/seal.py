"""A measured seal's friction (``measured_seal``): a hysteresis with reversal-point memory,
written from what twelve friction-rig records of real seals show (docs/friction.md), not from
the model's candidates.

The friction follows branches that start at reversal points of the motion. On the branch that
left the reversal point (x_r [m], F_r [N]) in direction d = +-1, at the displacement since it
u = d (y - x_r) >= 0 [m],

    F = F_r + d A phi(u / L),   phi(s) = (1 + c) s / (c + s) for s < 1, 1 beyond,

until it reaches the sliding level d g_d(v) of its direction, where it stays while the piston
slides (g_exit, g_entry [N]: the plant's Stribeck curve, Eq. 18, of each direction). L [m] is the
length over which a full swing builds up and c [-] the knee: phi rises steeply at first
(phi'(0) = (1 + c) / c) and approaches the level slowly, as the records do (the sign flips
within about 0.1 mm, the level is reached after 0.2-1.7 mm). The swing A = g_exit(0) + g_entry(0)
[N] is the full swing between the levels at rest: a branch from one level reaches the other
after L at most (sooner where the level at speed is lower). The reversal points are remembered on
a stack, oldest first. Every branch has the same shape and swing from its own reversal point, so
a small reversal inside a loop is as stiff as a large one (Masing's rule), and a branch that
comes back to the friction of the reversal point before its own passes through that point: the
inner loop closes there, the two points are wiped out and the branch it had left goes on (no
ratcheting). Reaching the level wipes out all of them. From rest (F = 0) the first branch
reaches the level where a full swing would be half done, about u_50 below. At rest the friction
holds whatever it is, without creep. Frictional memory follows:
decelerating toward a reversal the friction is at its level; after it, at the same speed, it is
still building up.

The parameters are read as the records report them: the displacement after a reversal at which
90 % of a full swing is covered, u_90 = L 0.9 c / (0.1 + c), and the ratio of the displacement
to half the swing to it, q = u_50 / u_90 = (0.1 + c) / (0.9 (1 + 2 c)) (q > 1/9; q -> 5/9 is a
straight build-up).
"""

from __future__ import annotations

import numpy as np
from numba import njit


def knee_of(half_fraction: float) -> float:
    """The knee c [-] of the build-up whose u_50 / u_90 is ``half_fraction`` (1/9 < q < 5/9)."""
    if not 1.0 / 9.0 < half_fraction < 5.0 / 9.0:
        raise ValueError(f"measured_seal: half_fraction = {half_fraction:g} is outside "
                         f"(1/9, 5/9): no build-up phi has that u_50 / u_90")
    return (0.9 * half_fraction - 0.1) / (1.0 - 1.8 * half_fraction)


def length_of(presliding: float, knee: float) -> float:
    """The build-up length L [m] of a full swing whose 90 % point lies ``presliding`` [m] after
    the reversal, for knee ``knee`` [-]."""
    return presliding * (0.1 + knee) / (0.9 * knee)


@njit(cache=True, error_model="numpy")
def branch_force(y: float, x_r: float, f_r: float, d: float, swing: float, level: float,
                 length: float, knee: float) -> tuple[float, float, bool]:
    """The seal's friction [N] (without the viscous term) at position ``y`` [m] on the branch
    that left the reversal point (``x_r`` [m], ``f_r`` [N]) in direction ``d``, with full swing
    ``swing`` A [N] and the sliding level ``level`` [N] (magnitude) of direction d; its
    stiffness dF/dy [N/m] there; and whether it has reached the level (module docstring:
    ``length`` L [m], ``knee`` c [-])."""
    u = max(d * (y - x_r), 0.0)
    s = u / length
    if s >= 1.0:
        f, slope = f_r + d * swing, 0.0
    else:
        f = f_r + d * swing * (1.0 + knee) * s / (knee + s)
        slope = swing * (1.0 + knee) * knee / ((knee + s) * (knee + s) * length)
    if d * f >= level:
        return d * level, 0.0, True
    return f, slope, False


@njit(cache=True, error_model="numpy")
def seal_force(y: float, points: np.ndarray, n: int, d: float, g_exit: float, g_entry: float,
               swing: float, length: float, knee: float) -> tuple[float, float, int]:
    """Friction [N] at ``y`` [m] and its stiffness [N/m] on the branch that left the newest of
    the ``n`` reversal points ``points`` (x_r [m], F_r [N] of each in turn, oldest first) in
    direction ``d`` (levels ``g_exit``, ``g_entry`` [N], full swing ``swing`` [N]), after the
    inner loops that the way to ``y`` closes are wiped out; and the
    number of points left (the stack is changed in place: wiped out points dropped, and on
    reaching the level the newest point moved to ``y`` at the level, the only one left)."""
    level = g_exit if d > 0.0 else g_entry
    while True:
        f, slope, sliding = branch_force(y, points[2 * n - 2], points[2 * n - 1], d, swing,
                                         level, length, knee)
        if sliding:
            points[0], points[1] = y, f
            return f, slope, 1
        if n >= 2 and d * (f - points[2 * n - 3]) >= 0.0:
            # Back at the friction of the reversal point before: that loop closes; continue on
            # the branch it had left (the base point's own branch, the other way, if none).
            n = n - 2 if n >= 3 else 1
            continue
        return f, slope, n


@njit(cache=True, error_model="numpy")
def seal_substep(y: float, v: float, points: np.ndarray, n: int, d: float, f_a: float,
                 inertia: float, damping: float, h: float, g_exit: float, g_entry: float,
                 swing: float, f_v_exit: float, f_v_entry: float, length: float, knee: float
                 ) -> tuple[float, int, float, float]:
    """One sub-step of length ``h`` [s] of a piston at ``y`` [m], ``v`` [m/s] under the force
    ``f_a`` [N] with the seal's friction: the new velocity w solves
    inertia (w - v) = f_a - F(y) - K h w - (F_v + damping) w, the friction's stiffness K
    [N/m] implicit (``inertia`` = M / h [kg/s], ``damping`` [N s/m] the caller's implicit
    linear terms, F_v [N s/m] the viscous coefficient ``f_v_exit`` or ``f_v_entry`` of the
    direction; levels ``g_exit``, ``g_entry`` and full swing ``swing`` [N]: module
    docstring). A w against the branch's direction is a reversal: (y, F(y)) is pushed on the
    stack ``points`` (``n`` of them; the oldest dropped when it is full; from sliding it is the
    only point already) and the branch turns. Returns (w [m/s], the number of points, the
    direction, the friction [N] at y + h w with its viscous term); ``points`` changes in place."""
    f, k, n = seal_force(y, points, n, d, g_exit, g_entry, swing, length, knee)
    f_v = f_v_exit if d > 0.0 else f_v_entry
    w = (inertia * v + f_a - f) / (inertia + max(k, 0.0) * h + f_v + damping)
    if w * d < 0.0:
        if not (n == 1 and points[0] == y):  # sliding, the only point is here already
            if 2 * n == points.shape[0]:
                points[:-2] = points[2:].copy()
                n -= 1
            points[2 * n], points[2 * n + 1] = y, f
            n += 1
        d = -d
        f, k, n = seal_force(y, points, n, d, g_exit, g_entry, swing, length, knee)
        f_v = f_v_exit if d > 0.0 else f_v_entry
        w = (inertia * v + f_a - f) / (inertia + max(k, 0.0) * h + f_v + damping)
    f, _, n = seal_force(y + h * w, points, n, d, g_exit, g_entry, swing, length,
                         knee)
    return w, n, d, f + f_v * w
