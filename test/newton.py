"""An independent solution of the piston on the regulated rig (for test_*.py): Eq. 14 with the
paper's Eq. 15, 18 and 20-27 typed from the paper, integrated by scipy.integrate.solve_ivp."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from jetpipe_ros.model.params import FRICTION_PLANES

AREA = 0.005433  #: piston area S [m^2] (Eq. 13)
HALF_STROKE = 0.025  #: end stops at +-25 mm


def paper_friction(p1: float, p2: float) -> tuple[float, float, float, float]:
    """(F_S, v_s, F_v, F_C) of Eq. 20-23 (p2 > p1, entry) or Eq. 24-27 (exit) at ``p1``,
    ``p2`` [Pa], inside the planes' fitted region."""
    phase = "exit" if p1 > p2 else "entry"
    a, b = p1 / 1e5, p2 / 1e5
    return tuple(c[0] + c[1] * a + c[2] * b for c in (  # type: ignore[return-value]
        FRICTION_PLANES[phase][q] for q in ("breakaway", "stribeck_velocity", "viscous",
                                           "coulomb")))


def slide(p1: float, p2: float, f_load: np.ndarray, y0: float, mass: float = 1.0,
          dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The piston at rest at ``y0`` [m] with the chamber pressures held at ``p1``, ``p2`` [Pa]
    and the external load ``f_load`` [N] held over each sample of ``dt`` [s].

    Eq. 15: it stays while |S (p1 - p2) - F_L| <= |F_S|; from the first sample beyond,
    M dv/dt = S (p1 - p2) - F_L - F(v) with Eq. 18's F(v) until it reaches the far end stop.
    Returns (y [m], v [m/s]) at the sample instants, the sample k0 over which it breaks away
    and the number of samples before the end stop.
    """
    f_s, v_s, f_v, f_c = paper_friction(p1, p2)
    f_a = AREA * (p1 - p2) - np.asarray(f_load, dtype=float)
    k0 = int(np.argmax(np.abs(f_a) > abs(f_s)))
    sign = 1.0 if p1 > p2 else -1.0

    def rhs(t: float, x: np.ndarray) -> list[float]:
        k = min(int(t / dt + 1e-9), f_a.size - 1)
        v = x[1]
        friction = f_c + (f_s - f_c) * np.exp(-(v / v_s) ** 2) + f_v * v
        return [v, (f_a[k] - friction) / mass]

    def stop(t: float, x: np.ndarray) -> float:
        return sign * x[0] - HALF_STROKE

    stop.terminal = True  # type: ignore[attr-defined]
    stop.direction = 1.0  # type: ignore[attr-defined]
    t = np.arange(f_a.size) * dt
    sol = solve_ivp(rhs, (t[k0], t[-1]), [y0, 0.0], method="LSODA", t_eval=t[k0:],
                    events=stop, rtol=1e-8, atol=[1e-10, 1e-9])  # stiff: F_v / M ~ 3000 1/s
    n = k0 + sol.y.shape[1]
    y, v = np.full(t.size, y0), np.zeros(t.size)
    y[k0:n], v[k0:n] = sol.y
    return y, v, k0, n
