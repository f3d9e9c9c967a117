"""The candidate causes of a gap: each unmodelled effect of docs/effects.md with the parameters the
diagnosis fits, their search ranges, and a typical size used to judge whether the experiments could
show the effect at all.

Ranges are wider than the typical sizes of docs/effects.md so a real effect is not clipped, and
each contains the value at which the effect vanishes (zero delay, hysteresis, leak, bias; n = 1; the
nominal supply and mass; a corner, wall heat conductance, bristle stiffness or supply line
conductance high enough, or a pre-sliding displacement short enough, to be invisible), so a fit to
data without the effect can land on "no effect". The forms the physics admits are candidates of
their own, judged on held-out data like the effects: the delay of the command, or of a line between
valve and chambers (the flow arrives late, and the valve sees the chambers' pressures late), or a
lumped hose before each chamber (its volume, the air's inertance, its wall friction: a length and a
bore); the valve lag of first order (a corner) or second order (a natural frequency and a damping
ratio) on the valve's output, or of second order on each chamber's mass flow after the flow map (a
port or a line; overdamped, zeta > 1, it is a first-order lag up to the frequencies it passes), or a
port volume before each chamber behind a restriction (a filter or a fitting: its volume and its ISO
6358 sonic conductance); the thermal effect as a polytropic index or as gas temperatures exchanging
heat with the walls; leaks as laminar conductances, compressible (choked) orifices, or a flow that
grows as the pressure difference to a fitted power, each across the piston and to atmosphere; the
supply constant, or a line (volume and conductance) fed from a set pressure and drained by the flow
the valve draws; dynamic friction as LuGre bristles or as Maxwell-slip elements (what real seals
show, docs/friction.md), the elements' spread a knob of its extent. Where forms blend continuously a
knob spans them: the hysteresis is eight play operators whose thresholds spread from one sharp
loop (spread 0) to a rounded Prandtl-Ishlinskii loop (spread 1), one end play weighing from an
equal share (sharp_share 0) to nearly all of the loop, the narrowest (towards 1) or the widest
(towards -1), the other plays a thin tail; the power-law leak's exponent runs from a turbulent,
orifice-like leak (0.5) to a laminar one (1).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from jetpipe_ros.model import ModelParams
from jetpipe_ros.model.flow import GAMMA_AIR, P_ATM


@dataclass(frozen=True)
class Knob:
    """One fitted parameter: its name (without ``effects.<effect>.``), range and scale."""

    name: str
    low: float
    high: float
    off: float  #: the value at which the effect vanishes (or is invisibly small)
    log: bool = False  #: search on a logarithmic scale
    #: other values of a later knob the starting grid also tries (a knob that selects a form)
    tries: tuple[float, ...] = ()
    #: the range is the knob's whole physical extent (a form's spread from 0 to 1), not a search
    #: limit: a fit at its edge is an answer, not a sign that the truth lies beyond
    extent: bool = False
    #: signals that must all be measured for the records to judge the knob; without them it
    #: moves nothing measured, or only what another knob moves, and is not fitted
    #: (:meth:`KnobGroup.judged`)
    needs: tuple[str, ...] = ()

    def to_value(self, z: float) -> float:
        """Map z in [0, 1] onto the range."""
        z = min(max(z, 0.0), 1.0)
        if self.log:
            value = math.exp(math.log(self.low) + z * math.log(self.high / self.low))
        else:
            value = self.low + z * (self.high - self.low)
        return float(min(max(value, self.low), self.high))  # no round-off past a bound

    def to_unit(self, value: float) -> float:
        """Map a value in the range onto [0, 1]."""
        if self.log:
            return math.log(value / self.low) / math.log(self.high / self.low)
        return (value - self.low) / (self.high - self.low)


@dataclass(frozen=True)
class KnobGroup:
    """Knobs fitted together and the way they change a model: a candidate effect, or the
    calibration of the nominal parameters (:mod:`calibration`)."""

    name: str
    knobs: tuple[Knob, ...]

    def start(self) -> np.ndarray:
        """Unit-scaled knobs at the point where the group changes nothing."""
        return np.array([k.to_unit(k.off) for k in self.knobs])

    def values(self, z: np.ndarray) -> dict[str, float]:
        """The group's parameters for the unit-scaled vector ``z``."""
        return {k.name: k.to_value(float(zi)) for k, zi in zip(self.knobs, z)}

    def to_unit(self, values: dict[str, float]) -> np.ndarray:
        """The unit-scaled vector of ``values`` (inverse of :meth:`values`)."""
        return np.array([k.to_unit(values[k.name]) for k in self.knobs])

    def judged(self, sensors: Sequence[str]) -> KnobGroup:
        """The group with only the knobs that records measuring ``sensors`` can judge
        (:attr:`Knob.needs`); the others stay where the group changes nothing. With one
        pressure sensor a second sensor's bias beyond the first's reads nothing measured (or,
        with chamber 2's alone, the same as the common bias): fitted, it would take any value,
        be reported as found, and cost the group a parameter it cannot use."""
        knobs = tuple(k for k in self.knobs if set(k.needs) <= set(sensors))
        return self if len(knobs) == len(self.knobs) else dataclasses.replace(self, knobs=knobs)

    def fitted(self, values: dict[str, float]) -> tuple[Knob, ...]:
        """The knobs among ``values`` (all, unless some were not judged)."""
        return tuple(k for k in self.knobs if k.name in values)

    def rest(self, values: dict[str, float]) -> np.ndarray:
        """:meth:`start` of the knobs among ``values``."""
        return np.array([k.to_unit(k.off) for k in self.fitted(values)])

    def pinned(self, values: dict[str, float], tolerance: float = 0.01) -> list[str]:
        """Knobs fitted within ``tolerance`` (of the unit-scaled range) of an edge of their
        search range: not the edge where the group changes nothing, nor the edge of a knob
        whose range is its whole physical extent. The truth may lie beyond such a knob."""
        out = []
        for k in self.fitted(values):
            z, z_off = k.to_unit(values[k.name]), k.to_unit(k.off)
            edge = 0.0 if z <= tolerance else 1.0 if z >= 1.0 - tolerance else None
            if edge is not None and not k.extent and abs(edge - z_off) > tolerance:
                out.append(k.name)
        return out

    def vanishes(self, values: dict[str, float], tolerance: float = 0.01) -> bool:
        """True when every knob but those spanning a form's extent lies within ``tolerance``
        (of the unit-scaled range) of the value where the group changes nothing."""
        return all(abs(k.to_unit(values[k.name]) - k.to_unit(k.off)) <= tolerance
                   for k in self.fitted(values) if not k.extent)

    def apply(self, params: ModelParams, values: dict[str, float]) -> ModelParams:
        """``params`` changed by this group at ``values``."""
        raise NotImplementedError


