"""Jet-pipe servo valve: the linear electro-mechanical chain and the jet-pipe characteristic.

Signal path (docs/model.md)::

    u [V] -> clip(+-command_limit) -> delay -> G_lag(s) * G_jp(s)/G_jp(0) -> u_f [V]
          -> (hysteresis effect) -> u_eq = clip(u_f, -2.8, 3.0) [V] -> flow map

G_jp is the third-order torque-motor model of Eq. 4 (Table 1), normalised to unit DC gain so that
u_f is an equivalent voltage; G_lag is the lead-lag of Eq. 9. The jet-pipe position is the
midpoint characteristic of Eq. 5 read from voltage to position with the sign flipped, saturated at
+-1 mm; that saturation is what bounds u_eq.
"""

from __future__ import annotations

import math

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from scipy import signal

#: Eq. 5 breakpoints: jet-pipe position [mm] and midpoint-line voltage [V]. Eq. 5's first and
#: fourth lines meet 8 mV apart at x = -0.46 mm; the node there keeps the central line exact.
_X_MM = np.array([-1.0, -0.76, -0.46, 0.46, 0.84, 1.0])
_U_V = np.array([3.0, -5.475 * 0.24 + 3.0, -2.9 * -0.46 - 0.03, -2.9 * 0.46 - 0.03, -2.0, -2.8])


def midpoint_voltage(x_mm: np.ndarray | float) -> np.ndarray:
    """Eq. 5: voltage [V] of the hysteresis midpoint lines at jet-pipe position ``x_mm`` [mm]."""
    return np.interp(x_mm, _X_MM, _U_V)


def jetpipe_position(u_f: np.ndarray | float) -> np.ndarray:
    """Jet-pipe position [m] for equivalent voltage ``u_f`` [V]: -h^-1(u_f), saturated at 1 mm.

    The sign flip makes positive voltage give positive position (docs/model.md).
    """
    x_mm = np.interp(u_f, _U_V[::-1], _X_MM[::-1])
    return -x_mm * 1e-3


#: Jet-pipe length r of Table 1 [m]. It scales G_jp only, so it cancels in the unit-DC-gain chain.
JET_PIPE_LENGTH = 0.0225

#: Bounds of the equivalent voltage seen by the flow map: h(+-1 mm) [V].
U_EQ_MIN = float(midpoint_voltage(1.0))
U_EQ_MAX = float(midpoint_voltage(-1.0))


