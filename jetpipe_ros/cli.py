"""The ``jetpipe`` command line: offline tools that need no ROS."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.model import ModelParams, ParameterError, load_params


def _cmd_simulate(args: argparse.Namespace) -> int:
    from jetpipe_ros.replay import replay_csv

    params = load_params(args.params) if args.params else ModelParams()
    trace = replay_csv(params, args.input, args.out, locked=args.locked)
    effects = ", ".join(params.enabled_effects()) or "none"
    print(f"simulated {trace.t[-1]:.3f} s ({trace.t.size} samples, effects: {effects}) "
          f"-> {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one sub-command per tool."""
    parser = argparse.ArgumentParser(
        prog="jetpipe", description="Jet-pipe servo actuator: simulation and sim-to-real tools.")
    sub = parser.add_subparsers(dest="command", required=True)
    sim = sub.add_parser("simulate", help="replay a voltage sequence through the model",
                         description="Replay the u column (and f_load, if present) of a CSV "
                                     "through the model; write t,u,y,p1,p2,v,f_load,friction.")
    sim.add_argument("--params", help="parameter YAML (ROS params-file layout or plain); "
                                      "default: the nominal model")
    sim.add_argument("--input", required=True, help="CSV with columns t [s], u [V]")
    sim.add_argument("--out", required=True, help="output CSV")
    sim.add_argument("--locked", action="store_true",
                     help="clamp the piston (constant-volume test)")
    sim.set_defaults(func=_cmd_simulate)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``jetpipe``; returns the process exit status."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ParameterError, DatasetError) as exc:
        print(f"jetpipe {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
