"""``jetpipe diagnose``: where the model departs from the measurements, which unmodelled effect
causes it, and how far the gap shrinks once that effect is modelled (DESIGN.md s.6).

Steps, each reported as progress: read and split the dataset; score the nominal model and locate
its gap (signals, subsystems, regimes, frequency bands); check which candidates the experiments
could show at all; fit every candidate on the training data (in parallel processes) and score it
on the held-out data; try pairs when one effect leaves a significant gap; cross-check, with the
roles of the data exchanged, a candidate the short holdout cannot confirm alone; decide; write
``diagnosis.json``, ``report.html`` and ``augmented.yaml``. The outputs are written to a temporary
directory and moved into place only when all three are complete.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.diagnosis.candidates import CANDIDATES, Candidate
from jetpipe_ros.diagnosis.data import SIGNALS, Prepared, prepare, swapped
from jetpipe_ros.diagnosis.fit import Fit, fit
from jetpipe_ros.diagnosis.localize import by_regime, frequency_response, position_error_pct
from jetpipe_ros.diagnosis.noise_floor import calibrate
from jetpipe_ros.diagnosis.prediction import HORIZON, predict
from jetpipe_ros.diagnosis.score import METRIC, predict_all, score, window_errors
from jetpipe_ros.diagnosis.verdict import Ranked, Verdict, decide, needs_pairs, paired_t, rank
from jetpipe_ros.model import EFFECTS, ModelParams, ParameterError, simulate

SCHEMA = "jetpipe.diagnosis/1"
OUTPUTS = ("diagnosis.json", "report.html", "augmented.yaml")
#: Candidates whose typical-size signature is below this fraction of the noise variance are
#: reported as invisible in the experiments given.
VISIBLE = 0.02
#: Candidates refitted jointly with the best single effect as pairs.
PAIR_POOL = 2


class Progress:
    """Progress lines on stderr with elapsed time."""

    def __init__(self, quiet: bool = False) -> None:
        self.quiet = quiet
        self.start = time.perf_counter()

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(f"[{time.perf_counter() - self.start:6.1f} s] {message}", file=sys.stderr,
                  flush=True)


_WORKER: dict = {}  #: the data a fitting process was started with (see :func:`fit_all`)


def _init_worker(prepared: Prepared, nominal: ModelParams) -> None:
    threadpool_limits(1)  # see diagnose()
    _WORKER.update(prepared=prepared, nominal=nominal)


def _fit_job(prepared: Prepared, nominal: ModelParams, names: tuple[str, ...],
             start: np.ndarray | None) -> Fit:
    return fit(prepared, nominal, [CANDIDATES[n] for n in names], start)


def _worker_job(names: tuple[str, ...], start: np.ndarray | None) -> Fit:
    return _fit_job(_WORKER["prepared"], _WORKER["nominal"], names, start)


def fit_all(prepared: Prepared, nominal: ModelParams, jobs: Sequence[tuple[str, ...]],
            starts: dict[tuple[str, ...], np.ndarray], workers: int,
            progress: Callable[[str], None]) -> list[Fit]:
    """Fit each tuple of candidates, in ``workers`` processes (1 = in this process)."""
    fits: list[Fit] = []
    if workers <= 1 or len(jobs) == 1:
        for i, names in enumerate(jobs, 1):
            f = _fit_job(prepared, nominal, names, starts.get(names))
            fits.append(f)
            progress(f"  [{i}/{len(jobs)}] {f.name}: held-out gap {f.holdout.gap:.2f} % "
                     f"({f.evaluations} runs, {f.seconds:.1f} s)")
        return fits
    # The data go to each process once, not with every job.
    with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), initializer=_init_worker,
                             initargs=(prepared, nominal)) as pool:
        futures = [pool.submit(_worker_job, names, starts.get(names)) for names in jobs]
        for i, fut in enumerate(as_completed(futures), 1):
            f = fut.result()
            fits.append(f)
            progress(f"  [{i}/{len(jobs)}] {f.name}: held-out gap {f.holdout.gap:.2f} % "
                     f"({f.evaluations} runs, {f.seconds:.1f} s)")
    order = {names: i for i, names in enumerate(jobs)}
    return sorted(fits, key=lambda f: order[f.effects])


def fit_pairs(best: Fit, candidates: Sequence[Candidate], prepared: Prepared,
              nominal: ModelParams, workers: int, progress: Callable[[str], None]) -> list[Fit]:
    """Pairs by forward selection: every other candidate fitted on top of the best single
    effect (held at its fitted values), the :data:`PAIR_POOL` that lower the training error
    most then refitted jointly with it. Selection uses the training data only."""
    (first,) = best.effects
    others = [c.effect for c in candidates if c.effect != first]
    progress(f"{first} leaves {best.holdout.gap:.2f} % of the gap: fitting each other "
             f"candidate on top of it")
    added = fit_all(prepared, best.params, [(e,) for e in others], {}, workers, progress)
    chosen = sorted(added, key=lambda f: f.train.total)[:PAIR_POOL]
    pairs = [(first, f.effects[0]) for f in chosen]
    starts = {(first, f.effects[0]): np.array(
        [k.to_unit(v[e][k.name]) for e, v in ((first, best.values), (f.effects[0], f.values))
         for k in CANDIDATES[e].knobs]) for f in chosen}
    progress(f"refitting {', '.join('+'.join(p) for p in pairs)} jointly")
    return fit_all(prepared, nominal, pairs, starts, workers, progress)


def cross_check(ranking: Sequence[Ranked], prepared: Prepared, nominal: ModelParams,
                nominal_preds, workers: int, progress: Callable[[str], None]) -> None:
    """Refit the candidates the holdout alone cannot confirm on the holdout, judge them on the
    training data, and store the paired t in their ranking rows (:attr:`Ranked.t_cross`)."""
    todo = [r for r in ranking if r.needs_cross_check]
    if not todo:
        return
    other = swapped(prepared)
    before = window_errors(other, nominal_preds, "holdout")
    progress(f"cross-check of {', '.join(r.fit.name for r in todo)}: refitted on the holdout, "
             f"judged on the training data")
    fits = fit_all(other, nominal, [r.fit.effects for r in todo], {}, workers, progress)
    for r, f in zip(todo, fits):
        r.t_cross = paired_t(before, f.holdout_windows)


def visibility(prepared: Prepared, nominal: ModelParams, base_preds, cand: Candidate) -> float:
    """Signature of the candidate at its typical size, as a fraction of the noise variance."""
    preds = predict_all(cand.apply(nominal, dict(cand.typical)), prepared, None)
    num, noise = [], []
    for s in SIGNALS:
        d, c = 0.0, 0
        for rec, a, b in zip(prepared.records, preds, base_preds):
            if s in rec.signals():
                m = a.free
                d += float(np.sum((a.signal(s)[m] - b.signal(s)[m]) ** 2))
                c += int(m.sum())
        if c:
            num.append(d / c / prepared.scale[s] ** 2)
            noise.append((prepared.noise[s] / prepared.scale[s]) ** 2)
    return float(np.mean(num) / max(np.mean(noise), 1e-12)) if num else 0.0


def subsystem_gaps(prepared: Prepared, nominal: ModelParams) -> dict:
    """Gap of each subsystem replayed with its inputs held on the measurements."""
    chambers = score(prepared, predict_all(nominal, prepared, None, "chambers"), None,
                     ("p1", "p2"))
    mechanics = score(prepared, [predict(nominal, r, prepared.dt, "mechanics")
                                 if not r.locked else None for r in prepared.records], None,
                      ("y",))
    offsets = []
    for rec in prepared.records:
        pred = predict(nominal, rec, prepared.dt, "chambers")
        steady = np.abs(np.gradient(rec.p1, prepared.dt)) < 2e4
        steady[: rec.t.size // 10] = False
        if steady.sum() > 100:
            offsets.append(float(np.median((rec.p1 - pred.p1)[steady])))
    return {
        "valve_and_chambers": {"driven_by": "measured command and piston motion",
                               **chambers.to_json()},
        "mechanics": {"driven_by": "measured chamber pressures", **mechanics.to_json()}
        if mechanics.mse else None,
        "sensors": {"steady_pressure_offset_pa": float(np.median(offsets)) if offsets else None,
                    "noise": {"y_m": prepared.noise["y"], "p1_pa": prepared.noise["p1"],
                              "p2_pa": prepared.noise["p2"]}},
    }


def separating_experiment(a: ModelParams, b: ModelParams, prepared: Prepared) -> dict | None:
    """The experiment where two fitted models differ most, relative to sensor noise.

    Candidates: the open-loop experiments of the default campaign (config/campaign.yaml),
    simulated whole with both models, and the experiments of this dataset, predicted as the
    diagnosis predicts them. The difference is the RMS over signals of (a - b) / noise.
    """
    from jetpipe_ros.campaign import default_campaign

    noise = {s: max(prepared.noise[s], 1e-12) for s in SIGNALS}
    menu = []
    for rec in prepared.records:
        pa = predict(a, rec, prepared.dt)
        pb = predict(b, rec, prepared.dt)
        d = np.mean([np.mean(((pa.signal(s) - pb.signal(s)) / noise[s])[pa.free] ** 2)
                     for s in rec.signals()])
        menu.append({"experiment": rec.name, "piston": rec.entry.piston, "in_dataset": True,
                     "difference_over_noise": float(np.sqrt(d))})
    campaign = default_campaign()
    have = {r.name for r in prepared.records}
    for exp in campaign.experiments:
        if exp.closed_loop or exp.name in have:
            continue
        u = exp.command(prepared.dt).voltage
        changes = {"mechanics.locked": exp.locked, "sensors.noise": False,
                   "integration.sample_time": prepared.dt}
        ta = simulate(a.with_values(changes), u, exp.load_force)
        tb = simulate(b.with_values(changes), u, exp.load_force)
        signals = ("p1", "p2") if exp.locked else SIGNALS
        d = np.mean([np.mean(((getattr(ta, f"{s}_meas") - getattr(tb, f"{s}_meas")) /
                              noise[s]) ** 2) for s in signals])
        menu.append({"experiment": exp.name, "piston": "locked" if exp.locked else "free",
                     "in_dataset": False, "difference_over_noise": float(np.sqrt(d))})
    return max(menu, key=lambda m: m["difference_over_noise"]) if menu else None


def diagnose(dataset_dir: str | Path, out_dir: str | Path, params: ModelParams | None = None,
             workers: int = 2, quiet: bool = False) -> dict:
    """Run the diagnosis on a dataset and write its outputs; return diagnosis.json's content."""
    # The linear algebra here is on small matrices: BLAS threads only spin and take the cores
    # the fitting processes need (measured: 2x slower per fit with them).
    with threadpool_limits(1):
        return _diagnose(dataset_dir, out_dir, params, workers, quiet)


