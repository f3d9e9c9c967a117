"""Speed of the plant stand-in (jetpipe_ros.plant): the default campaign recorded on it, against
the same campaign on the model, and the batch real-time factor.

Prints a markdown table. Medians over repeats in one run; compare rows, not machines.
Usage: .venv/bin/python bench/bench_plant.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
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


#: What a fresh clone compiles before its first plant record: the plant with every real effect
#: on (one friction law) for 10 ms, in a new process with an empty Numba cache.
FIRST_RUN = """
import time
start = time.perf_counter()
from jetpipe_ros.model import ModelParams
from jetpipe_ros.plant import REAL_EFFECTS, Plant, PlantSpec
spec = PlantSpec(ModelParams(), {n: {} for n in REAL_EFFECTS if n != "measured_seal"})
Plant(spec).run([0.5] * 10)
print(time.perf_counter() - start)
"""


def _cold_start() -> float:
    """Seconds to import and compile the plant in a new process with an empty Numba cache."""
    with tempfile.TemporaryDirectory() as cache:
        out = subprocess.run([sys.executable, "-c", FIRST_RUN], check=True, text=True,
                             capture_output=True, env={**os.environ, "NUMBA_CACHE_DIR": cache})
    return float(out.stdout.split()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    campaign = default_campaign()
    simulated = sum(p.samples for p in campaign.schedule()) * campaign.sample_time
    noisy = ModelParams().with_values({"sensors.noise": True})
    # Every real effect but the measured seal: it and the elasto-plastic law are both the
    # piston's friction, and a plant has one.
    every = PlantSpec(noisy, {name: {} for name in REAL_EFFECTS if name != "measured_seal"})
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
            ("plant, every real effect at once (one friction law)",
             lambda: campaign_dataset(every, root(), 1))]:
            run()  # compile and warm up outside the timing
            wall = _median_wall(run, args.repeats)
            rows.append((f"default campaign ({simulated:.1f} s simulated), {label}",
                         f"{simulated / wall:,.0f}", f"{wall:.2f} s"))
    u = rich_command(60.0)
    for label, actuator in [("model, 4 sub-steps", Actuator(noisy)),
                            ("plant, 8 sub-steps, no real effect", Plant(PlantSpec(noisy))),
                            ("plant, 8 sub-steps, every real effect (one friction law)", Plant(every))]:
        actuator.run(u[:10])

        def batch() -> None:
            actuator.reset()
            actuator.run(u)

        wall = _median_wall(batch, args.repeats)
        rows.append((f"batch, 60 s rich command, {label}", f"{60.0 / wall:,.0f}",
                     f"{wall * 1e3:.0f} ms"))
    rows.append(("first plant record in a new process, empty Numba cache (compile)", "",
                 f"{_cold_start():.1f} s"))
    print("| plant benchmark (single core) | real-time factor | wall (median) |")
    print("|---|---|---|")
    for row in rows:
        print(f"| {' | '.join(row)} |")


if __name__ == "__main__":
    main()
