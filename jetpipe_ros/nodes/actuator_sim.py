"""actuator_sim: the jet-pipe actuator model behind the topic contract, one sample per 1 ms.

A thin shell over :class:`jetpipe_ros.model.Actuator`: it loads and validates the parameters,
holds the latest commands, steps the model and publishes every sample. No physics here.

Time modes (parameter ``time_mode``):

- ``realtime``: a 1 kHz wall-clock timer; each tick steps the model by the samples due since the
  start (rclpy skips late ticks; the model does not lose time), at most ``max_catch_up`` at a
  time (a longer backlog is dropped and counted as an overrun). Stamps are the node clock at
  each sample's nominal time.
- ``sim``: the node publishes ``/clock`` with the simulated time, stamps with it, sets its own
  clock from it, and runs ``real_time_factor`` times faster than the wall clock (0: as fast as
  it can), handling incoming messages between batches of samples.
- ``sim`` with ``lockstep: true``: the commander paces the simulation. Each ``voltage_cmd``
  received applies that command for one sample, which is stepped and published at once; with
  no command the simulation waits, re-publishing its latest sample every ``lockstep_kick``
  seconds so that a commander that joins late can answer. Campaigns run this way (the
  ``id_recorder`` and ``controller`` answer every sample), as fast as the loop turns.

A rig without one or both chamber pressure sensors (position only, or one pressure) is
emulated with ``pressure_sensors``: the topics of the pressures it lacks are not advertised at
all, as on such a rig; the model still simulates both chambers.

Every sample also publishes ``voltage_applied``: the command [V] (joint ``valve``, position) and
the external load [N] (joint ``load``, effort) held over the sample that ends at its stamp, so a
recording pairs each measurement with the inputs that produced it whatever the transport delays.
Bad inputs never stop it: a non-finite command or load is ignored (the last one held), a command
beyond ``valve.command_limit`` and a load beyond 4 x the largest pneumatic force S (p_s - p_atm)
(:func:`jetpipe_ros.model.limits.load_limit`, 19.6 kN nominal) are clipped, each with a
throttled warning. Messages are applied in the order they arrive (the default EventsExecutor),
so a commander that publishes a sample's ``load_force`` before its ``voltage_cmd`` gets both on
that sample.

Model parameters may be changed at run time (``ros2 param set``, or a test rig's switch such as
``mechanics.locked``): the model is rebuilt with the new values and keeps its state.
``integration.sample_time`` and ``sensors.seed`` are fixed at start-up.

Run: ``ros2 run jetpipe_ros actuator_sim --ros-args --params-file config/actuator.yaml``
(or ``python -m jetpipe_ros.nodes.actuator_sim ...``). Exit status 2 on bad parameters.
"""

from __future__ import annotations

import array
import math
import sys
import time
from collections.abc import Sequence
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time import Time
from rclpy.time_source import TimeSource

from jetpipe_ros.model import SPECS, Actuator, ModelParams, ParameterError
from jetpipe_ros.model import kernel as k
from jetpipe_ros.model.limits import LOAD_FACTOR, load_limit
from jetpipe_ros.model.params import NODE_NAME, ParamSpec, check_value
from jetpipe_ros.nodes import interface, process
from jetpipe_ros.nodes.pacing import Pacer
from jetpipe_ros.nodes.parameters import (StartupError, declare, set_explained, skipped_sections,
                                          unknown_overrides, value)
from jetpipe_ros.package_data import share_file

