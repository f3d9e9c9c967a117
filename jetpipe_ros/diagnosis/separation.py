"""Telling two explanations apart: the experiment where two fitted models differ most, and the
unmodelled effects a recalibrated knob may stand in for.

**Separating experiment.** Two models that fit these experiments about equally well still
differ somewhere. The menu: the experiments of this dataset (predicted as the diagnosis predicts
them), the open-loop experiments of the default campaign (``config/campaign.yaml``) that the
dataset lacks, and experiments designed for one overlap (:func:`presliding_experiment`). Each is
simulated with both models, and the one where their outputs differ most relative to the sensor
noise is named, with its campaign entry so it can be recorded (``id_recorder``).

**Stand-ins.** A calibration knob can take the place of an effect in the experiments at hand
(README, *Diagnosis*): pre-sliding displacement before breakaway looks like a lower breakaway
force; a valve hysteresis like a higher friction; a lower supply pressure like a weaker charging
flow map; a polytropic or heat-exchanging gas like other dead volumes; extra valve dynamics like
a slower torque motor. :data:`STAND_INS` lists these pairs. When the answer is "no unmodelled
effect, the parameters were off", each effect a significantly moved knob may stand in for is
fitted in the knob's place (the other knobs held at their recalibrated values, the moved ones
back at nominal) and judged against the recalibration on the held-out data by the test the
ranking uses (:attr:`verdict.Ranked.significant`): the data prefer one, or cannot tell them
apart, and then the separating experiment is named. When the effect in the knobs' place
*explains* what the recalibration leaves (the ranking's test, :attr:`verdict.Ranked.explains`),
it is the answer (:func:`adopt`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from jetpipe_ros.campaign import default_campaign
from jetpipe_ros.campaign.plan import ExperimentSpec, parse_campaign
from jetpipe_ros.diagnosis.calibration import CALIBRATION, DESCRIPTIONS, describe
from jetpipe_ros.diagnosis.calibration import NAME as CAL
from jetpipe_ros.diagnosis.candidates import CANDIDATES, effect_of
from jetpipe_ros.diagnosis.data import SIGNALS, Prepared
from jetpipe_ros.diagnosis.fit import Fit, stacked
from jetpipe_ros.diagnosis.jobs import Fitter, Job
from jetpipe_ros.diagnosis.prediction import predict
from jetpipe_ros.diagnosis.verdict import Ranked, Settled, Verdict, confidence_of, rank
from jetpipe_ros.model import ModelParams, simulate

#: Effects (docs/effects.md) that can take the place of a calibration knob in the default
#: campaign's experiments, by knob and by the direction of its move (+1: factor above 1).
STAND_INS: dict[tuple[str, int], tuple[str, ...]] = {
    # pre-sliding displacement before breakaway reads as a lower breakaway force; a valve
    # hysteresis delays the force on every reversal, which reads as a higher one
    **{(f"friction_{ph}", -1): ("friction_dynamics",) for ph in ("entry", "exit")},
    **{(f"friction_{ph}", +1): ("valve_hysteresis",) for ph in ("entry", "exit")},
    # a lower supply bounds the pressure a chamber charges to: a weaker charging flow map
    ("flow_gain_charge", -1): ("supply_pressure",),
    # dp/dt = n r T q / V: an index n > 1 (or a gas between isothermal and adiabatic) reads as
    # a smaller volume
    ("dead_volume_1", -1): ("thermal",),
    ("dead_volume_2", -1): ("thermal",),
    # a slower torque motor against extra valve dynamics after it
    ("valve_frequency", -1): ("valve_lag", "valve_delay"),
}

#: A knob counts as moved when its factor differs from 1 by more than this many standard
#: errors (the curvature of the training error, :func:`fit.uncertainty`): a move the data do
#: not ask for stands in for nothing.
MOVED_SE = 3.0
#: ... and by at least the 2 % from which the report names a knob as off
#: (:func:`calibration.describe`).
NAMED = 0.02
#: The pre-sliding test: a triangle of voltage around the valve's null at this frequency [Hz]
#: and duration [s], at this fraction of the largest amplitude that leaves the recalibrated
#: piston stuck (searched by bisection on the amplitude to :data:`AMPLITUDE_TOL`).
PRESLIDING_FREQUENCY = 0.5
PRESLIDING_DURATION = 6.0
PRESLIDING_MARGIN = 0.9
AMPLITUDE_TOL = 0.02
#: Motion [m] below which a simulated piston counts as stuck (1 % of the position sensor's
#: noise, docs/model.md).
STUCK = 1.5e-7


def _stays_stuck(params: ModelParams, amplitude: float, dt: float) -> bool:
    spec = _presliding_spec(amplitude, dt)
    trace = simulate(params, spec.command(dt).voltage)
    return float(np.max(np.abs(trace.y - trace.y[0]))) < STUCK


def _presliding_spec(amplitude: float, dt: float) -> ExperimentSpec:
    doc = {"sample_time": dt, "experiments": [{
        "name": "presliding_triangle", "kind": "open_loop", "locked": False, "role": "train",
        "duration": PRESLIDING_DURATION,
        "voltage": {"signal": "triangle", "amplitude": round(float(amplitude), 4),
                    "frequency": PRESLIDING_FREQUENCY}}]}
    return parse_campaign(doc, "presliding_experiment").experiments[0]


def presliding_experiment(params: ModelParams, dt: float) -> ExperimentSpec | None:
    """Small oscillations around rest, below breakaway: a triangle of voltage around the null
    whose amplitude keeps the piston of ``params`` stuck (:data:`PRESLIDING_MARGIN` of the
    largest such amplitude). A model with pre-sliding friction moves there by its bristles'
    deflection, one with a lower breakaway force not at all: the test that tells the two apart,
    which the default campaign lacks. None when no amplitude of 1 mV already keeps the piston
    stuck (nothing below breakaway to probe)."""
    quiet = params.at_sample_time(dt).with_values({"sensors.noise": False})
    low, high = 1e-3, 1.0
    if not _stays_stuck(quiet, low, dt):
        return None
    if _stays_stuck(quiet, high, dt):
        return _presliding_spec(PRESLIDING_MARGIN * high, dt)
    while high / low > 1.0 + AMPLITUDE_TOL:  # bisection on a log scale
        mid = float(np.sqrt(low * high))
        low, high = (mid, high) if _stays_stuck(quiet, mid, dt) else (low, mid)
    return _presliding_spec(PRESLIDING_MARGIN * low, dt)


def separating_experiment(a: ModelParams, b: ModelParams, prepared: Prepared) -> dict | None:
    """The experiment where two fitted models differ most, relative to sensor noise (the RMS
    over signals of (a - b) / noise; see the module text for the menu), judged on the signals
    the dataset measures. Experiments not in the dataset come with ``campaign_entry``, their
    mapping for a campaign YAML. When the dataset lacks a chamber pressure, ``with_sensors``
    gives how far the two models' predictions of it differ on the dataset's own free-piston
    experiments, in units of a pressure sensor's noise (``sensors.pressure_sigma`` of ``a``):
    what logging that pressure would add without a new experiment."""
    noise = {s: max(prepared.noise[s], 1e-12) for s in SIGNALS}
    missing = prepared.unmeasured_pressures
    unmeasured: dict[str, list[float]] = {s: [] for s in missing}
    menu = []
    for rec in prepared.records:
        pa = predict(a, rec, prepared.dt)
        pb = predict(b, rec, prepared.dt)
        d = np.mean([np.mean(((pa.signal(s) - pb.signal(s)) / noise[s])[pa.free] ** 2)
                     for s in rec.signals()])
        menu.append({"experiment": rec.name, "piston": rec.entry.piston, "in_dataset": True,
                     "held_out": not rec.train.any(), "designed": False,
                     "difference_over_noise": float(np.sqrt(d))})
        for s in missing if not (rec.locked or rec.regulated) else ():
            unmeasured[s].append(float(np.mean(((pa.signal(s) - pb.signal(s)) /
                                                a["sensors.pressure_sigma"])[pa.free] ** 2)))
    have = {r.name for r in prepared.records}
    specs = [(exp, False) for exp in default_campaign().experiments
             if not exp.closed_loop and exp.name not in have]
    designed = presliding_experiment(a, prepared.dt)
    if designed is not None:
        specs.append((designed, True))
    for exp, is_designed in specs:
        u = exp.command(prepared.dt).voltage
        changes = {"mechanics.locked": exp.locked, "sensors.noise": False}
        ta = simulate(a.at_sample_time(prepared.dt).with_values(changes), u, exp.load_force)
        tb = simulate(b.at_sample_time(prepared.dt).with_values(changes), u, exp.load_force)
        # Only the sensors this bench has: a signal it cannot measure separates nothing.
        signals = [s for s in (("p1", "p2") if exp.locked else SIGNALS)
                   if s in prepared.sensors]
        if not signals:
            continue
        d = np.mean([np.mean(((getattr(ta, f"{s}_meas") - getattr(tb, f"{s}_meas")) /
                              noise[s]) ** 2) for s in signals])
        menu.append({"experiment": exp.name, "piston": "locked" if exp.locked else "free",
                     "in_dataset": False, "designed": is_designed,
                     "difference_over_noise": float(np.sqrt(d)),
                     "campaign_entry": exp.to_yaml()})
    if not menu:
        return None
    menu.sort(key=lambda m: -m["difference_over_noise"])
    out = {**menu[0], "menu": [{k: m[k] for k in ("experiment", "in_dataset",
                                                   "difference_over_noise")} for m in menu]}
    if any(unmeasured.values()):
        # A pressure the bench did not log, as a sensor with the model's noise would have read
        # it on the dataset's own experiments (RMS over them).
        out["with_sensors"] = {s: float(np.sqrt(np.mean(v))) for s, v in unmeasured.items() if v}
    return out


def moved_knobs(values: Mapping[str, float],
                stderr: Mapping[str, float | None]) -> dict[str, float]:
    """The knobs (name: factor) whose factor differs from 1 by more than :data:`MOVED_SE`
    standard errors and by at least :data:`NAMED` (a knob without a standard error, which the
    error does not depend on locally, has not moved)."""
    return {k: f for k, f in values.items()
            if abs(f - 1.0) >= NAMED and stderr.get(k) is not None
            and abs(f - 1.0) > MOVED_SE * float(stderr[k])}


def suspects(moved: Mapping[str, float], already: Sequence[str]) -> dict[str, list[str]]:
    """The effects the ``moved`` knobs (name: factor) may stand in for (:data:`STAND_INS`),
    each with the knobs it would replace; effects already in the nominal model are left out."""
    out: dict[str, list[str]] = {}
    for knob, factor in moved.items():
        for effect in STAND_INS.get((knob, 1 if factor > 1.0 else -1), ()):
            if effect not in already:
                out.setdefault(effect, []).append(knob)
    return out


@dataclass
class StandIn:
    """An effect fitted in the place of the knobs it may stand in for (:func:`stand_ins`)."""

    row: dict  #: the ``calibration.stand_ins`` row of diagnosis.json
    fit: Fit  #: calibration (the knobs replaced back at nominal) and the effect, stacked
    ranked: Ranked  #: the fit judged against the recalibration (held out)


def stand_ins(fitter: Fitter, prepared: Prepared, nominal: ModelParams, recalibrated: Fit,
              stderr: Mapping[str, float | None],
              progress: Callable[[str], None]) -> list[StandIn]:
    """Each effect a moved knob of ``recalibrated`` may stand in for, fitted in those knobs'
    place and judged against the recalibration on the held-out data (module text). Each row
    gives the knobs, the effect's best form and parameters, both held-out gaps, the paired t of
    the recalibration's advantage, which the data prefer and, unless one is preferred, the
    separating experiment. Preferred: ``recalibration`` (significantly better); ``effect``
    (it *explains* what the recalibration leaves, :attr:`verdict.Ranked.explains`: the answer
    then); ``partly`` (significantly better, but by less than :data:`verdict.MIN_SHRINKAGE`);
    ``cannot tell``; ``no effect`` (the effect fits to nothing)."""
    values = recalibrated.values[CAL]
    todo = suspects(moved_knobs(values, stderr), nominal.enabled_effects())
    if not todo:
        return []
    jobs, labels, owners, bases = [], [], [], {}
    for effect, knobs in todo.items():
        bases[effect] = {k: (1.0 if k in knobs else v) for k, v in values.items()}
        base = CALIBRATION.apply(nominal, bases[effect])
        for name in CANDIDATES:
            if effect_of(name) == effect:
                jobs.append(Job(base, (name,)))
                labels.append(f"{name} in place of {', '.join(knobs)}")
                owners.append(effect)
    progress(f"could the moved knobs stand in for an effect? fitting {len(jobs)} candidates in "
             f"their place")
    fits = fitter.run(jobs, labels)
    out = []
    for effect, knobs in todo.items():
        best = min((f for f, o in zip(fits, owners) if o == effect),
                   key=lambda f: f.train.total)
        best = stacked(dataclasses.replace(recalibrated, values={CAL: bases[effect]},
                                           z=CALIBRATION.to_unit(bases[effect])), best)
        (cal_vs,) = rank([recalibrated], best.holdout, best.holdout_windows, prepared.dt)
        (eff_vs,) = rank([best], recalibrated.holdout, recalibrated.holdout_windows,
                         prepared.dt)
        name = best.effects[0]
        if CANDIDATES[name].vanishes(best.values[name]):
            preferred = "no effect"  # fitted to nothing: the knobs' move is all there is
        elif cal_vs.significant and cal_vs.improvement > 0.0:
            preferred = "recalibration"
        elif eff_vs.explains:
            preferred = "effect"
        elif eff_vs.significant and eff_vs.improvement > 0.0:
            preferred = "partly"
        else:
            preferred = "cannot tell"
        row = {
            "effect": effect, "candidate": name, "form": CANDIDATES[name].form,
            "knobs": knobs, "knob_words": [DESCRIPTIONS[k][0] for k in knobs],
            "params": best.values[name], "holdout_gap": best.holdout.gap,
            "recalibrated_gap": recalibrated.holdout.gap, "t_recalibration": cal_vs.t,
            "shrinkage": eff_vs.shrinkage, "preferred": preferred,
            "separating_experiment": (separating_experiment(recalibrated.params, best.params,
                                                            prepared)
                                      if preferred in ("cannot tell", "partly") else None),
        }
        out.append(StandIn(row, best, eff_vs))
    return out


def adopt(choice: StandIn) -> Settled:
    """The answer when the data prefer an effect in the place of knobs that moved: the
    recalibration with those knobs back at nominal, and the effect. Confidence as
    :func:`verdict.decide` gives it (:func:`verdict.confidence_of`), the recalibration alone
    the runner-up."""
    r = choice.ranked
    off = ", ".join(describe(choice.fit.values[CAL])) or "all within 2 % of nominal"
    reason = f"the nominal parameters were off ({off}); {words(choice.row)}"
    return Settled(choice.fit, True, Verdict(r, confidence_of(r, r.base_gap), reason), reason)


def words(row: Mapping) -> str:
    """One stand-in row in plain words, e.g. "friction_dynamics in place of the entry-phase
    breakaway and Coulomb friction leaves 0.41 % (recalibrated: 0.32 %): these experiments
    cannot tell them apart; 'presliding_triangle' would (...)"."""
    text = (f"{row['candidate']} in place of the {' and '.join(row['knob_words'])} leaves "
            f"{row['holdout_gap']:.2f} % (recalibrated: {row['recalibrated_gap']:.2f} %)")
    if row["preferred"] == "recalibration":
        return text + f": the data prefer the recalibration (t = {row['t_recalibration']:.1f})"
    if row["preferred"] == "effect":
        return text + (f": the data prefer the effect, which removes "
                       f"{row['shrinkage']:.0%} of what the recalibration leaves")
    if row["preferred"] == "no effect":
        return text + f": fitted in their place, {row['effect']} vanishes"
    sep = row["separating_experiment"]
    if row["preferred"] == "partly":
        text += (f": significantly less, but only {row['shrinkage']:.0%} of what the "
                 f"recalibration leaves (under the 30 % that counts): these experiments do "
                 f"not settle it")
    else:
        text += ": these experiments cannot tell them apart"
    if not sep:
        return text
    apart = (f"their predictions differ most there, {sep['difference_over_noise']:.1f} x the "
             f"sensor noise")
    if sep["in_dataset"] and sep.get("held_out"):
        return text + (f"; they differ most in the held-out experiment '{sep['experiment']}' "
                       f"({apart}), not enough to decide: a longer or repeated held-out run of "
                       f"it would add the evidence")
    if sep["in_dataset"]:
        return text + (f"; the experiment '{sep['experiment']}' of this dataset, held out, "
                       f"could ({apart}): mark it 'role: holdout' in dataset.yaml and diagnose "
                       f"again, or record it again as a held-out experiment")
    return text + (f"; recording the experiment '{sep['experiment']}' "
                   f"({'designed for this' if sep['designed'] else 'of the default campaign'}, "
                   f"not in this dataset) could ({apart})")
