"""Parameters of the actuator model: one schema, YAML loading and validation.

Every parameter the simulator understands is declared once in :data:`SPECS` with its type,
default, unit, range and description. The same schema validates YAML files for the offline tools
and declares the ROS parameters of ``actuator_sim``, so a name, a unit or a range is never written
twice. Names are dotted (``effects.valve_lag.corner_frequency``); YAML files may nest them, and may
use the ROS layout ``/**/actuator_sim: ros__parameters: ...`` (any section that applies to a node
of that name, in any namespace).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from jetpipe_ros.fileio import read_yaml, section_applies
from jetpipe_ros.model.chamber import chamber_volumes
from jetpipe_ros.model.errors import ParameterError
from jetpipe_ros.model.flow import N_TERMS, TABLE_P, TABLE_SIZE, TABLE_U
from jetpipe_ros.model.friction import FRICTION_FORMS, LEVEL_FLOOR, MAX_ELEMENTS, PAPER_FLOOR

NODE_NAME = "actuator_sim"

#: The unmodelled effects of docs/effects.md, with the subsystem each belongs to.
EFFECTS: dict[str, str] = {
    "valve_delay": "valve",
    "valve_lag": "valve",
    "valve_hysteresis": "valve",
    "supply_pressure": "valve",
    "thermal": "chamber",
    "leakage": "chamber",
    "friction_dynamics": "mechanics",
    "moving_mass": "mechanics",
    "sensor_dynamics": "sensors",
}

#: Eq. 8 coefficients, in the order of the paper (u in V, p in bar, result in g/s).
FLOW_COEFFICIENTS = [
    3.562, 1.233, -2.037, 0.1701, -0.7901, 0.6697, 0.1335, -0.1801, 0.3379, -0.1243,
    0.01195, -0.01784, 0.03335, -0.0413, 0.008227, -0.007284, -0.0005998, 0.0003319,
    -0.001838, 0.001729, -0.0001519,
]

#: Friction planes c0 + c1 p1 + c2 p2 (p in bar), Eq. 20-23 (entry) and Eq. 24-27 (exit).
FRICTION_PLANES = {
    "entry": {
        "breakaway": [-27.31, 12.95, -11.6],
        "stribeck_velocity": [-0.00752, 0.00097, -0.00122],
        "viscous": [53.8, 265.2, 450.0],
        "coulomb": [-15.52, 8.413, -7.028],
    },
    "exit": {
        "breakaway": [26.39, 12.4, -14.43],
        "stribeck_velocity": [0.00928, 0.00122, -0.00097],
        "viscous": [-407.6, 325.8, 355.6],
        "coulomb": [26.16, 8.575, -11.72],
    },
}
THERMAL_FORMS = ("polytropic", "heat_transfer")
LEAKAGE_FORMS = ("laminar", "orifice", "power")
SUPPLY_FORMS = ("constant", "line")
LAG_FORMS = ("first_order", "second_order", "flow", "port")
DELAY_FORMS = ("command", "line", "hose")
DYNAMIC_FRICTION_FORMS = tuple(FRICTION_FORMS)
FRICTION_UNITS = {"breakaway": "N", "stribeck_velocity": "m/s", "viscous": "N s/m", "coulomb": "N"}


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: its dotted name, default (which fixes its type), unit and valid range."""

    name: str
    default: Any
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] | None = None
    length: int | None = None

    @property
    def kind(self) -> type:
        """Python type of the value: bool, int, float, str or list (of floats)."""
        return type(self.default)

    def describe(self) -> str:
        """One line for humans: description, unit and range."""
        unit = f" [{self.unit}]" if self.unit else ""
        rng = ""
        if self.low is not None or self.high is not None:
            rng = f", range [{self.low}, {self.high}]"
        if self.choices:
            rng = f", one of {', '.join(self.choices)}"
        return f"{self.description}{unit}{rng}"


def _p(name: str, default: Any, description: str, unit: str = "", low: float | None = None,
       high: float | None = None, **kw: Any) -> ParamSpec:
    return ParamSpec(name, default, description, unit, low, high, **kw)


