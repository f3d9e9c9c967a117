"""Offline simulation speed: real-time factor, per-sample step cost, one diagnosis evaluation.

Times the first compile of the kernel from an empty numba cache (what a fresh install pays once:
a node's step, then a replay with a load per sample),
the batch simulator on a 60 s rich command (real-time factor = simulated time / time taken),
``Actuator.step`` (the node's path), and one evaluation of a diagnosis fit's objective:
``predict_all`` over the training experiments of the default campaign's dataset (simulated with
sensor noise), with where its time goes (the kernel, the parameters compiled for it, the rest of
the prediction in Python), and the same with the valve hysteresis on (each record then predicted
from each start its plays may have). Times are the thread's CPU time (``time.thread_time``),
which on a shared machine leaves out the time other processes hold the core and on an idle core
equals wall time. Medians of repeats in one run, single core; compare rows, not machines.
``--baseline REV`` also runs the same measurements on the package as it was at git revision REV
(extracted into a temporary directory, same dataset), each in a fresh single-threaded subprocess,
so before and after come from one run on one machine; ``--rounds N`` alternates the two N times and
reports the medians over the rounds, so a machine whose speed drifts during the run (a shared host)
does not favour whichever was measured second. Prints markdown tables.
Usage: .venv/bin/python bench/bench_sim.py [--seconds 60] [--repeats 5] [--baseline REV]
[--rounds 3]
"""

from __future__ import annotations

import argparse
import io
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
RTF_ROWS = [("nominal, 4 sub-steps (default)", {}),
            ("nominal, 8 sub-steps", {"integration.substeps": 8}),
            ("LuGre + lag + hysteresis + noise",
             {"effects.friction_dynamics.enabled": True, "effects.valve_lag.enabled": True,
              "effects.valve_hysteresis.enabled": True, "sensors.noise": True}),
            ("nominal with a flow-map correction table", {"flow.table": [0.1] * 130}),
            ("valve delay, hose form",
             {"effects.valve_delay.enabled": True, "effects.valve_delay.form": "hose"}),
            ("valve lag, port form",
             {"effects.valve_lag.enabled": True, "effects.valve_lag.form": "port"})]
PARTS = {"kernel": "kernel.advance (the compiled integration)",
         "constants": "build_constants (valve discretisation included)",
         "actuator": "the rest of Actuator(...) (random generator, state)",
         "params": "ModelParams.with_values (one per experiment)",
         "rest": "the rest of predict: drive arrays, Actuator.run's checks, copies"}


