"""The showcase run by the README's first command: the paper's campaign through ROS, recorded.

Steps, in order (each a function below, so a later step is a small addition to :func:`main`):

1. the valve figures of the nominal model beside the paper's;
2. compile the model's kernel (numba caches it: the nodes then load it), start
   ``actuator_sim`` as the stand-in for real hardware: the nominal model with one
   unmodelled effect of docs/effects.md switched on (a 20 Hz valve lag) and sensor noise, in
   simulated time, lock-step; and the ``controller``;
3. run the default campaign (``config/campaign.yaml``) with ``id_recorder`` into an MCAP bag;
4. export the bag to a dataset (``jetpipe export``);
5. plot the recorded validation square waves against the nominal model replayed from the same
   commands;
6. diagnose the gap (``jetpipe diagnose``) without being told the stand-in's effect, compare the
   verdict with the truth, and print where everything is.

ROS traffic stays on this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless set) and
in the namespace ``/showcase``; every process started here is stopped on exit.
"""

from __future__ import annotations

import argparse
import io
import shutil
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

from jetpipe_ros import fileio  # noqa: E402
from jetpipe_ros.children import Nodes  # noqa: E402
from jetpipe_ros.bag import export_bag  # noqa: E402
from jetpipe_ros.dataset import COMPLETE, Dataset, read_dataset  # noqa: E402
from jetpipe_ros.model import ModelParams, compile_kernel, simulate  # noqa: E402
from jetpipe_ros.model.valve import valve_tf  # noqa: E402
from jetpipe_ros.package_data import share_file  # noqa: E402

NAMESPACE = "/showcase"
STANDIN = {"effect": "valve_lag", "corner_frequency": 20.0}  #: the "real" hardware's effect
PLOTTED = ("square_0p6V_0p1122Hz", "square_3V_0p97Hz")  #: the paper's validation inputs
STARTUP = 60.0  #: [s] longest wait for a node to start (first numba compile)
CAMPAIGN_TIMEOUT = 1800.0  #: [s] longest wait for the campaign


def valve_figures(params: ModelParams) -> dict[str, float]:
    """Gain peak [Hz], overshoot [-], 10-90 % rise [s] and 5 % settling [s] of the valve chain."""
    num, den = valve_tf(params)
    w = 2 * np.pi * np.linspace(1, 200, 100_000)
    _, resp = signal.freqs(num, den, w)
    t = np.arange(0, 0.1, 1e-6)
    _, y = signal.step((num, den), T=t)
    t = t + params["valve.delay"]
    outside = np.flatnonzero(np.abs(y - 1) > 0.05)
    return {"peak_hz": w[np.argmax(np.abs(resp))] / (2 * np.pi), "overshoot": y.max() - 1,
            "rise_s": t[np.argmax(y >= 0.9)] - t[np.argmax(y >= 0.1)],
            "settling_s": t[outside[-1] + 1]}


def compile_model() -> None:
    """Compile the model's kernel here, with a word, before a node needs it (numba caches it:
    a first compile on a fresh clone of a busy machine took longer than :data:`STARTUP`)."""
    print("Compiling the model (first run only; cached) ...", flush=True)
    print(f"  ready in {compile_kernel():.0f} s", flush=True)


def print_valve_figures() -> None:
    """Step 1: the nominal valve chain beside the paper's measurements."""
    fig = valve_figures(ModelParams())
    print("Valve chain (docs/model.md)    model     paper (measured)")
    print(f"  gain peak                 {fig['peak_hz']:6.1f} Hz  ~49 Hz")
    print(f"  overshoot                 {fig['overshoot'] * 100:6.1f} %")
    print(f"  rise 10-90 %              {fig['rise_s'] * 1e3:6.1f} ms   6 ms")
    print(f"  settling 5 %              {fig['settling_s'] * 1e3:6.1f} ms  36 ms")


def start_standin(nodes: Nodes, out: Path) -> ModelParams:
    """Step 2: the simulator as stand-in hardware (lock-step, simulated time), the controller."""
    standin = ModelParams().with_effect(
        STANDIN["effect"], corner_frequency=STANDIN["corner_frequency"]).with_values(
        {"sensors.noise": True, "sensors.seed": 1})
    params_file = out / "standin.yaml"
    # "/**/" so that the file applies to the node in the showcase namespace.
    fileio.write_text(params_file,
                      standin.to_ros_yaml(only_changed=True))
    nodes.start("actuator_sim", ["--params-file", str(share_file("config/actuator.yaml")),
                                 "--params-file", str(params_file), "-p", "time_mode:=sim",
                                 "-p", "lockstep:=true", "-p", "report_period:=0.0"])
    nodes.start("controller", ["--params-file", str(share_file("config/controller.yaml"))])
    print(f"\nStand-in hardware: actuator_sim with {STANDIN['effect']} "
          f"({STANDIN['corner_frequency']:g} Hz) and sensor noise ({params_file})")
    for name in ("actuator_sim", "controller"):
        nodes.wait_for(name, "started:", STARTUP)
    return standin


