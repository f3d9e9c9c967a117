"""``jetpipe friction DIR --out OUT``: seal friction from friction-rig records or from the
actuator's own friction tests (a dataset).

The fits (every form on every seal: :func:`jetpipe_ros.identify.seal.fit_seal_form`; then the
selected form's seal fit without each record, :func:`jetpipe_ros.identify.seal.unseen_fit`) run
on ``--jobs`` processes, each finished one said on stderr with the time since the start. Every
output (``friction.yaml``, ``friction.json``, ``report.html``, ``prediction/*.csv``) is written
together at the end: all or, on an error, none.
"""

from __future__ import annotations

import multiprocessing
import re
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from threadpoolctl import threadpool_limits

from jetpipe_ros.arguments import positive_int
from jetpipe_ros.progress import Progress


def usable(seals: dict[str, list], split: float) -> tuple[dict[str, list], dict[str, str]]:
    """The training records of each seal that can be fitted and judged (seal -> records:
    :func:`jetpipe_ros.identify.seal.training`), and why each other seal cannot (seal ->
    the reason, naming the seal and its files). DatasetError when no seal can: one seal's
    records that cannot be fitted do not keep the others from being fitted."""
    from jetpipe_ros.dataset import DatasetError
    from jetpipe_ros.identify.seal import training

    trained, refused = {}, {}
    for seal, preps in seals.items():
        try:
            trained[seal] = training(seal, preps, split)
        except DatasetError as err:
            refused[seal] = str(err)
    if not trained:
        raise DatasetError("; ".join(refused.values()))
    return trained, refused


def _fit_all(trained: dict[str, list], jobs: int, progress: Progress) -> dict:
    """Every form fitted to every seal's training records ``trained`` (seal -> form ->
    :func:`fit_seal_form`'s result), on ``jobs`` processes, each fit's end said through
    ``progress``."""
    from jetpipe_ros.identify.seal import FORMS

    tasks = [(seal, form, trained[seal]) for seal in trained for form in FORMS]
    progress(f"fitting {len(FORMS)} forms to {len(trained)} seal(s) "
             f"({sum(map(len, trained.values()))} training records): {len(tasks)} fits on "
             f"{min(jobs, len(tasks))} process(es)")
    fitted: dict[str, dict] = {seal: {} for seal in trained}
    for done, (seal, form, result) in enumerate(_pooled(_fit_task, tasks, jobs), 1):
        fitted[seal][form] = result
        progress(f"[{done}/{len(tasks)}] {f'seal {seal}: ' if seal else ''}{form} fitted")
    return fitted


def _unseen_all(results: list, trained: dict[str, list], fitted: dict, jobs: int,
                progress: Progress) -> list[str]:
    """For each seal with two training records or more, its selected form's fit without each
    of them (:func:`~jetpipe_ros.identify.seal.unseen_fit`), on ``jobs`` processes, and the
    record judged with it (:meth:`~jetpipe_ros.identify.seal.SealResult.judge_unseen`). Returns
    what could not be fitted, in words: optional, so such a record is left unjudged (its
    ``unseen`` null) and the command goes on."""
    tasks = [(res.seal, res.selected, trained[res.seal], fitted[res.seal][res.selected][0],
              p.record.name) for res in results if len(trained[res.seal]) > 1
             for p in trained[res.seal]]
    if not tasks:
        return []
    progress(f"each record judged by its seal's fit made without it (the selected form): "
             f"{len(tasks)} fits on {min(jobs, len(tasks))} process(es)")
    fits: dict[str, dict] = {res.seal: {} for res in results}
    failed = []
    for done, (seal, name, fit) in enumerate(_pooled(_unseen_task, tasks, jobs), 1):
        if isinstance(fit, str):
            failed.append(f"{f'seal {seal}: ' if seal else ''}{name} not judged by the seal's "
                          f"fit without it: {fit}")
        else:
            fits[seal][name] = fit
        progress(f"[{done}/{len(tasks)}] {f'seal {seal}: ' if seal else ''}without {name} "
                 f"{'not fitted' if isinstance(fit, str) else 'fitted'}")
    for res in results:
        res.judge_unseen(fits[res.seal])
    return failed


