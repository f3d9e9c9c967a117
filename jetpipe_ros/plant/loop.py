"""The plant's compiled integration loop, apart from the model's kernel.

Per sub-step of length h = dt / substeps (8 a 1 ms sample, and never longer than 125 us at other
sample times: :func:`~jetpipe_ros.plant.constants.substeps_of`; the model integrates in 4):

1. the valve chain advances by Runge-Kutta steps behind the continuous delay (the sample's
   command entered the command ring), then the plays and the null offset give u_eq
   (:mod:`valve`);
2. the regulator and the hose advance (the supply_droop effect); the valve flows (Eq. 8 by
   similarity, pressure-dependent gain; through the port volumes and the lines when they are
   on, advanced over the sub-step against the chambers' pressures at its start:
   :mod:`passages`) and the ISO 6358 and seal-gap leaks move gas mass (and
   enthalpy) at fixed volume (:mod:`chambers`), by Heun's rule (second order: the flows at the
   start and at the Euler prediction, averaged; u_eq the valve's output averaged over the
   sub-step);
3. the piston's velocity and position advance implicitly under the pressures so reached (the
   gas spring linearised implicit as well), with stick-slip, bristles or a measured seal
   (:mod:`seal`), cushions, a compliant load and the inelastic end stops (:mod:`mechanics`);
4. the chambers' gas follows the volume change (isothermal, or isentropic then exact wall heat
   exchange) and the pressures are read from mass (and energy) and volume;
5. the transducers advance on the pressures held over the sub-step and the position's mean over
   it (:mod:`sensors`).

With the regulators on (``chamber.regulated``) the pressures stay where they are and the gas
mass follows the volume; with the piston locked it stays, at zero velocity and friction.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from jetpipe_ros.plant.air import GAMMA_AIR, P_ATM
from jetpipe_ros.plant.chambers import (exchange_heat, gap_leak_mass, isentropic_energy,
                                        leak_mass, volumes)
from jetpipe_ros.plant.constants import (DRAWN, E1, E2, FRICTION, HEAD, LINE, LINE_SIZE, LOAD,
                                         M1, M2, N_PLAY, N_SEAL, N_VALVE, P1, P2, PLAY, PORT,
                                         POSITION, REGULATOR, SEAL, SEAL_D, SEAL_N, SENSOR1,
                                         SENSOR2, STEP, STUCK, SUPPLY, UCMD, UEQ, VALVE, V, Y, Z,
                                         PlantConstants)
from jetpipe_ros.plant.linear import second_order_step
from jetpipe_ros.plant.mechanics import bristles, directional_levels, stick_slip
from jetpipe_ros.plant.passages import filter_flow, line_step
from jetpipe_ros.plant.seal import seal_force, seal_substep
from jetpipe_ros.plant.sensors import measure
from jetpipe_ros.plant.valve import (U_EQ_HIGH, U_EQ_LOW, chain_output, chain_substep,
                                     valve_inflow, weighted_plays)


@njit(cache=True, error_model="numpy")
def _valve(c: PlantConstants, x: np.ndarray, xv: np.ndarray, ring: np.ndarray, head: int,
           j: int) -> float:
    """u_eq [V] over sub-step ``j`` of the sample whose command is at ``ring[head]`` (the
    chain's output averaged over the sub-step's ends: the flow integrates trapezoidally in
    it); advances the valve's states."""
    u_start = chain_output(c.chain, c.lead, xv)
    chain_substep(c.chain, xv, ring, head, j, c.substeps, c.delay, c.dt / c.substeps,
                  c.valve_steps)
    u_f = 0.5 * (u_start + chain_output(c.chain, c.lead, xv))
    if c.play_thresholds.shape[0]:
        u_f = weighted_plays(x[PLAY:PLAY + N_PLAY], c.play_thresholds, c.play_weights, u_f)
    return min(max(c.valve_gain * u_f + c.null_offset, U_EQ_LOW), U_EQ_HIGH)