@dataclass(frozen=True)
class Candidate(KnobGroup):
    """An effect in one form as a candidate cause: fitted knobs, fixed settings (the form), a
    typical size. ``name`` is ``effect`` or ``effect:form`` for an effect with several forms."""

    typical: dict[str, float] = field(default_factory=dict)
    fixed: dict[str, Any] = field(default_factory=dict)
    #: calibration knobs whose signature the effect carries by construction (a hose's volume is
    #: dead volume): a recalibration may have taken its place, so it is always refitted jointly
    #: with the calibration, also from the recalibration with these knobs back at nominal
    #: (:func:`jetpipe_ros.diagnosis.diagnose.fit_effects`)
    carries: tuple[str, ...] = ()

    @property
    def effect(self) -> str:
        """The effect's name (docs/effects.md)."""
        return effect_of(self.name)

    @property
    def form(self) -> str | None:
        """The form, for an effect with several."""
        return self.fixed.get("form")

    def apply(self, params: ModelParams, values: dict[str, float]) -> ModelParams:
        """``params`` with this effect switched on at ``values``."""
        return params.with_effect(self.effect, **self.fixed, **values)


#: Maxwell-slip elements of the ``friction_dynamics:maxwell_slip`` candidate (as fitted to the
#: friction-rig records: :data:`jetpipe_ros.identify.seal.ELEMENTS`).
SEAL_ELEMENTS = 3
#: Typical size of the Maxwell-slip friction of real seals: the medians of the twelve public
#: friction-rig records (three seals, 1-7 bar gauge, 25 mm bore) that chose the form, each fitted
#: alone on its first half (docs/friction.md, "The diagnosis' candidate"). Neither scales with the
#: bore: the pre-sliding displacement delta [m] is a length (range over the records 0.18-1.25 mm),
#: the spread [-] a ratio of lengths (0.013-0.38); the level the elements share is the model's
#: own planes, which the calibration scales.
SEAL_SIZE = {"presliding_displacement": 5.6e-4, "presliding_spread": 0.052}


