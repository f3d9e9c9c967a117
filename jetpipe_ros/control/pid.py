"""A position PID for a pneumatic axis with stiction: pure Python, no ROS.

The same law runs in the ``controller`` node and in the offline campaign runner, so a campaign
simulated offline and one run through ROS close the loop identically.

Per sample (sample time ``dt`` [s]), with position y [m] and setpoint r [m]:

- r is clamped to the usable stroke [``setpoint_min``, ``setpoint_max``] (the caller is told, so
  it can warn);
- e = r - y; inside ``deadband`` [m] e counts as 0 (no hunting around a stuck piston);
- u = kp e + ki integral(e) - kd dy_f/dt + friction compensation + excitation, with the
  derivative on the measurement through a first-order filter (``derivative_filter`` [s]) and
  the friction compensation ``friction_compensation`` [V] x sign(e) outside the deadband;
- u is limited to +-``output_limit`` [V]; the integrator stops when the output saturates in the
  direction it would grow (conditional integration: anti-windup).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from jetpipe_ros.model.errors import ParameterError
from jetpipe_ros.model.params import ParamSpec, check_value

#: The controller's parameters (``config/controller.yaml``), with units and ranges.
SPECS: dict[str, ParamSpec] = {s.name: s for s in [
    ParamSpec("kp", 300.0, "Proportional gain", "V/m", 0.0, 1e5),
    ParamSpec("ki", 20.0, "Integral gain", "V/(m s)", 0.0, 1e6),
    ParamSpec("kd", 0.0, "Derivative gain (on the measured position)", "V s/m", 0.0, 1e3),
    ParamSpec("derivative_filter", 0.005, "Time constant of the derivative's low-pass", "s",
              0.0, 1.0),
    ParamSpec("output_limit", 3.0, "Output limit +-", "V", 0.01, 10.0),
    ParamSpec("setpoint_min", -0.024, "Lowest setpoint; lower ones are clamped", "m",
              -1.0, 1.0),
    ParamSpec("setpoint_max", 0.024, "Highest setpoint; higher ones are clamped", "m",
              -1.0, 1.0),
    ParamSpec("deadband", 0.0, "Position error treated as zero", "m", 0.0, 0.01),
    ParamSpec("friction_compensation", 0.0,
              "Voltage added in the direction of the error outside the deadband", "V", 0.0, 3.0),
]}


@dataclass(frozen=True)
class PidConfig:
    """Gains and limits of :class:`Pid` (units as in :data:`SPECS`)."""

    kp: float = SPECS["kp"].default
    ki: float = SPECS["ki"].default
    kd: float = SPECS["kd"].default
    derivative_filter: float = SPECS["derivative_filter"].default
    output_limit: float = SPECS["output_limit"].default
    setpoint_min: float = SPECS["setpoint_min"].default
    setpoint_max: float = SPECS["setpoint_max"].default
    deadband: float = SPECS["deadband"].default
    friction_compensation: float = SPECS["friction_compensation"].default

    def __post_init__(self) -> None:
        for name, spec in SPECS.items():
            check_value(spec, getattr(self, name))
        if self.setpoint_min >= self.setpoint_max:
            raise ParameterError(f"parameter setpoint_min ({self.setpoint_min} m) must be "
                                 f"below setpoint_max ({self.setpoint_max} m)")

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], where: str = "") -> PidConfig:
        """Build from a mapping of parameter names (unknown names are errors)."""
        unknown = sorted(set(values) - set(SPECS))
        if unknown:
            at = f"{where}: " if where else ""
            raise ParameterError(f"{at}unknown controller parameter(s) {', '.join(unknown)}; "
                                 f"known: {', '.join(SPECS)}")
        checked = {name: check_value(SPECS[name], v, where) for name, v in values.items()}
        return cls(**checked)


@dataclass
class Pid:
    """The PID law of this module's docstring at sample time ``dt`` [s]."""

    config: PidConfig
    dt: float
    integral: float = field(default=0.0, init=False)  #: integral of the error [m s]
    _y_filtered: float = field(default=math.nan, init=False)
    _rate: float = field(default=0.0, init=False)  #: filtered dy/dt [m/s]

    def reset(self) -> None:
        """Forget the integral and the derivative's history."""
        self.integral = 0.0
        self._y_filtered = math.nan
        self._rate = 0.0

    def clamp(self, setpoint: float) -> float:
        """``setpoint`` [m] clamped to [setpoint_min, setpoint_max]."""
        c = self.config
        return min(max(setpoint, c.setpoint_min), c.setpoint_max)

    def update(self, setpoint: float, y: float, excitation: float = 0.0) -> float:
        """One sample: the valve command [V] for setpoint [m] and measured position ``y`` [m],
        with ``excitation`` [V] added before the output limit."""
        c = self.config
        error = self.clamp(setpoint) - y
        if abs(error) <= c.deadband:
            error = 0.0
        if math.isnan(self._y_filtered):
            self._y_filtered = y
        # First-order filter of y; its derivative is the filtered velocity.
        alpha = self.dt / (c.derivative_filter + self.dt)
        previous = self._y_filtered
        self._y_filtered += alpha * (y - self._y_filtered)
        self._rate = (self._y_filtered - previous) / self.dt
        friction = math.copysign(c.friction_compensation, error) if error else 0.0
        integral = self.integral + error * self.dt
        unsaturated = c.kp * error + c.ki * integral - c.kd * self._rate + friction + excitation
        u = min(max(unsaturated, -c.output_limit), c.output_limit)
        # Conditional integration: keep the new integral unless the output saturates and the
        # error would drive it further into the limit.
        if u == unsaturated or error * unsaturated < 0.0:
            self.integral = integral
        return u