def _diagnose(dataset_dir: str | Path, out_dir: str | Path, params: ModelParams | None,
              workers: int, quiet: bool) -> dict:
    progress = Progress(quiet)
    nominal = params if params is not None else ModelParams()
    already = nominal.enabled_effects()
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ParameterError(f"--out {out_dir}: exists and is not a directory")
    progress(f"reading {dataset_dir}")
    dataset = read_dataset(dataset_dir)
    prepared = prepare(dataset)
    progress(f"{len(prepared.records)} experiments, {prepared.seconds('train'):.1f} s train, "
             f"{prepared.seconds('holdout'):.1f} s holdout; {prepared.split_note}")

    progress("noise floor: scoring the model on a simulated twin of the dataset")
    prepared.floor = calibrate(prepared, nominal)
    progress("nominal model: predictions and where the gap lies")
    nom_all = predict_all(nominal, prepared, None)
    nom_hold = score(prepared, nom_all, "holdout")
    nom_windows = window_errors(prepared, nom_all, "holdout")
    nom_train = score(prepared, nom_all, "train")
    subsystems = subsystem_gaps(prepared, nominal)

    candidates = [c for name, c in CANDIDATES.items() if name not in already]
    progress("how visible each candidate would be at its typical size")
    seen = {c.effect: visibility(prepared, nominal, nom_all, c) for c in candidates}

    workers = max(1, min(workers, os.cpu_count() or 1))
    progress(f"fitting {len(candidates)} candidates on the training data ({workers} processes)")
    fits = fit_all(prepared, nominal, [(c.effect,) for c in candidates], {}, workers, progress)
    ranking = rank(fits, nom_hold, nom_windows, prepared.dt)
    if ranking and needs_pairs(ranking[0], nom_hold):
        fits += fit_pairs(ranking[0].fit, candidates, prepared, nominal, workers, progress)
        ranking = rank(fits, nom_hold, nom_windows, prepared.dt)
    cross_check(ranking, prepared, nominal, nom_all, workers, progress)
    verdict = decide(ranking, nom_hold)

    progress("scoring the augmented model")
    augmented = verdict.winner.fit.params if verdict.winner else nominal
    aug_all = predict_all(augmented, prepared, None) if verdict.winner else nom_all
    aug_hold = score(prepared, aug_all, "holdout")
    preds = {"nominal": nom_all, "augmented": aug_all}
    stroke = nominal["mechanics.stroke"]
    localization = {
        "metric": METRIC, "horizon_s": HORIZON,
        "signals": {"nominal": nom_hold.to_json(), "augmented": aug_hold.to_json(),
                    "nominal_train": nom_train.to_json()},
        "subsystems": subsystems,
        "regimes": by_regime(prepared, preds, "holdout", stroke),
        "frequency": frequency_response(prepared, preds),
    }
    separating = None
    if verdict.ambiguous and verdict.runner_up is not None:
        separating = separating_experiment(verdict.winner.fit.params,
                                           verdict.runner_up.fit.params, prepared)
    result = _result(prepared, nominal, verdict, ranking, nom_hold, aug_hold, localization,
                     seen, separating, preds)
    progress(f"writing {out_dir}")
    _write_outputs(out_dir, result, augmented, prepared, preds)
    progress(f"verdict: {result['verdict']['effect']} "
             f"(confidence {result['verdict']['confidence']:.2f}); {verdict.reason}")
    return result