@njit(cache=True, error_model="numpy")
def _passage(c: PlantConstants, x: np.ndarray, u_eq: float, chamber: int, p_chamber: float,
             h: float) -> tuple[float, float]:
    """Advance the port and the line before one chamber (``chamber`` 0 or 1, at ``p_chamber``
    [Pa]) over a sub-step ``h`` [s] in ``c.passage_steps`` inner steps (passages docstring);
    return the mean flows [kg/s] the chamber receives and the valve delivers."""
    n = c.passage_steps
    dt = h / n
    rt = c.r_gas * c.t_wall
    sign = 1.0 if chamber == 0 else -1.0
    base = LINE + chamber * LINE_SIZE
    port = PORT + chamber
    received = 0.0
    valve = 0.0
    for _ in range(n):
        p_in = x[port] if c.port else (x[base] if c.line else p_chamber)
        q_v = valve_inflow(sign * u_eq, p_in, x[SUPPLY], c.gain_charge, c.gain_discharge,
                           c.gain_slope, c.shape, c.shape_phase)
        q = q_v
        if c.port:
            # Heun: the port's flows at the step's start and at the Euler prediction.
            down = x[base] if c.line else p_chamber
            q_f = filter_flow(c.port_conductance, p_in, down, rt)
            guess = p_in + dt * rt / c.port_volume * (q_v - q_f)
            q_v2 = valve_inflow(sign * u_eq, guess, x[SUPPLY], c.gain_charge, c.gain_discharge,
                                c.gain_slope, c.shape, c.shape_phase)
            q_f2 = filter_flow(c.port_conductance, guess, down, rt)
            q_v = 0.5 * (q_v + q_v2)
            q = 0.5 * (q_f + q_f2)
            x[port] += dt * rt / c.port_volume * (q_v - q)
        if c.line:
            q = line_step(x, base, q, p_chamber, c.line_wave, c.line_inertance, c.line_bore,
                          c.line_area, c.segment_length, rt, dt)
        received += q
        valve += q_v
    return received / n, valve / n


@njit(cache=True, error_model="numpy")
def _valve_flows(c: PlantConstants, x: np.ndarray, u_eq: float, h: float
                 ) -> tuple[float, float]:
    """The flows [kg/s] reaching chambers 1 and 2 over the sub-step through the ports and the
    lines when they are on (passages docstring); records what the valve draws."""
    q1, v1 = _passage(c, x, u_eq, 0, x[P1], h)
    q2, v2 = _passage(c, x, u_eq, 1, x[P2], h)
    x[DRAWN] = max(v1, 0.0) + max(v2, 0.0)
    return q1, q2


@njit(cache=True, error_model="numpy")
def _supply(c: PlantConstants, x: np.ndarray, regulator_decay: float, hose_decay: float
            ) -> None:
    """Advance the regulator and the hose one sub-step (valve docstring), the flow the valve
    draws from the previous sub-step, each part exact with the other held."""
    hose = c.hose_conductance * (x[REGULATOR] - x[SUPPLY])
    outlet = c.supply_set - c.supply_droop * hose - c.supply_droop_2 * hose * abs(hose)
    x[REGULATOR] = outlet + (x[REGULATOR] - outlet) * regulator_decay
    line = x[REGULATOR] - x[DRAWN] / c.hose_conductance
    x[SUPPLY] = line + (x[SUPPLY] - line) * hose_decay


@njit(cache=True, error_model="numpy")
def _temperature(c: PlantConstants, x: np.ndarray, m: int, e: int) -> float:
    return x[e] / (x[m] * c.cv) if c.thermal else c.t_wall


@njit(cache=True, error_model="numpy")
def _vent(c: PlantConstants, x: np.ndarray, m: int, e: int, p: float, t: float, vol: float,
          kappa: float, h: float) -> None:
    """Leak one chamber (mass at ``m``, energy at ``e``) to atmosphere over a sub-step; air
    coming in is at the wall temperature."""
    t_up = t if p > P_ATM else c.t_wall
    dm = leak_mass(c.leak_atm, c.leak_b, p, P_ATM, t, c.t_wall, kappa * t_up / vol, h)
    x[m] -= dm
    if c.thermal:
        x[e] -= (c.cv + c.r_gas) * t_up * dm


