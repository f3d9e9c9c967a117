"""Seal friction fitting speed: wall time of ``jetpipe friction`` on a friction-rig folder with
its fits in one process and on two (``--jobs``), alternating, in fresh processes (the Numba cache
warmed first). Prints a markdown table; compare rows, not machines.
Usage: .venv/bin/python bench/bench_friction.py [RIG_DIR] [--repeats N]
(default: the three records shipped in test/data/friction-seals)
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SHIPPED = Path(__file__).resolve().parent.parent / "test" / "data" / "friction-seals"


def _run(rig: Path, out: Path, jobs: int) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "jetpipe_ros.cli", "friction", str(rig), "--out",
                    str(out), "--jobs", str(jobs), "--quiet"], check=True,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("rig", nargs="?", type=Path, default=SHIPPED)
    cli.add_argument("--repeats", type=int, default=3)
    args = cli.parse_args()
    walls: dict[int, list[float]] = {1: [], 2: []}
    with tempfile.TemporaryDirectory() as tmp:
        _run(args.rig, Path(tmp) / "warm", 2)  # the Numba cache of the workers, too
        for k in range(args.repeats):
            for jobs in walls:
                walls[jobs].append(_run(args.rig, Path(tmp) / f"{jobs}-{k}", jobs))
    one, two = (statistics.median(walls[j]) for j in (1, 2))
    print(f"| `jetpipe friction {args.rig.name}` | wall [s], median of {args.repeats} |\n"
          f"|---|---|")
    print(f"| --jobs 1 | {one:.1f} |\n| --jobs 2 | {two:.1f} ({one / two:.2f} x) |")


if __name__ == "__main__":
    main()