#: The ``valve_delay:hose`` candidate's knobs. Length [m]: 0 (no hose) to 2.5 m, a one-way delay
#: of 0-7.2 ms (L / c, c = 346 m/s), beyond the 1-5 ms of docs/effects.md and the 0.3-1.7 m
#: hoses of real benches, so a real one is not clipped (at 2.5 m and 8 mm it holds 126 cm^3,
#: over half a chamber). Bore [m]: 2-8 mm, the inner diameters of the pneumatic tubing that
#: fits a valve of this flow (4-10 mm outer); log-scaled, since the hose's volume grows as
#: d^2 and its friction falls as d^-4.75 (turbulent). The bore means nothing without a length,
#: so it is marked as spanning its extent: the candidate vanishes with the length alone, and a
#: bore at 2 or 8 mm is read as the narrowest or widest tube, not as a truth beyond.
HOSE_KNOBS = (Knob("length", 0.0, 2.5, 0.0),
              Knob("bore", 0.002, 0.008, 0.005, log=True, extent=True))


#: The ``valve_lag:port`` candidate's knobs. Port volume [m^3]: 0 (no port) to 100 cm^3, two
#: thirds of a chamber at mid-stroke (a valve body's drilling and a fitting hold a few cm^3, a
#: manifold block tens). Sonic conductance C [m^3/(s Pa)] of the restriction: 1e-9 to 1e-7
#: (0.1-10 dm^3/(s bar), from a small filter to an open port), log-scaled; behind 40 cm^3 at
#: 4.2 bar its time constant runs from 8 ms at rest (37 ms passing 1 g/s, its drop then 4.3 bar:
#: the narrowest a valve of this flow works through) to 0.1 ms (a dead volume and nothing
#: else at a 1 ms sample). Subsonic index m: 0.5 (an orifice, a fitting) to 1 (a porous
#: element: Darcy's compressible law, the drop linear in the flow), its whole extent. C and m
#: mean nothing without a volume, so they are marked as spanning their extent: the candidate
#: vanishes with the volume alone (as the hose's bore).
PORT_KNOBS = (Knob("port_volume", 0.0, 1e-4, 0.0),
              Knob("port_conductance", 1e-9, 1e-7, 1e-7, log=True, extent=True),
              Knob("port_index", 0.5, 1.0, 0.5, extent=True))

#: The supply_pressure candidates' law knob [Pa]: the pressure the flow map keeps its shape
#: relative to when the supply differs from the 10 bar of Eq. 8 (:mod:`jetpipe_ros.model.flow`).
#: Its range is its physical extent: from 0, similarity in absolute pressure (a choked jet's mass
#: flow grows with the absolute supply), to the atmosphere (the pressure a subsonic jet recovers
#: in a receiver grows with the supply's excess over it); the model's default, p_atm, is where
#: it "changes nothing". The starting grid tries both ends.
REFERENCE_KNOB = Knob("reference", 0.0, P_ATM, P_ATM, tries=(0.0,), extent=True)
#: Its typical value [Pa]: a sonic jet's thrust, C_F p_s - p_atm with a convergent nozzle's
#: thrust coefficient C_F = (gamma + 1) (2 / (gamma + 1))^(gamma / (gamma - 1)) = 1.27 in air,
#: grows with the supply above p_atm / C_F = 0.79 bar.
SONIC_REFERENCE = P_ATM / ((GAMMA_AIR + 1.0)
                           * (2.0 / (GAMMA_AIR + 1.0)) ** (GAMMA_AIR / (GAMMA_AIR - 1.0)))

#: Candidates that cannot be fitted together: each places a passage between the valve and each
#: chamber, and the model holds one (:func:`jetpipe_ros.model.params.ModelParams` refuses both).
EXCLUSIVE = (frozenset({"valve_lag:port", "valve_delay:line"}),
             frozenset({"valve_lag:port", "valve_delay:hose"}))


def combinable(a: str, b: str) -> bool:
    """Whether candidates ``a`` and ``b`` (names) can be fitted together."""
    return frozenset({a, b}) not in EXCLUSIVE


def effect_of(name: str) -> str:
    """The effect (docs/effects.md) of a candidate name (``effect`` or ``effect:form``)."""
    return name.split(":", 1)[0]