#: The node's own parameters (the model's are :data:`jetpipe_ros.model.SPECS`).
NODE_SPECS: dict[str, ParamSpec] = {s.name: s for s in [
    ParamSpec("time_mode", "realtime",
              "Time base: wall clock, or simulated time published on /clock",
              choices=("realtime", "sim")),
    ParamSpec("real_time_factor", 1.0,
              "sim mode: simulated seconds per wall second, 0 = as fast as possible", "",
              0.0, 1000.0),
    ParamSpec("command_timeout", 0.5,
              "Command 0 V after this long without a voltage_cmd (simulated time)", "s",
              1e-3, 3600.0),
    ParamSpec("frame_id", "actuator", "frame_id of the stamped messages"),
    ParamSpec("joint_name", "piston", "Name of the joint in joint_states"),
    ParamSpec("max_catch_up", 50,
              "Most samples stepped at one timer tick; realtime mode drops a longer backlog",
              "samples", 1, 1000),
    ParamSpec("report_period", 10.0, "Period of the step-rate report in the log, 0 = off",
              "s", 0.0, 3600.0),
    ParamSpec("lockstep", False,
              "sim mode: step one sample per voltage_cmd received, wait without one"),
    ParamSpec("lockstep_kick", 0.2,
              "lockstep: re-publish the latest sample after this long without a voltage_cmd",
              "s", 0.01, 10.0),
    ParamSpec("pressure_sensors", "p1,p2", "The chamber pressures the emulated rig measures "
              "and publishes beside the position (the others' topics are not advertised)",
              choices=interface.PRESSURE_SENSORS),
    ParamSpec("executor", "events",
              "rclpy executor: EventsExecutor (less CPU) or SingleThreadedExecutor",
              choices=("events", "single")),
]}
#: Node parameters that may change at run time; the others are read-only.
DYNAMIC = ("real_time_factor", "command_timeout", "report_period")
#: Model parameters fixed at start-up (the node's time line and noise sequence depend on them).
MODEL_STATIC = ("integration.sample_time", "sensors.seed")

TICK = 1e-3  #: shortest wall-clock timer period [s]
WARN_PERIOD = 1.0  #: throttle of repeated command warnings [s]
NS = 1_000_000_000


