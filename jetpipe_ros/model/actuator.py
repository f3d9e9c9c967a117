"""The actuator model assembled: parameters compiled for the kernel, state, and simulation.

:class:`Actuator` holds one actuator's state and advances it sample by sample (the ROS node) or
over a whole command sequence (the batch simulator, identification and diagnosis), always through
the same compiled kernel; :meth:`Actuator.reconfigure` switches parameters on a running model as
a test rig does (piston clamp, chamber regulators).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from jetpipe_ros.model import kernel
from jetpipe_ros.model.flow import (GAMMA_AIR, P_ATM, P_SUPPLY_NOMINAL, FlowLaw,
                                    chamber_inflow, flow_lag_matrix)
from jetpipe_ros.model.friction import FRICTION_FORMS, MAXWELL_SLIP, STATIC, element_slips
from jetpipe_ros.model.hose import hose_constants, inner_steps
from jetpipe_ros.model.params import ModelParams
from jetpipe_ros.model.port import POROUS_REFERENCE, effective_area, small_drop_conductance
from jetpipe_ros.model.valve import sample_valve


#: Parameters whose change, with the regulators on, re-imposes the chamber pressures and the
#: piston's place (:meth:`Actuator.reconfigure`).
REGULATOR_KEYS = ("chamber.regulated", "chamber.initial_pressure_1",
                  "chamber.initial_pressure_2", "mechanics.initial_position")


def profile_array(p: Mapping[str, Any]) -> np.ndarray:
    """The bore profile (3, K) of validated parameters: knots [m], exit and entry factors;
    (3, 0) when every factor is 1 (no profile)."""
    rows = [p[f"friction.profile.{q}"] for q in ("position", "exit", "entry")]
    if all(f == 1.0 for f in rows[1] + rows[2]):
        return np.zeros((3, 0))
    return np.array(rows, dtype=float)


def flow_map(p: Mapping[str, Any]) -> np.ndarray:
    """The kernel's flow map: Eq. 8's coefficients [g/s], followed by the correction table
    (``flow.table``, :func:`~jetpipe_ros.model.flow.table_flow`) when it is not all zero (the
    kernel skips an absent table: Eq. 8 alone costs no lookup)."""
    coef = np.array(p["flow.coefficients"], dtype=float)
    table = np.array(p["flow.table"], dtype=float)
    return np.concatenate([coef, table]) if np.any(table) else coef


def _plays(half_width: float, n: int, spread: float,
           sharp_share: float) -> tuple[np.ndarray, np.ndarray]:
    """The valve hysteresis's play thresholds [V] and weights (summing to 1): ``n`` thresholds
    evenly in r (1 +- ``spread``), the narrowest (``sharp_share`` > 0) or the widest (< 0)
    weighing ``|sharp_share|`` more than an equal share, r such that the weighted mean threshold
    is ``half_width``; ``n`` >= 1 (:func:`hysteresis_plays` builds none with the effect off).
    One play: ``half_width``."""
    offsets = (2.0 * np.arange(1, n + 1) - 1.0) / n - 1.0  # in (-1, 1), mean 0
    weights = np.full(n, (1.0 - abs(sharp_share)) / n)
    weights[0 if sharp_share >= 0.0 else -1] += abs(sharp_share)
    shape = 1.0 + spread * offsets
    return half_width * shape / float(weights @ shape), weights


def hysteresis_plays(p: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The play thresholds [V] and weights (summing to 1) of the valve hysteresis in validated
    parameters ``p``, the loop the kernel runs; both empty with the effect off."""
    on = p["effects.valve_hysteresis.enabled"]
    half_width = p["effects.valve_hysteresis.half_width"] if on else 0.0
    if half_width <= 0.0:  # built for every actuator: no array arithmetic for none
        return np.zeros(0), np.zeros(0)
    return _plays(half_width, p["effects.valve_hysteresis.elements"],
                  p["effects.valve_hysteresis.spread"], p["effects.valve_hysteresis.sharp_share"])


