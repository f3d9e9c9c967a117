"""``jetpipe diagnose`` and ``jetpipe selfcheck`` sub-commands."""

from __future__ import annotations

import argparse

from jetpipe_ros.arguments import positive_int


def _diagnose(args: argparse.Namespace) -> int:
    from jetpipe_ros.workflows.fleet import dataset_dirs
    from jetpipe_ros.fileio import output_dir
    from jetpipe_ros.model import ModelParams, load_params

    output_dir(args.out, "--out")  # before the work
    params = load_params(args.params) if args.params else ModelParams()
    dirs, is_fleet = dataset_dirs(args.dataset)
    if is_fleet:
        return _fleet(args, dirs, params)
    from jetpipe_ros.workflows.diagnose import diagnose

    result = diagnose(dirs[0], args.out, params, workers=args.jobs, quiet=args.quiet,
                      scheduler=args.scheduler)
    print("\n".join(summary_lines(result, args.out)))
    return 0


def summary_lines(result: dict, out: str) -> list[str]:
    """The last lines ``jetpipe diagnose`` prints of a diagnosis (``result``: diagnosis.json's
    content; ``out``: its folder): the signs when they were not the contract's, the time
    base, the verdict, what a ``none`` cannot rule out and which pressure sensor would tell it
    (not when the model does not describe the hardware: then no effect is in question), how
    small an effect its records would show, what the records cannot judge, the held-out gap
    and where the files are."""
    from jetpipe_ros.diagnosis.collinearity import ADDED, imitated_effects, telling
    from jetpipe_ros.diagnosis.detection import limit_words

    v, g = result["verdict"], result["gap"]
    signs = result["data"].get("signs")
    lines = [f"signs: {signs['explanation']}"] if signs and signs["against_as_logged"] else []
    lines.append(f"time base: {result['data']['time_base']['explanation']}")
    if not v["model_fits"]:
        lines += [v["reason"],  # it begins: the model does not describe this hardware
                  "verdict: no effect named (model_fits: false)"]
    else:
        lines.append(f"verdict: {v['effect']} (subsystem {v['subsystem']}, confidence "
                     f"{v['confidence']:.2f})")
    hidden = imitated_effects(result["visibility"].get("imitated_by_recalibration", {}))
    favoured = {row["effect"]: row for row in result["visibility"].get(
        "favoured_by_all_records", []) if row["favoured"]}
    for effect in result["visibility"].get("not_ruled_out", []) if v["model_fits"] else []:
        if effect in favoured and effect not in hidden:
            lines.append(f"cannot rule out {effect}: the records as a whole favour it, the "
                         f"held-out ones cannot confirm it; a training record like "
                         f"'{favoured[effect]['decisive_record']}' would decide it")
            continue
        added = hidden.get(effect, {}).get("with_sensors", {})
        sensors = " or ".join(ADDED[k] for k in telling(added))
        tell = (f"; {sensors} pressure{'s' if sensors == 'both' else ''} would tell" if sensors
                else "; not even the pressures these records lack would tell" if added else "")
        lines.append(f"cannot rule out {effect}: the recalibration imitates it{tell}")
    lines += limit_words(result["visibility"].get("smallest_shown", {}))
    for effect, why in result["data"].get("cannot_judge", {}).items():
        lines.append(f"not judged: {effect} ({why})")
    lines += [f"held-out gap ({g['metric']}): nominal {g['nominal']:.2f} %, augmented "
              f"{g['augmented']:.2f} %, shrinkage {100 * g['shrinkage']:.0f} %",
              f"report: {out}/report.html  augmented model: {out}/augmented.yaml"]
    return lines


def _fleet(args: argparse.Namespace, dirs, params) -> int:
    import sys

    from jetpipe_ros.workflows.fleet import run_fleet

    progress = (lambda line: None) if args.quiet else (
        lambda line: print(line, file=sys.stderr, flush=True))
    fleet = run_fleet(dirs, args.out, params, workers=args.jobs, scheduler=args.scheduler,
                      progress=progress)
    print(f"{fleet['datasets']} datasets: {fleet['succeeded']} diagnosed, {fleet['failed']} "
          f"failed")
    for r in fleet["actuators"]:
        if r["status"] == "ok":
            print(f"  {r['name']}: {r['verdict']['effect']} (confidence "
                  f"{r['verdict']['confidence']:.2f}), held-out gap {r['gap']['nominal']:.2f} "
                  f"-> {r['gap']['augmented']:.2f} %")
        else:
            print(f"  {r['name']}: failed: {r['error']}")
    print(f"fleet: {args.out}/fleet.html  {args.out}/fleet.json  (one folder per dataset)")
    return 0 if fleet["failed"] == 0 else 1


