"""The integration kernel: one compiled loop that advances the whole actuator.

Every simulator (the ROS node, the batch simulator, the diagnosis) advances the model through
:func:`advance`; there is no second copy of the physics. The state is a flat float array (layout
below) plus a ring buffer holding the valve's delay line (one command per sample). Per sub-step
of length h:

1. the delayed command drives the valve chain (exactly discretised), which produces u_f; the
   chain is linear and the command held over a sample, so it advances a whole sample at a time
   (:class:`~jetpipe_ros.model.valve.SampledValve`), its sub-step outputs included;
2. the hysteresis play operator (effect) and the jet-pipe saturation give u_eq;
3. the flow map, leakage (effect) and Eq. 11-12 advance the pressures explicitly; with the
   supply line (effect) the supply pressure the flow map sees is a state, the line volume fed
   through the line conductance from the set pressure and drained by the flow the valve draws
   into the chambers, advanced exactly over the sub-step at that flow; with the valve lag's
   ``flow`` form each chamber receives the map's flow through a second-order lag, advanced
   exactly over the sub-step with the map's flow held (its mean over the sub-step enters); with
   the valve delay's ``line`` form a line between valve and chambers: the map sees each
   chamber's pressure the line's delay ago and its flow reaches the chamber that delay later
   (a history of sub-steps at the end of the state, read between the sub-steps around the
   delay, so the delay is continuous); with its ``hose`` form a lumped hose between valve and
   each chamber (:mod:`~jetpipe_ros.model.hose`): the map reads the pressure at the hose's valve
   end, and the hose's nodes, flows and the chamber's pressure advance together, implicitly,
   in inner steps; with the valve lag's ``port`` form a port volume before each chamber behind
   a restriction (:mod:`~jetpipe_ros.model.port`): the map reads the port's pressure, and the
   port and its chamber advance together, implicitly;
4. the piston velocity advances with the viscous friction implicit (F_v/M reaches ~4000 1/s),
   and Eq. 15's stick condition is checked whenever the velocity reaches or crosses zero, so
   stick-slip cannot chatter; with the friction_dynamics effect a LuGre bristle state or
   Maxwell-slip elements replace the stick logic (the elements' stiffness implicit too); the
   bore profile scales the friction levels at the piston's position;
5. the position advances (semi-implicit Euler) and stops inelastically at the end stops.

Steps 1-2 depend on the command only, so :func:`advance` runs them ahead over a block of samples
(:func:`_valve_pass`) and steps 3-5 after (:func:`_physics_pass`); the arithmetic of a sample
does not depend on the block around it, so one sample at a time (the node) and a whole run give
the same bits.

Subsystems can be driven instead of simulated, to judge them apart (the diagnosis) or to emulate
test rigs: a ``drive`` array prescribes, sample by sample, the piston position and velocity
(the chambers then see the recorded motion) and/or the chamber pressures (the mechanics then see
the recorded pressures; with the heat-transfer form the gas temperatures go on following them
and the motion through the energy balance, so a prediction that restarts after pressures held
on measurements starts from the gas temperature they imply). With ``regulated`` the pressures
stay where they are (ideal regulators).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from jetpipe_ros.model.chamber import (chamber_volumes, pressure_rates,
                                      pressure_temperature_rates)
from jetpipe_ros.model.flow import (GAMMA_AIR, P_ATM, FlowLaw, chamber_inflow, flow_lag_step,
                                    orifice_flow, power_leak)
from jetpipe_ros.model.hose import HOSE_STATES, hose_step
from jetpipe_ros.model.port import port_step
from jetpipe_ros.model.friction import (LUGRE, MAX_ELEMENTS, MAXWELL_SLIP, lugre_step,
                                        maxwell_slip_force, maxwell_slip_step, scaled_parameters,
                                        sliding_levels, static_friction, stribeck_force)
from jetpipe_ros.model.valve import U_EQ_MAX, U_EQ_MIN

# State layout: scalars (with the flow lag's flows into chambers 1 and 2 [kg/s] and their rates
# [kg/s^2], the line's write slot, the ports' pressures [Pa]: the chambers' without a port), then
# the hysteresis play operators, the Maxwell-slip elements, the valve chain, and with the line its
# history: per sub-step a row of LINE_COLUMNS (the pressures at the port [Pa], the flows leaving the
# valve [kg/s]); with the hose instead, chamber 1's hose then chamber 2's (HOSE_STATES each: the
# nodes' pressures [Pa] from the valve, then the segments' flows [kg/s]).
Y, V, P1, P2, STUCK, Z, PS1, PS2, STEP, HEAD, UCMD, UEQ, FRICTION, T1, T2, SUPPLY, \
    FLOW1, RATE1, FLOW2, RATE2, LINE_HEAD, PORT1, PORT2 = range(23)
PLAY = 23  #: first of the MAX_PLAY hysteresis play-operator outputs
MAX_PLAY = 8
ELEMENT = PLAY + MAX_PLAY  #: first of the MAX_ELEMENTS Maxwell-slip normalised deflections
VALVE = ELEMENT + MAX_ELEMENTS  #: first of the valve chain's states
LINE_P1, LINE_P2, LINE_Q1, LINE_Q2 = range(4)  #: columns of a row of the line's history
LINE_COLUMNS = 4

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
    valve_a: np.ndarray  #: valve chain over one sample (:class:`valve.SampledValve`)
    valve_g: np.ndarray
    valve_c: np.ndarray
    valve_h: np.ndarray
    delay_samples: int  #: whole samples of the valve's transport delay
    hysteresis: np.ndarray  #: play thresholds [V], one per element; empty = off
    hysteresis_weight: np.ndarray  #: the plays' weights in the loop, summing to 1
    flow_coef: np.ndarray  #: the flow map: Eq. 8's coefficients, then its correction table
    flow_law: FlowLaw  #: how the map follows the supply, its gains per direction (flow.py)
    valve_gain: float  #: u_eq per u_f (jet-pipe deflection per volt relative to Eq. 5)
    p_supply: float  #: supply pressure [Pa] (with the line: the set pressure feeding it)
    line_conductance: float  #: supply line conductance [kg/(s Pa)], 0 = constant supply
    line_volume: float  #: supply line volume [m^3]
    flow_lag: np.ndarray  #: the flow lag over a sub-step (:func:`flow.flow_lag_matrix`, (3, 3));
    #: (0, 3) = off
    line_delay: float  #: one-way delay of the line between valve and chambers [sub-steps]; 0 = off
    hose_steps: int  #: inner steps per sub-step of the hose between valve and chambers; 0 = off
    hose_rate: float  #: a hose node's pressure rate per net inflow gamma r T / (A l) [Pa/kg]
    hose_accel: float  #: a hose segment's A / (kappa l) [1/m]
    hose_laminar: float  #: a segment's laminar friction K_lam [Pa^2 s/kg] (:mod:`hose`)
    hose_turbulent: float  #: a segment's turbulent friction K_turb [Pa^2 s^0.75/kg^0.75]
    port_rate: float  #: a port's pressure rate per net inflow gamma r T / V_p [Pa/kg]; 0 = off
    port_area: float  #: effective area of the restriction after each port [m^2] (:mod:`port`)
    port_index: float  #: subsonic index m of that restriction [-]
    leak_cross: float  #: conductance chamber 1 -> 2 [kg/(s Pa)]
    leak_atm: float  #: conductance of each chamber to atmosphere [kg/(s Pa)]
    orifice_cross: float  #: orifice leak area chamber 1 -> 2 [m^2]
    orifice_atm: float  #: orifice leak area of each chamber to atmosphere [m^2]
    power_cross: float  #: power-law leak chamber 1 -> 2 at 1 bar [kg/s]
    power_atm: float  #: power-law leak of each chamber to atmosphere at 1 bar [kg/s]
    leak_exponent: float  #: exponent of the power-law leaks [-]
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
    friction_floor: float  #: least Stribeck level |F_C|, |F_S| [N]
    profile: np.ndarray  #: bore profile (3, K) of the friction level; (3, 0) = none
    friction_form: int  #: :data:`~jetpipe_ros.model.friction.STATIC`, LUGRE or MAXWELL_SLIP
    sigma0: float  #: bristle stiffness [N/m]
    sigma1: float  #: bristle damping [N s/m]
    slips: np.ndarray  #: Maxwell-slip elements' slip displacements [m]; empty unless that form
    sensor_tau: float  #: pressure sensor lag [s], 0 = ideal
    sensor_bias: float  #: pressure sensor bias [Pa]
    sensor_bias_2: float  #: chamber 2's sensor bias beyond that [Pa]
    sensor_gain: float  #: relative gain error of the pressure sensors [-]
    sensor_drift: float  #: pressure sensor drift [Pa/s]
    sigma_p: float  #: pressure noise [Pa]
    sigma_y: float  #: position noise [m]


def state_size(c: Constants) -> int:
    """Length of the state array for constants ``c``: the scalars, plays, elements and valve
    chain, and the line's history (:data:`LINE_COLUMNS` per row, enough rows to read
    ``line_delay`` sub-steps back between two rows)."""
    rows = int(math.floor(c.line_delay)) + 2 if c.line_delay > 0.0 else 0
    hoses = 2 * HOSE_STATES if c.hose_steps > 0 else 0
    return VALVE + c.valve_a.shape[0] + LINE_COLUMNS * rows + hoses


def fill_line(c: Constants, x: np.ndarray) -> None:
    """A line or hose at rest in state ``x``: the line's history holds the present pressures
    and no flow, each hose's nodes its chamber's pressure and its segments no flow."""
    first = VALVE + c.valve_a.shape[0]
    if c.hose_steps > 0:
        half = HOSE_STATES // 2
        for i, chamber in enumerate((P1, P2)):
            at = first + i * HOSE_STATES
            x[at:at + half] = x[chamber]
            x[at + half:at + HOSE_STATES] = 0.0
        return
    history = x[first:].reshape(-1, LINE_COLUMNS)
    history[:, LINE_P1] = x[P1]
    history[:, LINE_P2] = x[P2]
    history[:, LINE_Q1:] = 0.0


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
    gain = 1.0 + c.sensor_gain
    if c.sensor_tau > 0.0:
        out[OUT_P1_MEAS] = gain * x[PS1] + offset + c.sigma_p * noise[1]
        out[OUT_P2_MEAS] = gain * x[PS2] + offset + c.sensor_bias_2 + c.sigma_p * noise[2]
    else:
        out[OUT_P1_MEAS] = gain * x[P1] + offset + c.sigma_p * noise[1]
        out[OUT_P2_MEAS] = gain * x[P2] + offset + c.sensor_bias_2 + c.sigma_p * noise[2]


#: Largest order of the valve chain: Eq. 4's third order, Eq. 9's lead-lag, the valve_lag effect
#: (second order at most).
VALVE_ORDER = 6

#: Samples per block of :func:`advance`: the valve pass fills one block's u_eq before the
#: physics pass reads it, so the buffer stays in the first-level cache.
BLOCK = 64


@njit(cache=True, error_model="numpy")
def _valve_pass(c: Constants, x: np.ndarray, ring: np.ndarray, u: np.ndarray,
                u_eq: np.ndarray) -> None:
    """Run the valve chain over the sub-steps of the samples ``u`` [V, clipped].

    ``u_eq[k * substeps + s]`` [V] receives the equivalent voltage of sub-step s of sample k.
    The chain advances a sample at a time (:class:`valve.SampledValve`). The chain's state, the
    hysteresis operators' outputs and the delay line's write slot in ``x``, and the delay line
    ``ring`` (one command per sample), are updated in place.
    """
    nv = c.valve_a.shape[0]
    ns = c.substeps
    # The chain's matrices padded with zeros to VALVE_ORDER: loops of constant length unroll.
    va = np.zeros((VALVE_ORDER, VALVE_ORDER))
    vg = np.zeros((VALVE_ORDER, 2))
    vc = np.zeros((ns, VALVE_ORDER))
    state = np.zeros(VALVE_ORDER)
    va[:nv, :nv] = c.valve_a
    vg[:nv] = c.valve_g
    vc[:, :nv] = c.valve_c
    vh = c.valve_h
    state[:nv] = x[VALVE:VALVE + nv]
    new = np.zeros(VALVE_ORDER)
    n_play = c.hysteresis.shape[0]
    play = x[PLAY:PLAY + n_play]
    head = int(x[HEAD])
    size = ring.shape[0]
    lag = size - c.delay_samples  # the slot delay_samples behind head, ahead of it modulo size
    i_out = 0
    for k in range(u.shape[0]):
        ring[head] = u[k]
        tail = head + lag
        tail = tail - size if tail >= size else tail
        u0 = ring[tail]  # u[k - m] and u[k - m - 1]
        u1 = ring[tail - 1 if tail > 0 else size - 1]
        head = head + 1 if head + 1 < size else 0
        for s in range(ns):
            u_f = vh[s, 0] * u0 + vh[s, 1] * u1
            for j in range(VALVE_ORDER):
                u_f += vc[s, j] * state[j]
            if n_play:
                # Prandtl-Ishlinskii: a weighted sum of play operators (one element = a play).
                acc = 0.0
                for i in range(n_play):
                    r = c.hysteresis[i]
                    play[i] = min(max(play[i], u_f - r), u_f + r)
                    acc += c.hysteresis_weight[i] * play[i]
                u_f = acc
            u_eq[i_out] = min(max(c.valve_gain * u_f, U_EQ_MIN), U_EQ_MAX)
            i_out += 1
        for i in range(VALVE_ORDER):
            acc = vg[i, 0] * u0 + vg[i, 1] * u1
            for j in range(VALVE_ORDER):
                acc += va[i, j] * state[j]
            # Decaying derivative states would otherwise end in subnormals (~100x slower).
            new[i] = acc if abs(acc) > 1e-200 else 0.0
        state, new = new, state
    x[VALVE:VALVE + nv] = state[:nv]
    x[HEAD] = head


@njit(cache=True, error_model="numpy", inline="always")
def _valve_flows(coef: np.ndarray, u_eq: float, p1: float, p2: float, p_supply: float,
                 law: FlowLaw) -> tuple[float, float, float]:
    """The valve's flows into chambers 1 and 2 [kg/s] (Eq. 8, the jet deflected by ``u_eq``
    [V] toward chamber 1) and what it draws from the supply [kg/s]: the flows that fill."""
    q1 = chamber_inflow(coef, u_eq, p1, p_supply, law)
    q2 = chamber_inflow(coef, -u_eq, p2, p_supply, law)
    return q1, q2, max(q1, 0.0) + max(q2, 0.0)


@njit(cache=True, error_model="numpy", inline="always")
def _chamber_rates(q1: float, q2: float,
                   leak_cross: float, leak_atm: float, orifice_cross: float, orifice_atm: float,
                   power_cross: float, power_atm: float, exponent: float,
                   r_gas: float, t_wall: float, rt: float, area: float, v01: float, v02: float,
                   polytropic: float, heat_transfer: float, y: float, v: float, p1: float,
                   p2: float, t1: float, t2: float) -> tuple[float, float, float, float]:
    """dp1/dt, dp2/dt [Pa/s] and dT1/dt, dT2/dt [K/s] (0 without the heat-transfer form) at one
    state, the valve's flows into the chambers ``q1``, ``q2`` [kg/s] given: the leaks, the
    volumes and the pressure (and gas temperature) rates, with the effects the arguments switch
    on (see :class:`Constants`)."""
    q_x = leak_cross * (p1 - p2)
    q1 += -q_x - leak_atm * (p1 - P_ATM)
    q2 += q_x - leak_atm * (p2 - P_ATM)
    if orifice_cross > 0.0 or orifice_atm > 0.0:
        t_up = t1 if p1 > p2 else t2
        q_x = orifice_flow(orifice_cross, p1, p2, r_gas * t_up)
        q1 += -q_x - orifice_flow(orifice_atm, p1, P_ATM, r_gas * t1)
        q2 += q_x - orifice_flow(orifice_atm, p2, P_ATM, r_gas * t2)
    if power_cross > 0.0 or power_atm > 0.0:
        q_x = power_leak(power_cross, exponent, p1, p2)
        q1 += -q_x - power_leak(power_atm, exponent, p1, P_ATM)
        q2 += q_x - power_leak(power_atm, exponent, p2, P_ATM)
    vol1, vol2 = chamber_volumes(y, area, v01, v02)
    if heat_transfer > 0.0:
        dvol = area * v
        dp1, dt1 = pressure_temperature_rates(q1, p1, t1, dvol, vol1, r_gas, t_wall, GAMMA_AIR,
                                              heat_transfer)
        dp2, dt2 = pressure_temperature_rates(q2, p2, t2, -dvol, vol2, r_gas, t_wall,
                                              GAMMA_AIR, heat_transfer)
        return dp1, dp2, dt1, dt2
    dp1, dp2 = pressure_rates(q1, q2, p1, p2, v, vol1, vol2, area, rt, polytropic)
    return dp1, dp2, 0.0, 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _lagged_flow(lag: np.ndarray, q: float, rate: float, q_v: float, p: float
                 ) -> tuple[float, float, float]:
    """The flow lag over a sub-step (:func:`flow.flow_lag_step`): the mean flow into a chamber
    at ``p`` [Pa], none out of it at or below the atmosphere (the valve vents there), and the
    lag's new flow and rate."""
    mean, q, rate = flow_lag_step(lag, q, rate, q_v)
    return (0.0 if mean < 0.0 and p <= P_ATM else mean), q, rate


