"""Replay a recorded or designed voltage sequence through the model (``jetpipe simulate``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from jetpipe_ros.dataset import Experiment, read_experiment, write_experiment
from jetpipe_ros.model import ModelParams, Trace, simulate


def replay(params: ModelParams, exp: Experiment, locked: bool = False) -> Trace:
    """Simulate ``exp``'s command (and load, if recorded) at the experiment's own sample time."""
    changes: dict[str, object] = {}
    if not math.isclose(exp.dt, params["integration.sample_time"], rel_tol=1e-6):
        params = params.at_sample_time(exp.dt)
    if locked:
        changes["mechanics.locked"] = True
    if changes:
        params = params.with_values(changes)
    f_load = exp.f_load if exp.f_load is not None else 0.0
    return simulate(params, exp.u, f_load)


def replay_csv(params: ModelParams, input_csv: str | Path, out_csv: str | Path,
               locked: bool = False) -> Trace:
    """Read ``input_csv`` (columns t, u; optional f_load), simulate, write ``out_csv``.

    The output has the dataset columns ``t,u,y,p1,p2`` (as the sensors would measure them) plus
    ``v``, ``f_load`` and ``friction``.
    """
    exp = read_experiment(input_csv, required=("t", "u"), any_of=())
    trace = replay(params, exp, locked)
    f_load = exp.f_load if exp.f_load is not None else np.zeros_like(exp.t)
    write_experiment(out_csv, {"t": exp.t, "u": trace.u, "y": trace.y_meas, "p1": trace.p1_meas,
                               "p2": trace.p2_meas, "v": trace.v, "f_load": f_load,
                               "friction": trace.friction})
    return trace


def _run(args) -> int:
    from jetpipe_ros.fileio import output_file
    from jetpipe_ros.model import load_params

    output_file(args.out, "--out")  # before the work: a writable file, not a directory
    params = load_params(args.params) if args.params else ModelParams()
    trace = replay_csv(params, args.input, args.out, locked=args.locked)
    effects = ", ".join(params.enabled_effects()) or "none"
    print(f"simulated {trace.t[-1]:.3f} s ({trace.t.size} samples, effects: {effects}) "
          f"-> {args.out}")
    return 0


def add_command(subparsers) -> None:
    """``jetpipe simulate``: replay a voltage sequence through the model."""
    sim = subparsers.add_parser(
        "simulate", help="replay a voltage sequence through the model",
        description="Replay the u column (and f_load, if present) of a CSV through the model; "
                    "write t,u,y,p1,p2,v,f_load,friction.")
    sim.add_argument("--params", help="parameter YAML (ROS params-file layout or plain); "
                                      "default: the nominal model")
    sim.add_argument("--input", required=True, help="CSV with columns t [s], u [V]")
    sim.add_argument("--out", required=True, help="output CSV")
    sim.add_argument("--locked", action="store_true",
                     help="clamp the piston (constant-volume test)")
    sim.set_defaults(func=_run)