def port_time_constant(p: Mapping[str, Any]) -> float | None:
    """The small-signal time constant [s] at rest of the port (``valve_lag``, ``form: port``)
    in validated parameters ``p``: V_p / (gamma r T (G_0 + K_v)), G_0 the restriction's slope
    within 0.5 % of equal pressures at the rest pressure (:data:`port.POROUS_REFERENCE`) and K_v
    the flow map's slope -dq/dp there with the valve at its null (:mod:`~jetpipe_ros.model.port`,
    *Time constant*). None without a port."""
    c = build_constants(p)
    if c.port_rate == 0.0:
        return None
    g_0 = small_drop_conductance(c.port_area, c.port_index, c.rt)
    # The map's slope by the kernel's own finite difference (the step its port integration uses).
    step = kernel.HOSE_SLOPE_STEP
    k_v = (chamber_inflow(c.flow_coef, 0.0, POROUS_REFERENCE, c.p_supply, c.flow_law)
           - chamber_inflow(c.flow_coef, 0.0, POROUS_REFERENCE + step, c.p_supply,
                            c.flow_law)) / step
    return 1.0 / (c.port_rate * (g_0 + k_v))  # port_rate = gamma r T / V_p


def build_constants(p: Mapping[str, Any]) -> kernel.Constants:
    """Compile validated parameters (nominal values plus enabled effects) for the kernel."""

    def effect(name: str, key: str, off: float) -> float:
        return p[f"effects.{name}.{key}"] if p[f"effects.{name}.enabled"] else off

    dt = p["integration.sample_time"]
    substeps = p["integration.substeps"]
    delay_form = p["effects.valve_delay.form"]
    line_delay = effect("valve_delay", "delay", 0.0) if delay_form == "line" else 0.0
    hose_length = effect("valve_delay", "length", 0.0) if delay_form == "hose" else 0.0
    rt = p["chamber.gas_constant"] * p["chamber.temperature"]
    hose = (hose_constants(hose_length, p["effects.valve_delay.bore"], rt) if hose_length > 0.0
            else (0.0, 0.0, 0.0, 0.0))
    lag_hz = effect("valve_lag", "corner_frequency", 0.0)
    lag_form = p["effects.valve_lag.form"]
    second_order = lag_hz and lag_form == "second_order"
    flow_lag = (flow_lag_matrix(lag_hz, p["effects.valve_lag.damping_ratio"], dt / substeps)
                if lag_hz and lag_form == "flow" else np.zeros((0, 3)))
    port_volume = (effect("valve_lag", "port_volume", 0.0) if lag_form == "port" else 0.0)
    valve = sample_valve(p, dt, substeps,
                         extra_lag_hz=lag_hz if lag_hz and lag_form in ("first_order",
                                                                        "second_order")
                         else None,
                         extra_delay=effect("valve_delay", "delay", 0.0)
                         if delay_form == "command" else 0.0,
                         extra_lag_damping=p["effects.valve_lag.damping_ratio"]
                         if second_order else None)
    planes = np.array([[p[f"friction.{phase}.{q}"] for q in
                        ("breakaway", "stribeck_velocity", "viscous", "coulomb")]
                       for phase in ("entry", "exit")], dtype=float)
    noise = p["sensors.noise"]
    hysteresis, hysteresis_weight = hysteresis_plays(p)
    thermal = p["effects.thermal.enabled"]
    heat_transfer = thermal and p["effects.thermal.form"] == "heat_transfer"
    leakage = p["effects.leakage.enabled"]
    orifice = leakage and p["effects.leakage.form"] == "orifice"
    power = leakage and p["effects.leakage.form"] == "power"
    laminar = leakage and p["effects.leakage.form"] == "laminar"
    line = p["effects.supply_pressure.enabled"] and p["effects.supply_pressure.form"] == "line"
    friction_form = (FRICTION_FORMS[p["effects.friction_dynamics.form"]]
                     if p["effects.friction_dynamics.enabled"] else STATIC)
    return kernel.Constants(
        dt=dt, substeps=substeps, u_limit=p["valve.command_limit"],
        valve_a=valve.a, valve_g=valve.g, valve_c=valve.c, valve_h=valve.h,
        delay_samples=valve.delay_samples,
        hysteresis=hysteresis, hysteresis_weight=hysteresis_weight,
        flow_coef=flow_map(p),
        flow_law=FlowLaw(reference=effect("supply_pressure", "reference", P_ATM),
                         gain_charge=p["flow.gain_charge"],
                         gain_discharge=p["flow.gain_discharge"]),
        valve_gain=p["valve.gain"],
        p_supply=effect("supply_pressure", "pressure", P_SUPPLY_NOMINAL),
        line_conductance=p["effects.supply_pressure.line_conductance"] if line else 0.0,
        line_volume=p["effects.supply_pressure.line_volume"],
        flow_lag=flow_lag, line_delay=line_delay * substeps / dt,
        hose_steps=inner_steps(hose_length, rt, dt / substeps) if hose_length > 0.0 else 0,
        hose_rate=hose[0], hose_accel=hose[1], hose_laminar=hose[2], hose_turbulent=hose[3],
        port_rate=GAMMA_AIR * rt / port_volume if port_volume > 0.0 else 0.0,
        port_area=effective_area(p["effects.valve_lag.port_conductance"],
                                 p["chamber.gas_constant"]) if port_volume > 0.0 else 0.0,
        port_index=p["effects.valve_lag.port_index"],
        leak_cross=p["effects.leakage.cross_coefficient"] if laminar else 0.0,
        leak_atm=p["effects.leakage.atmosphere_coefficient"] if laminar else 0.0,
        orifice_cross=p["effects.leakage.cross_area"] if orifice else 0.0,
        orifice_atm=p["effects.leakage.atmosphere_area"] if orifice else 0.0,
        power_cross=p["effects.leakage.cross_flow"] if power else 0.0,
        power_atm=p["effects.leakage.atmosphere_flow"] if power else 0.0,
        leak_exponent=p["effects.leakage.exponent"],
        polytropic=p["effects.thermal.polytropic_index"] if thermal and not heat_transfer
        else 1.0,
        heat_transfer=p["effects.thermal.heat_transfer"] if heat_transfer else 0.0,
        r_gas=p["chamber.gas_constant"], t_wall=p["chamber.temperature"],
        rt=rt,
        area=p["chamber.piston_area"], v01=p["chamber.dead_volume_1"],
        v02=p["chamber.dead_volume_2"],
        mass=effect("moving_mass", "mass", p["mechanics.mass"]),
        y_max=0.5 * p["mechanics.stroke"], locked=p["mechanics.locked"],
        regulated=p["chamber.regulated"], planes=planes, friction_floor=p["friction.floor"],
        profile=profile_array(p),
        friction_form=friction_form, sigma0=p["effects.friction_dynamics.bristle_stiffness"],
        sigma1=p["effects.friction_dynamics.bristle_damping"],
        slips=element_slips(p["effects.friction_dynamics.presliding_displacement"],
                            p["effects.friction_dynamics.presliding_spread"],
                            p["effects.friction_dynamics.elements"])
        if friction_form == MAXWELL_SLIP else np.zeros(0),
        sensor_tau=effect("sensor_dynamics", "time_constant", 0.0),
        sensor_bias=effect("sensor_dynamics", "bias", 0.0),
        sensor_bias_2=effect("sensor_dynamics", "bias_difference", 0.0),
        sensor_gain=effect("sensor_dynamics", "gain", 0.0),
        sensor_drift=effect("sensor_dynamics", "drift", 0.0),
        sigma_p=p["sensors.pressure_sigma"] if noise else 0.0,
        sigma_y=p["sensors.position_sigma"] if noise else 0.0,
    )