#: Pressure step [Pa] of the finite difference giving the map's slope at a hose's valve end.
HOSE_SLOPE_STEP = 100.0
#: Flow [kg/s] probing a chamber's pressure rate per inflow beside a hose (with the wall heat
#: exchange; without it the rate is linear in the flow, n r T / V).
HOSE_PROBE = 1e-3


@njit(cache=True, error_model="numpy", inline="always")
def _chamber_response(leak_cross: float, leak_atm: float, orifice_cross: float,
                      orifice_atm: float, power_cross: float, power_atm: float, exponent: float,
                      r_gas: float, t_wall: float, rt: float, area: float, v01: float,
                      v02: float, polytropic: float, heat_transfer: float, y: float, v: float,
                      p1: float, p2: float, t1: float, t2: float
                      ) -> tuple[float, float, float, float]:
    """What each chamber's pressure does [Pa/s] without the flow a hose or a port delivers, and
    per unit of that flow [Pa/kg] (:func:`_chamber_rates`' arguments)."""
    rate1, rate2, _, _ = _chamber_rates(
        0.0, 0.0, leak_cross, leak_atm, orifice_cross, orifice_atm, power_cross, power_atm,
        exponent, r_gas, t_wall, rt, area, v01, v02, polytropic, heat_transfer, y, v, p1, p2,
        t1, t2)
    if heat_transfer > 0.0:
        gain1, gain2, _, _ = _chamber_rates(
            HOSE_PROBE, HOSE_PROBE, leak_cross, leak_atm, orifice_cross, orifice_atm,
            power_cross, power_atm, exponent, r_gas, t_wall, rt, area, v01, v02, polytropic,
            heat_transfer, y, v, p1, p2, t1, t2)
        return rate1, rate2, (gain1 - rate1) / HOSE_PROBE, (gain2 - rate2) / HOSE_PROBE
    # Eq. 11-12 times n: n r T / V per kg/s
    vol1, vol2 = chamber_volumes(y, area, v01, v02)
    return rate1, rate2, polytropic * rt / vol1, polytropic * rt / vol2