def rich_command(seconds: float, dt: float = 1e-3) -> np.ndarray:
    """Square waves, a sine sweep and random steps: every regime of the actuator [V]."""
    t = np.arange(0, seconds, dt)
    rng = np.random.default_rng(0)
    sweep = 0.3 * np.sin(2 * np.pi * (1.6 + 68.4 * (t % 10) / 20) * (t % 10))
    steps = np.repeat(rng.uniform(-2, 2, t.size // 500 + 1), 500)[: t.size]
    return np.where((t // 10) % 2 == 0, sweep + 0.6 * np.sign(np.sin(2 * np.pi * 0.1122 * t)),
                    steps)


def make_dataset(root: Path) -> None:
    """The default campaign simulated with sensor noise (what ``jetpipe selfcheck`` diagnoses)."""
    from jetpipe_ros.campaign import campaign_dataset
    from jetpipe_ros.model import ModelParams

    campaign_dataset(ModelParams().with_values({"sensors.noise": True}), root, seed=1)


def measure(seconds: float, repeats: int, dataset: Path) -> dict:
    """All figures of the installed package (whatever ``jetpipe_ros`` imports as)."""
    import jetpipe_ros
    from jetpipe_ros.model import Actuator, ModelParams
    from jetpipe_ros.model.actuator import compile_kernel

    u = rich_command(seconds)
    # NUMBA_CACHE_DIR is empty: what a fresh install pays once, for a node's step and for a
    # replay with a load per sample (what identification and the diagnosis run)
    start = time.perf_counter()
    compile_kernel()
    Actuator(ModelParams()).run(u[:10], np.zeros(10))
    cold = time.perf_counter() - start
    rtf = {}
    for label, changes in RTF_ROWS:
        try:
            act = Actuator(ModelParams(changes))
        except ValueError:  # a baseline without these parameters
            rtf[label] = None
            continue
        act.run(u[:10])  # compile outside the timing
        times = []
        for _ in range(repeats):
            act.reset()
            start = time.thread_time()
            act.run(u)
            times.append(time.thread_time() - start)
        rtf[label] = statistics.median(times)
    act = Actuator(ModelParams())
    act.step(0.0)
    per_step = []
    for _ in range(repeats):
        start = time.thread_time()
        for k in range(20_000):
            act.step(u[k % u.size])
        per_step.append((time.thread_time() - start) / 20_000)
    return {"package": jetpipe_ros.__file__, "seconds": seconds, "cold_compile": cold,
            "rtf_time": rtf,
            "step": statistics.median(per_step), **evaluation(dataset, 3 * repeats)}


def evaluation(dataset: Path, repeats: int) -> dict:
    """CPU time of one ``predict_all`` on the training experiments, and its parts [s].

    The parts are timed by wrapping the functions in this process only.
    """
    import jetpipe_ros.model.actuator as actuator
    from jetpipe_ros.dataset import read_dataset
    from jetpipe_ros.diagnosis.data import prepare
    from jetpipe_ros.diagnosis.score import predict_all
    from jetpipe_ros.model import ModelParams, kernel

    prepared = prepare(read_dataset(dataset))
    spent = dict.fromkeys(("kernel", "constants", "setup", "params"), 0.0)

    def timed(part, func):
        def wrapper(*args, **kwargs):
            start = time.thread_time()
            try:
                return func(*args, **kwargs)
            finally:
                spent[part] += time.thread_time() - start
        return wrapper

    kernel.advance = timed("kernel", kernel.advance)
    actuator.build_constants = timed("constants", actuator.build_constants)
    actuator.Actuator.__init__ = timed("setup", actuator.Actuator.__init__)
    ModelParams.with_values = timed("params", ModelParams.with_values)
    params = ModelParams()
    predict_all(params, prepared, "train")  # compile and fill caches outside the timing
    # With the valve hysteresis on, each record is predicted from each start its plays may
    # have (diagnosis.prediction.PLAY_STARTS, since 2026-12-05): what a fit of it pays.
    hysteresis = params.with_effect("valve_hysteresis", half_width=0.25, elements=8, spread=1.0)
    predict_all(hysteresis, prepared, "train")
    hysteresis_times = []
    for _ in range(repeats):
        start = time.thread_time()
        predict_all(hysteresis, prepared, "train")
        hysteresis_times.append(time.thread_time() - start)
    rows = []
    for _ in range(repeats):
        spent.update(dict.fromkeys(spent, 0.0))
        start = time.thread_time()
        predict_all(params, prepared, "train")
        total = time.thread_time() - start
        rows.append({"kernel": spent["kernel"], "constants": spent["constants"],
                     "actuator": spent["setup"] - spent["constants"], "params": spent["params"],
                     "rest": total - spent["kernel"] - spent["setup"] - spent["params"],
                     "total": total})
    train = [r for r in prepared.records if r.train.any()]
    return {"experiments": len(train), "train_seconds": sum(r.t.size for r in train) * prepared.dt,
            "evaluation": {key: statistics.median(r[key] for r in rows) for key in rows[0]},
            "evaluation_hysteresis": statistics.median(hysteresis_times)}


def in_subprocess(package_root: Path, args: argparse.Namespace, dataset: Path) -> dict:
    """:func:`measure` on the package under ``package_root``, in a fresh single-threaded
    subprocess: before and after alike, so neither inherits the other's process state (the
    dataset's objects for the garbage collector, BLAS threads still spinning, numba's cache:
    each starts from an empty one, so the first compile is timed cold)."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "PYTHONPATH": str(package_root), "OPENBLAS_NUM_THREADS": "1",
               "OMP_NUM_THREADS": "1", "NUMBA_CACHE_DIR": cache}
        out = subprocess.run([sys.executable, __file__, "--json", "--seconds",
                              str(args.seconds), "--repeats", str(args.repeats), "--dataset",
                              str(dataset)], check=True, capture_output=True, text=True,
                             env=env).stdout
    figures = json.loads(out)
    if not figures["package"].startswith(str(package_root)):
        raise RuntimeError(f"imported {figures['package']}, not the one in {package_root}")
    return figures


def baseline(rev: str, args: argparse.Namespace, dataset: Path) -> dict:
    """:func:`measure` on the package at git revision ``rev``, in a subprocess."""
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", rev, "jetpipe_ros"],
                                 check=True, capture_output=True).stdout
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(tmp, filter="data")
        return in_subprocess(Path(tmp), args, dataset)


def median_figures(runs: list[dict]) -> dict:
    """The median, key by key, of the figures of several rounds (numbers and nested dicts)."""
    first = runs[0]
    if isinstance(first, dict):
        return {key: median_figures([r[key] for r in runs]) for key in first}
    if isinstance(first, (int, float)) and not isinstance(first, bool):
        return statistics.median(runs)
    return first


def table(now: dict, before: dict | None, rev: str | None) -> str:
    """Markdown tables of the figures, with the baseline's and the speed-up when given."""
    runs = [before, now] if before else [now]
    head = f"| before ({rev}) | after | speed-up |" if before else "| value |"
    rule = "|---|---|---|---|" if before else "|---|---|"

    def row(label, value, unit_format, higher_is_better=False):
        values = [value(f) for f in runs]
        cells = [unit_format(v) if v is not None else "n/a" for v in values]
        if before and None in values:
            cells.append("n/a")
        elif before:
            ratio = values[1] / values[0] if higher_is_better else values[0] / values[1]
            cells.append(f"{ratio:.2f} x")
        return f"| {label} | {' | '.join(cells)} |"

    lines = [f"| offline simulation, {now['seconds']:.0f} s rich command, single core {head}",
             rule]
    for label, _ in RTF_ROWS:
        lines.append(row(f"real-time factor, {label}",
                         lambda f, label=label: (f["seconds"] / f["rtf_time"][label]
                                                 if f["rtf_time"].get(label) else None),
                         lambda x: f"{x:,.0f}", higher_is_better=True))
    lines.append(row("`Actuator.step` (node path), per sample", lambda f: f["step"] * 1e6,
                     lambda x: f"{x:.1f} us"))
    lines.append(row("first compile: a step, then a run with a load per sample, empty numba "
                     "cache (wall)",
                     lambda f: f.get("cold_compile"), lambda x: f"{x:.1f} s"))
    lines += ["", f"| one diagnosis evaluation: `predict_all` on the {now['experiments']} "
                  f"training experiments ({now['train_seconds']:.1f} s at 1 kHz) {head}", rule,
              row("CPU time (median)", lambda f: f["evaluation"]["total"] * 1e3,
                  lambda x: f"{x:.1f} ms")]
    for key, label in PARTS.items():
        cells = [f"{f['evaluation'][key] * 1e3:.1f} ms "
                 f"({100 * f['evaluation'][key] / f['evaluation']['total']:.0f} %)" for f in runs]
        lines.append(f"| of which {label} | {' | '.join(cells)} |" + (" |" if before else ""))
    lines.append(row("CPU time with the valve hysteresis on (8 plays; median)",
                     lambda f: f["evaluation_hysteresis"] * 1e3, lambda x: f"{x:.1f} ms"))
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--baseline", metavar="REV",
                        help="git revision to measure too, e.g. the merge base of this branch")
    parser.add_argument("--rounds", type=int, default=1,
                        help="alternate baseline and current this many times (medians)")
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--dataset", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.json:
        print(json.dumps(measure(args.seconds, args.repeats, args.dataset)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        dataset = Path(tmp) / "data"
        make_dataset(dataset)
        befores, nows = [], []
        for _ in range(max(args.rounds, 1)):
            if args.baseline:
                befores.append(baseline(args.baseline, args, dataset))
            nows.append(in_subprocess(REPO, args, dataset))
        before = median_figures(befores) if befores else None
        now = median_figures(nows)
    note = f"\n\nMedians of {len(nows)} alternating rounds." if len(nows) > 1 else ""
    print(table(now, before, args.baseline) + note)


if __name__ == "__main__":
    main()