@dataclass
class Trace:
    """A simulated run sampled at the model's sample time; each field an array [SI units]."""

    t: np.ndarray  #: time [s]
    u: np.ndarray  #: applied (clipped) valve command [V]
    y: np.ndarray  #: piston position [m]
    v: np.ndarray  #: piston velocity [m/s]
    p1: np.ndarray  #: chamber 1 pressure [Pa, absolute]
    p2: np.ndarray  #: chamber 2 pressure [Pa, absolute]
    friction: np.ndarray  #: friction force F_f [N]
    force: np.ndarray  #: net pneumatic force S (p1 - p2) [N]
    u_eq: np.ndarray  #: equivalent valve voltage seen by the flow map [V]
    y_meas: np.ndarray  #: measured position [m]
    p1_meas: np.ndarray  #: measured chamber 1 pressure [Pa]
    p2_meas: np.ndarray  #: measured chamber 2 pressure [Pa]

    @classmethod
    def from_rows(cls, rows: np.ndarray) -> Trace:
        """Build from an (n, N_OUT) array of kernel outputs."""
        return cls(*(np.ascontiguousarray(rows[:, i]) for i in range(kernel.N_OUT)))


class Actuator:
    """One simulated actuator: compiled parameters, integration state and sensor noise.

    Args:
        params: validated model parameters (nominal values plus effects).
    """

    def __init__(self, params: ModelParams | None = None) -> None:
        self.params = params if params is not None else ModelParams()
        self.constants = build_constants(self.params)
        self._rng = np.random.default_rng(self.params["sensors.seed"])
        self._one_u = np.zeros(1)
        self._one_f = np.zeros(1)
        self._one_out = np.zeros((1, kernel.N_OUT))
        self._zero_noise = np.zeros((1, 3))
        self._no_drive = np.zeros((0, kernel.N_DRIVE))
        self.reset()

    def reset(self) -> None:
        """Return to the initial state: at rest, valve at rest, pressures as configured."""
        c = self.constants
        x = np.zeros(kernel.state_size(c))
        p = self.params
        x[kernel.Y] = min(max(p["mechanics.initial_position"], -c.y_max), c.y_max)
        x[kernel.P1] = x[kernel.PS1] = x[kernel.PORT1] = p["chamber.initial_pressure_1"]
        x[kernel.P2] = x[kernel.PS2] = x[kernel.PORT2] = p["chamber.initial_pressure_2"]
        kernel.fill_line(c, x)
        x[kernel.T1] = x[kernel.T2] = p["chamber.temperature"]
        x[kernel.SUPPLY] = c.p_supply
        x[kernel.STUCK] = 1.0
        self.state = x
        self.ring = np.zeros(c.delay_samples + 2)  # the current command and the delay's two

    def preload_hysteresis(self, side: float) -> None:
        """Place the valve hysteresis's plays (the ``valve_hysteresis`` effect) as a valve at
        rest at 0 V holds them after its command came to 0 V from above (``side`` = +1: each
        play's output at +its threshold [V]) or from below (-1), or anywhere between (0: at 0 V,
        the state :meth:`reset` leaves). A record that starts after commands it does not show
        starts anywhere in that range. Nothing changes without the hysteresis."""
        if not -1.0 <= side <= 1.0:
            raise ValueError(f"side must lie in [-1, 1], got {side}")
        r = self.constants.hysteresis
        self.state[kernel.PLAY:kernel.PLAY + r.shape[0]] = side * r

    def reconfigure(self, changes: Mapping[str, Any]) -> None:
        """Apply parameter ``changes`` in place, keeping the state, as a test rig's switch does.

        A real rig clamps the piston (constant-volume tests) or puts regulators on the chambers
        between experiments without resetting anything else. Position, velocity, pressures,
        temperatures, friction state, the supply line's pressure, sample count and the sensor
        noise sequence carry over. If
        the change alters the valve chain's order or delay (e.g. enabling ``valve_lag`` or
        changing ``valve.delay``), the valve chain restarts at rest (and a changed line between
        valve and chambers holds the present pressures and no flow).

        The regulated rig (the friction tests of the paper's Fig. 15) also acts on the state:
        with the regulators on after the change and one of :data:`REGULATOR_KEYS` changed, the
        chamber pressures [Pa] are set to the regulators' (``chamber.initial_pressure_1``,
        ``_2``) and the piston is placed at rest at ``mechanics.initial_position`` [m], as the
        rig's hydraulic cylinder does. Raises :class:`~jetpipe_ros.model.ParameterError` on a
        bad value, leaving the actuator unchanged.
        """
        params = self.params.with_values(changes)
        constants = build_constants(params)
        state, ring = self.state, self.ring
        size = kernel.state_size(constants)
        if state.shape[0] != size or ring.shape[0] != constants.delay_samples + 2:
            kept = state[:kernel.VALVE].copy()
            state = np.zeros(size)
            state[:kernel.VALVE] = kept
            state[kernel.PLAY:kernel.VALVE] = 0.0
            state[kernel.HEAD] = state[kernel.LINE_HEAD] = 0.0
            ring = np.zeros(constants.delay_samples + 2)
            kernel.fill_line(constants, state)
        if params["chamber.regulated"] and any(key in changes for key in REGULATOR_KEYS):
            state = state.copy()
            state[kernel.P1] = params["chamber.initial_pressure_1"]
            state[kernel.P2] = params["chamber.initial_pressure_2"]
            state[kernel.Y] = min(max(params["mechanics.initial_position"], -constants.y_max),
                                  constants.y_max)
            state[kernel.V] = 0.0
            state[kernel.STUCK] = 1.0
        self.params, self.constants = params, constants
        self.state, self.ring = state, ring

    @property
    def time(self) -> float:
        """Simulated time since the last reset [s]."""
        return self.state[kernel.STEP] * self.constants.dt

    def _noise(self, n: int) -> np.ndarray:
        if self.constants.sigma_p == 0.0 and self.constants.sigma_y == 0.0:
            return self._zero_noise if n == 1 else np.zeros((n, 3))
        return self._rng.standard_normal((n, 3))

    def outputs(self) -> np.ndarray:
        """Outputs (N_OUT,) of the current state, with fresh sensor noise."""
        out = np.zeros(kernel.N_OUT)
        kernel.measure(self.constants, self.state, self._noise(1)[0], out)
        return out

    def step(self, u: float, f_load: float = 0.0) -> np.ndarray:
        """Advance one sample with command ``u`` [V] and load ``f_load`` [N]; return outputs.

        The returned array (N_OUT,) is reused by the next call; copy it to keep it.
        """
        self._one_u[0] = u
        self._one_f[0] = f_load
        kernel.advance(self.constants, self.state, self.ring, self._one_u, self._one_f,
                       self._no_drive, self._noise(1), self._one_out)
        return self._one_out[0]

    def run(self, u: np.ndarray, f_load: np.ndarray | float = 0.0,
            drive: np.ndarray | None = None) -> np.ndarray:
        """Advance ``len(u)`` samples; return the (n, N_OUT) outputs at the end of each.

        ``drive`` (n, 4) optionally prescribes per sample the position [m] and velocity [m/s]
        and/or the two chamber pressures [Pa]; NaN entries leave that part simulated.
        """
        u = _kernel_array(u)
        if not np.all(np.isfinite(u)):
            raise ValueError("valve command contains NaN or infinite values")
        fl = _kernel_array(np.broadcast_to(f_load, u.shape))
        if drive is None:
            drive = self._no_drive
        else:
            drive = _kernel_array(drive)
            if drive.shape != (u.shape[0], kernel.N_DRIVE):
                raise ValueError(f"drive must have shape ({u.shape[0]}, {kernel.N_DRIVE}), "
                                 f"got {drive.shape}")
        out = np.empty((u.shape[0], kernel.N_OUT))
        kernel.advance(self.constants, self.state, self.ring, u, fl, drive,
                       self._noise(len(u)), out)
        return out


