"""The integration kernel: one compiled loop that advances the whole actuator.

Every simulator (the ROS node, the batch simulator, the diagnosis) advances the model through
:func:`advance`; there is no second copy of the physics. The state is a flat float array (layout
below) plus a ring buffer holding the valve's delay line. Per sub-step of length h:

1. the command enters the delay line; the valve chain (exactly discretised) produces u_f;
2. the hysteresis play operator (effect) and the jet-pipe saturation give u_eq;
3. the flow map, leakage (effect) and Eq. 11-12 advance the pressures explicitly;
4. the piston velocity advances with the viscous friction implicit (F_v/M reaches ~4000 1/s),
   and Eq. 15's stick condition is checked whenever the velocity reaches or crosses zero, so
   stick-slip cannot chatter; with the friction_dynamics effect a LuGre bristle state replaces
   the stick logic;
5. the position advances (semi-implicit Euler) and stops inelastically at the end stops.

Subsystems can be driven instead of simulated, to judge them apart (the diagnosis) or to emulate
test rigs: a ``drive`` array prescribes, sample by sample, the piston position and velocity
(the chambers then see the recorded motion) and/or the chamber pressures (the mechanics then see
the recorded pressures). With ``regulated`` the pressures stay where they are (ideal regulators).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from jetpipe_ros.model.chamber import (chamber_volumes, pressure_rates,
                                      pressure_temperature_rates)
from jetpipe_ros.model.flow import GAMMA_AIR, P_ATM, chamber_inflow, orifice_flow
from jetpipe_ros.model.friction import friction_parameters, static_friction, stribeck_force
from jetpipe_ros.model.valve import U_EQ_MAX, U_EQ_MIN

# State layout: scalars, then the hysteresis play operators, then the valve chain.
Y, V, P1, P2, STUCK, Z, PS1, PS2, STEP, HEAD, UCMD, UEQ, FRICTION, T1, T2 = range(15)
PLAY = 15  #: first of the MAX_PLAY hysteresis play-operator outputs
MAX_PLAY = 8
VALVE = PLAY + MAX_PLAY  #: first of the valve chain's states

# Columns of the ``drive`` array of :func:`advance` (NaN = simulate that part).
DRIVE_Y, DRIVE_V, DRIVE_P1, DRIVE_P2 = range(4)
N_DRIVE = 4

# Output columns of :func:`measure` and :func:`advance`.
OUT_T, OUT_U, OUT_Y, OUT_V, OUT_P1, OUT_P2, OUT_FRICTION, OUT_FORCE, OUT_UEQ, \
    OUT_Y_MEAS, OUT_P1_MEAS, OUT_P2_MEAS = range(12)
N_OUT = 12

MIN_PRESSURE = 1.0e3  #: numerical floor on chamber pressure [Pa]


class Constants(NamedTuple):
    """Everything the kernel needs, in SI units, built by :func:`actuator.build_constants`."""

    dt: float  #: sample time [s]
    substeps: int  #: sub-steps per sample
    u_limit: float  #: command saturation [V]
    valve_a: np.ndarray  #: discretised valve chain
    valve_b: np.ndarray
    valve_c: np.ndarray
    valve_d: float
    delay_steps: int  #: valve transport delay [sub-steps]
    hysteresis: np.ndarray  #: play thresholds [V], one per element; empty = off
    flow_coef: np.ndarray  #: Eq. 8 coefficients
    p_supply: float  #: supply pressure [Pa]
    leak_cross: float  #: conductance chamber 1 -> 2 [kg/(s Pa)]
    leak_atm: float  #: conductance of each chamber to atmosphere [kg/(s Pa)]
    orifice_cross: float  #: orifice leak area chamber 1 -> 2 [m^2]
    orifice_atm: float  #: orifice leak area of each chamber to atmosphere [m^2]
    polytropic: float  #: polytropic index n
    heat_transfer: float  #: wall heat conductance h A [W/K], 0 = no temperature state
    r_gas: float  #: gas constant r [J/(kg K)]
    t_wall: float  #: wall (and supply) temperature [K]
    rt: float  #: r T [J/kg]
    area: float  #: piston area [m^2]
    v01: float  #: chamber volumes at y = 0 [m^3]
    v02: float
    mass: float  #: moving mass [kg]
    y_max: float  #: end stops at +-y_max [m]
    locked: bool  #: piston clamped
    regulated: bool  #: chamber pressures held (ideal regulators)
    planes: np.ndarray  #: friction planes (2, 4, 3)
    lugre: bool  #: LuGre friction dynamics instead of the stick logic
    sigma0: float  #: bristle stiffness [N/m]
    sigma1: float  #: bristle damping [N s/m]
    sensor_tau: float  #: pressure sensor lag [s], 0 = ideal
    sensor_bias: float  #: pressure sensor bias [Pa]
    sensor_drift: float  #: pressure sensor drift [Pa/s]
    sigma_p: float  #: pressure noise [Pa]
    sigma_y: float  #: position noise [m]


@njit(cache=True, error_model="numpy")
def measure(c: Constants, x: np.ndarray, noise: np.ndarray, out: np.ndarray) -> None:
    """Write the outputs of state ``x`` into ``out`` (N_OUT,); ``noise`` is 3 standard normals."""
    t = x[STEP] * c.dt
    out[OUT_T] = t
    out[OUT_U] = x[UCMD]
    out[OUT_Y] = x[Y]
    out[OUT_V] = x[V]
    out[OUT_P1] = x[P1]
    out[OUT_P2] = x[P2]
    out[OUT_FRICTION] = x[FRICTION]
    out[OUT_FORCE] = c.area * (x[P1] - x[P2])
    out[OUT_UEQ] = x[UEQ]
    out[OUT_Y_MEAS] = x[Y] + c.sigma_y * noise[0]
    offset = c.sensor_bias + c.sensor_drift * t
    if c.sensor_tau > 0.0:
        out[OUT_P1_MEAS] = x[PS1] + offset + c.sigma_p * noise[1]
        out[OUT_P2_MEAS] = x[PS2] + offset + c.sigma_p * noise[2]
    else:
        out[OUT_P1_MEAS] = x[P1] + offset + c.sigma_p * noise[1]
        out[OUT_P2_MEAS] = x[P2] + offset + c.sigma_p * noise[2]


@njit(cache=True, error_model="numpy", inline="always")
def _valve_substep(c: Constants, xv: np.ndarray, tmp: np.ndarray, ring: np.ndarray, head: int,
                   u: float, play: np.ndarray) -> float:
    """Advance the valve chain one sub-step from delay-line slot ``head``; return u_eq [V].

    ``xv`` holds the chain's state (updated in place, ``tmp`` is scratch of the same size);
    ``play`` the hysteresis operators' outputs [V] (updated in place).
    """
    ring[head] = u
    u_d = ring[(head - c.delay_steps) % ring.shape[0]]
    va = c.valve_a
    vb = c.valve_b
    vc = c.valve_c
    nv = vb.shape[0]
    u_f = c.valve_d * u_d
    for i in range(nv):
        u_f += vc[i] * xv[i]
    for i in range(nv):
        acc = vb[i] * u_d
        for j in range(nv):
            acc += va[i, j] * xv[j]
        # Decaying derivative states would otherwise end in subnormals, which are ~100x slower.
        tmp[i] = acc if abs(acc) > 1e-200 else 0.0
    xv[:] = tmp
    n_play = c.hysteresis.shape[0]
    if n_play:
        # Prandtl-Ishlinskii: the mean of play operators (one element = a single play).
        acc = 0.0
        for i in range(n_play):
            r = c.hysteresis[i]
            play[i] = min(max(play[i], u_f - r), u_f + r)
            acc += play[i]
        u_f = acc / n_play
    return min(max(u_f, U_EQ_MIN), U_EQ_MAX)


@njit(cache=True, error_model="numpy", inline="always")
def _mechanics_substep(c: Constants, x: np.ndarray, f_load: float, h: float) -> None:
    """Advance piston velocity and position one sub-step (Eq. 14 with Eq. 15-18 friction)."""
    p1 = x[P1]
    p2 = x[P2]
    f_a = c.area * (p1 - p2) - f_load
    v = x[V]
    if c.lugre:
        d = math.copysign(1.0, v) if v != 0.0 else (math.copysign(1.0, f_a) if f_a != 0.0
                                                     else math.copysign(1.0, x[Z]))
        f_s, v_s, f_v, f_c = friction_parameters(c.planes, d, p1, p2)
        g = abs(stribeck_force(v, f_s, v_s, f_c))
        a = c.sigma0 * abs(v) / g
        z = x[Z]
        if a * h < 1e-12:
            z_new = z + h * v
        else:
            z_new = v / a + (z - v / a) * math.exp(-a * h)
        # Bristle force sigma0 z + sigma1 dz/dt with dz/dt = v - a z; v implicit.
        v_new = (v + h / c.mass * (f_a - c.sigma0 * z_new + c.sigma1 * a * z_new)) / \
            (1.0 + h * (f_v + c.sigma1) / c.mass)
        x[Z] = z_new
        x[FRICTION] = c.sigma0 * z_new + c.sigma1 * (v_new - a * z_new) + f_v * v_new
    else:
        if x[STUCK] != 0.0:
            d = math.copysign(1.0, f_a)
            f_s, v_s, f_v, f_c = friction_parameters(c.planes, d, p1, p2)
            if abs(f_a) <= abs(f_s):
                x[FRICTION] = f_a
                x[V] = 0.0
                return
            x[STUCK] = 0.0
            v = 0.0
        else:
            d = math.copysign(1.0, v) if v != 0.0 else math.copysign(1.0, f_a)
            f_s, v_s, f_v, f_c = friction_parameters(c.planes, d, p1, p2)
        f_st = stribeck_force(v, f_s, v_s, f_c)
        v_new = (v + h / c.mass * (f_a - f_st)) / (1.0 + h * f_v / c.mass)
        if v_new * d <= 0.0:
            # Velocity reached zero within the step: stick (Eq. 15 decides release next step).
            v_new = 0.0
            x[STUCK] = 1.0
            x[FRICTION] = static_friction(f_a, f_s)
        else:
            x[FRICTION] = f_st + f_v * v_new
    y = x[Y] + h * v_new
    if y > c.y_max or y < -c.y_max:
        y = min(max(y, -c.y_max), c.y_max)
        v_new = 0.0
        x[STUCK] = 1.0
    x[Y] = y
    x[V] = v_new


@njit(cache=True, error_model="numpy", inline="always")
def _chambers_substep(c: Constants, x: np.ndarray, u_eq: float, h: float) -> None:
    """Advance both chamber pressures (and gas temperatures) one sub-step (Eq. 11-13)."""
    p1 = x[P1]
    p2 = x[P2]
    q1 = chamber_inflow(c.flow_coef, u_eq, p1, c.p_supply)
    q2 = chamber_inflow(c.flow_coef, -u_eq, p2, c.p_supply)
    q_x = c.leak_cross * (p1 - p2)
    q1 += -q_x - c.leak_atm * (p1 - P_ATM)
    q2 += q_x - c.leak_atm * (p2 - P_ATM)
    if c.orifice_cross > 0.0 or c.orifice_atm > 0.0:
        t_up = x[T1] if p1 > p2 else x[T2]
        q_x = orifice_flow(c.orifice_cross, p1, p2, c.r_gas * t_up)
        q1 += -q_x - orifice_flow(c.orifice_atm, p1, P_ATM, c.r_gas * x[T1])
        q2 += q_x - orifice_flow(c.orifice_atm, p2, P_ATM, c.r_gas * x[T2])
    vol1, vol2 = chamber_volumes(x[Y], c.area, c.v01, c.v02)
    if c.heat_transfer > 0.0:
        dvol = c.area * x[V]
        dp1, dt1 = pressure_temperature_rates(q1, p1, x[T1], dvol, vol1, c.r_gas, c.t_wall,
                                              GAMMA_AIR, c.heat_transfer)
        dp2, dt2 = pressure_temperature_rates(q2, p2, x[T2], -dvol, vol2, c.r_gas, c.t_wall,
                                              GAMMA_AIR, c.heat_transfer)
        x[T1] = max(x[T1] + h * dt1, 1.0)
        x[T2] = max(x[T2] + h * dt2, 1.0)
    else:
        dp1, dp2 = pressure_rates(q1, q2, p1, p2, x[V], vol1, vol2, c.area, c.rt, c.polytropic)
    x[P1] = max(p1 + h * dp1, MIN_PRESSURE)
    x[P2] = max(p2 + h * dp2, MIN_PRESSURE)


@njit(cache=True, error_model="numpy")
def advance(c: Constants, x: np.ndarray, ring: np.ndarray, u: np.ndarray, f_load: np.ndarray,
            drive: np.ndarray, noise: np.ndarray, out: np.ndarray) -> None:
    """Advance ``len(u)`` samples from state ``x`` (in place).

    ``u`` [V] and ``f_load`` [N] are held over each sample; ``noise`` (n, 3) holds standard
    normals for the sensors; ``out[k]`` receives the outputs at the end of sample k.
    ``drive`` is empty or (n, N_DRIVE): where row k holds finite values, sample k starts from
    the prescribed position [m] and velocity [m/s] (then moves at that velocity, friction not
    computed) and/or holds the prescribed pressures [Pa]. Non-finite commands must be filtered
    by the caller.
    """
    h = c.dt / c.substeps
    nv = c.valve_b.shape[0]
    xv = x[VALVE:VALVE + nv].copy()
    tmp = np.empty(nv)
    play = x[PLAY:PLAY + MAX_PLAY].copy()
    head = int(x[HEAD])
    driven = drive.shape[0] > 0
    for k in range(u.shape[0]):
        u_k = min(max(u[k], -c.u_limit), c.u_limit)
        x[UCMD] = u_k
        fl = f_load[k]
        move = not c.locked
        pressurise = not c.regulated
        if driven:
            if math.isfinite(drive[k, DRIVE_Y]):
                x[Y] = drive[k, DRIVE_Y]
                x[V] = drive[k, DRIVE_V]
                x[FRICTION] = 0.0
                move = False
            if math.isfinite(drive[k, DRIVE_P1]):
                x[P1] = drive[k, DRIVE_P1]
                x[P2] = drive[k, DRIVE_P2]
                pressurise = False
        for _ in range(c.substeps):
            u_eq = _valve_substep(c, xv, tmp, ring, head, u_k, play)
            head = (head + 1) % ring.shape[0]
            x[UEQ] = u_eq
            if pressurise:
                _chambers_substep(c, x, u_eq, h)
            if move:
                _mechanics_substep(c, x, fl, h)
            elif c.locked:
                x[V] = 0.0
                x[FRICTION] = 0.0
            else:
                x[Y] = min(max(x[Y] + h * x[V], -c.y_max), c.y_max)
            if c.sensor_tau > 0.0:
                w = 1.0 - math.exp(-h / c.sensor_tau)
                x[PS1] += w * (x[P1] - x[PS1])
                x[PS2] += w * (x[P2] - x[PS2])
        x[STEP] += 1.0
        measure(c, x, noise[k], out[k])
    x[VALVE:VALVE + nv] = xv
    x[PLAY:PLAY + MAX_PLAY] = play
    x[HEAD] = head
