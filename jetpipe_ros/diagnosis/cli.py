"""``jetpipe diagnose`` and ``jetpipe selfcheck`` sub-commands."""

from __future__ import annotations

import argparse


def _diagnose(args: argparse.Namespace) -> int:
    from jetpipe_ros.diagnosis.diagnose import diagnose
    from jetpipe_ros.model import ModelParams, load_params

    params = load_params(args.params) if args.params else ModelParams()
    result = diagnose(args.dataset, args.out, params, workers=args.jobs, quiet=args.quiet)
    v, g = result["verdict"], result["gap"]
    print(f"verdict: {v['effect']} (subsystem {v['subsystem']}, confidence "
          f"{v['confidence']:.2f})")
    print(f"held-out gap ({g['metric']}): nominal {g['nominal']:.2f} %, augmented "
          f"{g['augmented']:.2f} %, shrinkage {100 * g['shrinkage']:.0f} %")
    print(f"report: {args.out}/report.html  augmented model: {args.out}/augmented.yaml")
    return 0


def add_command(subparsers) -> None:
    """Register ``diagnose``."""
    p = subparsers.add_parser(
        "diagnose", help="find where the model departs from a dataset and which effect causes it",
        description="Fit every unmodelled effect on the training experiments of DATASET_DIR, "
                    "judge them on the held-out ones, and write diagnosis.json, report.html and "
                    "augmented.yaml to OUT_DIR.")
    p.add_argument("dataset", metavar="DATASET_DIR", help="dataset directory (dataset.yaml)")
    p.add_argument("--out", required=True, metavar="OUT_DIR", help="output directory")
    p.add_argument("--params", help="nominal model parameter YAML (default: DESIGN.md s.2)")
    p.add_argument("--jobs", type=int, default=2, help="parallel fitting processes (default 2)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=_diagnose)