def _kernel_array(values: Any) -> np.ndarray:
    """``values`` as the kernel takes every array: float, C-contiguous and writable. Numba
    compiles a kernel per array type, and a read-only array (a broadcast load, a memory-mapped
    record) is another type: without the copy a first run with a load array compiled the whole
    kernel a second time (40-50 s on a fresh install)."""
    array = np.ascontiguousarray(values, dtype=float)
    return array if array.flags.writeable else array.copy()


def compile_kernel() -> float:
    """Compile the kernel (or load it from numba's cache on disk, where a first compile leaves
    it for every later process); returns the seconds it took. A process that starts nodes calls
    it first, so the nodes load the kernel instead of compiling it within their start-up wait."""
    start = time.perf_counter()
    Actuator(ModelParams()).step(0.0)
    return time.perf_counter() - start


def simulate(params: ModelParams, u: np.ndarray, f_load: np.ndarray | float = 0.0) -> Trace:
    """Replay a command sequence sampled at the model's sample time from the initial state.

    Row k of the result is the state at t_k = k dt, before command ``u[k]`` acts; ``u[k]`` is
    held over [t_k, t_k+1). The result has ``len(u)`` rows.
    """
    return replay_command(Actuator(params), u, f_load)


def replay_command(act: Any, u: np.ndarray, f_load: np.ndarray | float = 0.0) -> Trace:
    """Run a fresh actuator ``act`` (the model's :class:`Actuator`, or anything with its
    ``outputs()``, ``run(u, f_load)`` and ``constants.u_limit``, e.g. the plant) through a
    command sequence [V] and load [N]: row k is the state at t_k, before ``u[k]`` acts."""
    u = np.asarray(u, dtype=float)
    if u.ndim != 1 or u.size == 0:
        raise ValueError("command must be a non-empty 1-D sequence")
    fl = np.broadcast_to(np.asarray(f_load, dtype=float), u.shape)
    rows = np.empty((u.size, kernel.N_OUT))
    rows[0] = act.outputs()
    if u.size > 1:
        rows[1:] = act.run(u[:-1], fl[:-1])
    rows[:, kernel.OUT_U] = np.clip(u, -act.constants.u_limit, act.constants.u_limit)
    return Trace.from_rows(rows)
