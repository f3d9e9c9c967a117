"""A plant specification compiled for the plant's loop, and the layout of its state vector."""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from jetpipe_ros.plant.air import GAMMA_AIR, P_SUPPLY
from jetpipe_ros.plant.linear import second_order_lag
from jetpipe_ros.plant.passages import N_SEGMENTS, inner_steps
from jetpipe_ros.plant.seal import knee_of, length_of
from jetpipe_ros.plant.spec import PlantSpec
from jetpipe_ros.plant.valve import MAP_P_MAX, MAP_P_MIN, VALVE_STEPS, chain_parameters, jet_flow

# State layout: scalars, the ports, the sensors, the load, the plays, the measured seal's
# reversal points, the valve chain, then the lines.
(Y, V, M1, M2, E1, E2, P1, P2, STUCK, Z, SUPPLY, DRAWN, STEP, HEAD, UCMD, UEQ,
 FRICTION, SEAL_D, SEAL_N, REGULATOR) = range(20)  # SEAL_D: the seal's branch direction,
# SEAL_N: its reversal points in use; REGULATOR: the supply regulator's outlet pressure [Pa]
PORT = 20  #: the port volumes' pressures [Pa]: chamber 1's, chamber 2's (passages docstring)
SENSOR1 = 22  #: chamber 1 transducer: reading [Pa], its rate [Pa/s]
SENSOR2 = 24  #: chamber 2 transducer
POSITION = 26  #: position transducer: reading [m], its rate [m/s]
LOAD = 28  #: the compliant load: position [m], velocity [m/s]
PLAY = 30  #: the N_PLAY play operators' outputs [V]
N_PLAY = 3
SEAL = PLAY + N_PLAY  #: the measured seal's N_SEAL reversal points: x_r [m], F_r [N] each
N_SEAL = 8
VALVE = SEAL + 2 * N_SEAL  #: the valve chain's states: coil current, rotor rate, angle, lead-lag
N_VALVE = 4
#: The lines to chambers 1 and 2, LINE_SIZE states each: the nodes' pressures [Pa], then the
#: segments' mass flows [kg/s] (passages docstring).
LINE = VALVE + N_VALVE
LINE_SIZE = 2 * N_SEGMENTS
SIZE = LINE + 2 * LINE_SIZE  #: length of the state vector


#: The pressure transducers' span: 0-10 bar gauge [Pa].
SENSOR_LOW, SENSOR_SPAN = 1.0e5, 1.0e6