def jetpipe_tf(p: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 4: numerator and denominator of G_jp(s) = X(s)/U(s) [m/V] from Table 1 parameters."""
    kt = p["valve.torque_constant"]
    kb = p["valve.back_emf_constant"]
    res = p["valve.coil_resistance"]
    ind = p["valve.coil_inductance"]
    jr = p["valve.rotor_inertia"]
    kf = p["valve.friction_coefficient"]
    ks = p["valve.magnetic_stiffness"]
    num = np.array([JET_PIPE_LENGTH * kt / (jr * ind)])
    den = np.array([1.0, kf / jr + res / ind, (res * kf + kb * kt + ks * ind) / (jr * ind),
                    res * ks / (jr * ind)])
    return num, den


def valve_tf(p: Mapping[str, Any], extra_lag_hz: float | None = None,
             extra_lag_damping: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unit-DC-gain valve chain G_lag(s) G_jp(s)/G_jp(0) [V/V], without the delay.

    ``extra_lag_hz`` appends a lag (valve_lag effect): first order, 1 / (s / w + 1), with that
    corner frequency [Hz]; or, given ``extra_lag_damping`` zeta, second order,
    w^2 / (s^2 + 2 zeta w s + w^2), with that natural frequency.
    """
    num_jp, den_jp = jetpipe_tf(p)
    num = num_jp * den_jp[-1] / num_jp[-1]
    wz, wp = p["valve.lag_zero"], p["valve.lag_pole"]
    num = np.polymul(num, [1.0 / wz, 1.0])
    den = np.polymul(den_jp, [1.0 / wp, 1.0])
    if extra_lag_hz is not None:
        w = 2.0 * np.pi * extra_lag_hz
        lag = ([1.0 / w, 1.0] if extra_lag_damping is None else
               [1.0 / w**2, 2.0 * extra_lag_damping / w, 1.0])
        den = np.polymul(den, lag)
    return num, den


@dataclass(frozen=True)
class DiscreteValve:
    """The valve chain discretised exactly (zero-order hold) at the integration sub-step."""

    a: np.ndarray  #: state matrix (n, n)
    b: np.ndarray  #: input vector (n,)
    c: np.ndarray  #: output vector (n,)
    d: float  #: feed-through
    delay_steps: int  #: total transport delay, whole sub-steps
    delay_fraction: float  #: and the fraction of a sub-step beyond them, in [0, 1)


def discretise_valve(p: Mapping[str, Any], h: float, extra_lag_hz: float | None = None,
                     extra_delay: float = 0.0, extra_lag_damping: float | None = None
                     ) -> DiscreteValve:
    """Discretise the valve chain at sub-step ``h`` [s]; the delay in whole sub-steps and a
    fraction of one (the kernel interpolates the delay line linearly between them, so the
    delay is continuous: a fit can move it by less than a sub-step).

    The result is cached by the chain's parameters and the arguments, so models that differ
    elsewhere (an experiment's initial state, a chamber or friction parameter) share one
    discretisation: treat its arrays as read-only.
    """
    values = tuple(p[name] for name in _CHAIN_PARAMS)
    return _discretise(values, h, extra_lag_hz, extra_delay, extra_lag_damping)


#: The parameters the discretised chain depends on (Eq. 4, 9, 10).
_CHAIN_PARAMS = ("valve.torque_constant", "valve.back_emf_constant", "valve.coil_resistance",
                 "valve.coil_inductance", "valve.rotor_inertia", "valve.friction_coefficient",
                 "valve.magnetic_stiffness", "valve.lag_zero", "valve.lag_pole", "valve.delay")


@lru_cache(maxsize=64)
def _discretise(values: tuple[float, ...], h: float, extra_lag_hz: float | None,
                extra_delay: float, extra_lag_damping: float | None) -> DiscreteValve:
    p = dict(zip(_CHAIN_PARAMS, values))
    num, den = valve_tf(p, extra_lag_hz, extra_lag_damping)
    a, b, c, d = signal.tf2ss(num, den)
    ad, bd, cd, dd, _ = signal.cont2discrete((a, b, c, d), h, method="zoh")
    steps = (p["valve.delay"] + extra_delay) / h
    whole = math.floor(steps + 1e-9)  # a delay of whole sub-steps up to round-off stays whole
    fraction = max(steps - whole, 0.0) if steps - whole > 1e-9 else 0.0
    return DiscreteValve(np.ascontiguousarray(ad), np.ascontiguousarray(bd[:, 0]),
                         np.ascontiguousarray(cd[0]), float(dd[0, 0]), int(whole), fraction)


@dataclass(frozen=True)
class SampledValve:
    """The discretised chain advanced a whole sample at a time (the lifted system).

    The command is held over each sample, so over the sub-steps of sample k the delayed command
    mixes only two samples, u[k - m] and u[k - m - 1] (m = ``delay_samples``), with weights fixed
    by the delay. From the chain's state x at the start of the sample, sub-step s's output is
    ``c[s] @ x + h[s] @ (u[k - m], u[k - m - 1])`` and the next sample's state
    ``a @ x + g @ (u[k - m], u[k - m - 1])``: the sub-step recursion's result with under half its
    multiplications (80 a sample instead of 196 at order 6 and 4 sub-steps).
    """

    a: np.ndarray  #: state over one sample, A^substeps (n, n)
    g: np.ndarray  #: state from the two delayed commands (n, 2)
    c: np.ndarray  #: sub-step outputs from the state (substeps, n)
    h: np.ndarray  #: sub-step outputs from the two delayed commands (substeps, 2)
    delay_samples: int  #: m: whole samples of delay before the two commands


def sample_valve(p: Mapping[str, Any], dt: float, substeps: int,
                 extra_lag_hz: float | None = None, extra_delay: float = 0.0,
                 extra_lag_damping: float | None = None) -> SampledValve:
    """:func:`discretise_valve` at the sub-step dt / ``substeps`` [s], lifted to the sample
    time ``dt`` [s] (:class:`SampledValve`); cached like it (treat its arrays as read-only)."""
    values = tuple(p[name] for name in _CHAIN_PARAMS)
    return _sample(values, dt, substeps, extra_lag_hz, extra_delay, extra_lag_damping)


@lru_cache(maxsize=64)
def _sample(values: tuple[float, ...], dt: float, substeps: int, extra_lag_hz: float | None,
            extra_delay: float, extra_lag_damping: float | None) -> SampledValve:
    chain = _discretise(values, dt / substeps, extra_lag_hz, extra_delay, extra_lag_damping)
    # Sub-step s of sample k reads the command delay_steps + fraction sub-steps back, linearly
    # interpolated between the sub-steps around it: whole samples m, then sub-steps r.
    m, r = divmod(chain.delay_steps, substeps)
    f = chain.delay_fraction
    s = np.arange(substeps)
    recent = (1.0 - f) * (s >= r) + f * (s >= r + 1)  # weight of u[k - m]
    weights = np.stack([recent, 1.0 - recent], axis=1)  # (substeps, 2)
    n = chain.b.shape[0]
    from_state, from_input = np.eye(n), np.zeros((n, 2))  # x(s) = from_state x + from_input u
    c_rows, h_rows = [], []
    for w in weights:
        c_rows.append(chain.c @ from_state)
        h_rows.append(chain.c @ from_input + chain.d * w)
        from_state = chain.a @ from_state
        from_input = chain.a @ from_input + np.outer(chain.b, w)
    return SampledValve(np.ascontiguousarray(from_state), np.ascontiguousarray(from_input),
                        np.array(c_rows), np.array(h_rows), int(m))