@njit(cache=True, error_model="numpy")
def _flows(c: PlantConstants, x: np.ndarray, u_eq: float, vol1: float, vol2: float,
           h: float, q1: float, q2: float) -> None:
    """Move gas through the valve and the leaks over a sub-step at fixed volume; the valve's
    flows are ``q1``, ``q2`` [kg/s] through ports or lines, else the map's at the present
    pressures."""
    p1 = x[P1]
    p2 = x[P2]
    if not (c.port or c.line):
        ps = x[SUPPLY]
        q1 = valve_inflow(u_eq, p1, ps, c.gain_charge, c.gain_discharge, c.gain_slope, c.shape,
                          c.shape_phase)
        q2 = valve_inflow(-u_eq, p2, ps, c.gain_charge, c.gain_discharge, c.gain_slope,
                          c.shape, c.shape_phase)
        x[DRAWN] = max(q1, 0.0) + max(q2, 0.0)
    t1 = _temperature(c, x, M1, E1)
    t2 = _temperature(c, x, M2, E2)
    cp = c.cv + c.r_gas
    x[M1] += h * q1
    x[M2] += h * q2
    if c.thermal:
        x[E1] += h * cp * q1 * (c.t_supply if q1 > 0.0 else t1)
        x[E2] += h * cp * q2 * (c.t_supply if q2 > 0.0 else t2)
    # Pressure per kg moved at the upstream temperature: r T / V, or gamma r T / V adiabatic.
    kappa = GAMMA_AIR * c.r_gas if c.thermal else c.r_gas
    if c.leak_cross > 0.0 or c.gap_width > 0.0:
        t_up = t1 if p1 > p2 else t2
        stiffness = kappa * t_up * (1.0 / vol1 + 1.0 / vol2)
        dm = leak_mass(c.leak_cross, c.leak_b, p1, p2, t1, t2, stiffness, h) + \
            gap_leak_mass(c.gap_width, c.gap_height, c.gap_length, c.gap_loss, p1, p2,
                          c.r_gas * t_up, stiffness, h)
        x[M1] -= dm
        x[M2] += dm
        if c.thermal:
            x[E1] -= cp * t_up * dm
            x[E2] += cp * t_up * dm
    if c.leak_atm > 0.0:
        _vent(c, x, M1, E1, p1, t1, vol1, kappa, h)
        _vent(c, x, M2, E2, p2, t2, vol2, kappa, h)


@njit(cache=True, error_model="numpy")
def _pressures(c: PlantConstants, x: np.ndarray, vol1: float, vol2: float) -> None:
    if c.thermal:
        x[P1] = (GAMMA_AIR - 1.0) * x[E1] / vol1
        x[P2] = (GAMMA_AIR - 1.0) * x[E2] / vol2
    else:
        x[P1] = x[M1] * c.r_gas * c.t_wall / vol1
        x[P2] = x[M2] * c.r_gas * c.t_wall / vol2


@njit(cache=True, error_model="numpy")
def _friction(c: PlantConstants, x: np.ndarray, f: float, damping: float, h: float,
              points: np.ndarray) -> tuple[float, bool, float, float, int, float]:
    """(velocity, stuck, bristle deflection, friction, the measured seal's number of reversal
    points and branch direction) after a sub-step under force ``f`` [N] and extra implicit
    ``damping`` [N s/m]; the state is not changed (the seal's reversal points change in
    ``points``, a copy of the state's)."""
    if c.seal:
        g_exit, g_entry, f_v_exit, f_v_entry = directional_levels(c.planes, x[V], x[P1], x[P2])
        rest_exit, rest_entry, _, _ = directional_levels(c.planes, 0.0, x[P1], x[P2])
        w, n, d, friction = seal_substep(
            x[Y], x[V], points, int(x[SEAL_N]), x[SEAL_D], f, c.mass / h, damping, h, g_exit,
            g_entry, rest_exit + rest_entry, f_v_exit, f_v_entry, c.seal_length, c.seal_knee)
        return w, False, x[Z], friction, n, d
    if c.bristles:
        w, z, friction = bristles(x[V], x[Z], f, c.planes, x[P1], x[P2], c.mass / h, damping, h,
                                  c.sigma0, c.sigma1, c.v_damp, c.z_fraction)
        return w, False, z, friction, int(x[SEAL_N]), x[SEAL_D]
    w, stuck, friction = stick_slip(x[V], x[STUCK] != 0.0, f, c.planes, x[P1], x[P2],
                                    c.mass / h, damping)
    return w, stuck, x[Z], friction, int(x[SEAL_N]), x[SEAL_D]