class PlantConstants(NamedTuple):
    """Everything the plant's loop needs, SI units; built by :func:`build_constants`."""

    dt: float  #: sample time [s]
    substeps: int  #: sub-steps per sample
    u_limit: float  #: command saturation [V]
    chain: np.ndarray  #: the valve chain's (R, L, K_t, K_b, J, K_f, K_s, w_p) (valve docstring)
    lead: float  #: w_p / w_z of Eq. 9
    delay: float  #: the valve's delay in samples
    delay_whole: int  #: whole samples it reaches back (the command ring holds 2 more)
    valve_steps: int  #: Runge-Kutta steps of the chain per sub-step
    port: bool  #: a port volume behind a filter before each chamber (flow_lag) on
    port_volume: float  #: V_p [m^3]
    port_conductance: float  #: the filter's K [m^3/(s Pa)]
    line: bool  #: a pneumatic line to each chamber (transport_delay) on
    line_bore: float  #: d [m]
    line_area: float  #: A [m^2]
    segment_length: float  #: l_s [m]
    line_wave: float  #: gamma r T / V_s [Pa/kg]
    line_inertance: float  #: l_s / A [1/m]
    passage_steps: int  #: inner steps of the ports and lines per sub-step
    play_thresholds: np.ndarray  #: [V]; empty = no hysteresis
    play_weights: np.ndarray  #: normalised to sum 1
    valve_gain: float  #: u_eq per u_h
    null_offset: float  #: [V]
    gain_charge: float
    gain_discharge: float
    gain_slope: float  #: pressure-dependent valve gain k
    shape: float  #: the flow map's departure from Eq. 8: amplitude [kg/s]
    shape_phase: float  #: and phase [rad]
    supply_droops: bool  #: supply_droop on (else the supply stays at supply_set)
    supply_set: float  #: regulator set pressure [Pa]
    supply_droop: float  #: regulator droop R [Pa s/kg]
    supply_droop_2: float  #: its quadratic term S [Pa s^2/kg^2]
    supply_tau: float  #: regulator time constant [s]
    hose_conductance: float  #: G_h [kg/(s Pa)]
    hose_volume: float  #: V_h [m^3]
    leak_cross: float  #: sonic conductance across the piston [m^3/(s Pa)]
    leak_atm: float  #: sonic conductance of each chamber to atmosphere [m^3/(s Pa)]
    leak_b: float  #: critical pressure ratio
    gap_width: float  #: seal gap across the piston: width [m]; 0 = none
    gap_height: float  #: its height [m]
    gap_length: float  #: its length along the flow [m]
    gap_loss: float  #: its entrance and exit loss coefficient [-]
    thermal: bool  #: energy balance with wall heat exchange on
    heat_coefficient: float  #: h_c [W/(m^2 K)]
    t_wall: float  #: wall (and isothermal gas) temperature [K]
    t_supply: float  #: supply air temperature [K]
    r_gas: float  #: [J/(kg K)]
    cv: float  #: [J/(kg K)]
    area: float  #: piston area [m^2]
    v01: float  #: chamber volumes at y = 0 [m^3]
    v02: float
    mass: float  #: moving mass [kg]
    load: bool  #: the compliant load on
    load_mass: float  #: m_x [kg]
    load_k: float  #: k_x [N/m]
    load_c: float  #: c_x [N s/m]
    y_max: float  #: end stops at +-y_max [m]
    locked: bool
    regulated: bool
    planes: np.ndarray  #: friction planes (2, 4, 3)
    bristles: bool  #: elasto-plastic friction on
    sigma0: float  #: [N/m]
    sigma1: float  #: [N s/m]
    v_damp: float  #: [m/s]
    z_fraction: float  #: beta
    seal: bool  #: measured seal's friction on
    seal_length: float  #: its build-up length L of a full swing [m]
    seal_knee: float  #: its knee c [-]
    cushion_length: float  #: [m]; 0 = no cushion
    cushion_k: float  #: [N/m]
    cushion_c: float  #: [N s/m]
    spring_k: float  #: load spring stiffness [N/m]; 0 = no spring
    spring_y0: float  #: where the spring is relaxed [m]
    sensor: bool  #: second-order transducers on
    sensor_a: np.ndarray
    sensor_b: np.ndarray
    sensor_bow: float  #: the transducers' nonlinearity at mid-span [Pa]
    sensor_low: float  #: their span's start [Pa, absolute]
    sensor_span: float  #: and width [Pa]
    sensor_offset_1: float  #: [Pa]
    sensor_offset_2: float  #: [Pa]
    position_filter: bool  #: two-stage position transducer on
    position_a: np.ndarray  #: its discretisation over a sub-step (critically damped lag)
    position_b: np.ndarray
    sigma_p: float  #: pressure noise [Pa]
    sigma_y: float  #: position noise [m]


@functools.cache
def valve_slope_max() -> float:
    """The steepest fall of Eq. 8's flow with pressure, max -dq/dp [kg/(s Pa)] over its range
    (u_eq -2.8-3 V, 1-10 bar; central differences on a grid)."""
    slopes = [(jet_flow(u, p - 1e-3) - jet_flow(u, p + 1e-3)) / 2e-3 * 1e-5
              for u in np.linspace(-2.8, 3.0, 30)
              for p in np.linspace(MAP_P_MIN + 1e-3, MAP_P_MAX - 1e-3, 30)]
    return max(slopes)


def _port_rate(port: dict, rt: float) -> float:
    """The port's fastest rate (G + K_v) / C_p [1/s]: the filter's G at 10 bar and the valve's
    steepest slope, C_p = V_p / (r T) (passages docstring); sets the inner step."""
    return (port["filter_conductance"] * MAP_P_MAX * 1e5 / rt + valve_slope_max()) * rt \
        / port["port_volume"]