def record_campaign(nodes: Nodes, bag: Path) -> str:
    """Step 3: the default campaign through controller and recorder; the recorder's summary."""
    print("Running the default campaign (config/campaign.yaml) in lock-step ...")
    start = time.monotonic()
    rec = nodes.start("id_recorder", ["-p", f"bag:={bag}"])
    seen = 0
    path = nodes.logs / "id_recorder.log"
    while rec.poll() is None and time.monotonic() - start < CAMPAIGN_TIMEOUT:
        lines = path.read_text().splitlines()
        for line in lines[seen:]:
            if "experiment " in line:
                print("  " + line.split("]: ", 1)[-1])
        seen = len(lines)
        time.sleep(0.5)
    if rec.poll() != 0:
        raise RuntimeError(f"id_recorder failed (exit {rec.poll()}); see {path}")
    summary = nodes.wait_for("id_recorder", "joint_states samples", 1.0).split("]: ", 1)[-1]
    print(f"  {summary}")
    return summary


def plot_square_waves(data: Dataset, out: Path) -> Path:
    """Step 5: recorded validation square waves vs the nominal model on the same commands."""
    nominal = ModelParams()
    figure, axes = plt.subplots(len(PLOTTED), 1, figsize=(10, 7), constrained_layout=True)
    for ax, name in zip(axes, PLOTTED):
        entry, exp = next((e, x) for e, x in data if e.name == name)
        start = nominal.with_values({"mechanics.initial_position": float(exp.y[0]),
                                     "chamber.initial_pressure_1": float(exp.p1[0]),
                                     "chamber.initial_pressure_2": float(exp.p2[0])})
        model = simulate(start, exp.u)
        gap = exp.y - model.y
        rel = np.sqrt(np.mean(gap ** 2)) / np.ptp(exp.y) * 100
        print(f"  {name}: position gap recorded vs nominal model {rel:.1f} % of travel (RMS)")
        ax.plot(exp.t, exp.y * 1e3, label=f"recorded (stand-in, {STANDIN['effect']})")
        ax.plot(model.t, model.y * 1e3, label="nominal model, same command")
        ax.set_title(f"{name} ({entry.role})")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("y [mm]")
        ax.legend(loc="upper right")
    plot = out / "showcase.png"
    image = io.BytesIO()
    figure.savefig(image, format="png", dpi=110)
    fileio.write_files({plot: image.getvalue()})
    return plot


def diagnose_gap(dataset: Path, out: Path) -> dict:
    """Step 6: the sim-to-real gap diagnosis of the recorded dataset, judged against the truth."""
    from jetpipe_ros.workflows.diagnose import diagnose

    print("Diagnosing the gap between the nominal model and the recording (jetpipe diagnose) ...")
    result = diagnose(dataset, out)
    v, g = result["verdict"], result["gap"]
    params = ", ".join(f"{k} {x:.3g}" for k, x in v["params"].items())
    print(f"  verdict: {v['effect']} ({params}), confidence {v['confidence']:.2f}; the stand-in "
          f"has {STANDIN['effect']} at {STANDIN['corner_frequency']:g} Hz")
    print(f"  held-out gap ({g['metric']}): nominal {g['nominal']:.2f} % -> augmented "
          f"{g['augmented']:.2f} % (shrinkage {100 * g['shrinkage']:.0f} %)")
    return result


def main(argv: list[str] | None = None) -> int:
    """Run the showcase; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/showcase", help="output directory")
    args = parser.parse_args(argv)
    try:
        out = fileio.output_dir(args.out, "--out").resolve()
    except fileio.FileError as exc:
        print(f"showcase: error: {exc}", file=sys.stderr)
        return 2
    for stale in ("bag", "dataset", "logs", "diagnosis"):  # a previous run's results
        shutil.rmtree(out / stale, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)

    print_valve_figures()
    print()
    compile_model()
    nodes = Nodes(out / "logs", NAMESPACE)
    try:
        start_standin(nodes, out)
        record_campaign(nodes, out / "bag")
    finally:
        nodes.stop()
    print("Exporting the bag (jetpipe export) ...")
    dataset = export_bag(out / "bag", out / "dataset", progress=lambda _: None)
    data = read_dataset(dataset, required=COMPLETE)
    print(f"  {len(data)} experiments, {sum(x.t.size for _, x in data)} samples")
    plot = plot_square_waves(data, out)
    diagnose_gap(dataset, out / "diagnosis")

    print(f"\nResults in {out}")
    print(f"  bag (rosbag2, MCAP, metadata v9): {out / 'bag'}")
    print(f"  dataset (docs/data.md):           {dataset}")
    print(f"  plot:                             {plot}")
    print(f"  diagnosis report:                 {out / 'diagnosis' / 'report.html'}")
    print(f"  improved model (loads in the sim): {out / 'diagnosis' / 'augmented.yaml'}")
    print(f"  node logs:                        {out / 'logs'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