_BASE: list[ParamSpec] = [
    # Servo valve, Sec. 2.1 Table 1, Eq. 9 and the 2 ms delay of Eq. 10.
    _p("valve.torque_constant", 2.4, "Torque motor constant K_t", "N m/A", 1e-3, 1e3),
    _p("valve.back_emf_constant", 0.1, "Back-EMF constant K_b", "V s/rad", 1e-4, 10.0),
    _p("valve.coil_resistance", 193.0, "Control coil resistance R", "ohm", 1.0, 1e4),
    _p("valve.coil_inductance", 0.016, "Control coil inductance L", "H", 1e-5, 10.0),
    _p("valve.rotor_inertia", 6.8e-6, "Rotor and jet-pipe moment of inertia J", "kg m^2",
       1e-9, 1e-2),
    _p("valve.friction_coefficient", 6e-5, "Rotor friction coefficient K_f", "N m s/rad",
       0.0, 1.0),
    _p("valve.magnetic_stiffness", 0.8, "Magnetic stiffness K_s", "N m/rad", 1e-3, 1e3),
    _p("valve.delay", 0.002, "Valve transport delay (Eq. 10)", "s", 0.0, 0.05),
    _p("valve.lag_zero", 220.0, "Lead-lag zero of Eq. 9", "rad/s", 1.0, 1e6),
    _p("valve.lag_pole", 155.0, "Lead-lag pole of Eq. 9", "rad/s", 1.0, 1e6),
    _p("valve.command_limit", 3.4, "Valve command saturation |u|", "V", 0.1, 10.0),
    _p("valve.gain", 1.0, "Jet-pipe deflection per volt relative to Eq. 5's midpoint lines: "
       "u_eq = clip(gain u_f); an individual valve's torque motor differs by a few %", "",
       0.2, 5.0),
    # Mass flow map, Eq. 8.
    _p("flow.coefficients", list(FLOW_COEFFICIENTS),
       "Eq. 8 polynomial coefficients (u in V, p in bar, result in g/s), paper order", "",
       length=N_TERMS),
    _p("flow.table", [0.0] * TABLE_SIZE,
       f"Correction to Eq. 8, cubic between nodes (u in V, p in bar, result in g/s): entry "
       f"i * {TABLE_P.size} + j at u = {TABLE_U[0]:g} + {TABLE_U[1] - TABLE_U[0]:g} i, "
       f"p = {TABLE_P[0]:g} + {TABLE_P[1] - TABLE_P[0]:g} j; zero: Eq. 8 alone", "g/s",
       length=TABLE_SIZE),
    _p("flow.gain_charge", 1.0, "Factor on the Eq. 8 flow where it fills a chamber (q > 0): an "
       "individual valve's receiver differs from the paper's by several %", "", 0.1, 10.0),
    _p("flow.gain_discharge", 1.0, "Factor on the Eq. 8 flow where it empties a chamber "
       "(q < 0)", "", 0.1, 10.0),
    # Chambers, Sec. 3 and Eq. 13.
    _p("chamber.gas_constant", 287.0, "Specific gas constant of air r", "J/(kg K)", 100.0, 1000.0),
    _p("chamber.temperature", 298.15, "Gas temperature T (isothermal)", "K", 200.0, 400.0),
    _p("chamber.piston_area", 0.005433, "Effective piston area S", "m^2", 1e-5, 1.0),
    _p("chamber.dead_volume_1", 1.533e-4, "Chamber 1 volume at y = 0", "m^3", 1e-7, 1.0),
    _p("chamber.dead_volume_2", 1.915e-4, "Chamber 2 volume at y = 0", "m^3", 1e-7, 1.0),
    _p("chamber.initial_pressure_1", 416480.0, "Initial chamber 1 pressure (absolute)", "Pa",
       1e4, 1.2e6),
    _p("chamber.initial_pressure_2", 416480.0, "Initial chamber 2 pressure (absolute)", "Pa",
       1e4, 1.2e6),
    _p("chamber.regulated", False, "Chamber pressures held at their initial values by "
       "regulators instead of the valve (the friction tests of the paper's Fig. 15)"),
    # Mechanics, Sec. 4.
    _p("mechanics.mass", 1.0, "Moving mass M", "kg", 0.01, 100.0),
    _p("mechanics.stroke", 0.05, "Stroke; end stops at +-stroke/2", "m", 1e-3, 1.0),
    _p("mechanics.initial_position", 0.0, "Initial piston position y", "m", -0.5, 0.5),
    _p("mechanics.locked", False, "Piston clamped at its initial position (constant volume)"),
    # Sensors.
    _p("sensors.noise", False, "Add Gaussian sensor noise (the paper's sensor accuracies)"),
    _p("sensors.seed", 0, "Seed of the sensor noise", "", 0, 2**31 - 1),
    _p("sensors.pressure_sigma", 500.0, "Pressure noise standard deviation", "Pa", 0.0, 1e5),
    _p("sensors.position_sigma", 1.5e-5, "Position noise standard deviation", "m", 0.0, 1e-2),
    # Integration.
    _p("integration.sample_time", 0.001, "Output sample time", "s", 1e-4, 0.01),
    _p("integration.substeps", 4, "Integration sub-steps per sample", "", 1, 200),
]

