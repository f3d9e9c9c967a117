"""Calibration: the nominal parameters an individual actuator and bench differ by.

Real hardware never has the paper's numbers exactly: every valve, seal, dead volume and bench
differs by several to tens of per cent. The diagnosis recalibrates a small set of lumped knobs on
the training data before it judges any unmodelled effect, and reports them apart, so that a gap
recalibration closes is not blamed on an effect and an effect masked by mis-set parameters is
still found. Each knob is a factor on the nominal model (the ``--params`` file, else the
model's defaults, docs/model.md), so 1 means "as nominal":

| knob | multiplies | what differs on real hardware |
|---|---|---|
| ``flow_gain_charge`` | ``flow.gain_charge``: Eq. 8 where it fills a chamber | receiver geometry, supply regulator |
| ``flow_gain_discharge`` | ``flow.gain_discharge``: Eq. 8 where it empties one | exhaust path |
| ``valve_gain`` | ``valve.gain``: jet-pipe deflection per volt | torque motor, Eq. 5's slope |
| ``valve_frequency`` | the torque motor's natural frequency (rotor inertia / factor^2) | inertia, magnetic stiffness |
| ``dead_volume_1``, ``_2`` | the volume each chamber keeps at its end stop (Eq. 13) | ports, hoses, fittings |
| ``friction_entry``, ``_exit`` | breakaway and Coulomb planes of one phase (Eq. 20-27) | seal preload, wear, lubrication |
| ``viscous_entry``, ``_exit`` | the viscous plane of one phase | seal material, temperature |

Ranges are wide enough for the truth to lie inside (about a factor 1.6-2.5 each way); a knob that
ends at its bound is reported as such. Knobs are searched on a log scale: a factor of 0.8 is as
far from nominal as 1.25.

How far hardware of one type typically differs from its nominal numbers (:data:`SPREAD`) is
known before any record is read; :mod:`nuisance` weighs it against what the training records
pin.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from jetpipe_ros.diagnosis.candidates import CANDIDATES, Knob, KnobGroup
from jetpipe_ros.model import ModelParams
from jetpipe_ros.model.params import end_stop_volumes

NAME = "calibration"

#: Plain-words description of each knob (what a factor above 1 means) and the parameters it
#: multiplies.
DESCRIPTIONS = {
    "flow_gain_charge": ("flow map when charging", ("flow.gain_charge",)),
    "flow_gain_discharge": ("flow map when discharging", ("flow.gain_discharge",)),
    "valve_gain": ("valve gain (jet-pipe deflection per volt)", ("valve.gain",)),
    "valve_frequency": ("valve natural frequency", ("valve.rotor_inertia",)),
    "dead_volume_1": ("chamber 1 dead volume (at its end stop)", ("chamber.dead_volume_1",)),
    "dead_volume_2": ("chamber 2 dead volume (at its end stop)", ("chamber.dead_volume_2",)),
    **{f"friction_{ph}": (f"{ph}-phase breakaway and Coulomb friction",
                          (f"friction.{ph}.breakaway", f"friction.{ph}.coulomb"))
       for ph in ("entry", "exit")},
    **{f"viscous_{ph}": (f"{ph}-phase viscous friction", (f"friction.{ph}.viscous",))
       for ph in ("entry", "exit")},
}


#: How far hardware of one type typically differs from its nominal numbers, per knob: a
#: standard deviation of the natural log of the factor (0.1: about one actuator in three lies
#: beyond a factor 0.905-1.105). Set from these sources, before any self-check was run with it:
#:
#: - flow gains, 0.10: a servo valve's rated flow is specified to +-10 % (the rated-flow
#:   tolerance servo-valve catalogues commonly state);
#: - valve gain, 0.10: the same tolerance, read as the jet pipe's deflection per volt;
#: - valve frequency, 0.10: the torque motor's natural frequency, sqrt(K / J), moves by half
#:   the spread of its net stiffness (magnet and flexure tolerances of about +-20 %);
#: - dead volumes, 0.30: ports, hoses and fittings belong to the installation, not the
#:   actuator (a hose a third longer or shorter than the nominal bench's);
#: - friction and viscous levels, 0.40: seal friction follows preload, wear, lubrication and
#:   temperature; the friction-rig records of docs/friction.md drift by tens of per cent
#:   between records of one seal and differ by a factor of five between seal types.
SPREAD = {
    "flow_gain_charge": 0.10, "flow_gain_discharge": 0.10,
    "valve_gain": 0.10, "valve_frequency": 0.10,
    "dead_volume_1": 0.30, "dead_volume_2": 0.30,
    "friction_entry": 0.40, "friction_exit": 0.40,
    "viscous_entry": 0.40, "viscous_exit": 0.40,
}


@dataclass(frozen=True)
class Calibration(KnobGroup):
    """The calibration knobs as one group the fitter handles like a candidate's knobs."""

    def log_slopes(self) -> np.ndarray:
        """d(ln factor) / d(unit-scaled knob) of each knob: ln(high / low) (log scales)."""
        return np.array([math.log(k.high / k.low) for k in self.knobs])

    def moved(self, z: np.ndarray, step: np.ndarray) -> np.ndarray:
        """The unit-scaled knobs ``z`` with their factors' natural logs moved by ``step``,
        within the knobs' ranges."""
        out = np.empty(len(self.knobs))
        for i, (k, zi, d) in enumerate(zip(self.knobs, z, step)):
            out[i] = k.to_unit(float(np.clip(k.to_value(float(zi)) * math.exp(d),
                                             k.low, k.high)))
        return out

    def prior_residuals(self, z: np.ndarray) -> np.ndarray:
        """How far the unit-scaled knobs ``z`` lie from nominal in the hardware's spread: the
        natural log of each factor over its :data:`SPREAD` (a standard normal under the prior)."""
        return np.array([math.log(k.to_value(float(zi))) / SPREAD[k.name]
                         for k, zi in zip(self.knobs, z)])

    def apply(self, params: ModelParams, values: dict[str, float]) -> ModelParams:
        """``params`` with each nominal parameter multiplied by its knob's factor."""
        changes: dict = {}
        dead = end_stop_volumes(params)
        for knob, factor in values.items():
            if knob == "valve_frequency":
                # Natural frequency ~ sqrt(K_s / J): scaling J by 1/f^2 scales it by f.
                changes["valve.rotor_inertia"] = params["valve.rotor_inertia"] / factor ** 2
                continue
            if knob.startswith("dead_volume"):
                # The volume no stroke sweeps scales; the swept part is the bore's.
                i = int(knob[-1])
                changes[f"chamber.dead_volume_{i}"] = (params[f"chamber.dead_volume_{i}"]
                                                       + (factor - 1.0) * dead[i - 1])
                continue
            for name in DESCRIPTIONS[knob][1]:
                value = params[name]
                changes[name] = ([factor * c for c in value] if isinstance(value, list)
                                 else factor * value)
        return params.with_values(changes)


