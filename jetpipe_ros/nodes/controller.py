"""controller: a position PID closing the loop over the topics of docs/node.md.

Subscribes ``position`` [m] (1 kHz from the simulator or the hardware driver),
``position_setpoint`` [m] and ``voltage_excitation`` [V]; publishes ``voltage_cmd`` [V], one per
position sample once a setpoint has arrived. The law is :class:`jetpipe_ros.control.Pid` (the
one the offline campaign runner uses): setpoint clamped to the stroke (with a throttled
warning), anti-windup, output limit, optional friction compensation. Gains and limits come from
``config/controller.yaml`` and may be changed at run time.

``enabled`` (parameter, settable at run time) switches the output on and off; the
``id_recorder`` turns the controller off for open-loop experiments. When enabled it answers at
once with the latest position, so a lock-step simulator waiting for a command moves on.
With ``pace_on_setpoint`` it answers each ``position_setpoint`` message (with the latest
position) instead of each ``position``: the ``id_recorder`` sets it so that the recorder, which
publishes one setpoint per recorded sample, paces a lock-step campaign and never falls behind.

Bad messages (NaN, infinite) are ignored with a throttled warning; ``voltage_cmd`` is never
non-finite. Run: ``ros2 run jetpipe_ros controller --ros-args --params-file
config/controller.yaml``. Exit status 2 on bad parameters.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from jetpipe_ros.control import SPECS, Pid, PidConfig
from jetpipe_ros.model import ParameterError
from jetpipe_ros.model.params import ParamSpec
from jetpipe_ros.nodes import interface, process
from jetpipe_ros.nodes.parameters import (StartupError, declare, set_explained, skipped_sections,
                                          unknown_overrides, value)

NODE_NAME = "controller"
NODE_SPECS: dict[str, ParamSpec] = {s.name: s for s in [
    ParamSpec("enabled", True, "Publish voltage_cmd (false: listen only)"),
    ParamSpec("pace_on_setpoint", False,
              "Answer each position_setpoint message instead of each position message"),
    ParamSpec("sample_time", 0.001, "Period of the position messages the law is tuned for",
              "s", 1e-5, 1.0),
]}
WARN_PERIOD = 1.0  #: throttle of repeated warnings [s]


class Controller(Node):
    """The controller node; raises :class:`StartupError` on bad parameters."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        errors = declare(self, SPECS.values(), read_only=False)
        errors += declare(self, [NODE_SPECS["enabled"], NODE_SPECS["pace_on_setpoint"]],
                          read_only=False)
        errors += declare(self, [NODE_SPECS["sample_time"]], read_only=True)
        errors += [f"unknown parameter {n!r}" for n in
                   unknown_overrides(self, [*SPECS, *NODE_SPECS])]
        errors += skipped_sections(self, kwargs.get("cli_args"))
        config = None
        if not errors:
            try:
                config = PidConfig.from_mapping({n: value(self, n) for n in SPECS})
            except ParameterError as exc:
                errors.append(str(exc))
        if errors:
            raise StartupError(errors)
        assert config is not None
        self.pid = Pid(config, value(self, "sample_time"))
        self.enabled = bool(value(self, "enabled"))
        self.pace_on_setpoint = bool(value(self, "pace_on_setpoint"))
        self._setpoint: float | None = None  # [m] as received (clamped in the law)
        self._excitation = 0.0  # [V]
        self._y: float | None = None  # latest position [m]
        self._msg = interface.topic("voltage_cmd").message_class()()
        self._pub = interface.publisher(self, "voltage_cmd")
        interface.subscription(self, "position", self._on_position)
        interface.subscription(self, "position_setpoint", self._on_setpoint)
        interface.subscription(self, "voltage_excitation", self._on_excitation)
        self.add_on_set_parameters_callback(self._check_update)
        self.add_post_set_parameters_callback(self._apply_update)
        c = config
        self.get_logger().info(
            f"started: kp {c.kp:g} V/m, ki {c.ki:g} V/(m s), kd {c.kd:g} V s/m, output "
            f"+-{c.output_limit:g} V, setpoints [{c.setpoint_min:g}, {c.setpoint_max:g}] m, "
            f"{'enabled' if self.enabled else 'disabled'}")

    # -- parameters -------------------------------------------------------------------------

    def set_parameters_atomically(self, parameter_list: list[Parameter[Any]]) -> Any:
        """rclpy's, with rejections naming the parameter and the types (remote sets)."""
        return set_explained(self, parameter_list, super().set_parameters_atomically)

    def _changed_config(self, params: list[Parameter[Any]]) -> PidConfig | None:
        gains = {p.name: p.value for p in params if p.name in SPECS}
        if not gains:
            return None
        current = {n: getattr(self.pid.config, n) for n in SPECS}
        return PidConfig.from_mapping({**current, **gains})

    def _check_update(self, params: list[Parameter[Any]]) -> SetParametersResult:
        try:
            self._changed_config(params)
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_update(self, params: list[Parameter[Any]]) -> None:
        config = self._changed_config(params)
        if config is not None:
            self.pid.config = config
        for p in params:
            if p.name == "pace_on_setpoint":
                self.pace_on_setpoint = bool(p.value)
            if p.name == "enabled" and p.value != self.enabled:
                self.enabled = bool(p.value)
                self.pid.reset()
                self.get_logger().info("enabled" if self.enabled else "disabled")
                if self.enabled:
                    self._command()  # answer the latest sample at once

    # -- messages ---------------------------------------------------------------------------

    def _on_setpoint(self, msg: Any) -> None:
        r = msg.data
        if not math.isfinite(r):
            self.get_logger().warning(f"ignoring non-finite position_setpoint {r}",
                                      throttle_duration_sec=WARN_PERIOD)
            return
        clamped = self.pid.clamp(r)
        if clamped != r:
            c = self.pid.config
            self.get_logger().warning(
                f"position_setpoint {r:g} m outside [{c.setpoint_min:g}, {c.setpoint_max:g}] "
                f"m; clamped to {clamped:g} m", throttle_duration_sec=WARN_PERIOD)
        self._setpoint = r
        if self.pace_on_setpoint:
            self._command()

    def _on_excitation(self, msg: Any) -> None:
        if not math.isfinite(msg.data):
            self.get_logger().warning(f"ignoring non-finite voltage_excitation {msg.data}",
                                      throttle_duration_sec=WARN_PERIOD)
            return
        self._excitation = msg.data

    def _on_position(self, msg: Any) -> None:
        if not math.isfinite(msg.data):
            self.get_logger().warning(f"ignoring non-finite position {msg.data}",
                                      throttle_duration_sec=WARN_PERIOD)
            return
        self._y = msg.data
        if not self.pace_on_setpoint:
            self._command()

    def _command(self) -> None:
        """Publish the law's output for the latest position, if enabled and set."""
        if not self.enabled or self._setpoint is None or self._y is None:
            return
        self._msg.data = self.pid.update(self._setpoint, self._y, self._excitation)
        self._pub.publish(self._msg)


def main(args: Sequence[str] | None = None) -> int:
    """Run the controller until Ctrl-C or SIGTERM; 0, or 2 on bad parameters."""
    return process.run_nodes(NODE_NAME, args, [(NODE_NAME, Controller)])


if __name__ == "__main__":
    sys.exit(main())
