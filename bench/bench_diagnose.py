"""Diagnosis speed on the default campaign's dataset (about 1.5 min at 1 kHz), all candidates.

Simulates the default campaign (config/campaign.yaml) with a 25 Hz valve lag and sensor noise as
the "real" data, then times `diagnose` with 2 fitting processes (median of repeats) and once with
1 for the parallel speed-up. Prints a markdown table; compare rows, not machines.
Usage: .venv/bin/python bench/bench_diagnose.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.diagnosis import diagnose
from jetpipe_ros.diagnosis.cli import campaign_dataset
from jetpipe_ros.model import ModelParams


def timed(data: Path, out: Path, workers: int) -> tuple[float, dict]:
    t0 = time.perf_counter()
    result = diagnose(data, out, workers=workers, quiet=True)
    return time.perf_counter() - t0, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data"
        truth = ModelParams().with_effect("valve_lag", corner_frequency=25.0)
        campaign_dataset(truth.with_values({"sensors.noise": True}), data, seed=1)
        seconds = sum(e.t[-1] - e.t[0] for e in read_dataset(data).experiments)
        timed(data, Path(tmp) / "warm", 2)  # numba cache and imports
        walls = []
        for i in range(args.repeats):
            wall, result = timed(data, Path(tmp) / f"out{i}", 2)
            walls.append(wall)
        single, _ = timed(data, Path(tmp) / "single", 1)
    med = statistics.median(walls)
    v = result["verdict"]
    print("| diagnosis, default campaign dataset, 9 candidates | value | target |")
    print("|---|---|---|")
    print(f"| dataset length | {seconds:.1f} s | |")
    print(f"| wall, 2 processes (median of {args.repeats}) | {med:.1f} s | <= 60 s |")
    print(f"| wall, 1 process | {single:.1f} s | |")
    print(f"| parallel speed-up | {single / med:.2f}x | |")
    print(f"| verdict (truth: valve_lag 25 Hz) | {v['effect']} "
          f"{v['params'].get('corner_frequency', 0):.1f} Hz, shrinkage "
          f"{100 * result['gap']['shrinkage']:.0f} % | |")


if __name__ == "__main__":
    main()