CANDIDATES: dict[str, Candidate] = {c.name: c for c in (
    Candidate("valve_delay", (Knob("delay", 0.0, 0.008, 0.0),), {"delay": 0.003},
              {"form": "command"}),
    Candidate("valve_delay:line", (Knob("delay", 0.0, 0.008, 0.0),), {"delay": 0.003},
              {"form": "line"}),
    Candidate("valve_delay:hose", HOSE_KNOBS, {"length": 1.0, "bore": 0.005}, {"form": "hose"},
              carries=("dead_volume_1", "dead_volume_2")),
    Candidate("valve_lag:first_order", (Knob("corner_frequency", 3.0, 300.0, 300.0, log=True),),
              {"corner_frequency": 30.0}, {"form": "first_order"}),
    Candidate("valve_lag:second_order", (Knob("corner_frequency", 3.0, 300.0, 300.0, log=True),
                                         Knob("damping_ratio", 0.2, 2.0, 0.7)),
              {"corner_frequency": 30.0, "damping_ratio": 0.7}, {"form": "second_order"}),
    Candidate("valve_lag:flow", (Knob("corner_frequency", 3.0, 300.0, 300.0, log=True),
                                 Knob("damping_ratio", 0.2, 2.0, 0.7)),
              {"corner_frequency": 30.0, "damping_ratio": 0.7}, {"form": "flow"}),
    Candidate("valve_lag:port", PORT_KNOBS,
              {"port_volume": 4e-5, "port_conductance": 5e-9, "port_index": 0.5},
              {"form": "port"}, carries=("dead_volume_1", "dead_volume_2")),
    Candidate("valve_hysteresis", (Knob("half_width", 0.0, 0.6, 0.0),
                                   Knob("spread", 0.0, 1.0, 0.0, tries=(1.0,), extent=True),
                                   Knob("sharp_share", -0.95, 0.95, 0.0, extent=True)),
              {"half_width": 0.25, "spread": 0.0, "sharp_share": 0.0}, {"elements": 8}),
    Candidate("supply_pressure", (Knob("pressure", 4e5, 1.1e6, 1e6), REFERENCE_KNOB),
              {"pressure": 8e5, "reference": SONIC_REFERENCE}, {"form": "constant"}),
    Candidate("supply_pressure:line", (Knob("line_conductance", 3e-9, 1e-5, 1e-5, log=True),
                                       Knob("pressure", 4e5, 1.1e6, 1e6),
                                       Knob("line_volume", 1e-6, 1e-3, 1e-6, log=True),
                                       REFERENCE_KNOB),
              {"line_conductance": 5e-8, "pressure": 9e5, "line_volume": 1e-4,
               "reference": SONIC_REFERENCE}, {"form": "line"}),
    Candidate("thermal:polytropic", (Knob("polytropic_index", 1.0, 1.4, 1.0),),
              {"polytropic_index": 1.2}, {"form": "polytropic"}),
    Candidate("thermal:heat_transfer", (Knob("heat_transfer", 0.05, 100.0, 100.0, log=True),),
              {"heat_transfer": 0.5}, {"form": "heat_transfer"}),
    Candidate("leakage:laminar", (Knob("cross_coefficient", 0.0, 3e-9, 0.0),
                                  Knob("atmosphere_coefficient", 0.0, 3e-9, 0.0,
                                       tries=(5e-10,))),
              {"cross_coefficient": 3e-10, "atmosphere_coefficient": 0.0}, {"form": "laminar"}),
    Candidate("leakage:orifice", (Knob("cross_area", 0.0, 4e-7, 0.0),
                                  Knob("atmosphere_area", 0.0, 4e-7, 0.0, tries=(5e-8,))),
              {"cross_area": 1e-7, "atmosphere_area": 0.0}, {"form": "orifice"}),
    Candidate("leakage:power", (Knob("cross_flow", 0.0, 3e-4, 0.0),
                                Knob("atmosphere_flow", 0.0, 3e-4, 0.0, tries=(5e-5,)),
                                Knob("exponent", 0.5, 1.0, 0.75, extent=True)),
              {"cross_flow": 3e-5, "atmosphere_flow": 0.0, "exponent": 0.75},
              {"form": "power"}),
    Candidate("friction_dynamics:lugre", (Knob("bristle_stiffness", 1e3, 1e7, 1e7, log=True),
                                          Knob("bristle_damping", 0.0, 3e3, 0.0)),
              {"bristle_stiffness": 1e5, "bristle_damping": 0.0}, {"form": "lugre"}),
    Candidate("friction_dynamics:maxwell_slip",
              (Knob("presliding_displacement", 2e-6, 5e-3, 2e-6, log=True),
               Knob("presliding_spread", 0.01, 1.0, SEAL_SIZE["presliding_spread"], log=True,
                    extent=True)),
              dict(SEAL_SIZE), {"form": "maxwell_slip", "elements": SEAL_ELEMENTS}),
    Candidate("moving_mass", (Knob("mass", 0.1, 10.0, 1.0, log=True),), {"mass": 3.0}),
    Candidate("sensor_dynamics", (Knob("time_constant", 0.0, 0.02, 0.0),
                                  Knob("bias", -2e4, 2e4, 0.0),
                                  Knob("bias_difference", -2e4, 2e4, 0.0,
                                       needs=("p1", "p2")),
                                  Knob("gain", -0.05, 0.05, 0.0),
                                  Knob("drift", -500.0, 500.0, 0.0)),
              {"time_constant": 0.005, "bias": 5e3, "drift": 0.0}),
)}
