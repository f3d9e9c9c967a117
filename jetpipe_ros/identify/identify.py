"""The identification run: each procedure on the experiments that feed it, then one parameter
set the simulator loads, and replays that check it on experiments no procedure used.

Order matters: the flow map first, Eq. 8 then its correction table (the valve and hysteresis
procedures read u_eq through both), then the valve, the hysteresis and the friction. A
procedure whose experiments are missing or insufficient is skipped with the reason (its
parameters keep their starting values), unless it was required, which makes that a
DatasetError; so is a run where nothing could be identified.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from jetpipe_ros.dataset import Dataset, DatasetError
from jetpipe_ros.identify import experiments as kinds
from jetpipe_ros.identify.experiments import Recording, of_kind, recordings
from jetpipe_ros.identify.flow_map import (FlowMapResult, FlowTableResult, identify_flow_map,
                                           identify_flow_table)
from jetpipe_ros.identify.friction import FrictionResult, identify_friction, rig
from jetpipe_ros.identify.hysteresis import HysteresisResult, identify_hysteresis
from jetpipe_ros.identify.valve import ValveResult, identify_valve
from jetpipe_ros.model import ModelParams, simulate
from jetpipe_ros.replay import replay

PROCEDURES = ("flow_map", "flow_table", "valve", "hysteresis", "friction")
#: Each procedure in the words of a progress line.
WHAT = {"flow_map": "flow map (Eq. 8)", "flow_table": "flow map's correction table",
        "valve": "valve dynamics", "hysteresis": "valve's hysteresis",
        "friction": "friction planes"}


@dataclass
class Replay:
    """One experiment replayed through a parameter set, against its measurements."""

    name: str
    kind: str  #: validation | friction
    t: np.ndarray  #: time [s]
    measured: np.ndarray  #: measured position [m]
    simulated: dict[str, np.ndarray]  #: label (identified, starting) -> simulated position [m]
    rms_position: dict[str, float]  #: label -> RMS position error [m]
    rms_pressure: dict[str, float]  #: label -> RMS pressure error over both chambers [Pa]


@dataclass
class Identification:
    """Everything one run found: the parameters, each procedure's result, and the checks."""

    params: ModelParams  #: starting parameters with the identified values
    base: ModelParams  #: the starting parameters
    recordings: list[Recording]
    flow: FlowMapResult | None = None
    table: FlowTableResult | None = None
    valve: ValveResult | None = None
    hysteresis: HysteresisResult | None = None
    friction: FrictionResult | None = None
    skipped: dict[str, str] = field(default_factory=dict)  #: procedure -> why it did not run
    replays: list[Replay] = field(default_factory=list)
    #: how the records were read before the procedures ran, if not as logged (their signs)
    notes: list[str] = field(default_factory=list)

    def changes(self) -> dict[str, Any]:
        """The identified parameters that differ from the starting ones."""
        return {k: v for k, v in self.params.items() if v != self.base[k]}


def identify(dataset: Dataset, base: ModelParams | None = None,
             procedures: Iterable[str] = PROCEDURES, required: Iterable[str] = (),
             progress: Callable[[str], None] = lambda message: None) -> Identification:
    """Run ``procedures`` on ``dataset`` starting from ``base`` (default: the nominal model),
    each procedure's start (and each friction test's end) said through ``progress``.

    Procedures in ``required`` that cannot run raise DatasetError; the others are skipped with
    the reason in ``skipped``. DatasetError too when no procedure ran.
    """
    base = base if base is not None else ModelParams()
    wanted = [p for p in PROCEDURES if p in set(procedures)]
    required = set(required)
    recs = recordings(dataset)
    out = Identification(params=base, base=base, recordings=recs)
    changes: dict[str, Any] = {}
    coefficients = list(base["flow.coefficients"])
    table = list(base["flow.table"])

    def attempt(name: str, run):  # type: ignore[no-untyped-def]
        if name not in wanted:
            return None
        progress(f"identifying the {WHAT[name]}")
        try:
            return run()
        except DatasetError as exc:
            if name in required:
                raise
            out.skipped[name] = str(exc)
            return None

    out.flow = attempt("flow_map", lambda: identify_flow_map(of_kind(recs, kinds.CHARGE), base))
    if out.flow is not None:
        coefficients = out.flow.coefficients
        changes["flow.coefficients"] = coefficients
        table = [0.0] * len(table)  # a table corrects the Eq. 8 it was fitted beside
    out.table = attempt("flow_table", lambda: identify_flow_table(
        of_kind(recs, kinds.CHARGE), base, coefficients))
    if out.table is not None:
        table = out.table.table
    if table != list(base["flow.table"]):
        changes["flow.table"] = table
    flow_map = coefficients + table
    out.valve = attempt("valve", lambda: identify_valve(of_kind(recs, kinds.SWEEP), base,
                                                        flow_map))
    if out.valve is not None:
        changes.update(out.valve.values)
    out.hysteresis = attempt("hysteresis", lambda: identify_hysteresis(
        of_kind(recs, kinds.RAMP), base, flow_map))
    if out.hysteresis is not None:
        changes["effects.valve_hysteresis.enabled"] = out.hysteresis.significant
        if out.hysteresis.significant:
            changes["effects.valve_hysteresis.half_width"] = out.hysteresis.half_width
            changes["effects.valve_hysteresis.elements"] = 1
    out.friction = attempt("friction", lambda: identify_friction(of_kind(recs, kinds.FRICTION),
                                                                 base, progress))
    if out.friction is not None:
        for phase, planes in out.friction.planes.items():
            changes.update({f"friction.{phase}.{q}": c for q, c in planes.items()})
    if not set(wanted) - set(out.skipped):
        raise DatasetError("nothing identified: " + "; ".join(
            f"{k}: {v}" for k, v in out.skipped.items()) if out.skipped else
            "nothing identified: no procedure selected")
    out.params = base.with_values(changes)
    progress("replaying the held-out runs and the friction tests")
    out.replays = [check(r, {"identified": out.params, "starting": base}) for r in recs
                   if r.kind in (kinds.VALIDATION, kinds.FRICTION)]
    return out


def check(rec: Recording, params: dict[str, ModelParams]) -> Replay:
    """Replay ``rec`` through each parameter set and compare with its measurements.

    Validation runs replay the command (and load) from the model's initial state; friction
    tests replay the rig: regulated pressures at the measured means, the piston at its
    measured start, the measured load (the paper's check of Fig. 26-28). The errors are taken
    over the measured rows (none filled over a logger's gap).
    """
    exp = rec.experiment
    measured = exp.measured
    sims, rms_y, rms_p = {}, {}, {}
    for label, p in params.items():
        if rec.kind == kinds.FRICTION:
            load = exp.f_load if exp.f_load is not None else rec.entry.load_force
            trace = simulate(rig(rec, p), exp.u, load)
        else:
            trace = replay(p, exp, locked=rec.entry.locked)
        sims[label] = trace.y
        rms_y[label] = float(np.sqrt(np.mean((trace.y - exp.y)[measured] ** 2)))
        rms_p[label] = float(np.sqrt(np.mean(((trace.p1 - exp.p1) ** 2
                                              + (trace.p2 - exp.p2) ** 2)[measured] / 2.0)))
    return Replay(rec.name, rec.kind, exp.t, exp.y, sims, rms_y, rms_p)