@njit(cache=True, error_model="numpy", inline="always")
def _passage_response(c: Constants, pressurise: bool, y: float, v: float, p1: float,
                      p2: float, t1: float, t2: float) -> tuple[float, float, float, float]:
    """The chambers' pressure rates and gains (:func:`_chamber_response`) that a passage
    before them (hose, port) advances with; zeros while the pressures are held."""
    if not pressurise:
        return 0.0, 0.0, 0.0, 0.0
    return _chamber_response(c.leak_cross, c.leak_atm, c.orifice_cross, c.orifice_atm,
                             c.power_cross, c.power_atm, c.leak_exponent, c.r_gas, c.t_wall,
                             c.rt, c.area, c.v01, c.v02, c.polytropic, c.heat_transfer, y, v,
                             p1, p2, t1, t2)


@njit(cache=True, error_model="numpy", inline="always")
def _passage_close(c: Constants, pressurise: bool, line: bool, line_decay: float, m1: float,
                   m2: float, d1: float, d2: float, p1_new: float, p2_new: float, y: float,
                   v: float, p1: float, p2: float, t1: float, t2: float, p_s: float,
                   h: float) -> tuple[float, float, float, float, float]:
    """The end of a sub-step through a passage (hose, port): the chambers' new pressures
    ``p*_new`` [Pa], unless held on measurements, and gas temperatures from the mass flows
    ``m*`` [kg/s] into them, held or not (with held pressures, the temperatures follow the
    measured pressures and motion: a restart after a warm-up then starts from the gas
    temperature the warm-up's compression and heat exchange left); the supply line drained by
    the flows ``d*`` the valve draws [kg/s]. Returns p1, p2, t1, t2, p_s."""
    if c.heat_transfer > 0.0:
        _, _, dt1, dt2 = _chamber_rates(
            m1, m2, c.leak_cross, c.leak_atm, c.orifice_cross, c.orifice_atm,
            c.power_cross, c.power_atm, c.leak_exponent, c.r_gas, c.t_wall, c.rt, c.area,
            c.v01, c.v02, c.polytropic, c.heat_transfer, y, v, p1, p2, t1, t2)
        t1 = max(t1 + h * dt1, 1.0)
        t2 = max(t2 + h * dt2, 1.0)
    if pressurise:
        p1 = max(p1_new, MIN_PRESSURE)
        p2 = max(p2_new, MIN_PRESSURE)
    if line:
        p_s = supply_step(p_s, c.p_supply, c.line_conductance, max(d1, 0.0) + max(d2, 0.0),
                          line_decay)
    return p1, p2, t1, t2, p_s


