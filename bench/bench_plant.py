"""Speed of the plant stand-in (jetpipe_ros.plant): the default campaign recorded on it, against
the same campaign on the model, and the batch real-time factor.

Prints a markdown table. Medians over repeats in one run; compare rows, not machines.
Usage: .venv/bin/python bench/bench_plant.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from bench_sim import rich_command

from jetpipe_ros.campaign import default_campaign, run_campaign_offline
from jetpipe_ros.model import Actuator, ModelParams
from jetpipe_ros.plant import REAL_EFFECTS, Plant, PlantSpec, campaign_dataset


def _median_wall(run, repeats: int) -> float:
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        walls.append(time.perf_counter() - start)
    return statistics.median(walls)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    campaign = default_campaign()
    simulated = sum(p.samples for p in campaign.schedule()) * campaign.sample_time
    noisy = ModelParams().with_values({"sensors.noise": True})
    every = PlantSpec(noisy, {name: {} for name in REAL_EFFECTS})
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        count = iter(range(10**6))

        def root() -> Path:
            return Path(tmp) / f"d{next(count)}"

        for label, run in [
            ("model (`run_campaign_offline`)",
             lambda: run_campaign_offline(noisy, campaign, root(), seed=1)),
            ("plant, no real effect (`campaign_dataset`)",
             lambda: campaign_dataset(PlantSpec(noisy), root(), 1)),
            ("plant, every real effect at once",
             lambda: campaign_dataset(every, root(), 1))]:
            run()  # compile and warm up outside the timing
            wall = _median_wall(run, args.repeats)
            rows.append((f"default campaign ({simulated:.1f} s simulated), {label}",
                         f"{simulated / wall:,.0f}", f"{wall:.2f} s"))
    u = rich_command(60.0)
    for label, actuator in [("model, 4 sub-steps", Actuator(noisy)),
                            ("plant, 8 sub-steps, no real effect", Plant(PlantSpec(noisy))),
                            ("plant, 8 sub-steps, every real effect", Plant(every))]:
        actuator.run(u[:10])

        def batch() -> None:
            actuator.reset()
            actuator.run(u)

        wall = _median_wall(batch, args.repeats)
        rows.append((f"batch, 60 s rich command, {label}", f"{60.0 / wall:,.0f}",
                     f"{wall * 1e3:.0f} ms"))
    print("| plant benchmark (single core) | real-time factor | wall (median) |")
    print("|---|---|---|")
    for row in rows:
        print(f"| {' | '.join(row)} |")


if __name__ == "__main__":
    main()
