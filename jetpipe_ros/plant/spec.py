"""What a plant is made of: the model's parameters of one actuator and bench, and real effects.

:class:`PlantSpec` holds a :class:`~jetpipe_ros.model.ModelParams` (the nominal values with the
bench's deviations, the rig switches and the sensor noise; no model effect on) and the real
effects switched on, each with its parameters (:data:`EFFECT_PARAMS`, unit and range each; the
equations are in the docstrings of :mod:`valve`, :mod:`passages`, :mod:`chambers`,
:mod:`mechanics` and :mod:`sensors`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from jetpipe_ros.model import ModelParams, ParameterError
from jetpipe_ros.model.params import ParamSpec, check_value
from jetpipe_ros.plant.errors import PlantError
from jetpipe_ros.plant.valve import EQ8, PAPER_TERMS


def _p(name: str, default: float, description: str, unit: str = "", low: float | None = None,
       high: float | None = None) -> ParamSpec:
    return ParamSpec(name, default, description, unit, low, high)


#: Parameters of each real effect, by effect name.
EFFECT_PARAMS: dict[str, tuple[ParamSpec, ...]] = {
    "wall_heat_exchange": (
        _p("heat_transfer_coefficient", 30.0, "Convective coefficient h_c between the gas and "
           "the wetted wall", "W/(m^2 K)", 0.0, 1e9),
        _p("supply_temperature_offset", 0.0, "Supply air temperature minus the wall "
           "temperature (chamber.temperature)", "K", -50.0, 50.0),
    ),
    "iso6358_leak": (
        _p("cross_conductance", 2e-10, "Sonic conductance C of the leak across the piston",
           "m^3/(s Pa)", 0.0, 1e-8),
        _p("atmosphere_conductance", 0.0, "Sonic conductance C of each chamber's leak to "
           "atmosphere", "m^3/(s Pa)", 0.0, 1e-8),
        _p("critical_ratio", 0.35, "Critical pressure ratio b", "", 0.05, 0.6),
    ),
    "seal_gap_leak": (
        _p("width", 3e-3, "Width w of the gap across the piston (a scratched or worn seal)",
           "m", 0.0, 0.3),
        _p("height", 2e-5, "Height delta of the gap", "m", 1e-7, 1e-3),
        _p("length", 1e-3, "Length L of the gap along the flow", "m", 1e-5, 0.05),
        _p("loss_coefficient", 1.5, "Entrance and exit loss coefficient zeta of the gap, in "
           "dynamic heads", "", 0.0, 10.0),
    ),
    "weighted_play_hysteresis": tuple(
        spec for i, (r, w) in enumerate(((0.05, 0.5), (0.2, 0.3), (0.45, 0.2)), 1) for spec in (
            _p(f"threshold_{i}", r, f"Threshold r_{i} of play {i}", "V", 0.0, 2.0),
            _p(f"weight_{i}", w, f"Weight w_{i} of play {i} (weights are normalised to sum 1)",
               "", 0.0, 1.0))),
    "elastoplastic_friction": (
        _p("bristle_stiffness", 1e5, "Bristle stiffness sigma_0", "N/m", 1e3, 1e8),
        _p("bristle_damping", 300.0, "Bristle damping sigma_1 at rest", "N s/m", 0.0, 1e5),
        _p("damping_velocity", 2e-3, "Velocity v_d over which the bristle damping fades",
           "m/s", 1e-5, 1.0),
        _p("breakaway_fraction", 0.7, "Elastic range z_ba as a fraction beta of |F_C| / "
           "sigma_0", "", 0.01, 0.99),
    ),
    "measured_seal": (
        _p("presliding_displacement", 5.7e-4, "Displacement after a reversal at which the "
           "friction has covered 90 % of its swing from one direction's sliding level to the "
           "other's, u_90", "m", 1e-5, 0.01),
        _p("half_fraction", 0.16, "Displacement to half the swing over u_90, q = u_50 / u_90 "
           "(small: the sign flips soon after a reversal, the level comes slowly)", "", 0.115,
           0.5),
    ),
    "sensor_second_order": (
        _p("natural_frequency", 50.0, "Pressure transducer natural frequency f_n", "Hz",
           1.0, 1e5),
        _p("damping_ratio", 0.7, "Pressure transducer damping ratio zeta", "", 0.05, 5.0),
        _p("nonlinearity", 5e3, "Pressure transducers' bow nonlinearity N at mid-span (0-10 "
           "bar gauge)", "Pa", -1e5, 1e5),
        _p("offset_1", 5e3, "Chamber 1 transducer offset o_1", "Pa", -1e5, 1e5),
        _p("offset_2", -2e3, "Chamber 2 transducer offset o_2", "Pa", -1e5, 1e5),
    ),
    "transport_delay": (
        _p("length", 1.0, "Length L of the pneumatic line from the valve's port to each "
           "chamber (waves take L / c, 346 m/s)", "m", 0.01, 20.0),
        _p("bore", 5e-3, "Bore d of that line", "m", 1e-3, 0.05),
    ),
    "flow_lag": (
        _p("port_volume", 4e-5, "Port volume V_p between the valve and each chamber's filter",
           "m^3", 1e-7, 1e-3),
        _p("filter_conductance", 1e-8, "Conductance K of the porous filter from each port to "
           "its chamber: q = K (p_p^2 - p^2) / (2 r T)", "m^3/(s Pa)", 1e-12, 1e-5),
    ),
    "supply_droop": (
        _p("set_pressure", 8e5, "Regulator set pressure p_set (absolute)", "Pa", 2e5, 1e6),
        _p("droop", 1e7, "Regulator outlet pressure lost per flow through it R", "Pa s/kg",
           0.0, 1e8),
        _p("droop_quadratic", 4e9, "Regulator outlet pressure lost per flow squared S",
           "Pa s^2/kg^2", 0.0, 1e12),
        _p("time_constant", 0.01, "Regulator time constant tau_r", "s", 1e-4, 1.0),
        _p("hose_conductance", 2e-7, "Hose mass flow per pressure drop G_h", "kg/(s Pa)",
           1e-9, 1e-3),
        _p("hose_volume", 1e-4, "Hose volume V_h between regulator and valve", "m^3",
           1e-7, 0.1),
    ),
    "extra_mass": (
        _p("mass", 1.5, "Load mass m_x on the rod through a compliant coupling", "kg",
           1e-3, 50.0),
        _p("frequency", 60.0, "Natural frequency f_x = sqrt(k_x / m_x) / (2 pi) of the load on "
           "its coupling", "Hz", 1.0, 1e4),
        _p("damping_ratio", 0.15, "Damping ratio zeta_x = c_x / (2 sqrt(k_x m_x)) of the "
           "coupling", "", 0.0, 5.0),
    ),
    "null_offset": (
        _p("offset", 0.1, "Valve null offset u_0 on the equivalent voltage", "V", -0.5, 0.5),
    ),
    "flow_map_shape": (
        _p("amplitude", 3e-4, "Amplitude A of the flow map's departure from Eq. 8 (within the "
           "fit's 0.5 g/s)", "kg/s", -5e-4, 5e-4),
        _p("phase", 0.0, "Phase phi of the departure along the pressure", "rad", -7.0, 7.0),
    ),
    "pressure_dependent_gain": (
        _p("slope", 0.3, "Flow gain slope k: factor 1 + k (p - p_mid) / p_s", "", -0.9, 0.9),
    ),
    "load_spring": (
        _p("stiffness", 8e3, "Spring stiffness k_s between the rod and the frame", "N/m",
           0.0, 1e7),
        _p("free_position", 0.0, "Piston position y_s where the spring is relaxed", "m",
           -0.5, 0.5),
    ),
    "position_filter": (
        _p("time_constant", 2e-3, "Time constant tau of each of the position transducer's "
           "two first-order stages (its lag is 2 tau)", "s", 1e-5, 0.1),
    ),
    "end_stop_cushion": (
        _p("length", 3e-3, "Cushioned length d_c before each end stop", "m", 1e-4, 0.02),
        _p("stiffness", 5e5, "Cushion stiffness k_c", "N/m", 1e3, 1e8),
        _p("damping", 5e3, "Cushion damping c_c", "N s/m", 0.0, 1e6),
    ),
}


@dataclass(frozen=True)
class PlantSpec:
    """One plant: the model's parameters (nominal values, the bench's deviations, rig switches,
    sensor noise; model effects off) and the real effects on, name -> parameters (missing
    parameters take their defaults). ``substeps``: integration sub-steps per sample, at least
    (more at sample times beyond 1 ms: :func:`jetpipe_ros.plant.constants.substeps_of`).

    Raises :class:`~jetpipe_ros.plant.PlantError` naming the effect and parameter on an
    unknown name, a value out of range, or a model effect switched on.
    """

    params: ModelParams = field(default_factory=ModelParams)
    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    substeps: int = 8

    def __post_init__(self) -> None:
        on = self.params.enabled_effects()
        if on:
            raise PlantError(f"model effects {', '.join(on)} are on: the plant's effects are "
                             f"its own (jetpipe_ros.plant.EFFECT_PARAMS)")
        if not 1 <= self.substeps <= 1000:
            raise PlantError(f"substeps = {self.substeps} is out of range [1, 1000]")
        effects = {}
        for name, values in self.effects.items():
            specs = EFFECT_PARAMS.get(name)
            if specs is None:
                raise PlantError(f"unknown real effect {name!r}; known: "
                                 f"{', '.join(EFFECT_PARAMS)}")
            known = {s.name: s for s in specs}
            unknown = set(values) - set(known)
            if unknown:
                raise PlantError(f"{name}: unknown parameter(s) {', '.join(sorted(unknown))}; "
                                 f"known: {', '.join(known)}")
            try:
                effects[name] = {s.name: check_value(s, values.get(s.name, s.default), name)
                                 for s in specs}
            except ParameterError as exc:
                raise PlantError(str(exc)) from exc
        object.__setattr__(self, "effects", effects)
        coefficients = self.params["flow.coefficients"]
        if any(abs(c - EQ8[term]) > 1e-12 * max(abs(c), 1.0)
               for c, term in zip(coefficients, PAPER_TERMS)):
            raise PlantError("flow.coefficients: the plant's flow map is the paper's Eq. 8 "
                             "(jetpipe_ros.plant.valve.EQ8); an individual valve differs by "
                             "flow.gain_charge and flow.gain_discharge")
        if any(self.params["flow.table"]):
            raise PlantError("flow.table: the plant's flow map is the paper's Eq. 8; a map of "
                             "another shape is its flow_map_shape effect")
        if "elastoplastic_friction" in effects and "measured_seal" in effects:
            raise PlantError("elastoplastic_friction and measured_seal are both friction laws "
                             "of the piston: switch on one")
        hysteresis = effects.get("weighted_play_hysteresis")
        if hysteresis and sum(hysteresis[f"weight_{i}"] for i in (1, 2, 3)) <= 0.0:
            raise PlantError("weighted_play_hysteresis: the weights sum to 0")

    def with_effect(self, name: str, **values: float) -> PlantSpec:
        """A copy with real effect ``name`` on (or its parameters changed)."""
        return PlantSpec(self.params, {**self.effects, name: {**self.effects.get(name, {}),
                                                              **values}}, self.substeps)

    def with_params(self, params: ModelParams) -> PlantSpec:
        """A copy with other model parameters, the same effects."""
        return PlantSpec(params, self.effects, self.substeps)

    def with_values(self, changes: Mapping[str, Any]) -> PlantSpec:
        """A copy with some model parameters changed (dotted names, validated)."""
        return self.with_params(self.params.with_values(changes))

    def describe(self) -> dict[str, Any]:
        """The plant as plain data: its effects and the model parameters off their defaults."""
        return {"effects": {k: dict(v) for k, v in self.effects.items()},
                "params": self.params.non_default(), "substeps": self.substeps}