@njit(cache=True, error_model="numpy", inline="always")
def _port_substep(coef: np.ndarray, u: float, p_s: float, law: FlowLaw, p_p: float, p_c: float,
                  rate_c: float, gain_c: float, port_rate: float, area: float, index: float,
                  rt: float, h: float
                  ) -> tuple[float, float, float, float]:
    """A port and its chamber over a sub-step ``h`` [s] (:func:`port.port_step`), the map at
    ``u`` [V] reading the port's pressure ``p_p`` [Pa] (its slope by a finite difference).
    Returns the new port and chamber pressures, the mean flow into the chamber and the mean
    flow leaving the valve [kg/s]."""
    q = chamber_inflow(coef, u, p_p, p_s, law)
    slope = (chamber_inflow(coef, u, p_p + HOSE_SLOPE_STEP, p_s, law) - q) / HOSE_SLOPE_STEP
    p_p, p_c, into, sent = port_step(p_p, p_c, q, slope, rate_c, gain_c, port_rate, area, index,
                                     rt, h)
    return max(p_p, MIN_PRESSURE), p_c, into, sent


@njit(cache=True, error_model="numpy", inline="always")
def _hose_substep(coef: np.ndarray, u: float, p_s: float, law: FlowLaw, q_given: float,
                  p0: float, p1: float, w0: float, w1: float, p_c: float, rate_c: float,
                  gain_c: float, node_rate: float, accel: float, laminar: float,
                  turbulent: float, h: float, steps: int
                  ) -> tuple[float, float, float, float, float, float, float]:
    """A hose and its chamber over a sub-step ``h`` [s] in ``steps`` inner steps
    (:func:`hose.hose_step`): the map at ``u`` [V] reads the hose's valve end, or with a finite
    ``q_given`` [kg/s] (the flow lag's) that flow enters it. Returns the new node pressures,
    flows and chamber pressure, the mean flow into the chamber and the mean flow leaving the
    valve [kg/s]."""
    k = 0.5 * h / steps
    into, sent = 0.0, 0.0
    mapped = not math.isfinite(q_given)
    for _ in range(steps):
        if mapped:
            q = chamber_inflow(coef, u, p0, p_s, law)
            slope = (chamber_inflow(coef, u, p0 + HOSE_SLOPE_STEP, p_s, law)
                     - q) / HOSE_SLOPE_STEP
        else:
            q, slope = q_given, 0.0
        slope = min(slope, 0.0)
        start = p0
        p0, p1, w0, w1, p_c, mean = hose_step(p0, p1, w0, w1, q, slope, p_c, rate_c, gain_c,
                                              node_rate, accel, laminar, turbulent, k)
        sent += q + 0.5 * slope * (p0 - start)  # the trapezoid's mean
        p0 = max(p0, MIN_PRESSURE)
        p1 = max(p1, MIN_PRESSURE)
        into += mean
    return p0, p1, w0, w1, p_c, into / steps, sent / steps