def _factor(name: str, low: float, high: float) -> Knob:
    return Knob(name, low, high, 1.0, log=True)


CALIBRATION = Calibration(NAME, (
    _factor("flow_gain_charge", 0.6, 1.6),
    _factor("flow_gain_discharge", 0.6, 1.6),
    _factor("valve_gain", 0.8, 1.25),
    _factor("valve_frequency", 0.8, 1.25),
    _factor("dead_volume_1", 0.5, 2.0),
    _factor("dead_volume_2", 0.5, 2.0),
    _factor("friction_entry", 0.4, 2.5),
    _factor("friction_exit", 0.4, 2.5),
    _factor("viscous_entry", 0.4, 2.5),
    _factor("viscous_exit", 0.4, 2.5),
))


def at_bound(values: dict[str, float], tolerance: float = 0.01) -> list[str]:
    """Knobs whose fitted factor lies within ``tolerance`` (in log range) of a bound."""
    return CALIBRATION.pinned(values, tolerance)


def describe(values: dict[str, float], least: float = 0.02) -> list[str]:
    """Plain words for the knobs that differ from nominal by at least ``least``: e.g. "flow
    map when charging 9% weaker"."""
    words = []
    for k in CALIBRATION.knobs:
        f = values.get(k.name, 1.0)
        if abs(f - 1.0) < least:
            continue
        if k.name.startswith("dead_volume"):
            sense = "larger" if f > 1.0 else "smaller"
        elif k.name.startswith(("valve", "friction", "viscous")):
            sense = "higher" if f > 1.0 else "lower"
        else:
            sense = "stronger" if f > 1.0 else "weaker"
        words.append(f"{DESCRIPTIONS[k.name][0]} {abs(f - 1.0):.0%} {sense}")
    return words



def group(name: str, sensors: Sequence[str] | None = None) -> KnobGroup:
    """The knob group of a candidate (``effect`` or ``effect:form``), or the calibration; with
    the knobs records measuring ``sensors`` can judge (:meth:`KnobGroup.judged`; None: all)."""
    g = CALIBRATION if name == NAME else CANDIDATES[name]
    return g if sensors is None else g.judged(sensors)