def _selfcheck(args: argparse.Namespace) -> int:
    from pathlib import Path

    from jetpipe_ros.workflows.selfcheck import Logged, run_selfcheck
    from jetpipe_ros.fileio import output_dir

    output_dir(args.out, "--out")  # before the work
    logged = Logged(None if args.logger == "none" else args.logger, args.rate)
    summary = run_selfcheck(args.cases, args.seed, logged, out_dir=Path(args.out),
                            workers=args.jobs,
                            deviate=args.deviations, source=args.truth,
                            scheduler=args.scheduler, restart=args.restart,
                            shape=args.flow_map_shape, kinds=args.kinds,
                            flow_table=args.flow_table,
                            progress=lambda line: print(line, flush=True))  # also into a file
    lo, hi = summary["top1_interval"]
    print(f"\n{summary['cases']} cases in {summary['seconds']:.0f} s: top-1 accuracy "
          f"{100 * summary['top1_accuracy']:.0f} % ({100 * lo:.0f}-{100 * hi:.0f} %, "
          f"{100 * summary['confidence_level']:.0f} % Wilson interval), none correct: "
          f"{'yes' if summary['none_correct'] else 'no'}, median held-out shrinkage "
          f"{100 * (summary['median_shrinkage'] or 0):.0f} %")
    print(f"accuracy per effect, confusion matrix, shrinkage, parameter recovery: "
          f"{args.out}/selfcheck.md")
    return 0


def add_command(subparsers) -> None:
    """Register ``diagnose`` and ``selfcheck``."""
    from jetpipe_ros.plant.logger import LOGGERS
    p = subparsers.add_parser(
        "diagnose", help="find where the model departs from a dataset and which effect causes it",
        description="Fit every unmodelled effect on the training experiments of DATASET_DIR, "
                    "judge them on the held-out ones, and write diagnosis.json, report.html and "
                    "augmented.yaml to OUT_DIR (to OUT_DIR/<dataset name>/ for several "
                    "datasets, with fleet.json and fleet.html).")
    p.add_argument("dataset", metavar="DATASET_DIR", nargs="+",
                   help="dataset directory (dataset.yaml); several, or a quoted glob, diagnose "
                        "a fleet: one folder of outputs each in OUT_DIR, plus fleet.json and "
                        "fleet.html (exit status 1 if any dataset failed)")
    p.add_argument("--out", required=True, metavar="OUT_DIR", help="output directory")
    p.add_argument("--params", help="nominal model parameter YAML (default: the paper's "
                   "model, docs/model.md)")
    p.add_argument("--jobs", type=positive_int, default=2,
                   help="worker processes of the local Dask cluster (default 2; 1: in this "
                        "process); ignored with --scheduler")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler to run on, e.g. tcp://host:8786 (default: the "
                        "DASK_SCHEDULER_ADDRESS environment variable, else a local cluster)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=_diagnose)
    c = subparsers.add_parser(
        "selfcheck", help="judge the diagnosis on simulated data whose effect is withheld",
        description="Simulate the default campaign with one effect (or two, or none, or an "
                    "effect in a form no candidate has) at a random realistic size, diagnose "
                    "each dataset blind, and print the confusion matrix, parameter recovery "
                    "and held-out shrinkage.")
    c.add_argument("--cases", type=positive_int, default=30, help="number of cases (default 30)")
    c.add_argument("--seed", type=int, default=0, help="seed of sizes and noise (default 0)")
    c.add_argument("--out", default="out/selfcheck", help="where selfcheck.md/json go")
    c.add_argument("--jobs", type=positive_int, default=2,
                   help="worker processes of the local Dask cluster, one case each at a time "
                        "(default 2; 1: in this process); ignored with --scheduler")
    c.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler to run the cases on, e.g. tcp://host:8786 (default: "
                        "the DASK_SCHEDULER_ADDRESS environment variable, else a local "
                        "cluster)")
    c.add_argument("--kinds", type=lambda text: [k for k in text.split(",") if k], default=[],
                   metavar="KIND[,KIND...]",
                   help="run and score only the cases of these kinds among the --cases (e.g. "
                        "flow_lag,parameters_only; the same cases as in the whole run, which "
                        "then resumes them); an unknown kind is refused with the kinds there are")
    c.add_argument("--restart", action="store_true",
                   help="discard the cases an earlier run left in OUT (by default a run with "
                        "the same --cases, --seed, --truth, --deviations resumes them, and "
                        "another configuration is refused)")
    c.add_argument("--truth", choices=("plant", "model"), default="plant",
                   help="where the data come from: the plant written apart from the candidates "
                        "(default), or the simulator's own effects")
    c.add_argument("--logger", choices=("none", *LOGGERS), default="none",
                   help="rewrite each record as another data logger would (a row off, 1 %% of "
                        "rows lost with jittered stamps, gauge bar and mm declared, one or no "
                        "pressure sensor, a position counted the other way, the pressures "
                        "crossed, or 'bench': a row off, lost rows, jitter, gauge bar and mm "
                        "and a spreadsheet's export with its own column names at once; "
                        "default: none, the package's own convention)")
    c.add_argument("--rate", type=float, default=1000.0,
                   help="sample rate of the records [Hz] (default 1000)")
    c.add_argument("--deviations", action=argparse.BooleanOptionalAction, default=True,
                   help="move the nominal parameters of every case as an individual actuator "
                        "and bench would (default on; --no-deviations: the nominal model)")
    c.add_argument("--flow-map-shape", action="store_true",
                   help="give every plant bench a flow map departing from Eq. 8 within the "
                        "paper's fit error (0.2-0.5 g/s, smooth, nulls kept): the diagnosis's "
                        "known limit (docs/selfcheck.md); off by default")
    c.add_argument("--flow-table", action="store_true",
                   help="diagnose each case against the flow map's correction table identified "
                        "on its own constant-volume tests (jetpipe identify --procedures "
                        "flow_table), as a user whose valve departs from Eq. 8 would; off by "
                        "default")
    c.set_defaults(func=_selfcheck)