@njit(cache=True, error_model="numpy", inline="always")
def supply_step(p_s: float, p_set: float, conductance: float, drawn: float, decay: float
                ) -> float:
    """The supply line's pressure [Pa] after a step over which the valve draws ``drawn`` [kg/s]
    from it: V dp_s/dt = r T (G (p_set - p_s) - Q), exact for Q held, with ``decay`` =
    exp(-step / tau), tau = V / (r T G) (:func:`supply_decay`). In steady state
    p_s = p_set - Q / G."""
    target = p_set - drawn / conductance
    return target + (p_s - target) * decay


@njit(cache=True, error_model="numpy")
def supply_decay(c: Constants, step: float) -> float:
    """exp(-step / tau) of the supply line over ``step`` [s], tau = V / (r T G) [s] (1 with a
    constant supply)."""
    if c.line_conductance == 0.0:
        return 1.0
    return math.exp(-step * c.rt * c.line_conductance / c.line_volume)


@njit(cache=True, error_model="numpy", inline="always")
def _row_at(a: np.ndarray, at: float) -> float:
    """``a`` at the fractional row ``at``, linear between rows, the first row's before it."""
    if at <= 0.0:
        return a[0]
    k = int(math.floor(at))
    w = at - k
    return a[k] if w == 0.0 else (1.0 - w) * a[k] + w * a[k + 1]