# Friction planes: one 3-vector parameter per phase and quantity.
for _phase, _planes in FRICTION_PLANES.items():
    for _qty, _coef in _planes.items():
        _BASE.append(_p(
            f"friction.{_phase}.{_qty}", list(_coef),
            f"{_phase} phase {_qty.replace('_', ' ')} plane c0 + c1 p1 + c2 p2 (p in bar)",
            FRICTION_UNITS[_qty], length=3))

# The planes' floor (model/friction.py, friction_parameters) and the bore profile of the
# friction level (level_factors): factors on each direction's Stribeck curve at knots along the
# piston position; one knot at factor 1 = none.
_BASE += [
    _p("friction.floor", PAPER_FLOOR, "Least breakaway and Coulomb level |F_S|, |F_C| the "
       "planes give (they extrapolate linearly beyond the tests' pressures; the paper's exit "
       "Coulomb plane reaches 0 near p1 = p2 = 8.3 bar)", "N", LEVEL_FLOOR, 100.0),
    _p("friction.profile.position", [0.0], "Bore profile: the knots' piston positions y, "
       "increasing (as many as the factors)", "m"),
    _p("friction.profile.exit", [1.0], "Bore profile: factor on the exit phase's Stribeck "
       "level (F_S and F_C) at each knot, linear between knots and held beyond them", ""),
    _p("friction.profile.entry", [1.0], "Bore profile: factor on the entry phase's Stribeck "
       "level (F_S and F_C) at each knot", ""),
]
#: Factors of the bore profile lie in [PROFILE_LOW, PROFILE_HIGH] (a level the seal's squeeze
#: changes by more than this along one bore is not a profile but another seal).
PROFILE_LOW, PROFILE_HIGH = 0.2, 5.0
#: Most knots a bore profile holds.
MAX_KNOTS = 200