@njit(cache=True, error_model="numpy")
def _mechanics(c: PlantConstants, x: np.ndarray, f_load: float, h: float,
               points: np.ndarray) -> None:
    """Advance piston velocity and position one sub-step (mechanics docstring); ``points`` is
    scratch for the measured seal's reversal points (2 N_SEAL)."""
    y = x[Y]
    if c.seal:
        points[:] = x[SEAL:SEAL + 2 * N_SEAL]
    f_a = c.area * (x[P1] - x[P2]) - f_load - c.spring_k * (y - c.spring_y0)
    # The gas spring implicit too: S (p1 - p2) falls by k_gas dy as the piston moves dy = h w,
    # k_gas = n S^2 (p1 / V1 + p2 / V2), n = 1 isothermal, gamma isentropic.
    gas = 0.0
    if not c.regulated:
        vol1, vol2 = volumes(y, c.area, c.v01, c.v02)
        gas = (GAMMA_AIR if c.thermal else 1.0) * c.area * c.area * \
            (x[P1] / vol1 + x[P2] / vol2) * h
    gas += c.spring_k * h  # the load spring implicit as well
    if c.load:
        # The compliant load held: k_x (y + h w - x_l - h v_l) + c_x (w - v_l), w implicit.
        f_a -= c.load_k * (y - x[LOAD] - h * x[LOAD + 1]) - c.load_c * x[LOAD + 1]
        gas += c.load_k * h + c.load_c
    depth = abs(y) - (c.y_max - c.cushion_length)
    side = math.copysign(1.0, y)
    if c.cushion_length > 0.0 and depth > 0.0:
        # Spring-damper at the end of the sub-step, k (depth + h side w) + c side w, implicit.
        w, stuck, z, friction, n, d = _friction(
            c, x, f_a - side * c.cushion_k * depth, gas + c.cushion_k * h + c.cushion_c, h,
            points)
        if c.cushion_k * (depth + h * side * w) + c.cushion_c * side * w < 0.0:
            # It would pull: let go.
            if c.seal:
                points[:] = x[SEAL:SEAL + 2 * N_SEAL]
            w, stuck, z, friction, n, d = _friction(c, x, f_a, gas, h, points)
    else:
        w, stuck, z, friction, n, d = _friction(c, x, f_a, gas, h, points)
    y_new = y + h * w
    if abs(y_new) > c.y_max:
        y_new = math.copysign(c.y_max, y_new)
        w = 0.0
        stuck = True
        if c.bristles:
            # Against the stop the bristles deflect only by the distance the piston really
            # moved (elastically: at rest nothing flows); the stop takes the rest of the force.
            z = x[Z] + (y_new - y)
            friction = c.sigma0 * z
        if c.seal:
            # The seal holds what it holds where the stop left it; the stop takes the rest.
            g_exit, g_entry, _, _ = directional_levels(c.planes, 0.0, x[P1], x[P2])
            friction, _, n = seal_force(y_new, points, n, d, g_exit, g_entry, g_exit + g_entry,
                                        c.seal_length, c.seal_knee)
    if c.load:
        # The load follows, implicit in its velocity: m_x (v_l' - v_l) / h = k_x (y' - x_l -
        # h v_l') + c_x (w - v_l').
        inertia = c.load_mass / h
        v_l = (inertia * x[LOAD + 1] + c.load_k * (y_new - x[LOAD]) + c.load_c * w) / \
            (inertia + c.load_k * h + c.load_c)
        x[LOAD] += h * v_l
        x[LOAD + 1] = v_l
    x[Y] = y_new
    x[V] = w
    x[STUCK] = 1.0 if stuck else 0.0
    x[Z] = z
    if c.seal:
        x[SEAL_N], x[SEAL_D] = n, d
        x[SEAL:SEAL + 2 * N_SEAL] = points
    x[FRICTION] = friction