def _result(prepared: Prepared, nominal: ModelParams, verdict: Verdict,
            ranking: Sequence[Ranked], nom_hold, aug_hold, localization: dict,
            seen: dict[str, float], separating: dict | None, preds: dict) -> dict:
    win = verdict.winner
    effects = list(win.fit.effects) if win else []
    verdict_json = {
        "effect": win.fit.name if win else "none",
        "effects": effects,
        "subsystem": "+".join(dict.fromkeys(EFFECTS[e] for e in effects)) if win else "none",
        "params": (win.fit.values[effects[0]] if len(effects) == 1 else win.fit.values)
        if win else {},
        "confidence": verdict.confidence,
        "reason": verdict.reason,
        "ambiguous_with": verdict.runner_up.fit.name if verdict.ambiguous else None,
        "separating_experiment": separating,
    }
    invisible = sorted(e for e, v in seen.items() if v < VISIBLE)
    paper = {}
    for label in ("nominal", "augmented"):
        pos = position_error_pct(prepared, preds[label], "holdout")
        paper[label] = {"position_error_pct": pos}
        for band, vals in localization["frequency"].get("bands", {}).items():
            paper[label][f"gain_error_pct {band}"] = vals[label]["gain_error_pct"]
            paper[label][f"phase_error_deg {band}"] = vals[label]["phase_error_deg"]
    return {
        "schema": SCHEMA,
        "verdict": verdict_json,
        "gap": {"metric": METRIC, "nominal": nom_hold.gap, "augmented": aug_hold.gap,
                "shrinkage": 1.0 - aug_hold.gap / nom_hold.gap if nom_hold.gap > 0 else 0.0,
                "on": "holdout", "paper_metrics": paper},
        "localization": localization,
        "ranking": [r.to_json(nom_hold) for r in ranking],
        "visibility": {"at_typical_size": seen, "too_small_to_see": invisible,
                       "threshold": VISIBLE},
        "data": {"split": prepared.split_note, "notes": prepared.notes,
                 "sample_time_s": prepared.dt, "noise": prepared.noise,
                 "scale": prepared.scale,
                 "experiments": [{"name": r.name, "piston": r.entry.piston,
                                  "train_s": float(r.train.sum() * prepared.dt),
                                  "holdout_s": float(r.holdout.sum() * prepared.dt)}
                                 for r in prepared.records]},
        "nominal_effects": nominal.enabled_effects(),
    }


def _write_outputs(out_dir: Path, result: dict, augmented: ModelParams, prepared: Prepared,
                   preds: dict) -> None:
    from jetpipe_ros import fileio
    from jetpipe_ros.diagnosis.report import render

    header = ("# jetpipe diagnose: the nominal model plus the effect the diagnosis "
              f"identified ({result['verdict']['effect']}).\n")
    texts = {"diagnosis.json": fileio.to_json(result) + "\n",  # strict: NaN/inf as null
             "augmented.yaml": header + augmented.to_ros_yaml(only_changed=True),
             "report.html": render(result, prepared, preds)}
    fileio.write_files({out_dir / name: texts[name] for name in OUTPUTS})  # all or none