class ActuatorSim(Node):
    """The simulator node; raises :class:`StartupError` on bad parameters."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        params, opts = self._load_parameters(kwargs.get("cli_args"))
        self.opts = opts
        self.get_logger().info("loading the model's kernel (compiled once after an install, "
                               "about a minute on 2 cores; then loaded from numba's cache)")
        Actuator(params).step(0.0)  # compile (or load) the kernel before the clock starts
        self.actuator = Actuator(params)
        self._dt = self.actuator.constants.dt
        self._dt_ns = round(self._dt * NS)
        self._limit = params["valve.command_limit"]
        self._load_limit = load_limit(params)
        self._variance = self.actuator.constants.sigma_p ** 2
        self._sim = opts["time_mode"] == "sim"
        self._lockstep = self._sim and opts["lockstep"]
        self._last_out: list[float] | None = None  # latest published outputs (lockstep kick)
        self._last_load = 0.0  # load [N] held over the latest published sample
        self._waiting_since = -math.inf  # wall time [s] lockstep began waiting for a command

        self._u = 0.0  # held valve command [V]
        self._f_load = 0.0  # held load force [N]
        self._last_cmd: float | None = None  # node time of the last valid command [s]
        self._timed_out = False
        self._samples = 0  # samples stepped since the start (not reset with the model)
        self._resets = 0

        self._make_messages()
        measured = interface.measured_pressures(opts["pressure_sensors"])
        #: (message, output index, topic) of each pressure the emulated rig measures
        self._pressures = [(msg, index, interface.SENSOR_TOPICS[p]) for msg, index, p in (
            (self._msg_p[0], k.OUT_P1_MEAS, "p1"), (self._msg_p[1], k.OUT_P2_MEAS, "p2"))
            if p in measured]
        self._pub = {name: interface.publisher(self, name) for name in (
            "position", *(topic for _, _, topic in self._pressures), "friction_force",
            "joint_states", "voltage_applied")}
        if self._sim:
            self._pub["/clock"] = interface.publisher(self, "/clock")
            self._take_clock()
        interface.subscription(self, "voltage_cmd", self._on_voltage)
        interface.subscription(self, "load_force", self._on_load)
        self.add_on_set_parameters_callback(self._check_update)
        self.add_post_set_parameters_callback(self._apply_update)

        self._pacer = Pacer(self._dt, opts["real_time_factor"] if self._sim else 1.0,
                            opts["max_catch_up"], time.monotonic())
        self._ticking = False  # the time line restarts at the first tick
        self._start(time.monotonic())
        self.create_timer(max(self._dt, TICK), self._tick,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        effects = ", ".join(params.enabled_effects()) or "none"
        rate = f", real_time_factor {opts['real_time_factor']:g}" if self._sim else ""
        if self._lockstep:
            rate = ", lockstep (one sample per voltage_cmd)"
        self.get_logger().info(
            f"started: time_mode {opts['time_mode']}{rate}, sample time {self._dt * 1e3:g} ms, "
            f"effects: {effects}, pressure sensors: {opts['pressure_sensors']}, topic contract "
            f"{share_file(interface.CONTRACT)}")

    # -- start-up ---------------------------------------------------------------------------

    def _load_parameters(self, cli_args: Sequence[str] | None
                         ) -> tuple[ModelParams, dict[str, Any]]:
        """Declare and validate every parameter (``cli_args``: the node's own command line, as
        given to its constructor); raise StartupError listing all problems."""
        static = [s for s in NODE_SPECS.values() if s.name not in DYNAMIC]
        errors = declare(self, [SPECS[n] for n in MODEL_STATIC], read_only=True)
        errors += declare(self, [s for s in SPECS.values() if s.name not in MODEL_STATIC],
                          read_only=False)
        errors += declare(self, static, read_only=True)
        errors += declare(self, [NODE_SPECS[n] for n in DYNAMIC], read_only=False)
        for name in unknown_overrides(self, [*SPECS, *NODE_SPECS]):
            try:
                ModelParams({name: None})  # names the unknown effect or parameter
            except ParameterError as exc:
                errors.append(str(exc))
        errors += skipped_sections(self, cli_args)
        if errors:
            raise StartupError(errors)
        try:
            params = ModelParams({name: value(self, name) for name in SPECS})
        except ParameterError as exc:
            raise StartupError([str(exc)]) from exc
        opts = {name: value(self, name) for name in NODE_SPECS}
        if value(self, "use_sim_time") and opts["time_mode"] == "realtime":
            raise StartupError(["parameter use_sim_time is true but time_mode is realtime; "
                                "use time_mode sim (the simulator then publishes /clock)"])
        return params, opts

    def _take_clock(self) -> None:
        """Sim mode: drive this node's ROS clock from the simulated time directly."""
        if value(self, "use_sim_time"):
            # Its own /clock would come back late through DDS; the node sets the clock itself.
            self.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, False)])
        self._time_source = TimeSource()
        self._time_source.attach_clock(self.get_clock())
        self._time_source.ros_time_is_active = True
        self.get_clock().set_ros_time_override(Time(nanoseconds=0))

    def _make_messages(self) -> None:
        """Message objects reused for every sample."""
        from rosgraph_msgs.msg import Clock as ClockMsg
        from sensor_msgs.msg import FluidPressure, JointState
        from std_msgs.msg import Float64

        self._msg_position = Float64()
        self._msg_friction = Float64()
        self._msg_p = (FluidPressure(), FluidPressure())
        for m in self._msg_p:
            m.header.frame_id = self.opts["frame_id"]
            m.variance = self._variance
        self._msg_joint = JointState()
        self._msg_joint.header.frame_id = self.opts["frame_id"]
        self._msg_joint.name = [self.opts["joint_name"]]
        self._msg_applied = JointState()
        self._msg_applied.header.frame_id = self.opts["frame_id"]
        self._msg_applied.name = ["valve", "load"]
        self._msg_clock = ClockMsg()

    # -- run-time parameters ----------------------------------------------------------------

    def set_parameters_atomically(self, parameter_list: list[Parameter[Any]]) -> Any:
        """rclpy's, with rejections naming the parameter and the types (remote sets)."""
        return set_explained(self, parameter_list, super().set_parameters_atomically)

    def _check_update(self, params: list[Parameter[Any]]) -> SetParametersResult:
        model = {p.name: _plain(p.value) for p in params if p.name in SPECS}
        if model:
            try:
                self.actuator.params.with_values(model)
            except ParameterError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        for p in params:
            if p.name == "use_sim_time" and p.value:
                return SetParametersResult(successful=False, reason=(
                    "actuator_sim never follows an external /clock; use time_mode sim"))
            if p.name in DYNAMIC:
                try:
                    check_value(NODE_SPECS[p.name], p.value)
                except ParameterError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_update(self, params: list[Parameter[Any]]) -> None:
        model = {p.name: _plain(p.value) for p in params if p.name in SPECS}
        if model:
            self.actuator.reconfigure(model)
            self._limit = self.actuator.params["valve.command_limit"]
            self._load_limit = load_limit(self.actuator.params)
            self._variance = self.actuator.constants.sigma_p ** 2
            for m in self._msg_p:
                m.variance = self._variance
            shown = ", ".join(f"{k} = {v}" for k, v in model.items())
            # The new model acts from the latest sample on: the first sample it moves is the
            # next one published (stamps in the time the samples carry).
            self.get_logger().info(f"model parameters changed, acting from the sample stamped "
                                   f"{self._stamp_ns() / NS:.3f} s (state kept): {shown}")
        for p in params:
            if p.name in DYNAMIC:
                self.opts[p.name] = p.value
            if p.name == "real_time_factor" and self._sim:
                self._pacer.set_rate(p.value, time.monotonic())

    # -- commands ---------------------------------------------------------------------------

    def _on_voltage(self, msg: Any) -> None:
        u = msg.data
        if not math.isfinite(u):
            self.get_logger().warning(
                f"ignoring non-finite voltage_cmd {u}; holding {self._u:g} V",
                throttle_duration_sec=WARN_PERIOD)
            u = self._u
        if abs(u) > self._limit:
            self.get_logger().warning(
                f"voltage_cmd {u:g} V beyond valve.command_limit {self._limit:g} V; clipped",
                throttle_duration_sec=WARN_PERIOD)
            u = math.copysign(self._limit, u)
        self._u = u
        self._last_cmd = self._samples * self._dt
        self._timed_out = False
        if self._lockstep:
            self._step()
            self.get_clock().set_ros_time_override(Time(nanoseconds=self._stamp_ns()))
            self._waiting_since = time.monotonic()

    def _on_load(self, msg: Any) -> None:
        f = msg.data
        if not math.isfinite(f):
            self.get_logger().warning(
                f"ignoring non-finite load_force {f}; holding {self._f_load:g} N",
                throttle_duration_sec=WARN_PERIOD)
            return
        if abs(f) > self._load_limit:
            self.get_logger().warning(
                f"load_force {f:g} N beyond {self._load_limit:g} N ({LOAD_FACTOR:g} x the "
                f"largest pneumatic force S (p_s - p_atm)); clipped",
                throttle_duration_sec=WARN_PERIOD)
            f = math.copysign(self._load_limit, f)
        self._f_load = f

    def _command(self, t: float) -> float:
        """The valve command [V] at node time ``t`` [s], 0 V once the commands stopped."""
        if (self._last_cmd is not None and not self._timed_out
                and t - self._last_cmd > self.opts["command_timeout"]):
            self._timed_out = True
            self._u = 0.0
            self.get_logger().warning(
                f"no voltage_cmd for {self.opts['command_timeout']:g} s; commanding 0 V")
        return self._u

    # -- stepping ---------------------------------------------------------------------------

    def _start(self, now: float) -> None:
        """(Re)start the time line at wall time ``now`` [s, monotonic]."""
        self._pacer.set_rate(self._pacer.rate, now)
        self._stamp0 = 0 if self._sim else self.get_clock().now().nanoseconds
        self._report_at = (now, self._samples, self._pacer.ticks)
        self._started = now

    def _tick(self) -> None:
        now = time.monotonic()
        if not self._ticking:  # not counting the time the node took to get spinning
            self._start(now)
            self._ticking = True
        if self._lockstep:
            self._kick(now)
            self._maybe_report()
            return
        n = self._pacer.due(now)
        for _ in range(n):
            self._step()
        if n and self._sim:
            self.get_clock().set_ros_time_override(Time(nanoseconds=self._stamp_ns()))
        self._maybe_report()

    def _kick(self, now: float) -> None:
        """Lockstep: (re-)publish the latest sample if no command came for lockstep_kick."""
        if now - self._waiting_since < self.opts["lockstep_kick"]:
            return
        if self._last_out is None:  # nothing published yet: the initial state at t = 0
            self._last_out = self.actuator.outputs().tolist()
        self._publish(self._last_out, self._stamp_ns(), self._last_load)
        self._waiting_since = now

    def _stamp_ns(self) -> int:
        """Stamp of the latest sample [ns]: simulated time, or the node clock at the sample."""
        slots = self._samples if self._sim else self._samples + self._pacer.dropped
        return self._stamp0 + slots * self._dt_ns

    def _step(self) -> None:
        out = self.actuator.step(self._command(self._samples * self._dt), self._f_load).tolist()
        self._samples += 1
        if not all(math.isfinite(out[i]) for i in (
                k.OUT_Y_MEAS, k.OUT_V, k.OUT_P1_MEAS, k.OUT_P2_MEAS, k.OUT_FRICTION, k.OUT_FORCE)):
            self._resets += 1
            self.get_logger().error(
                f"model state not finite at t = {self._samples * self._dt:.3f} s "
                f"(u = {self._u:g} V, load {self._f_load:g} N); model reset")
            self.actuator.reset()
            return
        self._last_out, self._last_load = out, self._f_load
        self._publish(out, self._stamp_ns(), self._f_load)

    def _publish(self, out: list[float], stamp_ns: int, load: float) -> None:
        """Publish one sample's outputs ``out`` stamped ``stamp_ns`` [ns]; ``load`` [N] is the
        external load held over it (``voltage_applied``)."""
        sec, nanosec = divmod(stamp_ns, NS)
        y = out[k.OUT_Y_MEAS]
        self._msg_position.data = y
        self._pub["position"].publish(self._msg_position)
        for msg, index, name in self._pressures:
            msg.header.stamp.sec = sec
            msg.header.stamp.nanosec = nanosec
            msg.fluid_pressure = out[index]
            self._pub[name].publish(msg)
        self._msg_friction.data = out[k.OUT_FRICTION]
        self._pub["friction_force"].publish(self._msg_friction)
        joint = self._msg_joint
        joint.header.stamp.sec = sec
        joint.header.stamp.nanosec = nanosec
        joint.position = [y]
        joint.velocity = [out[k.OUT_V]]
        joint.effort = [out[k.OUT_FORCE]]
        self._pub["joint_states"].publish(joint)
        applied = self._msg_applied
        applied.header.stamp.sec = sec
        applied.header.stamp.nanosec = nanosec
        applied.position = [out[k.OUT_U], math.nan]
        applied.effort = [math.nan, load]
        self._pub["voltage_applied"].publish(applied)
        if self._sim:
            self._msg_clock.clock.sec = sec
            self._msg_clock.clock.nanosec = nanosec
            self._pub["/clock"].publish(self._msg_clock)

    # -- reporting --------------------------------------------------------------------------

    def _maybe_report(self) -> None:
        period = self.opts["report_period"]
        if period > 0.0 and time.monotonic() - self._report_at[0] >= period:
            self.report()

    def report(self, final: bool = False) -> None:
        """Log the step rate since the last report (or, if ``final``, since the start)."""
        now = time.monotonic()
        since, samples, ticks = (self._started, 0, 0) if final else self._report_at
        wall = max(now - since, 1e-9)
        n = self._samples - samples
        p = self._pacer
        over = "" if self._lockstep else f" over {p.ticks - ticks} timer ticks"
        self.get_logger().info(
            f"{'total: ' if final else ''}stepped {n} samples in {wall:.2f} s: "
            f"{n / wall:.1f} Hz ({n * self._dt / wall:.2f} x real time){over}; largest catch-up "
            f"{p.largest} samples, overruns {p.overruns} ({p.dropped} samples dropped), "
            f"model resets {self._resets}")
        self._report_at = (now, self._samples, p.ticks)


def _plain(v: Any) -> Any:
    """A parameter value as the model schema wants it (arrays as lists)."""
    return list(v) if isinstance(v, (array.array, tuple)) else v


def _executor(kind: str) -> Any:
    return EventsExecutor() if kind == "events" else SingleThreadedExecutor()


def main(args: Sequence[str] | None = None) -> int:
    """Run the node until Ctrl-C or SIGTERM; return 0, or 2 on bad parameters."""
    return process.run_nodes(NODE_NAME, args, [(NODE_NAME, ActuatorSim)],
                             executor=lambda nodes: _executor(nodes[0].opts["executor"]),
                             finish=lambda nodes: nodes[0].report(final=True))


if __name__ == "__main__":
    sys.exit(main())