@njit(cache=True, error_model="numpy")
def advance(c: PlantConstants, x: np.ndarray, ring: np.ndarray, u: np.ndarray,
            f_load: np.ndarray, noise: np.ndarray, out: np.ndarray) -> None:
    """Advance ``len(u)`` samples from state ``x`` (in place): ``u`` [V] and ``f_load`` [N]
    held over each sample, ``noise`` (n, 3) standard normals, ``out[k]`` the outputs at the end
    of sample k; ``ring`` the commands of the last samples (in place). Commands must be
    finite."""
    h = c.dt / c.substeps
    xv = x[VALVE:VALVE + N_VALVE].copy()
    points = np.empty(2 * N_SEAL)
    head = int(x[HEAD])
    regulator_decay = math.exp(-h / c.supply_tau)
    hose_decay = math.exp(-h * c.r_gas * c.t_wall * c.hose_conductance / c.hose_volume)
    for k in range(u.shape[0]):
        u_k = min(max(u[k], -c.u_limit), c.u_limit)
        x[UCMD] = u_k
        head = (head + 1) % ring.shape[0]
        ring[head] = u_k
        for j in range(c.substeps):
            u_eq = _valve(c, x, xv, ring, head, j)
            x[UEQ] = u_eq
            p1_held = x[P1]
            p2_held = x[P2]
            y_held = x[Y]
            vol1, vol2 = volumes(x[Y], c.area, c.v01, c.v02)
            if c.supply_droops:
                _supply(c, x, regulator_decay, hose_decay)
            if not c.regulated:
                q1 = q2 = 0.0
                if c.port or c.line:
                    q1, q2 = _valve_flows(c, x, u_eq, h)
                # Heun: the flows at the start and at the Euler prediction, averaged.
                m1, m2, e1, e2 = x[M1], x[M2], x[E1], x[E2]
                _flows(c, x, u_eq, vol1, vol2, h, q1, q2)
                _pressures(c, x, vol1, vol2)
                _flows(c, x, u_eq, vol1, vol2, h, q1, q2)
                x[M1] = 0.5 * (m1 + x[M1])
                x[M2] = 0.5 * (m2 + x[M2])
                x[E1] = 0.5 * (e1 + x[E1])
                x[E2] = 0.5 * (e2 + x[E2])
                _pressures(c, x, vol1, vol2)
            if c.locked:
                x[V] = 0.0
                x[FRICTION] = 0.0
            else:
                _mechanics(c, x, f_load[k], h, points)
            new1, new2 = volumes(x[Y], c.area, c.v01, c.v02)
            if c.regulated:
                t1 = _temperature(c, x, M1, E1)
                t2 = _temperature(c, x, M2, E2)
                x[M1] = x[P1] * new1 / (c.r_gas * t1)
                x[M2] = x[P2] * new2 / (c.r_gas * t2)
                x[E1] = x[M1] * c.cv * t1
                x[E2] = x[M2] * c.cv * t2
            else:
                if c.thermal:
                    x[E1] = exchange_heat(isentropic_energy(x[E1], vol1, new1), x[M1], new1,
                                          c.area, c.heat_coefficient, c.t_wall, c.cv, h)
                    x[E2] = exchange_heat(isentropic_energy(x[E2], vol2, new2), x[M2], new2,
                                          c.area, c.heat_coefficient, c.t_wall, c.cv, h)
                _pressures(c, x, new1, new2)
            if c.sensor:
                second_order_step(c.sensor_a, c.sensor_b, x, SENSOR1, p1_held)
                second_order_step(c.sensor_a, c.sensor_b, x, SENSOR2, p2_held)
            if c.position_filter:
                second_order_step(c.position_a, c.position_b, x, POSITION,
                                  0.5 * (y_held + x[Y]))
        x[STEP] += 1.0
        measure(c, x, noise[k], out[k])
    x[VALVE:VALVE + N_VALVE] = xv
    x[HEAD] = head