#: Parameters of each effect (besides ``effects.<name>.enabled``). Typical sizes: docs/effects.md.
_EFFECT_PARAMS: dict[str, list[ParamSpec]] = {
    "valve_delay": [
        _p("form", "command", "Where the delay acts: on the valve command (command), or in a "
           "line between valve and chambers (line: the valve sees each chamber's pressure "
           "delay ago, and its flow reaches the chamber delay later; hose: a lumped hose of a "
           "length and a bore before each chamber, its volume, air inertance and wall "
           "friction, the valve reading the pressure at its valve end)", choices=DELAY_FORMS),
        _p("delay", 0.002, "Extra transport delay (forms command and line; form line: one way "
           "along the line)", "s", 0.0, 0.05),
        _p("length", 1.0, "Length of the hose before each chamber (form hose; 0 = none): a "
           "one-way delay of length / c, c = 346 m/s at 25 degC", "m", 0.0, 20.0),
        _p("bore", 0.005, "Inner diameter of the hose (form hose)", "m", 5e-4, 0.05),
    ],
    "valve_lag": [
        _p("form", "first_order", "Lag on the valve's output: first order (a corner), or "
           "second order (a natural frequency and a damping ratio); or flow: a second-order "
           "lag on each chamber's mass flow after the flow map (a port or line between valve "
           "and chamber); or port: a port volume before each chamber behind a restriction "
           "(a filter, a fitting), the valve's map reading the port's pressure",
           choices=LAG_FORMS),
        _p("corner_frequency", 30.0, "Corner frequency (first order) or natural frequency "
           "(second order, flow) of the lag", "Hz", 0.5, 1000.0),
        _p("damping_ratio", 0.7, "Damping ratio of the lag (forms second_order, flow)", "",
           0.05, 5.0),
        _p("port_volume", 4e-5, "Volume of the port between the valve and each chamber (form "
           "port; 0 = none): the valve's map reads its pressure, its gas adiabatic", "m^3",
           0.0, 1e-3),
        _p("port_conductance", 3e-9, "Sonic conductance C of the restriction between the port "
           "and its chamber (form port; ISO 6358, choked flow C rho_0 p_up, critical ratio "
           "0.528): 1e-8 m^3/(s Pa) = 1 dm^3/(s bar)", "m^3/(s Pa)", 1e-11, 1e-5),
        _p("port_index", 0.5, "Subsonic index m of that restriction (form port; ISO "
           "6358-1:2013, its flow times (mean pressure / 4.1648 bar)^(2 m - 1)): 0.5 an "
           "orifice, up to 1 a porous element following Darcy's compressible law (the drop "
           "linear in the flow near equal pressures, the conductance in proportion to the "
           "mean pressure)", "", 0.5, 1.0),
    ],
    "valve_hysteresis": [
        _p("half_width", 0.25, "Hysteresis loop half-width (the plays' weighted mean "
           "threshold)", "V", 0.0, 2.0),
        _p("elements", 1, "Play operators in parallel (1 = one sharp loop; more = a rounded "
           "Prandtl-Ishlinskii loop, thresholds spread evenly around their mean)", "", 1, 8),
        _p("spread", 1.0, "Spread of the play thresholds as a fraction of their mean r: they "
           "lie evenly in r (1 +- spread), r = half_width with plays of equal weight (0 = all "
           "equal, one sharp loop; 1 = from 0 to twice r)", "", 0.0, 1.0),
        _p("sharp_share", 0.0, "Share of the loop held by one end play beyond an equal share "
           "(elements > 1), the narrowest if positive, the widest if negative: 0 = plays of "
           "equal weight; towards 1 a sharp loop at the narrowest threshold whose corners the "
           "wider plays round off; towards -1 a sharp loop at the widest threshold, the "
           "narrower plays a soft start of each branch; half_width stays the weighted mean "
           "threshold", "", -0.95, 0.95),
    ],
    "supply_pressure": [
        _p("form", "constant", "Supply seen by the valve: constant, or a line volume fed "
           "through a line conductance from the set pressure and drained by the flow the valve "
           "draws into the chambers (a long hose, a small regulator, a shared line)",
           choices=SUPPLY_FORMS),
        _p("pressure", 8e5, "Supply pressure (absolute): the constant supply (form constant), "
           "or the set pressure feeding the line (form line)", "Pa", 2e5, 1.2e6),
        _p("line_conductance", 5e-8, "Mass flow through the line per pressure drop across it "
           "(form line): the supply sags by the drawn flow over it in steady state", "kg/(s Pa)",
           1e-10, 1e-3),
        _p("line_volume", 1e-4, "Volume of the line and regulator between the line conductance "
           "and the valve (form line): time constant line_volume / (r T line_conductance)",
           "m^3", 1e-7, 0.1),
        _p("reference", 1e5, "Pressure (absolute) the flow map keeps its shape relative to "
           "when the supply differs from 10 bar: chamber pressures map from [reference, supply] "
           "onto [reference, 10 bar], flows scale by the span (1e5 = the atmosphere: the "
           "recovery of a subsonic jet; 0 = similarity in absolute pressure: a choked jet's "
           "mass flow; about 0.79e5: a sonic jet's thrust)", "Pa", 0.0, 1e5),
    ],
    "thermal": [
        _p("form", "polytropic", "Thermal model: polytropic index, or heat transfer to the "
           "walls with a gas temperature state per chamber", choices=THERMAL_FORMS),
        _p("polytropic_index", 1.2, "Polytropic index n of the chamber gas (form polytropic)",
           "", 1.0, 1.4),
        _p("heat_transfer", 1.0, "Wall heat conductance h A of each chamber "
           "(form heat_transfer)", "W/K", 1e-3, 100.0),
    ],
    "leakage": [
        _p("form", "laminar", "Leak law: laminar (flow proportional to the pressure "
           "difference), orifice (compressible flow, choked below 0.528), or power (flow "
           "proportional to the pressure difference to a fitted exponent between 0.5 and 1)",
           choices=LEAKAGE_FORMS),
        _p("cross_area", 0.0, "Effective orifice area across the piston (form orifice)", "m^2",
           0.0, 1e-5),
        _p("atmosphere_area", 0.0, "Effective orifice area of each chamber to atmosphere "
           "(form orifice)", "m^2", 0.0, 1e-5),
        _p("cross_coefficient", 3e-10, "Leak conductance across the piston, chamber 1 to 2 "
           "(form laminar)", "kg/(s Pa)", 0.0, 1e-7),
        _p("atmosphere_coefficient", 0.0, "Leak conductance of each chamber to atmosphere "
           "(form laminar)", "kg/(s Pa)", 0.0, 1e-7),
        _p("cross_flow", 3e-5, "Leak flow across the piston at a pressure difference of 1 bar "
           "(form power)", "kg/s", 0.0, 1e-2),
        _p("atmosphere_flow", 0.0, "Leak flow of each chamber to atmosphere at 1 bar above it "
           "(form power)", "kg/s", 0.0, 1e-2),
        _p("exponent", 0.75, "Exponent n of the pressure difference in the leak law (form "
           "power): 1 laminar, 0.5 turbulent (orifice-like)", "", 0.5, 1.0),
    ],
    "friction_dynamics": [
        _p("form", "lugre", "Dynamic friction over the Stribeck curves of the planes: LuGre "
           "bristles (a stiffness and a damping), or Maxwell-slip elements (a pre-sliding "
           "displacement and its spread; what real seals show)", choices=DYNAMIC_FRICTION_FORMS),
        _p("bristle_stiffness", 1e5, "LuGre bristle stiffness sigma_0 (form lugre)", "N/m",
           1e2, 1e8),
        _p("bristle_damping", 0.0, "LuGre bristle damping sigma_1 (form lugre)", "N s/m", 0.0,
           1e5),
        _p("presliding_displacement", 5e-4, "Slip displacement delta of the softest "
           "Maxwell-slip element (form maxwell_slip): the friction reaches its sliding level "
           "about 2 delta after a reversal", "m", 1e-6, 0.01),
        _p("presliding_spread", 0.1, "Stiffest element's slip displacement as a fraction of "
           "presliding_displacement; the elements lie geometrically between (form "
           "maxwell_slip)", "", 1e-3, 1.0),
        _p("elements", 3, "Maxwell-slip elements (form maxwell_slip)", "", 1, MAX_ELEMENTS),
    ],
    "moving_mass": [_p("mass", 2.0, "Actual moving mass", "kg", 0.01, 100.0)],
    "sensor_dynamics": [
        _p("time_constant", 0.005, "Pressure sensor first-order lag", "s", 0.0, 1.0),
        _p("bias", 0.0, "Pressure sensor bias", "Pa", -1e5, 1e5),
        _p("bias_difference", 0.0, "Chamber 2's pressure sensor bias beyond chamber 1's", "Pa",
           -1e5, 1e5),
        _p("gain", 0.0, "Relative gain error of the pressure sensors: they read (1 + gain) p",
           "", -0.2, 0.2),
        _p("drift", 0.0, "Pressure sensor drift rate", "Pa/s", -1e4, 1e4),
    ],
}