@njit(cache=True, error_model="numpy")
def chamber_rates(c: Constants, y: np.ndarray, v: np.ndarray, p1: np.ndarray, p2: np.ndarray,
                  u_eq: np.ndarray) -> np.ndarray:
    """What the model's chambers do at given states, sample by sample: rows dp1/dt, dp2/dt
    [Pa/s] (the gas at the wall temperature), the valve's inflows q1, q2 [kg/s] and their
    sensitivities to the equivalent voltage dq1/du_eq, dq2/du_eq [kg/(s V)]. For equation
    errors (the diagnosis): the same rates the kernel integrates. With the supply line its
    pressure starts at the set pressure and follows the drawn flow from row to row, the rows
    ``c.dt`` apart; so do the flow lag's flows (the map's flow of each row held over it); with
    the line between valve and chambers the map reads the pressures of the rows the line's
    delay back and its flows arrive that delay later (both interpolated between rows; before
    the first row, the first row's); with the hose, each hose (at rest at the first row's
    pressures) advances over each row with its chamber held at the row's pressure, and the
    chamber receives its mean flow over the row; so does each port of the valve lag's port form
    (at rest at the first row's pressures)."""
    n = y.shape[0]
    out = np.empty((6, n))
    du = 1e-3
    line = c.line_conductance > 0.0
    decay = supply_decay(c, c.dt)
    p_s = c.p_supply
    lag = c.flow_lag
    f1, r1, f2, r2 = 0.0, 0.0, 0.0, 0.0
    rows_back = c.line_delay / c.substeps
    sent = np.zeros((2, n))  # flows leaving the valve, row by row (the line's)
    hose = np.zeros((2, HOSE_STATES))  # each hose's nodes and flows
    if c.hose_steps > 0 and n:
        hose[0, :HOSE_STATES // 2] = p1[0]
        hose[1, :HOSE_STATES // 2] = p2[0]
    port = np.zeros(2)  # each port's pressure
    if n:
        port[0], port[1] = p1[0], p2[0]
    h = c.dt / c.substeps
    for k in range(n):
        if c.hose_steps > 0:
            q1, q2, drawn = 0.0, 0.0, 0.0
            for _ in range(c.substeps):
                given1 = given2 = math.nan
                if lag.shape[0]:
                    given1, given2, _ = _valve_flows(c.flow_coef, u_eq[k], hose[0, 0],
                                                     hose[1, 0], p_s, c.flow_law)
                    given1, f1, r1 = _lagged_flow(lag, f1, r1, given1, hose[0, 0])
                    given2, f2, r2 = _lagged_flow(lag, f2, r2, given2, hose[1, 0])
                for i, (sign, p, given) in enumerate(((1.0, p1[k], given1),
                                                      (-1.0, p2[k], given2))):
                    hose[i, 0], hose[i, 1], hose[i, 2], hose[i, 3], _, m, d = _hose_substep(
                        c.flow_coef, sign * u_eq[k], p_s, c.flow_law, given, hose[i, 0],
                        hose[i, 1], hose[i, 2], hose[i, 3], p, 0.0, 0.0, c.hose_rate,
                        c.hose_accel, c.hose_laminar, c.hose_turbulent, h, c.hose_steps)
                    if i == 0:
                        q1 += m / c.substeps
                    else:
                        q2 += m / c.substeps
                    drawn += max(d, 0.0) / c.substeps
        elif c.port_rate > 0.0:
            q1, q2, drawn = 0.0, 0.0, 0.0
            for _ in range(c.substeps):
                for i, (sign, p) in enumerate(((1.0, p1[k]), (-1.0, p2[k]))):
                    port[i], _, m, d = _port_substep(
                        c.flow_coef, sign * u_eq[k], p_s, c.flow_law, port[i], p, 0.0, 0.0,
                        c.port_rate, c.port_area, c.port_index, c.rt, h)
                    if i == 0:
                        q1 += m / c.substeps
                    else:
                        q2 += m / c.substeps
                    drawn += max(d, 0.0) / c.substeps
        elif rows_back > 0.0:
            q1, q2, drawn = _valve_flows(c.flow_coef, u_eq[k], _row_at(p1, k - rows_back),
                                         _row_at(p2, k - rows_back), p_s, c.flow_law)
        else:
            q1, q2, drawn = _valve_flows(c.flow_coef, u_eq[k], p1[k], p2[k], p_s, c.flow_law)
        if lag.shape[0] and c.hose_steps == 0:
            m1, m2 = 0.0, 0.0
            for _ in range(c.substeps):
                m, f1, r1 = _lagged_flow(lag, f1, r1, q1, p1[k])
                m1 += m / c.substeps
                m, f2, r2 = _lagged_flow(lag, f2, r2, q2, p2[k])
                m2 += m / c.substeps
            q1, q2 = m1, m2
        if rows_back > 0.0:
            sent[0, k], sent[1, k] = q1, q2
            q1, q2 = _row_at(sent[0], k - rows_back), _row_at(sent[1], k - rows_back)
            q1 = 0.0 if q1 < 0.0 and p1[k] <= P_ATM else q1
            q2 = 0.0 if q2 < 0.0 and p2[k] <= P_ATM else q2
        out[0, k], out[1, k], _, _ = _chamber_rates(
            q1, q2, c.leak_cross, c.leak_atm,
            c.orifice_cross, c.orifice_atm, c.power_cross, c.power_atm, c.leak_exponent,
            c.r_gas, c.t_wall, c.rt, c.area, c.v01, c.v02, c.polytropic, c.heat_transfer,
            y[k], v[k], p1[k], p2[k], c.t_wall, c.t_wall)
        for i, (sign, p) in enumerate(((1.0, p1[k]), (-1.0, p2[k]))):
            u = sign * u_eq[k]
            out[2 + i, k] = chamber_inflow(c.flow_coef, u, p, p_s, c.flow_law)
            out[4 + i, k] = sign * (
                chamber_inflow(c.flow_coef, u + du, p, p_s, c.flow_law)
                - chamber_inflow(c.flow_coef, u - du, p, p_s, c.flow_law)) / (2.0 * du)
        if line:
            p_s = supply_step(p_s, c.p_supply, c.line_conductance, drawn, decay)
    return out


@njit(cache=True, error_model="numpy")
def _physics_pass(c: Constants, x: np.ndarray, u: np.ndarray, u_eq: np.ndarray,
                  f_load: np.ndarray, drive: np.ndarray, noise: np.ndarray, out: np.ndarray
                  ) -> None:
    """Advance chambers and piston over the samples of ``u`` [V, clipped] from state ``x``.

    ``u_eq`` [V] holds the equivalent voltage of every sub-step (:func:`_valve_pass`);
    ``f_load``, ``drive``, ``noise`` and ``out`` are row-aligned with ``u`` (see
    :func:`advance`). Within a sample the state lives in local variables. The inlined helpers
    take arrays and numbers (a :class:`FlowLaw` holds numbers only), not ``c``: passing a tuple
    that holds arrays to an inlined function costs reference counting (atomic operations) on
    every sub-step.
    """
    ns = c.substeps
    h = c.dt / ns
    coef, law = c.flow_coef, c.flow_law
    planes = c.planes
    sensor_w = 1.0 - math.exp(-h / c.sensor_tau) if c.sensor_tau > 0.0 else 0.0
    line = c.line_conductance > 0.0
    line_decay = supply_decay(c, h)
    lag = c.flow_lag
    lagged = lag.shape[0] > 0
    line_on = c.line_delay > 0.0
    hose_on = c.hose_steps > 0
    port_on = c.port_rate > 0.0
    first_row = VALVE + c.valve_a.shape[0]
    hose_2 = first_row + HOSE_STATES
    rows = (x.shape[0] - first_row) // LINE_COLUMNS
    back = int(math.floor(c.line_delay))
    theta = c.line_delay - back  # weight of the older of the two rows read
    driven = drive.shape[0] > 0
    for k in range(u.shape[0]):
        move = not c.locked
        pressurise = not c.regulated
        if driven:
            if math.isfinite(drive[k, DRIVE_Y]):
                x[Y] = drive[k, DRIVE_Y]
                x[V] = drive[k, DRIVE_V]
                x[FRICTION] = 0.0
                move = False
            p1_given = math.isfinite(drive[k, DRIVE_P1])
            p2_given = math.isfinite(drive[k, DRIVE_P2])
            if p1_given or p2_given:
                if p1_given:
                    x[P1] = drive[k, DRIVE_P1]
                if p2_given:
                    x[P2] = drive[k, DRIVE_P2]
                pressurise = False
        y, v, p1, p2 = x[Y], x[V], x[P1], x[P2]
        stuck, z, friction = x[STUCK], x[Z], x[FRICTION]
        elements = x[ELEMENT:ELEMENT + c.slips.shape[0]]
        t1, t2, ps1, ps2 = x[T1], x[T2], x[PS1], x[PS2]
        f1, r1, f2, r2 = x[FLOW1], x[RATE1], x[FLOW2], x[RATE2]
        p_s = x[SUPPLY] if line else c.p_supply
        f_l = f_load[k]
        # Pressures held on measurements (not by regulators): the valve still draws from the
        # line and feeds the flow lag, and the gas temperatures follow the measured pressures
        # and motion.
        flows = pressurise or ((line or lagged or line_on or hose_on or port_on
                                or c.heat_transfer > 0.0) and not c.regulated)
        pp1, pp2 = x[PORT1], x[PORT2]
        slot = int(x[LINE_HEAD])
        row = old = new = first_row
        for s in range(k * ns, (k + 1) * ns):
            if flows and hose_on:
                q1 = q2 = math.nan
                if lagged:
                    q1, q2, _ = _valve_flows(coef, u_eq[s], x[first_row], x[hose_2], p_s, law)
                    q1, f1, r1 = _lagged_flow(lag, f1, r1, q1, x[first_row])
                    q2, f2, r2 = _lagged_flow(lag, f2, r2, q2, x[hose_2])
                rate1, rate2, gain1, gain2 = _passage_response(c, pressurise, y, v, p1, p2, t1,
                                                               t2)
                a = first_row
                x[a], x[a + 1], x[a + 2], x[a + 3], p1_new, m1, d1 = _hose_substep(
                    coef, u_eq[s], p_s, law, q1, x[a], x[a + 1], x[a + 2], x[a + 3], p1, rate1,
                    gain1, c.hose_rate, c.hose_accel, c.hose_laminar, c.hose_turbulent, h,
                    c.hose_steps)
                a = hose_2
                x[a], x[a + 1], x[a + 2], x[a + 3], p2_new, m2, d2 = _hose_substep(
                    coef, -u_eq[s], p_s, law, q2, x[a], x[a + 1], x[a + 2], x[a + 3], p2, rate2,
                    gain2, c.hose_rate, c.hose_accel, c.hose_laminar, c.hose_turbulent, h,
                    c.hose_steps)
                p1, p2, t1, t2, p_s = _passage_close(c, pressurise, line, line_decay, m1, m2,
                                                     d1, d2, p1_new, p2_new, y, v, p1, p2,
                                                     t1, t2, p_s, h)
            elif flows and port_on:
                rate1, rate2, gain1, gain2 = _passage_response(c, pressurise, y, v, p1, p2, t1,
                                                               t2)
                pp1, p1_new, m1, d1 = _port_substep(
                    coef, u_eq[s], p_s, law, pp1, p1, rate1, gain1, c.port_rate, c.port_area,
                    c.port_index, c.rt, h)
                pp2, p2_new, m2, d2 = _port_substep(
                    coef, -u_eq[s], p_s, law, pp2, p2, rate2, gain2, c.port_rate, c.port_area,
                    c.port_index, c.rt, h)
                p1, p2, t1, t2, p_s = _passage_close(c, pressurise, line, line_decay, m1, m2,
                                                     d1, d2, p1_new, p2_new, y, v, p1, p2,
                                                     t1, t2, p_s, h)
            elif flows:
                if line_on:
                    # The port's pressures of line_delay sub-steps ago.
                    row = first_row + LINE_COLUMNS * slot
                    x[row + LINE_P1], x[row + LINE_P2] = p1, p2
                    new = first_row + LINE_COLUMNS * ((slot - back + rows) % rows)
                    old = first_row + LINE_COLUMNS * ((slot - back - 1 + rows) % rows)
                    q1, q2, drawn = _valve_flows(
                        coef, u_eq[s], theta * x[old + LINE_P1] + (1.0 - theta) * x[new + LINE_P1],
                        theta * x[old + LINE_P2] + (1.0 - theta) * x[new + LINE_P2], p_s, law)
                else:
                    q1, q2, drawn = _valve_flows(coef, u_eq[s], p1, p2, p_s, law)
                if lagged:
                    q1, f1, r1 = _lagged_flow(lag, f1, r1, q1, p1)
                    q2, f2, r2 = _lagged_flow(lag, f2, r2, q2, p2)
                if line_on:
                    # What left the valve line_delay sub-steps ago; none out of a chamber at or
                    # below the atmosphere (the valve vents there).
                    x[row + LINE_Q1], x[row + LINE_Q2] = q1, q2
                    q1 = theta * x[old + LINE_Q1] + (1.0 - theta) * x[new + LINE_Q1]
                    q2 = theta * x[old + LINE_Q2] + (1.0 - theta) * x[new + LINE_Q2]
                    q1 = 0.0 if q1 < 0.0 and p1 <= P_ATM else q1
                    q2 = 0.0 if q2 < 0.0 and p2 <= P_ATM else q2
                    slot = slot + 1 if slot + 1 < rows else 0
                if pressurise or c.heat_transfer > 0.0:
                    # Chambers (Eq. 11-13): leakage, volumes, pressure (and gas temperature)
                    # rates; explicit. Pressures held on measurements still move the gas
                    # temperatures (_passage_close).
                    dp1, dp2, dt1, dt2 = _chamber_rates(
                        q1, q2, c.leak_cross, c.leak_atm,
                        c.orifice_cross, c.orifice_atm, c.power_cross, c.power_atm,
                        c.leak_exponent, c.r_gas, c.t_wall, c.rt, c.area, c.v01, c.v02,
                        c.polytropic, c.heat_transfer, y, v, p1, p2, t1, t2)
                    if c.heat_transfer > 0.0:
                        t1 = max(t1 + h * dt1, 1.0)
                        t2 = max(t2 + h * dt2, 1.0)
                    if pressurise:
                        p1 = max(p1 + h * dp1, MIN_PRESSURE)
                        p2 = max(p2 + h * dp2, MIN_PRESSURE)
                if line:
                    p_s = supply_step(p_s, c.p_supply, c.line_conductance, drawn, line_decay)
            if move:
                y, v, stuck, z, friction = _mechanics_substep(
                    planes, c.friction_floor, c.profile, c.area * (p1 - p2) - f_l, p1, p2, h,
                    c.mass, c.y_max,
                    c.friction_form, c.sigma0, c.sigma1, c.slips, elements, y, v, stuck, z,
                    friction)
            elif c.locked:
                v = 0.0
                friction = 0.0
            else:
                y = min(max(y + h * v, -c.y_max), c.y_max)
            if c.sensor_tau > 0.0:
                ps1 += sensor_w * (p1 - ps1)
                ps2 += sensor_w * (p2 - ps2)
        x[Y], x[V], x[P1], x[P2] = y, v, p1, p2
        x[STUCK], x[Z], x[FRICTION] = stuck, z, friction
        x[T1], x[T2], x[PS1], x[PS2] = t1, t2, ps1, ps2
        x[SUPPLY] = p_s
        x[FLOW1], x[RATE1], x[FLOW2], x[RATE2] = f1, r1, f2, r2
        x[LINE_HEAD] = slot
        # Without a port (or with it off), its pressure is the chamber's: a port switched on
        # starts at rest.
        x[PORT1], x[PORT2] = (pp1, pp2) if port_on else (p1, p2)
        x[UCMD] = u[k]
        x[UEQ] = u_eq[(k + 1) * ns - 1]
        x[STEP] += 1.0
        measure(c, x, noise[k], out[k])


@njit(cache=True, error_model="numpy", inline="always")
def _mechanics_substep(planes: np.ndarray, floor: float, profile: np.ndarray, f_a: float,
                       p1: float, p2: float, h: float, mass: float, y_max: float, form: int,
                       sigma0: float, sigma1: float, slips: np.ndarray, elements: np.ndarray,
                       y: float, v: float, stuck: float, z: float, friction: float
                       ) -> tuple[float, float, float, float, float]:
    """Advance the piston one sub-step (Eq. 14 with Eq. 15-18 friction or a dynamic form).

    ``f_a`` [N] is the applied force S (p1 - p2) - F_L at pressures ``p1``, ``p2`` [Pa];
    ``planes``, ``floor`` (``friction_floor``), ``profile``, ``mass``, ``y_max``, ``form``
    (``friction_form``), ``sigma0``, ``sigma1`` and ``slips`` are the fields of
    :class:`Constants` (the bore profile's factors
    taken at the sub-step's starting position). From position ``y`` [m], velocity ``v``
    [m/s], the stuck flag, the LuGre bristle deflection ``z`` [m] and the friction force [N],
    returns the new (y, v, stuck, z, friction); the Maxwell-slip elements' normalised
    deflections ``elements`` advance in place.
    """
    if form == MAXWELL_SLIP:
        g_exit, g_entry, f_v_exit, f_v_entry = sliding_levels(planes, profile, v, y, p1, p2,
                                                              floor)
        d = v if v != 0.0 else f_a
        f_v = f_v_exit if d > 0.0 else f_v_entry
        # Elements that stay elastic over the step are springs, implicit in the velocity:
        # F = f_0 + h K v_new (+ F_v v_new).
        f_0 = 0.0
        stiffness = 0.0
        n = slips.shape[0]
        for i in range(n):
            s = elements[i]
            g = g_exit if (s > 0.0 or (s == 0.0 and d > 0.0)) else g_entry
            if abs(s + h * v / slips[i]) < 1.0:
                f_0 += s * g
                stiffness += g / slips[i]
            else:
                f_0 += math.copysign(g, s + h * v)
        f_0 /= n
        stiffness /= n
        v_new = (v + h / mass * (f_a - f_0)) / (1.0 + h * (f_v + h * stiffness) / mass)
        maxwell_slip_step(elements, h * v_new, slips)
        friction = maxwell_slip_force(elements, g_exit, g_entry) + f_v * v_new
    elif form == LUGRE:
        d = math.copysign(1.0, v) if v != 0.0 else (math.copysign(1.0, f_a) if f_a != 0.0
                                                     else math.copysign(1.0, z))
        f_s, v_s, f_v, f_c = scaled_parameters(planes, profile, d, y, p1, p2, floor)
        g = abs(stribeck_force(v, f_s, v_s, f_c))
        z_new, a = lugre_step(z, v, g, sigma0, h)
        # Bristle force sigma0 z + sigma1 dz/dt with dz/dt = v - a z; v implicit.
        v_new = (v + h / mass * (f_a - sigma0 * z_new + sigma1 * a * z_new)) / \
            (1.0 + h * (f_v + sigma1) / mass)
        z = z_new
        friction = sigma0 * z_new + sigma1 * (v_new - a * z_new) + f_v * v_new
    else:
        if stuck != 0.0:
            d = math.copysign(1.0, f_a)
            f_s, v_s, f_v, f_c = scaled_parameters(planes, profile, d, y, p1, p2, floor)
            if abs(f_a) <= abs(f_s):
                return y, 0.0, stuck, z, f_a
            stuck = 0.0
            v = 0.0
        else:
            d = math.copysign(1.0, v) if v != 0.0 else math.copysign(1.0, f_a)
            f_s, v_s, f_v, f_c = scaled_parameters(planes, profile, d, y, p1, p2, floor)
        f_st = stribeck_force(v, f_s, v_s, f_c)
        # Times the reciprocal, which does not wait on the Stribeck term (see pressure_rates).
        v_new = (v + h / mass * (f_a - f_st)) * (1.0 / (1.0 + h * f_v / mass))
        if v_new * d <= 0.0:
            # Velocity reached zero within the step: stick (Eq. 15 decides release next step).
            v_new = 0.0
            stuck = 1.0
            friction = static_friction(f_a, f_s)
        else:
            friction = f_st + f_v * v_new
    y = y + h * v_new
    if y > y_max or y < -y_max:
        y = min(max(y, -y_max), y_max)
        v_new = 0.0
        stuck = 1.0
    return y, v_new, stuck, z, friction


@njit(cache=True, error_model="numpy")
def advance(c: Constants, x: np.ndarray, ring: np.ndarray, u: np.ndarray, f_load: np.ndarray,
            drive: np.ndarray, noise: np.ndarray, out: np.ndarray) -> None:
    """Advance ``len(u)`` samples from state ``x`` (in place).

    ``u`` [V] and ``f_load`` [N] are held over each sample; ``noise`` (n, 3) holds standard
    normals for the sensors; ``out[k]`` receives the outputs at the end of sample k.
    ``drive`` is empty or (n, N_DRIVE): where row k holds finite values, sample k starts from
    the prescribed position [m] and velocity [m/s] (then moves at that velocity, friction not
    computed) and/or holds the prescribed pressures [Pa] (a pressure given as NaN beside a finite
    one is held at its current value). Non-finite commands must be filtered by the caller.

    Each block of :data:`BLOCK` samples runs in two passes: the valve chain over all its
    sub-steps (:func:`_valve_pass`), then chambers and piston (:func:`_physics_pass`).
    """
    n = u.shape[0]
    u_clip = np.empty(min(n, BLOCK))
    u_eq = np.empty(min(n, BLOCK) * c.substeps)
    for first in range(0, n, BLOCK):
        last = min(first + BLOCK, n)
        for k in range(first, last):
            u_clip[k - first] = min(max(u[k], -c.u_limit), c.u_limit)
        _valve_pass(c, x, ring, u_clip[:last - first], u_eq)
        # An empty drive slices to an empty drive.
        _physics_pass(c, x, u_clip[:last - first], u_eq, f_load[first:last], drive[first:last],
                      noise[first:last], out[first:last])