#: The plant's longest integration sub-step [s]: its default 8 sub-steps of a 1 ms sample. A
#: record logged at a lower rate is the same physics sampled less often, so the sub-step stays
#: this short whatever the sample time (:func:`substeps_of`).
MAX_SUBSTEP = 1e-3 / 8


def substeps_of(spec: PlantSpec) -> int:
    """Sub-steps per sample: ``spec.substeps``, or more where the sample time would make them
    longer than :data:`MAX_SUBSTEP` (40 at 200 Hz: with 8 of 625 us the plant's own integration
    error on a 3 V square wave into the end stops reached 92 um and 12 kPa against the 1 kHz
    plant, far beyond the sensors' noise, and the diagnosis read it as a gap of the model's)."""
    dt = spec.params["integration.sample_time"]
    return max(spec.substeps, math.ceil(dt / MAX_SUBSTEP - 1e-9))


def build_constants(spec: PlantSpec) -> PlantConstants:
    """Compile ``spec`` for the loop."""
    p = spec.params
    e = spec.effects
    dt = p["integration.sample_time"]
    substeps = substeps_of(spec)
    h = dt / substeps
    chain, lead = chain_parameters(p)
    delay = p["valve.delay"] / dt
    r_gas = p["chamber.gas_constant"]
    rt = r_gas * p["chamber.temperature"]
    port = e.get("flow_lag")
    line = e.get("transport_delay")
    line_length = line["length"] if line else 0.0
    bore = line["bore"] if line else 1.0
    line_area = math.pi * bore * bore / 4.0
    segment = line_length / N_SEGMENTS
    wave_speed = math.sqrt(GAMMA_AIR * rt)
    steps = inner_steps(h, line_length, wave_speed, _port_rate(port, rt) if port else 0.0)
    load = e.get("extra_mass")
    if load:
        load_k = load["mass"] * (2.0 * math.pi * load["frequency"]) ** 2
        load_c = 2.0 * load["damping_ratio"] * math.sqrt(load_k * load["mass"])
    else:
        load_k = load_c = 0.0
    plays = e.get("weighted_play_hysteresis")
    if plays:
        thresholds = np.array([plays[f"threshold_{i}"] for i in range(1, N_PLAY + 1)])
        weights = np.array([plays[f"weight_{i}"] for i in range(1, N_PLAY + 1)])
        weights = weights / weights.sum()
    else:
        thresholds = weights = np.zeros(0)
    supply = e.get("supply_droop", {"set_pressure": P_SUPPLY, "droop": 0.0,
                                    "droop_quadratic": 0.0, "time_constant": 1.0,
                                    "hose_conductance": 1.0, "hose_volume": 1.0})
    gap = e.get("seal_gap_leak", {"width": 0.0, "height": 0.0, "length": 0.0,
                                  "loss_coefficient": 0.0})
    leak = e.get("iso6358_leak", {"cross_conductance": 0.0, "atmosphere_conductance": 0.0,
                                  "critical_ratio": 0.5})
    heat = e.get("wall_heat_exchange")
    friction = e.get("elastoplastic_friction", {"bristle_stiffness": 1.0, "bristle_damping": 0.0,
                                                "damping_velocity": 1.0,
                                                "breakaway_fraction": 0.5})
    seal = e.get("measured_seal")
    knee = knee_of(seal["half_fraction"]) if seal else 1.0
    cushion = e.get("end_stop_cushion", {"length": 0.0, "stiffness": 0.0, "damping": 0.0})
    spring = e.get("load_spring", {"stiffness": 0.0, "free_position": 0.0})
    position = e.get("position_filter")
    # Two equal first-order stages in series: the critically damped lag with w = 1 / tau.
    position_a, position_b = second_order_lag(
        1.0 / (2.0 * math.pi * position["time_constant"]), 1.0, h) if position \
        else (np.zeros((2, 2)), np.zeros(2))
    sensor = e.get("sensor_second_order")
    sensor_a, sensor_b = second_order_lag(sensor["natural_frequency"], sensor["damping_ratio"],
                                          h) if sensor else (np.zeros((2, 2)), np.zeros(2))
    noise = p["sensors.noise"]
    # The line's far half-segment lies in the chamber (passages docstring).
    far = 0.5 * line_area * segment
    return PlantConstants(
        dt=dt, substeps=substeps, u_limit=p["valve.command_limit"],
        chain=chain, lead=lead, delay=delay, delay_whole=int(math.ceil(delay - 1e-9)),
        valve_steps=VALVE_STEPS,
        port=port is not None, port_volume=port["port_volume"] if port else 1.0,
        port_conductance=port["filter_conductance"] if port else 0.0,
        line=line is not None, line_bore=bore, line_area=line_area, segment_length=segment,
        line_wave=GAMMA_AIR * rt / (line_area * segment) if line else 0.0,
        line_inertance=segment / line_area, passage_steps=steps,
        play_thresholds=thresholds, play_weights=weights,
        valve_gain=p["valve.gain"], null_offset=e.get("null_offset", {}).get("offset", 0.0),
        gain_charge=p["flow.gain_charge"], gain_discharge=p["flow.gain_discharge"],
        gain_slope=e.get("pressure_dependent_gain", {}).get("slope", 0.0),
        shape=e.get("flow_map_shape", {}).get("amplitude", 0.0),
        shape_phase=e.get("flow_map_shape", {}).get("phase", 0.0),
        supply_droops="supply_droop" in e,
        supply_set=supply["set_pressure"], supply_droop=supply["droop"],
        supply_droop_2=supply["droop_quadratic"], supply_tau=supply["time_constant"],
        hose_conductance=supply["hose_conductance"], hose_volume=supply["hose_volume"],
        leak_cross=leak["cross_conductance"], leak_atm=leak["atmosphere_conductance"],
        leak_b=leak["critical_ratio"],
        gap_width=gap["width"], gap_height=gap["height"], gap_length=gap["length"],
        gap_loss=gap["loss_coefficient"],
        thermal=heat is not None,
        heat_coefficient=heat["heat_transfer_coefficient"] if heat else 0.0,
        t_wall=p["chamber.temperature"],
        t_supply=p["chamber.temperature"] + (heat["supply_temperature_offset"] if heat else 0.0),
        r_gas=r_gas, cv=r_gas / (GAMMA_AIR - 1.0),
        area=p["chamber.piston_area"], v01=p["chamber.dead_volume_1"] + far,
        v02=p["chamber.dead_volume_2"] + far, mass=p["mechanics.mass"],
        load=load is not None, load_mass=load["mass"] if load else 0.0, load_k=load_k,
        load_c=load_c,
        y_max=0.5 * p["mechanics.stroke"], locked=p["mechanics.locked"],
        regulated=p["chamber.regulated"],
        planes=np.array([[p[f"friction.{phase}.{q}"] for q in
                          ("breakaway", "stribeck_velocity", "viscous", "coulomb")]
                         for phase in ("entry", "exit")], dtype=float),
        bristles="elastoplastic_friction" in e,
        sigma0=friction["bristle_stiffness"], sigma1=friction["bristle_damping"],
        v_damp=friction["damping_velocity"], z_fraction=friction["breakaway_fraction"],
        seal=seal is not None, seal_knee=knee,
        seal_length=length_of(seal["presliding_displacement"], knee) if seal else 1.0,
        cushion_length=cushion["length"], cushion_k=cushion["stiffness"],
        cushion_c=cushion["damping"],
        spring_k=spring["stiffness"], spring_y0=spring["free_position"],
        sensor=sensor is not None, sensor_a=sensor_a, sensor_b=sensor_b,
        sensor_bow=sensor["nonlinearity"] if sensor else 0.0,
        sensor_low=SENSOR_LOW, sensor_span=SENSOR_SPAN,
        sensor_offset_1=sensor["offset_1"] if sensor else 0.0,
        sensor_offset_2=sensor["offset_2"] if sensor else 0.0,
        position_filter=position is not None,
        position_a=position_a, position_b=position_b,
        sigma_p=p["sensors.pressure_sigma"] if noise else 0.0,
        sigma_y=p["sensors.position_sigma"] if noise else 0.0,
    )
