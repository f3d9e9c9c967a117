"""``jetpipe selfcheck``: the diagnosis judged on data whose effect and parameters are withheld.

Each case switches on one effect (or two, or none) at a random realistic size and, unless
switched off, moves the nominal parameters as an individual actuator and bench would
(:func:`deviations`: drawn on the model's raw physical parameters, more of them than the
diagnosis's calibration knobs and independently of how those knobs act). The data come from one
of two sources:

- ``plant`` (the default): :mod:`jetpipe_ros.plant`, a stand-in for real hardware written apart
  from the candidates, whose effects take other functional forms than the simulator's (an
  energy balance with wall exchange, ISO 6358 leaks, a seal-gap leak, three weighted plays,
  elasto-plastic friction, a seal as friction-rig records show it, a second-order sensor with
  gain error and offsets, a pneumatic line with distributed dynamics, a port volume behind a
  filter, a supply through a drooping regulator and a hose, extra mass)
  and include effects on no list (a valve null offset, a pressure-dependent valve gain,
  end-stop cushioning, a load spring, a position transducer's filter: the right answer is
  ``unlisted`` placed in their subsystem); pairs of a strong and a weak effect;
- ``model``: the simulator's own effects (the candidates' forms, plus a multi-element
  hysteresis), the check of earlier versions, kept for comparison.

It simulates the default campaign with sensor noise and runs the diagnosis on the dataset
directory alone. The truth stays here: the diagnosis reads only what a user would give it. Then
the verdicts are scored: top-1 accuracy (an effect too small to show in the experiments counts as
correctly answered by ``none``; a parameters-only case must be answered ``none`` with the
calibration significant; an unlisted truth must be answered ``unlisted`` placed in its
subsystem),
a confusion matrix, the recovery of the fitted parameters and of the calibration, and the
held-out shrinkage; how sure these figures are: top-1 accuracy per truth kind and per expected
answer with Wilson score intervals, the shrinkage's quantiles and histogram.

The cases run in parallel on a Dask cluster (:mod:`cluster`), one case per task. Each finished
case is kept in ``OUT/cases/caseNN/`` (its diagnosis, its truth, ``result.json``), so an
interrupted run started again with the same configuration computes only what is left.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from distributed import as_completed

from jetpipe_ros.campaign import campaign_dataset as on_model
from jetpipe_ros.dataset import DatasetError, read_dataset
from jetpipe_ros.workflows.cluster import Cluster
from jetpipe_ros.workflows.diagnose import diagnose
from jetpipe_ros.fileio import to_json, write_files, write_text
from jetpipe_ros.identify import identify
from jetpipe_ros.model import EFFECTS, ModelParams, ParameterError, simulate
from jetpipe_ros.model.params import end_stop_volumes
from jetpipe_ros.plant import REAL_EFFECTS, PlantSpec
from jetpipe_ros.plant.effects import flow_map_shape
from jetpipe_ros.plant import campaign_dataset as on_plant
from jetpipe_ros.plant import simulate as simulate_plant
from jetpipe_ros.plant.logger import log, without_velocity

SOURCES = ("plant", "model")
#: In ``OUT/cases/``: the run's configuration; in each ``caseNN/``: the scored case.
CONFIG = "config.json"
RESULT = "result.json"
#: The histogram of held-out shrinkage, beside selfcheck.md.
SHRINKAGE_PNG = "selfcheck_shrinkage.png"
#: Confidence level of the accuracy intervals.
CONFIDENCE = 0.95

#: Model truths: realistic sizes (docs/effects.md), name -> sampler of the effect's parameters.
SIZES: dict[str, Callable[[np.random.Generator], dict]] = {
    "valve_delay": lambda r: {"delay": r.uniform(1e-3, 5e-3)},
    "valve_lag": lambda r: {"corner_frequency": math.exp(r.uniform(math.log(10), math.log(60)))},
    "valve_hysteresis": lambda r: {"half_width": r.uniform(0.1, 0.4)},
    "supply_pressure": lambda r: {"pressure": r.uniform(6e5, 9e5)},
    "thermal": lambda r: {"polytropic_index": r.uniform(1.1, 1.4)},
    "leakage": lambda r: {"cross_coefficient": r.uniform(2e-10, 8e-10)},
    "friction_dynamics": lambda r: {"bristle_stiffness": math.exp(r.uniform(math.log(1e4),
                                                                            math.log(1e6)))},
    "moving_mass": lambda r: {"mass": r.choice([r.uniform(0.5, 0.7), r.uniform(2.0, 5.0)])},
    "sensor_dynamics": lambda r: {"time_constant": r.uniform(1e-3, 1e-2),
                                  "bias": r.choice([-1.0, 1.0]) * r.uniform(1e3, 1e4)},
}
#: Model truths in the simulator's other forms: (effect, sampler) by variant name.
VARIANTS: dict[str, tuple[str, Callable[[np.random.Generator], dict]]] = {
    "hysteresis_multi_element": ("valve_hysteresis", lambda r: {
        "half_width": r.uniform(0.15, 0.4), "elements": 4}),
    "orifice_leak": ("leakage", lambda r: {"form": "orifice",
                                           "cross_area": r.uniform(0.6e-7, 1.5e-7)}),
    "heat_transfer_thermal": ("thermal", lambda r: {
        "form": "heat_transfer", "heat_transfer": math.exp(r.uniform(math.log(0.2),
                                                                     math.log(2.0)))}),
}
PAIRS = (("valve_lag", "leakage"), ("valve_hysteresis", "thermal"))
#: Plant truths: pairs of a strong effect and a weak one (drawn at the low end of its sizes).
PLANT_PAIRS = (("wall_heat_exchange", "sensor_second_order"), ("transport_delay", "iso6358_leak"))
WEAK: dict[str, Callable[[np.random.Generator], dict]] = {
    "sensor_second_order": lambda r: {
        "natural_frequency": math.exp(r.uniform(math.log(60.0), math.log(100.0))),
        "damping_ratio": float(r.uniform(0.7, 1.0)), "nonlinearity": 0.0,
        "offset_1": float(r.choice([-1.0, 1.0]) * r.uniform(1e3, 3e3)),
        "offset_2": float(r.choice([-1.0, 1.0]) * r.uniform(1e3, 3e3))},
    "iso6358_leak": lambda r: {"cross_conductance": 0.0,
                               "atmosphere_conductance": float(r.uniform(0.4e-10, 0.8e-10)),
                               "critical_ratio": float(r.uniform(0.3, 0.45))},
}
#: The cycle of case kinds per source: none (a parameters-only case with deviations, twice per
#: cycle then), every effect, every variant, the pairs.
KINDS = {
    "model": ("none", *EFFECTS, *VARIANTS, *("+".join(p) for p in PAIRS)),
    "plant": ("none", *REAL_EFFECTS, *("+".join(p) for p in PLANT_PAIRS)),
}


def deviations(rng: np.random.Generator, nominal: ModelParams) -> tuple[dict, dict]:
    """Raw parameter changes of an individual actuator and bench, and the calibration knob
    factors they amount to (for scoring).

    Sizes (uniform): flow map per direction +-10 %, gas temperature +-2 % (it multiplies the flow
    term of Eq. 11-12 too); jet-pipe gain +-5 %; torque-motor inertia, magnetic stiffness,
    back-EMF constant and coil resistance each +-5 % (the resonance moves by about +-5 %);
    the volume each chamber keeps at its end stop (ports, hoses, fittings) +-25 %, the piston
    area +-0.5 % (the chambers' end-stop volumes kept); friction: a common factor on all forces
    +-30 %, times +-10 % per phase and quantity (breakaway, Coulomb), the viscous planes their
    own factor +-30 % times +-10 % per phase, the Stribeck velocity +-20 % per phase. Every plane
    is scaled whole (its c0, c1, c2), so the forces keep their sign and pressure dependence.
    """
    u = lambda half: float(rng.uniform(1.0 - half, 1.0 + half))  # noqa: E731
    g_c, g_d, temp, g_v = u(0.10), u(0.10), u(0.02), u(0.05)
    inertia, stiffness = u(0.05), u(0.05)
    d1, d2 = u(0.25), u(0.25)
    area = nominal["chamber.piston_area"] * u(0.005)
    swept = area * 0.5 * nominal["mechanics.stroke"]
    stop1, stop2 = end_stop_volumes(nominal)
    changes: dict = {
        "flow.gain_charge": nominal["flow.gain_charge"] * g_c,
        "flow.gain_discharge": nominal["flow.gain_discharge"] * g_d,
        "chamber.temperature": nominal["chamber.temperature"] * temp,
        "valve.gain": nominal["valve.gain"] * g_v,
        "valve.rotor_inertia": nominal["valve.rotor_inertia"] * inertia,
        "valve.magnetic_stiffness": nominal["valve.magnetic_stiffness"] * stiffness,
        "valve.back_emf_constant": nominal["valve.back_emf_constant"] * u(0.05),
        "valve.coil_resistance": nominal["valve.coil_resistance"] * u(0.05),
        "chamber.piston_area": area,
        "chamber.dead_volume_1": swept + d1 * stop1,
        "chamber.dead_volume_2": swept + d2 * stop2,
    }
    static, viscous = u(0.30), u(0.30)
    knobs = {"flow_gain_charge": g_c * temp, "flow_gain_discharge": g_d * temp,
             "valve_gain": g_v, "valve_frequency": math.sqrt(stiffness / inertia),
             "dead_volume_1": d1, "dead_volume_2": d2}
    for phase in ("entry", "exit"):
        statics = []
        for qty, common in (("breakaway", static), ("coulomb", static), ("viscous", viscous)):
            f = common * u(0.10)
            if qty == "viscous":
                knobs[f"viscous_{phase}"] = f
            else:
                statics.append(f)
            changes[f"friction.{phase}.{qty}"] = [f * c for c in
                                                   nominal[f"friction.{phase}.{qty}"]]
        knobs[f"friction_{phase}"] = float(np.mean(statics))
        changes[f"friction.{phase}.stribeck_velocity"] = [
            u(0.20) * c for c in nominal[f"friction.{phase}.stribeck_velocity"]]
    return changes, knobs


@dataclass
class Case:
    """One withheld truth and what the diagnosis said about it."""

    index: int
    kind: str
    source: str  #: plant | model
    effects: dict[str, dict]  #: effect (the plant's or the model's) -> parameters switched on
    seed: int
    deviations: dict = field(default_factory=dict)  #: raw parameter changes (the bench)
    knob_truth: dict = field(default_factory=dict)  #: the calibration factors they amount to
    bench_effects: dict = field(default_factory=dict)  #: the plant bench's own (flow map shape)
    visible: bool = True  #: the effect shows in the data (else ``none`` is right too)
    deviated: bool = False  #: the parameter deviations show in the data
    verdict: str = ""
    verdict_subsystem: str = ""
    verdict_params: dict = field(default_factory=dict)
    confidence: float = 0.0
    calibrated: bool = False  #: the diagnosis recalibrated (calibration significant)
    knobs: dict = field(default_factory=dict)  #: the calibration factors it reported
    recalibration_shrinkage: float = 0.0  #: held-out shrinkage of the recalibration alone
    shrinkage: float = 0.0
    #: effects the diagnosis said these records cannot judge, or, answering none, cannot rule
    #: out (the recalibration imitates them), or cannot tell from the one it named (its
    #: ``ambiguous_with``): said, not graded; a miss stays a miss
    not_judged: list = field(default_factory=list)
    gap_nominal: float = 0.0
    gap_augmented: float = 0.0
    #: with ``flow_table``: whether the flow map's correction table identified on the case's
    #: own constant-volume tests was kept (None: not identified)
    flow_table: bool | None = None
    seconds: float = 0.0

    @property
    def truth(self) -> str:
        """The expected answer: the listed effects joined by '+', ``unlisted``, or none."""
        if self.source == "model":
            return "+".join(sorted(self.effects)) or "none"
        listed = {REAL_EFFECTS[e].listed for e in self.effects}
        return "unlisted" if "unlisted" in listed else "+".join(sorted(listed)) or "none"

    @property
    def truth_subsystem(self) -> str | None:
        """The subsystem an unlisted truth lies in."""
        if self.truth != "unlisted":
            return None
        return "+".join(sorted({REAL_EFFECTS[e].subsystem for e in self.effects}))

    @property
    def parameters_only(self) -> bool:
        """No effect, only the parameter deviations."""
        return not self.effects and bool(self.deviations)

    @property
    def correct(self) -> bool:
        """The verdict names the truth (or says none for an invisible truth); an unlisted
        truth must be answered ``unlisted`` placed in its subsystem (that one alone); a
        parameters-only case must also be recalibrated, unless its deviations do not show."""
        got = "+".join(sorted(self.verdict.split("+"))) if self.verdict != "none" else "none"
        named = got == self.truth or (not self.visible and got == "none")
        if got == "unlisted" and named:
            named = self.verdict_subsystem == self.truth_subsystem
        if self.parameters_only and self.deviated:
            return named and self.calibrated
        return named

    @property
    def warned(self) -> bool:
        """The diagnosis said it could not judge, not rule out, or not tell from its answer an
        effect of the truth."""
        return any(e in self.not_judged for e in self.truth.split("+"))

    def bench(self) -> ModelParams | PlantSpec:
        """The nominal parameters moved by the deviations, without the effect."""
        params = ModelParams().with_values(self.deviations)
        return PlantSpec(params, self.bench_effects) if self.source == "plant" else params

    def truth_model(self) -> ModelParams | PlantSpec:
        """The model (or plant) the data were recorded on."""
        truth = self.bench()
        for effect, kw in self.effects.items():
            truth = truth.with_effect(effect, **kw)
        return truth


def _draw(kind: str, source: str, rng: np.random.Generator) -> dict[str, dict]:
    if kind == "none":
        return {}
    if source == "model":
        if kind in VARIANTS:
            effect, sampler = VARIANTS[kind]
            return {effect: sampler(rng)}
        return {e: SIZES[e](rng) for e in kind.split("+")}
    names = kind.split("+")
    out = {names[0]: REAL_EFFECTS[names[0]].sample(rng)}
    for weak in names[1:]:
        out[weak] = WEAK[weak](rng)
    return out


def make_cases(n: int, seed: int, deviate: bool = True, source: str = "plant",
               shape: bool = False) -> list[Case]:
    """``n`` cases cycling through :data:`KINDS` of ``source`` (with parameter deviations,
    ``none`` twice per cycle), sizes drawn with ``seed``; with ``shape`` every plant bench's
    flow map departs from Eq. 8 within the fit's error (drawn apart: the cases are otherwise
    those without it)."""
    if source not in SOURCES:
        raise ValueError(f"source must be one of {SOURCES}, got {source!r}")
    if shape and source != "plant":
        raise ValueError("a flow map of another shape is the plant's (source 'plant')")
    rng = np.random.default_rng(seed)
    kinds = KINDS[source]
    if deviate:
        kinds = ("none", *kinds)
    cases = []
    for i in range(n):
        kind = kinds[i % len(kinds)]
        effects = _draw(kind, source, rng)
        case_seed = int(rng.integers(1, 2**31 - 1))
        changes, knobs = deviations(rng, ModelParams()) if deviate else ({}, {})
        bench = {"flow_map_shape": flow_map_shape(np.random.default_rng([seed, i]))} \
            if shape else {}
        cases.append(Case(i, "parameters_only" if deviate and kind == "none" else kind, source,
                          effects, case_seed, changes, knobs, bench))
    return cases


#: A truth is visible when on some signal the RMS of its noise-free difference from the bench
#: without it is at least this many sensor noise standard deviations: its systematic part then
#: carries at least 4/5 of the variance of the residual a person plots (4 sigma^2 against
#: sigma^2). The grader's own rule, from the plant's sensors, not the diagnosis's threshold.
VISIBLE_SIGMAS = 2.0


def signature(a: ModelParams | PlantSpec, b: ModelParams | PlantSpec,
              dataset_dir: Path) -> float:
    """How far models (or plants) ``a`` and ``b`` differ on the dataset's commands: the
    largest over signals of the RMS of their noise-free difference (as the sensors read them,
    every experiment replayed open loop from rest) over the sensor's noise standard deviation
    (``a``'s ``sensors.*_sigma``). A truth at least :data:`VISIBLE_SIGMAS` from the bench
    without it shows in the data; below, ``none`` is a right answer too."""
    ds = read_dataset(dataset_dir)
    params = a.params if isinstance(a, PlantSpec) else a
    sigma = {"y": params["sensors.position_sigma"], "p1": params["sensors.pressure_sigma"],
             "p2": params["sensors.pressure_sigma"]}
    squares = {s: [] for s in sigma}
    for entry, exp in ds:
        changes = {"mechanics.locked": entry.locked, "sensors.noise": False}
        ta, tb = (simulate_plant(m.with_params(m.params.at_sample_time(exp.dt))
                                 .with_values(changes), exp.u) if isinstance(m, PlantSpec)
                  else simulate(m.at_sample_time(exp.dt).with_values(changes), exp.u)
                  for m in (a, b))
        for s in (("p1", "p2") if entry.locked else ("y", "p1", "p2")):
            if getattr(exp, s) is not None:  # not measured: cannot show there
                squares[s].append((getattr(ta, f"{s}_meas") - getattr(tb, f"{s}_meas")) ** 2)
    return max((float(np.sqrt(np.mean(np.concatenate(d)))) / sigma[s]
                for s, d in squares.items() if d), default=0.0)


def record(truth: ModelParams | PlantSpec, root: Path, seed: int,
           sample_time: float | None = None) -> None:
    """The default campaign recorded on ``truth`` (the plant or the model) into ``root``, at
    its own sample time or ``sample_time`` [s], as a rig without a velocity sensor logs it: the
    simulation's true velocity stays out of what the diagnosis reads."""
    if isinstance(truth, PlantSpec):
        on_plant(truth, root, seed, sample_time)
    else:
        on_model(truth, root, seed, sample_time)
    without_velocity(root)


@dataclass(frozen=True)
class Logged:
    """A ``make_dataset`` for :func:`run_selfcheck`: the default campaign recorded on the truth
    at ``rate`` [Hz], then rewritten as another data logger would have written it (``logger``,
    one of :data:`jetpipe_ros.plant.logger.LOGGERS`: a row off, lost rows and jitter, declared
    units, fewer sensors). The diagnosis must give the verdicts it gives on the clean record."""

    logger: str | None = None
    rate: float = 1000.0

    def __call__(self, truth: ModelParams | PlantSpec, root: Path, seed: int) -> None:
        record(truth, root, seed, 1.0 / self.rate)
        if self.logger:
            log(self.logger, root, seed + 1)

    def describe(self) -> str:
        """How the records were logged, in words."""
        words = f"{self.rate:g} Hz"
        return words + (f", logger '{self.logger}'" if self.logger else ", the package's logger")


class SelfcheckError(ParameterError):
    """A self-check that cannot start (another configuration in its output directory) or whose
    cases failed; the message names the directory and what to do."""


def not_judged(result: dict) -> list[str]:
    """The effects a diagnosis (its diagnosis.json) said the records cannot judge, cannot rule
    out (answering none) or cannot tell from the one it named (``verdict.ambiguous_with``)."""
    ambiguous = result["verdict"].get("ambiguous_with") or ""
    return sorted({*result["data"]["cannot_judge"], *result["visibility"]["not_ruled_out"],
                   *ambiguous.split("+")} - {""})


def run_case(case: Case, make_dataset: Callable[[ModelParams | PlantSpec, Path, int], None],
             cases_dir: str | None, flow_table: bool = False) -> Case:
    """Record ``case``'s dataset in a temporary directory, diagnose it blind (its fits in this
    process) and score it; return the case with the verdict filled in. With ``cases_dir`` the
    diagnosis's outputs, the truth (``truth.yaml``) and the scored case (``result.json``, written
    last and atomically: the mark of a finished case) go to ``cases_dir/caseNN/``. With
    ``flow_table`` the diagnosis runs against the flow map's correction table identified on the
    record's own constant-volume tests (``jetpipe identify --procedures flow_table``), as a
    user whose valve departs from Eq. 8 would run it."""
    t0 = time.perf_counter()
    name = f"case{case.index:02d}"
    work = Path(tempfile.mkdtemp(prefix=f"jetpipe-selfcheck-{name}-"))
    try:
        data = work / name
        truth = case.truth_model()
        make_dataset(truth.with_values({"sensors.noise": True,
                                        "sensors.seed": case.seed % 100000}), data, case.seed)
        bench = case.bench()
        case.visible = not case.effects or signature(truth, bench, data) >= VISIBLE_SIGMAS
        nominal = PlantSpec() if case.source == "plant" else ModelParams()
        case.deviated = bool(case.deviations) and \
            signature(bench, nominal, data) >= VISIBLE_SIGMAS
        out = (Path(cases_dir) if cases_dir else work / "out") / name
        params = None
        if flow_table:
            try:
                found = identify(read_dataset(data), procedures=["flow_table"])
                case.flow_table, params = found.table.kept, found.params
            except DatasetError:  # no two constant-volume tests with both pressures
                pass
        result = diagnose(data, out, params, workers=1, quiet=True)
        write_text(out / "truth.yaml", _truth_yaml(truth))
        v = result["verdict"]
        case.verdict, case.verdict_params = v["effect"], v["params"]
        case.verdict_subsystem = v["subsystem"]
        case.confidence = v["confidence"]
        cal = result["calibration"]
        case.calibrated, case.knobs = cal["significant"], cal["knobs"]
        case.recalibration_shrinkage = cal["shrinkage"]
        case.gap_nominal, case.gap_augmented = (result["gap"]["nominal"],
                                                result["gap"]["augmented"])
        case.shrinkage = result["gap"]["shrinkage"]
        case.not_judged = not_judged(result)
        case.seconds = time.perf_counter() - t0
        if cases_dir:
            write_text(out / RESULT, to_json(dataclasses.asdict(case), indent=1))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return case


def _configuration(cases_dir: Path, config: dict, restart: bool) -> dict[int, Case]:
    """Check ``cases_dir`` against this run's configuration (write it if new); return the
    cases an earlier run of it finished (by index). Another configuration is refused unless
    ``restart``, which discards it."""
    stored = cases_dir / CONFIG
    if restart and cases_dir.exists():
        shutil.rmtree(cases_dir)
    if stored.exists():
        old = json.loads(stored.read_text())
        if old != config:
            flags = lambda c: (f"--cases {c['cases']} --seed {c['seed']} --truth {c['truth']} "  # noqa: E731
                               f"--{'' if c['deviations'] else 'no-'}deviations --logger "
                               f"{c.get('logger') or 'none'} --rate {c.get('rate', 1000.0):g}"
                               f"{' --flow-map-shape' if c.get('flow_map_shape') else ''}"
                               f"{' --flow-table' if c.get('flow_table') else ''}")
            raise SelfcheckError(f"{cases_dir.parent}: holds a self-check run with "
                                 f"{flags(old)}, not {flags(config)}: give another --out, or "
                                 f"--restart to discard it")
    cases_dir.mkdir(parents=True, exist_ok=True)
    for stale in cases_dir.glob(".case*"):  # outputs a stopped run was writing
        shutil.rmtree(stale, ignore_errors=True)
    write_text(stored, to_json(config, indent=1))
    done = {}
    for path in sorted(cases_dir.glob(f"case*/{RESULT}")):
        case = Case(**json.loads(path.read_text()))
        if case.index < config["cases"]:
            done[case.index] = case
    return done


def _duration(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}m{s:02d}s" if m else f"{s}s"


def run_selfcheck(n: int, seed: int,
                  make_dataset: Callable[[ModelParams | PlantSpec, Path, int], None] = Logged(),
                  out_dir: Path | None = None, workers: int = 2,
                  progress: Callable[[str], None] = print, deviate: bool = True,
                  source: str = "plant", scheduler: str | None = None,
                  restart: bool = False, shape: bool = False,
                  kinds: Sequence[str] = (), flow_table: bool = False) -> dict:
    """Run ``n`` cases; ``make_dataset(truth, root, seed)`` writes a noisy dataset to root.

    The cases run in parallel, one per task on the workers of a Dask cluster
    (:class:`cluster.Cluster`: ``workers`` local processes, 1 = one after the other in this
    process, or the cluster at ``scheduler``), each case's diagnosis serial in its worker. With
    ``out_dir`` each case is kept in ``out_dir/cases/caseNN/`` as it finishes, so that a run
    stopped half-way and started again with the same configuration (``n``, ``seed``,
    ``source``, ``deviate``) computes only the cases left; another configuration there is
    refused unless ``restart``. A case that fails does not stop the others: they finish and are
    kept, then :class:`SelfcheckError` names the failures. With ``shape`` every bench's flow map
    departs from Eq. 8 within the fit's error (:func:`make_cases`). With ``kinds`` only the
    cases of those kinds (:attr:`Case.kind`) among the ``n`` run and are scored: the same cases,
    sizes and seeds as in the whole run, so a later run of all ``n`` in the same ``out_dir``
    computes only the rest. With ``flow_table`` each case is diagnosed against the flow map's
    correction table identified on its own records (:func:`run_case`).
    """
    cases = select_kinds(make_cases(n, seed, deviate, source, shape), kinds)
    cases_dir = out_dir / "cases" if out_dir is not None else None
    done: dict[int, Case] = {}
    if cases_dir is not None:
        config = {"cases": n, "seed": seed, "truth": source, "deviations": deviate}
        if shape:
            config["flow_map_shape"] = True
        if flow_table:
            config["flow_table"] = True
        if isinstance(make_dataset, Logged):
            config.update(logger=make_dataset.logger, rate=make_dataset.rate)
        done = _configuration(cases_dir, config, restart)
        done = {i: c for i, c in done.items() if i in {c.index for c in cases}}
        if done:
            progress(f"resuming: {len(done)} of {len(cases)} cases already done in {cases_dir} "
                     f"(skipped: {', '.join(str(i) for i in sorted(done))})")
    todo = [c for c in cases if c.index not in done]
    began = time.perf_counter()
    failures: list[str] = []

    def report(case: Case) -> None:
        done[case.index] = case
        finished = len(done) - (len(cases) - len(todo))
        elapsed = time.perf_counter() - began
        left = elapsed / finished * (len(todo) - finished - len(failures))
        progress(f"[{len(done)}/{len(cases)}] {case.kind:42s} truth {case.truth:28s} -> "
                 f"{case.verdict:28s} {'ok ' if case.correct else 'MISS'} "
                 f"{'recalibrated ' if case.calibrated else ''}"
                 f"shrinkage {100 * case.shrinkage:4.0f} %  ({case.seconds:.0f} s; "
                 f"{_duration(elapsed)} elapsed, about {_duration(left)} left)")

    where = str(cases_dir) if cases_dir is not None else None
    with Cluster(workers, scheduler, plant=True) as cluster:
        client = cluster.client if todo else None
        if client is None:
            for case in todo:
                report(run_case(case, make_dataset, where, flow_table))
        else:
            futures = [client.submit(run_case, case, make_dataset, where, flow_table, pure=False)
                       for case in todo]
            index = {f.key: c.index for f, c in zip(futures, todo)}
            for fut in as_completed(futures):
                try:
                    report(fut.result())
                except Exception as exc:  # the others go on  # noqa: BLE001
                    failures.append(f"case {index[fut.key]}: {type(exc).__name__}: {exc}")
                    progress(f"case {index[fut.key]} FAILED: {type(exc).__name__}: {exc}")
    if failures:
        kept = f"; the {len(done)} finished are kept in {cases_dir}: run the same command " \
               f"again to retry the rest" if cases_dir is not None else ""
        raise SelfcheckError(f"{len(failures)} of {len(cases)} cases failed ({'; '.join(failures)})"
                             f"{kept}")
    summary = summarise([done[c.index] for c in cases], time.perf_counter() - began)
    summary["resumed"] = len(cases) - len(todo)
    if kinds:
        summary["kinds"] = sorted({c.kind for c in cases})
    summary["flow_map_shape"] = shape
    summary["flow_table"] = flow_table
    if isinstance(make_dataset, Logged):
        summary["logged"] = make_dataset.describe()
    summary["ran_on"] = str(cluster)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        write_files({out_dir / "selfcheck.json": to_json(summary) + "\n",
                     out_dir / "selfcheck.md": render(summary)})
        shrinkage_figure(summary, out_dir / SHRINKAGE_PNG)
    return summary


def select_kinds(cases: list[Case], kinds: Sequence[str]) -> list[Case]:
    """The cases of the given kinds (all for none); a kind none of the cases has is refused with
    the kinds they have."""
    if not kinds:
        return cases
    have = sorted({c.kind for c in cases})
    unknown = [k for k in kinds if k not in have]
    if unknown:
        raise SelfcheckError(f"--kinds: {', '.join(unknown)} is not among these "
                             f"{len(cases)} cases' kinds: {', '.join(have)}")
    return [c for c in cases if c.kind in kinds]


def _truth_yaml(truth: ModelParams | PlantSpec) -> str:
    if isinstance(truth, PlantSpec):
        return yaml.safe_dump({"plant": truth.describe()}, sort_keys=False)
    return truth.to_ros_yaml(only_changed=True)


def accuracy_by(cases: list[Case], key: Callable[[Case], str]) -> dict[str, dict]:
    """Top-1 accuracy of the cases grouped by ``key``, each with its Wilson score interval at
    :data:`CONFIDENCE` (statsmodels ``proportion_confint``)."""
    from statsmodels.stats.proportion import proportion_confint

    out = {}
    for name in sorted({key(c) for c in cases}):
        group = [c for c in cases if key(c) == name]
        k = sum(c.correct for c in group)
        lo, hi = proportion_confint(k, len(group), alpha=1.0 - CONFIDENCE, method="wilson")
        out[name] = {"cases": len(group), "correct": k, "accuracy": k / len(group),
                     "interval": [float(lo), float(hi)]}
    return out


#: Quantiles of the shrinkage distribution reported, by name.
QUANTILES = {"min": 0.0, "q10": 0.1, "q25": 0.25, "median": 0.5, "q75": 0.75, "q90": 0.9,
             "max": 1.0}


def summarise(cases: list[Case], seconds: float) -> dict:
    """Accuracy (overall, and per truth kind and per expected answer with Wilson intervals),
    confusion matrix, parameter and calibration recovery and the distribution of shrinkage."""
    labels = sorted({c.truth for c in cases} | {c.verdict for c in cases})
    confusion = {t: {v: sum(1 for c in cases if c.truth == t and c.verdict == v)
                     for v in labels} for t in sorted({c.truth for c in cases})}
    recovery = []
    for c in cases:
        if c.correct and len(c.effects) == 1 and c.truth in EFFECTS:
            (effect, truth), = c.effects.items()
            for k, x in truth.items():
                got = c.verdict_params.get(k)
                if isinstance(x, float) and got is not None:
                    recovery.append({"case": c.index, "effect": effect, "param": k,
                                     "truth": x, "fitted": got,
                                     "rel_error": abs(got - x) / abs(x)})
    knobs = []  # calibration factors against the truth's, where the diagnosis recalibrated
    for c in cases:
        if c.calibrated and c.knob_truth:
            for k, x in c.knob_truth.items():
                got = c.knobs.get(k, 1.0)
                knobs.append({"case": c.index, "knob": k, "truth": x, "fitted": got,
                              "error": got - x,
                              "named": abs(x - 1.0) < 0.05 or (got - 1.0) * (x - 1.0) > 0})
    with_gap = [c for c in cases if (c.effects and c.visible) or c.deviated]
    with_effect = [c for c in cases if c.effects]
    params_only = [c for c in cases if c.parameters_only]
    unlisted = [c for c in cases if c.truth == "unlisted"]
    singles = [c for c in cases if len(c.effects) == 1 and c.visible and c.truth != "unlisted"]
    return {
        "cases": len(cases), "seconds": seconds,
        "source": cases[0].source if cases else None,
        "deviations": any(c.deviations for c in cases),
        "top1_accuracy": float(np.mean([c.correct for c in cases])),
        "top1_interval": accuracy_by(cases, lambda c: "all")["all"]["interval"],
        "effect_accuracy": float(np.mean([c.correct for c in with_effect]))
        if with_effect else None,
        "none_correct": all(c.correct for c in cases if not c.effects),
        "variant_accuracy": float(np.mean([c.correct for c in cases if c.kind in VARIANTS]))
        if any(c.kind in VARIANTS for c in cases) else None,
        "unlisted_accuracy": float(np.mean([c.correct for c in unlisted])) if unlisted else None,
        "least_single_shrinkage": float(min(c.shrinkage for c in singles)) if singles else None,
        "parameters_only": {
            "cases": len(params_only),
            "accuracy": float(np.mean([c.correct for c in params_only])),
            "median_recalibration_shrinkage": float(np.median(
                [c.recalibration_shrinkage for c in params_only])),
            "min_recalibration_shrinkage": float(min(
                c.recalibration_shrinkage for c in params_only)),
        } if params_only else None,
        "median_shrinkage": float(np.median([c.shrinkage for c in with_gap]))
        if with_gap else None,
        "confidence_level": CONFIDENCE,
        "accuracy_by_kind": accuracy_by(cases, lambda c: c.kind),
        "accuracy_by_truth": accuracy_by(cases, lambda c: c.truth),
        "shrinkage_quantiles": {"cases": len(with_gap), **{
            k: float(np.quantile([c.shrinkage for c in with_gap], q))
            for k, q in QUANTILES.items()}} if with_gap else None,
        "median_param_rel_error": float(np.median([r["rel_error"] for r in recovery]))
        if recovery else None,
        "knobs_named": float(np.mean([k["named"] for k in knobs])) if knobs else None,
        "median_knob_error": float(np.median([abs(k["error"]) for k in knobs]))
        if knobs else None,
        "confusion": confusion, "recovery": recovery, "knob_recovery": knobs,
        "results": [{"case": c.index, "kind": c.kind, "source": c.source, "truth": c.truth,
                     "truth_subsystem": c.truth_subsystem, "effects": c.effects,
                     "deviations": c.knob_truth, "visible": c.visible, "deviated": c.deviated,
                     "verdict": c.verdict, "subsystem": c.verdict_subsystem,
                     "params": c.verdict_params,
                     "calibrated": c.calibrated, "knobs": c.knobs,
                     "recalibration_shrinkage": c.recalibration_shrinkage,
                     "confidence": c.confidence, "correct": c.correct,
                     "gap_nominal": c.gap_nominal, "gap_augmented": c.gap_augmented,
                     "shrinkage": c.shrinkage, "not_judged": c.not_judged,
                     "warned": c.warned, "seconds": c.seconds} for c in cases],
        "misses_warned": sum(1 for c in cases if not c.correct and c.warned),
    }


def render(summary: dict) -> str:
    """The self-check as Markdown: headline figures, confusion matrix, parameter recovery."""
    dev = "with" if summary["deviations"] else "without"
    logged = f", logged at {summary['logged']}" if summary.get("logged") else ""
    shape = ", every flow map of another shape than Eq. 8" if summary.get("flow_map_shape") \
        else ""
    if summary.get("flow_table"):
        shape += ", diagnosed against the flow map's correction table identified on each record"
    only = f", only the kinds {', '.join(summary['kinds'])}" if summary.get("kinds") else ""
    lines = [f"# jetpipe selfcheck: {summary['cases']} cases in {summary['seconds']:.0f} s, "
             f"data from the {summary['source']}, {dev} parameter deviations{shape}{logged}"
             f"{only}",
             "",
             f"- top-1 accuracy: {100 * summary['top1_accuracy']:.0f} % "
             f"({100 * summary['top1_interval'][0]:.0f}-{100 * summary['top1_interval'][1]:.0f} "
             f"%, {100 * summary['confidence_level']:.0f} % Wilson interval)"]
    if summary["effect_accuracy"] is not None:
        lines.append(f"- top-1 unmodelled effect (cases with an effect): "
                     f"{100 * summary['effect_accuracy']:.0f} %")
    lines.append(f"- `none` answered correctly on every effect-free case: "
                 f"{'yes' if summary['none_correct'] else 'no'}")
    po = summary["parameters_only"]
    if po:
        lines.append(f"- parameters-only cases ({po['cases']}): {100 * po['accuracy']:.0f} % "
                     f"answered `none` with the calibration significant; recalibration removes "
                     f"{100 * po['median_recalibration_shrinkage']:.0f} % of the held-out gap "
                     f"(median; least {100 * po['min_recalibration_shrinkage']:.0f} %)")
    if summary["variant_accuracy"] is not None:
        lines.append(f"- accuracy on the simulator's other forms: "
                     f"{100 * summary['variant_accuracy']:.0f} %")
    if summary["unlisted_accuracy"] is not None:
        lines.append(f"- effects on no list answered `unlisted` with their subsystem: "
                     f"{100 * summary['unlisted_accuracy']:.0f} %")
    if summary["least_single_shrinkage"] is not None:
        lines.append(f"- least held-out shrinkage of a visible single listed effect: "
                     f"{100 * summary['least_single_shrinkage']:.0f} %")
    if summary["median_shrinkage"] is not None:
        lines.append(f"- median held-out shrinkage (cases with a visible gap): "
                     f"{100 * summary['median_shrinkage']:.0f} %")
    if summary["median_param_rel_error"] is not None:
        lines.append(f"- median relative error of recovered parameters: "
                     f"{100 * summary['median_param_rel_error']:.1f} %")
    if summary["knobs_named"] is not None:
        lines.append(f"- calibration knobs off by >= 5 % named in the right direction: "
                     f"{100 * summary['knobs_named']:.0f} %; median knob error "
                     f"{summary['median_knob_error']:.3f}")
    misses = sum(1 for r in summary["results"] if not r["correct"])
    if misses:
        lines.append(f"- misses where the diagnosis said the records cannot judge, rule out or "
                     f"tell apart the true effect: {summary.get('misses_warned', 0)} of "
                     f"{misses} (still counted as misses)")
    if summary.get("resumed"):
        lines.append(f"- {summary['resumed']} of the cases were finished by an earlier run "
                     f"(resumed); the time above is this run's")
    level = f"{100 * summary['confidence_level']:.0f} %"
    for key, title in (("accuracy_by_truth", "expected answer"), ("accuracy_by_kind",
                                                                    "truth kind")):
        lines += ["", f"## Top-1 accuracy per {title} ({level} Wilson interval)", "",
                  f"| {title} | cases | correct | accuracy | {level} interval |",
                  "|---|---|---|---|---|"]
        for name, a in summary[key].items():
            lo, hi = a["interval"]
            lines.append(f"| {name} | {a['cases']} | {a['correct']} | "
                         f"{100 * a['accuracy']:.0f} % | {100 * lo:.0f}-{100 * hi:.0f} % |")
    q = summary["shrinkage_quantiles"]
    if q:
        lines += ["", f"## Held-out shrinkage ({q['cases']} cases with a visible gap)", "",
                  "| " + " | ".join(QUANTILES) + " |", "|---" * len(QUANTILES) + "|",
                  "| " + " | ".join(f"{100 * q[k]:.0f} %" for k in QUANTILES) + " |", "",
                  f"![held-out shrinkage per case]({SHRINKAGE_PNG})"]
    conf = summary["confusion"]
    cols = sorted({v for row in conf.values() for v, n in row.items() if n})
    lines += ["", "## Confusion matrix (rows: truth, columns: verdict)", "",
              "| truth | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for t, row in conf.items():
        lines.append(f"| {t} | " + " | ".join(str(row.get(c, 0) or "") for c in cols) + " |")
    lines += ["", "## Cases", "", "| # | kind | truth | verdict | subsystem | recalibrated | ok "
              "| shrinkage | recalibration alone | confidence |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in summary["results"]:
        ok = "yes" if r["correct"] else "**no** (warned)" if r.get("warned") else "**no**"
        vis = "" if r["visible"] else " (too small to see)"
        lines.append(f"| {r['case']} | {r['kind']}{vis} | {r['truth']} | {r['verdict']} | "
                     f"{r['subsystem']} | {'yes' if r['calibrated'] else 'no'} | {ok} "
                     f"| {100 * r['shrinkage']:.0f} % | "
                     f"{100 * r['recalibration_shrinkage']:.0f} % | {r['confidence']:.2f} |")
    if summary["recovery"]:
        lines += ["", "## Parameter recovery", "", "| effect | parameter | truth | fitted | "
                  "error |", "|---|---|---|---|---|"]
        for r in summary["recovery"]:
            lines.append(f"| {r['effect']} | {r['param']} | {r['truth']:.4g} | "
                         f"{r['fitted']:.4g} | {100 * r['rel_error']:.1f} % |")
    if summary["knob_recovery"]:
        lines += ["", "## Calibration recovery (truth: the factor the raw deviations amount "
                  "to)", "", "| case | knob | truth | fitted | named |", "|---|---|---|---|---|"]
        for r in summary["knob_recovery"]:
            lines.append(f"| {r['case']} | {r['knob']} | {r['truth']:.3f} | {r['fitted']:.3f} "
                         f"| {'yes' if r['named'] else '**no**'} |")
    return "\n".join(lines) + "\n"


def shrinkage_figure(summary: dict, path: Path) -> None:
    """The histogram of held-out shrinkage over the cases with a visible gap, correct and
    missed verdicts stacked, the median marked; written to ``path`` as PNG (atomically)."""
    from jetpipe_ros.figures import pyplot

    plt = pyplot()
    rows = [r for r in summary["results"]
            if (r["effects"] and r["visible"]) or r["deviated"]]
    fig, ax = plt.subplots(figsize=(7, 3.2))
    if rows:
        values = [[100 * r["shrinkage"] for r in rows if r["correct"] is ok]
                  for ok in (True, False)]
        low = min(0.0, *(100 * r["shrinkage"] for r in rows))
        ax.hist(values, bins=np.linspace(low, 100, 21), stacked=True,
                color=["#1f77b4", "#d62728"], label=["verdict correct", "verdict missed"])
        ax.axvline(100 * summary["shrinkage_quantiles"]["median"], color="k", ls="--",
                   label=f"median {100 * summary['shrinkage_quantiles']['median']:.0f} %")
        ax.legend(fontsize=8, loc="upper left")
    ax.set_xlabel("held-out shrinkage of the gap, 1 - augmented / nominal [%]")
    ax.set_ylabel("cases")
    ax.set_title(f"{len(rows)} of {summary['cases']} cases with a visible gap", fontsize=9)
    fig.tight_layout()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=90)
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        Path(tmp).unlink(missing_ok=True)