for _name, _specs in _EFFECT_PARAMS.items():
    _BASE.append(_p(f"effects.{_name}.enabled", False, f"Switch on the {_name} effect"))
    for _s in _specs:
        _BASE.append(ParamSpec(f"effects.{_name}.{_s.name}", _s.default,
                               f"{_name}: {_s.description}", _s.unit, _s.low, _s.high,
                               _s.choices, _s.length))

#: All model parameters by dotted name.
SPECS: dict[str, ParamSpec] = {s.name: s for s in _BASE}


def effect_param_names(effect: str) -> list[str]:
    """Dotted names of an effect's own parameters (without ``enabled``)."""
    if effect not in EFFECTS:
        raise ParameterError(f"unknown effect {effect!r}; known: {', '.join(EFFECTS)}")
    return [f"effects.{effect}.{s.name}" for s in _EFFECT_PARAMS[effect]]


def check_value(spec: ParamSpec, value: Any, where: str = "") -> Any:
    """Return ``value`` converted to the spec's type, or raise ParameterError naming it."""
    at = f"{where}: " if where else ""
    name = spec.name
    kind = spec.kind
    if kind is bool:
        if not isinstance(value, bool):
            raise ParameterError(f"{at}parameter {name} must be true or false, got {value!r}")
        return value
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParameterError(f"{at}parameter {name} must be an integer, got {value!r}")
        _check_range(spec, float(value), at)
        return value
    if kind is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParameterError(f"{at}parameter {name} must be a number [{spec.unit}], "
                                 f"got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ParameterError(f"{at}parameter {name} must be finite, got {value!r}")
        _check_range(spec, value, at)
        return value
    if kind is str:
        if not isinstance(value, str) or (spec.choices and value not in spec.choices):
            raise ParameterError(f"{at}parameter {name} must be one of {spec.choices}, "
                                 f"got {value!r}")
        return value
    # list of floats: of spec.length, or of 1 to MAX_KNOTS when the spec has no length
    if spec.length is None:
        if not isinstance(value, (list, tuple)) or not 1 <= len(value) <= MAX_KNOTS:
            raise ParameterError(f"{at}parameter {name} must be a list of 1 to {MAX_KNOTS} "
                                 f"numbers, got {value!r}")
    elif not isinstance(value, (list, tuple)) or len(value) != spec.length:
        raise ParameterError(f"{at}parameter {name} must be a list of {spec.length} numbers, "
                             f"got {value!r}")
    out = []
    for i, item in enumerate(value):
        if isinstance(item, bool) or not isinstance(item, (int, float)) or not math.isfinite(item):
            raise ParameterError(f"{at}parameter {name}[{i}] must be a finite number, "
                                 f"got {item!r}")
        out.append(float(item))
    return out


def _check_range(spec: ParamSpec, value: float, at: str) -> None:
    if (spec.low is not None and value < spec.low) or (spec.high is not None and value > spec.high):
        raise ParameterError(f"{at}parameter {spec.name} = {value:g} {spec.unit} is out of range "
                             f"[{spec.low:g}, {spec.high:g}]")


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Flatten nested mappings into dotted names: ``{'a': {'b': 1}} -> {'a.b': 1}``."""
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, f"{name}."))
        else:
            flat[name] = value
    return flat


def _unflatten(flat: Mapping[str, Any]) -> dict[str, Any]:
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        node = tree
        *parents, leaf = name.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return tree


class ModelParams(Mapping[str, Any]):
    """A complete, validated set of model parameters, read like a dict by dotted name."""

    def __init__(self, overrides: Mapping[str, Any] | None = None, where: str = "") -> None:
        self._values = {name: spec.default for name, spec in SPECS.items()}
        self._set(overrides or {}, where)

    def _set(self, changes: Mapping[str, Any], where: str) -> None:
        for name, value in changes.items():
            spec = SPECS.get(name)
            if spec is None:
                raise ParameterError(_unknown_message(name, where))
            self._values[name] = check_value(spec, value, where)
        _check_geometry(self._values, where)
        _check_profile(self._values, where)
        _check_passages(self._values, where)

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def with_values(self, changes: Mapping[str, Any]) -> ModelParams:
        """A copy with the given dotted-name parameters changed (validated)."""
        copy = ModelParams.__new__(ModelParams)
        # Only the changes need checking: this set's values passed already.
        copy._values = {name: list(value) if isinstance(value, list) else value
                        for name, value in self._values.items()}
        copy._set(changes, "")
        return copy

    def at_sample_time(self, dt: float) -> ModelParams:
        """A copy that outputs a sample every ``dt`` [s] with sub-steps no longer than this
        set's own (``integration.sample_time / integration.substeps``), so a record logged at
        another rate is simulated with the accuracy of the model's own rate."""
        step = self["integration.sample_time"] / self["integration.substeps"]
        return self.with_values({"integration.sample_time": dt,
                                 "integration.substeps": max(1, math.ceil(dt / step - 1e-9))})

    def with_effect(self, effect: str, **params: float) -> ModelParams:
        """A copy with ``effect`` switched on and its parameters set."""
        effect_param_names(effect)
        changes: dict[str, Any] = {f"effects.{effect}.enabled": True}
        changes.update({f"effects.{effect}.{k}": v for k, v in params.items()})
        return self.with_values(changes)

    def enabled_effects(self) -> list[str]:
        """Names of the effects switched on."""
        return [e for e in EFFECTS if self._values[f"effects.{e}.enabled"]]

    def non_default(self) -> dict[str, Any]:
        """The parameters that differ from their defaults."""
        return {k: v for k, v in self._values.items() if v != SPECS[k].default}

    def to_ros_yaml(self, node_name: str = NODE_NAME, only_changed: bool = False) -> str:
        """YAML text in the ROS params-file layout, loadable by the node in any namespace
        (section ``/**/<node_name>``) and by the CLI."""
        values = self.non_default() if only_changed else dict(self._values)
        tree = {f"/**/{node_name}": {"ros__parameters": _unflatten(values)}}
        return yaml.safe_dump(tree, sort_keys=False, default_flow_style=None)


def end_stop_volumes(values: Mapping[str, Any]) -> tuple[float, float]:
    """Volumes [m^3] chambers 1 and 2 keep with the piston at their end stops (Eq. 13 at
    y = -stroke/2 and +stroke/2): the ports, hoses and fittings no stroke sweeps."""
    half = 0.5 * values["mechanics.stroke"]
    args = (values["chamber.piston_area"], values["chamber.dead_volume_1"],
            values["chamber.dead_volume_2"])
    return chamber_volumes(-half, *args)[0], chamber_volumes(half, *args)[1]


def _check_geometry(values: Mapping[str, Any], where: str) -> None:
    """Each chamber keeps a volume at its end stop."""
    for i, volume in enumerate(end_stop_volumes(values), 1):
        if volume <= 0.0:
            at = f"{where}: " if where else ""
            raise ParameterError(
                f"{at}parameter chamber.dead_volume_{i} = "
                f"{values[f'chamber.dead_volume_{i}']:g} m^3 is not larger than the volume the "
                f"piston sweeps from the centre to the end stop (chamber.piston_area * "
                f"mechanics.stroke / 2 = {values['chamber.dead_volume_' + str(i)] - volume:g} "
                f"m^3): chamber {i} would vanish")


def _check_passages(values: Mapping[str, Any], where: str) -> None:
    """At most one passage between the valve and each chamber: the valve lag's port, or the
    valve delay's line or hose (a port before a line or a hose is not modelled)."""
    if not (values["effects.valve_lag.enabled"] and values["effects.valve_lag.form"] == "port"
            and values["effects.valve_lag.port_volume"] > 0.0):
        return
    if values["effects.valve_delay.enabled"] and values["effects.valve_delay.form"] in (
            "line", "hose"):
        at = f"{where}: " if where else ""
        raise ParameterError(
            f"{at}parameter effects.valve_lag.form = port cannot be combined with "
            f"effects.valve_delay.form = {values['effects.valve_delay.form']} (both place a "
            f"passage between the valve and each chamber); use the valve delay's command form, "
            f"or set effects.valve_lag.port_volume to 0")


def _check_profile(values: Mapping[str, Any], where: str) -> None:
    """The bore profile's lists are equally long, its knots increasing, its factors in
    [PROFILE_LOW, PROFILE_HIGH]."""
    at = f"{where}: " if where else ""
    position = values["friction.profile.position"]
    for phase in ("exit", "entry"):
        factors = values[f"friction.profile.{phase}"]
        if len(factors) != len(position):
            raise ParameterError(f"{at}parameter friction.profile.{phase} has {len(factors)} "
                                 f"factors for {len(position)} knots in "
                                 f"friction.profile.position")
        bad = [f for f in factors if not PROFILE_LOW <= f <= PROFILE_HIGH]
        if bad:
            raise ParameterError(f"{at}parameter friction.profile.{phase} = {bad[0]:g} is out "
                                 f"of range [{PROFILE_LOW:g}, {PROFILE_HIGH:g}]")
    if any(b <= a for a, b in zip(position, position[1:])):
        raise ParameterError(f"{at}parameter friction.profile.position must be increasing, "
                             f"got {position!r}")


def _unknown_message(name: str, where: str) -> str:
    at = f"{where}: " if where else ""
    parts = name.split(".")
    if parts[0] == "effects" and len(parts) >= 2 and parts[1] not in EFFECTS:
        return (f"{at}unknown effect {parts[1]!r} (parameter {name}); "
                f"known effects: {', '.join(EFFECTS)}")
    return f"{at}unknown parameter {name!r}"


def params_from_tree(tree: Mapping[str, Any], where: str = "",
                     node_name: str = NODE_NAME, ignore: tuple[str, ...] = ()) -> ModelParams:
    """Model parameters from a parsed YAML document (ROS layout or plain nesting).

    Top-level names listed in ``ignore`` (e.g. node-only parameters) are skipped.
    """
    if not isinstance(tree, Mapping):
        raise ParameterError(f"{where}: expected a mapping of parameters, "
                             f"got {type(tree).__name__}")
    sections = [k for k, v in tree.items() if isinstance(v, Mapping) and "ros__parameters" in v]
    if sections or node_name in tree:
        # The ROS layout. Offline there is no namespace: every section that would apply to the
        # node in some namespace is read, in the file's order (a later one wins, as in rcl).
        mine = [k for k in sections if section_applies(k, "/" + node_name)
                or str(k).rsplit("/", 1)[-1] == node_name]
        if not mine:
            raise ParameterError(
                f"{where}: no ros__parameters section for {node_name} (sections: "
                f"{', '.join(map(str, sections)) or 'none'}); key it '/**/{node_name}:'")
        merged: dict[str, Any] = {}
        for k in mine:
            merged.update(flatten(tree[k]["ros__parameters"] or {}))
        tree = _unflatten(merged)
    flat = {k: v for k, v in flatten(tree).items() if k.split(".")[0] not in ignore
            and k not in ignore}
    return ModelParams(flat, where)


def load_params(path: str | Path, node_name: str = NODE_NAME,
                ignore: tuple[str, ...] = ()) -> ModelParams:
    """Read and validate a parameter YAML file; errors name the file and the parameter."""
    path = Path(path)
    tree = read_yaml(path, ParameterError, "parameter file")
    return params_from_tree(tree or {}, str(path), node_name, ignore)