def _pooled(function, work: list[tuple], jobs: int) -> Iterator[tuple]:
    """``function``'s result on each item of ``work`` as it ends: in this process with one
    job, else on a pool of ``jobs`` processes (:func:`_worker`). An error in a task is raised
    here; then, as on Ctrl-C, the pool's processes are terminated at once, the tasks running
    in them dropped."""
    if jobs == 1:
        yield from map(function, work)
        return
    with multiprocessing.get_context("spawn").Pool(min(jobs, len(work)), _worker) as pool:
        yield from pool.imap_unordered(function, work)


def _worker() -> None:
    """Set up a fitting process: spawned (a forked one would inherit numba's and BLAS's
    threads), held to one BLAS thread as the command is (more would oversubscribe the cores),
    and deaf to Ctrl-C, which the command answers by terminating the pool."""
    threadpool_limits(1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _fit_task(task: tuple[str, str, list]) -> tuple[str, str, tuple]:
    """One fit, in a pool process or this one: (seal, form, :func:`fit_seal_form`'s result)."""
    from jetpipe_ros.identify.seal import fit_seal_form

    seal, form, trained = task
    return seal, form, fit_seal_form(seal, form, trained)


def _unseen_task(task: tuple[str, str, list, dict, str]) -> tuple[str, str, Any]:
    """One seal's fit without one record, in a pool process or this one: (seal, the record's
    name, :func:`~jetpipe_ros.identify.seal.unseen_fit`, or why it failed)."""
    from jetpipe_ros.dataset import DatasetError
    from jetpipe_ros.identify.seal import unseen_fit

    seal, form, trained, own, name = task
    try:
        return seal, name, unseen_fit(seal, form, trained, own, name)
    except DatasetError as err:
        return seal, name, str(err)


def _seal_file(seal: str, taken: dict) -> str:
    """``friction-<seal>.yaml``, the seal's name made a file name (a character other than a
    letter, digit, ``.``, ``-`` or ``_`` becomes ``_``), numbered if that name is taken."""
    stem = "friction-" + (re.sub(r"[^\w.-]+", "_", seal) or "seal")
    names = {Path(path).name for path in taken}
    name, k = f"{stem}.yaml", 1
    while name in names:
        k += 1
        name = f"{stem}-{k}.yaml"
    return name


def _run(args) -> int:
    from jetpipe_ros import fileio
    from jetpipe_ros.dataset import DatasetError, grouped_notes, read_dataset, read_records
    from jetpipe_ros.identify.drift import describe, level_drift
    from jetpipe_ros.identify.experiments import FRICTION, of_kind, recordings
    from jetpipe_ros.identify.seal import identify_seal, prepare, prepare_test
    from jetpipe_ros.identify.seal_report import (describe_unseen, html_report, params_yaml,
                                                  piston_scale, prediction_csv, to_json)
    from jetpipe_ros.model import ModelParams, load_params

    progress = Progress(args.quiet)
    out = fileio.output_dir(args.out, "--out")
    if not 0.05 <= args.split <= 0.95:
        raise DatasetError(f"--split: {args.split:g} must lie in [0.05, 0.95]")
    base = load_params(args.params) if args.params else ModelParams()
    root = Path(args.dir)
    seals: dict[str, list] = {}
    if not (root / "records.yaml").is_file() and (root / "dataset.yaml").is_file():
        tests = of_kind(recordings(read_dataset(root)), FRICTION)
        if not tests:
            raise DatasetError(f"{root / 'dataset.yaml'}: no friction test (a free piston "
                               f"with 'regulated: true', released from its end stop: "
                               f"docs/friction.md)")
        seals[root.name] = [prepare_test(rec, base, args.split) for rec in tests]
        notes = [f"{root.name}: {len(tests)} friction tests of the actuator's own dataset, "
                 f"friction from Newton's law (Eq. 19) with the piston area and mass of "
                 f"{args.params or 'the nominal model'}"]
    else:
        records = read_records(root)
        for rec in records:
            seals.setdefault(rec.seal, []).append(prepare(rec, args.split))
        notes = [n for rec in records for n in rec.notes]
    for note in grouped_notes(notes):
        print(f"read: {note}", flush=True)
    trained, refused = usable(seals, args.split)
    fitted = _fit_all(trained, args.jobs, progress)
    results = [identify_seal(seal, seals[seal], args.split, fitted[seal]) for seal in trained]
    unjudged = _unseen_all(results, trained, fitted, args.jobs, progress)
    notes += unjudged
    drifts = {p.record.name: level_drift(p) for res in results for p in res.preps}
    doc = to_json(results, args.split, notes, drifts, refused)
    files: dict = {out / "friction.yaml": params_yaml(results[0], base, args.scale_to_piston),
                   out / "friction.json": fileio.to_json(doc) + "\n",
                   out / "report.html": html_report(results, doc, drifts)}
    if len(results) > 1:
        for res in results:
            files[out / _seal_file(res.seal, files)] = params_yaml(res, base,
                                                                   args.scale_to_piston)
    for res in results:
        for prep in res.preps:
            files[out / "prediction" / f"{prep.record.name}.csv"] = prediction_csv(res, prep)
    fileio.write_files(files)
    for form, s in doc["summary"].items():
        print(f"{form:16s} held-out median NRMSE {s['median_nrmse'] * 100:5.2f} %  "
              f"R^2 within direction {s['median_r2_within']:5.2f}")
    for reason in refused.values():
        print(f"not fitted: {reason}")
    for words in unjudged:
        print(words)
    for res in results:
        for warning in res.warnings(args.split):
            print(f"seal {res.seal or '(unnamed)'}: {warning}")
        print(f"seal {res.seal or '(unnamed)'}: selected {res.selected}")
        unseen = describe_unseen(res)
        if unseen:
            print(f"seal {res.seal or '(unnamed)'}: {unseen}")
        drift = describe({p.record.name: drifts[p.record.name] for p in res.preps})
        if drift:
            print(f"seal {res.seal or '(unnamed)'}: {drift}")
        if args.scale_to_piston:
            print(f"seal {res.seal or '(unnamed)'}: {piston_scale(res, base)[1]}")
    print(f"parameters -> {out / 'friction.yaml'}\nscores -> {out / 'friction.json'}\n"
          f"report -> {out / 'report.html'}")
    return 0


def add_command(subparsers) -> None:
    """``jetpipe friction``: fit and select seal friction models on friction-rig records."""
    cmd = subparsers.add_parser(
        "friction", help="seal friction from friction-rig records (t,x,p,F) or the "
                         "actuator's own friction tests",
        description="Fit the model's friction forms (Coulomb + viscous, the static planes, "
                    "LuGre, Maxwell-slip) to friction-rig records (records.yaml + CSVs "
                    "t,x,p,F), or to the friction tests of an actuator's dataset (Eq. 19), "
                    "on the first part of each record, judge them on the rest, select "
                    "the best by held-out NRMSE, judge each record by its seal's fit made "
                    "without it, measure how each record's sliding level "
                    "drifts over time, and write OUT/friction.yaml (loadable by "
                    "jetpipe simulate and actuator_sim), OUT/friction.json, OUT/report.html "
                    "and OUT/prediction/<record>.csv.")
    cmd.add_argument("dir", help="friction-rig folder (records.yaml + CSVs), or a dataset of "
                                 "the actuator with friction tests (dataset.yaml; "
                                 "docs/friction.md)")
    cmd.add_argument("--out", required=True, help="output directory")
    cmd.add_argument("--params", help="parameters the fitted friction is written into (YAML); "
                                      "default: the nominal model")
    cmd.add_argument("--scale-to-piston", action="store_true",
                     help="scale the seal's forces in friction.yaml from the rig's bore to the "
                          "piston of --params (the nominal model's: 83.2 mm) by the ratio of "
                          "their circumferences; default: as measured")
    cmd.add_argument("--split", type=float, default=0.5,
                     help="fraction of each record fitted; the rest is judged (default 0.5)")
    cmd.add_argument("--jobs", type=positive_int, default=2,
                     help="processes the fits run on (default 2; 1: in this process)")
    cmd.add_argument("--quiet", action="store_true", help="no progress lines")
    cmd.set_defaults(func=_run)
