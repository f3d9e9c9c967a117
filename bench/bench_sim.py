"""Offline simulation speed: real-time factor of the batch simulator and per-sample step cost.

Prints a markdown table. Medians over repeats in one run; compare rows, not machines.
Usage: .venv/bin/python bench/bench_sim.py [--seconds 60] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from jetpipe_ros.model import Actuator, ModelParams


def rich_command(seconds: float, dt: float = 1e-3) -> np.ndarray:
    """Square waves, a sine sweep and random steps: every regime of the actuator [V]."""
    t = np.arange(0, seconds, dt)
    rng = np.random.default_rng(0)
    sweep = 0.3 * np.sin(2 * np.pi * (1.6 + 68.4 * (t % 10) / 20) * (t % 10))
    steps = np.repeat(rng.uniform(-2, 2, t.size // 500 + 1), 500)[: t.size]
    return np.where((t // 10) % 2 == 0, sweep + 0.6 * np.sign(np.sin(2 * np.pi * 0.1122 * t)),
                    steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    u = rich_command(args.seconds)
    rows = []
    for label, changes in [("nominal, 4 sub-steps (default)", {}),
                           ("nominal, 8 sub-steps", {"integration.substeps": 8}),
                           ("LuGre + lag + hysteresis + noise",
                            {"effects.friction_dynamics.enabled": True,
                             "effects.valve_lag.enabled": True,
                             "effects.valve_hysteresis.enabled": True, "sensors.noise": True})]:
        act = Actuator(ModelParams(changes))
        act.run(u[:10])  # compile outside the timing
        walls = []
        for _ in range(args.repeats):
            act.reset()
            start = time.perf_counter()
            act.run(u)
            walls.append(time.perf_counter() - start)
        wall = statistics.median(walls)
        rows.append((label, f"{args.seconds / wall:,.0f}", f"{wall * 1e3:.0f} ms"))
    act = Actuator(ModelParams())
    act.step(0.0)
    n = 20_000
    start = time.perf_counter()
    for k in range(n):
        act.step(u[k % u.size])
    rows.append(("Actuator.step (node path), per sample", "-",
                 f"{(time.perf_counter() - start) / n * 1e6:.1f} us"))
    print(f"| offline simulation ({args.seconds:.0f} s rich command, single core) "
          "| real-time factor | wall (median) |")
    print("|---|---|---|")
    for row in rows:
        print(f"| {' | '.join(row)} |")


if __name__ == "__main__":
    main()
