"""``jetpipe diagnose`` and ``jetpipe selfcheck`` sub-commands."""

from __future__ import annotations

import argparse

from jetpipe_ros.arguments import positive_int


def _diagnose(args: argparse.Namespace) -> int:
    from jetpipe_ros.diagnosis.diagnose import diagnose
    from jetpipe_ros.fileio import output_dir
    from jetpipe_ros.model import ModelParams, load_params

    output_dir(args.out, "--out")  # before the work
    params = load_params(args.params) if args.params else ModelParams()
    result = diagnose(args.dataset, args.out, params, workers=args.jobs, quiet=args.quiet)
    v, g = result["verdict"], result["gap"]
    print(f"verdict: {v['effect']} (subsystem {v['subsystem']}, confidence "
          f"{v['confidence']:.2f})")
    print(f"held-out gap ({g['metric']}): nominal {g['nominal']:.2f} %, augmented "
          f"{g['augmented']:.2f} %, shrinkage {100 * g['shrinkage']:.0f} %")
    print(f"report: {args.out}/report.html  augmented model: {args.out}/augmented.yaml")
    return 0


def campaign_dataset(params, root, seed: int) -> None:
    """The default campaign (config/campaign.yaml) simulated offline with ``params``."""
    from jetpipe_ros.campaign import default_campaign, run_campaign_offline

    run_campaign_offline(params, default_campaign(), root, seed=seed % 100000)


def _selfcheck(args: argparse.Namespace) -> int:
    from pathlib import Path

    from jetpipe_ros.diagnosis.selfcheck import run_selfcheck
    from jetpipe_ros.fileio import output_dir

    output_dir(args.out, "--out")  # before the work
    summary = run_selfcheck(args.cases, args.seed, out_dir=Path(args.out), workers=args.jobs,
                            deviate=args.deviations, source=args.truth)
    print(f"\n{summary['cases']} cases in {summary['seconds']:.0f} s: top-1 accuracy "
          f"{100 * summary['top1_accuracy']:.0f} %, none correct: "
          f"{'yes' if summary['none_correct'] else 'no'}, median held-out shrinkage "
          f"{100 * (summary['median_shrinkage'] or 0):.0f} %")
    print(f"confusion matrix and parameter recovery: {args.out}/selfcheck.md")
    return 0


def add_command(subparsers) -> None:
    """Register ``diagnose`` and ``selfcheck``."""
    p = subparsers.add_parser(
        "diagnose", help="find where the model departs from a dataset and which effect causes it",
        description="Fit every unmodelled effect on the training experiments of DATASET_DIR, "
                    "judge them on the held-out ones, and write diagnosis.json, report.html and "
                    "augmented.yaml to OUT_DIR.")
    p.add_argument("dataset", metavar="DATASET_DIR", help="dataset directory (dataset.yaml)")
    p.add_argument("--out", required=True, metavar="OUT_DIR", help="output directory")
    p.add_argument("--params", help="nominal model parameter YAML (default: DESIGN.md s.2)")
    p.add_argument("--jobs", type=positive_int, default=2,
                   help="parallel fitting processes (default 2)")
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
                   help="parallel fitting processes (default 2)")
    c.add_argument("--truth", choices=("plant", "model"), default="plant",
                   help="where the data come from: the plant written apart from the candidates "
                        "(default), or the simulator's own effects")
    c.add_argument("--deviations", action=argparse.BooleanOptionalAction, default=True,
                   help="move the nominal parameters of every case as an individual actuator "
                        "and bench would (default on; --no-deviations: the nominal model)")
    c.set_defaults(func=_selfcheck)
