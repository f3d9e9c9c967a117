"""The showcase run by the README's first command.

Replays the paper's validation inputs (Sec. 6: square waves 0.6 V at 0.1122 Hz and 3 V at
0.97 Hz) through the nominal model and through a stand-in for real hardware (the nominal model
with an unmodelled valve lag switched on), writes both as dataset CSVs, plots them, and prints the
valve figures next to the paper's.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

from jetpipe_ros.dataset import write_experiment  # noqa: E402
from jetpipe_ros.model import ModelParams, simulate  # noqa: E402
from jetpipe_ros.model.valve import valve_tf  # noqa: E402

EXPERIMENTS = {"square_0p6V_0p1122Hz": (0.6, 0.1122, 20.0), "square_3V_0p97Hz": (3.0, 0.97, 5.0)}


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


def main(argv: list[str] | None = None) -> int:
    """Run the showcase; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/showcase", help="output directory")
    args = parser.parse_args(argv)
    out = Path(args.out)
    nominal = ModelParams()
    real = nominal.with_effect("valve_lag", corner_frequency=20.0).with_values(
        {"sensors.noise": True, "sensors.seed": 1})

    fig = valve_figures(nominal)
    print("Valve chain (DESIGN.md s.2)    model     paper (measured)")
    print(f"  gain peak                 {fig['peak_hz']:6.1f} Hz  ~49 Hz")
    print(f"  overshoot                 {fig['overshoot'] * 100:6.1f} %")
    print(f"  rise 10-90 %              {fig['rise_s'] * 1e3:6.1f} ms   6 ms")
    print(f"  settling 5 %              {fig['settling_s'] * 1e3:6.1f} ms  36 ms")

    figure, axes = plt.subplots(len(EXPERIMENTS), 1, figsize=(10, 7), constrained_layout=True)
    for ax, (name, (amp, freq, duration)) in zip(axes, EXPERIMENTS.items()):
        t = np.arange(0, duration, 1e-3)
        u = np.where(np.sin(2 * np.pi * freq * t) >= 0, amp, -amp)
        start = time.perf_counter()
        runs = {"nominal": simulate(nominal, u), "stand-in (valve_lag 20 Hz)": simulate(real, u)}
        wall = time.perf_counter() - start
        for label, tr in runs.items():
            tag = "nominal" if label == "nominal" else "standin"
            write_experiment(out / f"{name}_{tag}.csv",
                             {"t": tr.t, "u": tr.u, "y": tr.y_meas, "p1": tr.p1_meas,
                              "p2": tr.p2_meas, "v": tr.v})
            ax.plot(tr.t, tr.y_meas * 1e3, label=label)
        gap = runs["stand-in (valve_lag 20 Hz)"].y_meas - runs["nominal"].y_meas
        rel = np.sqrt(np.mean(gap**2)) / np.ptp(runs["nominal"].y) * 100
        print(f"{name}: {duration:.0f} s simulated twice in {wall * 1e3:.0f} ms; "
              f"position gap stand-in vs nominal {rel:.1f} % of travel (RMS)")
        ax.set_title(f"square wave {amp} V peak, {freq} Hz")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("y [mm]")
        ax.legend(loc="upper right")
    plot = out / "showcase.png"
    figure.savefig(plot, dpi=110)
    print(f"\nDatasets (t,u,y,p1,p2,v CSVs) and plot written to {out.resolve()}")
    print(f"  plot: {plot.resolve()}")
    print("Next: run the simulator node:  .venv/bin/actuator_sim --ros-args "
          "--params-file config/actuator.yaml")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
