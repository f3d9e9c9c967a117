"""Scale-out on Dask: the cluster's start-up, selfcheck cases per minute with 1 and 2 workers,
and a fleet of 3 datasets, on the default campaign (config/campaign.yaml).

Start-up: a LocalCluster of 2 single-threaded worker processes, from entering
:class:`Cluster` until both workers are warm (package imported, kernels loaded from numba's
cache), then closing it (median of ``--repeats``). Selfcheck: ``--cases`` cases (plant truths
with bench deviations, as ``jetpipe selfcheck``) with 1 worker (in this process) and with 2
(a LocalCluster, its start included). Fleet: 3 datasets of the default campaign recorded on
three benches (a 25 Hz valve lag, a flow map 8 % weak, a cross-piston leak; sensor noise on),
diagnosed by ``run_fleet`` (one diagnosis per worker task, 2 workers), against the same 3
diagnosed one after the other with their fits on 2 workers (one cluster per diagnosis, as
``jetpipe diagnose DIR`` does). Wall-clock times on a machine others share: the load average is
printed with the table; compare rows of one run, not machines.
Usage: .venv/bin/python bench/bench_fleet.py [--cases 4] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from jetpipe_ros.workflows import diagnose
from jetpipe_ros.campaign import campaign_dataset
from jetpipe_ros.workflows.cluster import Cluster
from jetpipe_ros.workflows.fleet import run_fleet
from jetpipe_ros.workflows.selfcheck import run_selfcheck
from jetpipe_ros.model import ModelParams


def startup(repeats: int) -> tuple[float, float]:
    """Median seconds to a warm 2-worker LocalCluster, and to close it."""
    up, down = [], []
    for _ in range(repeats):
        with Cluster(2) as cluster:
            cluster.client  # noqa: B018 - waits for the warm workers
            up.append(cluster.startup_s)
            t0 = time.perf_counter()
        down.append(time.perf_counter() - t0)
    return statistics.median(up), statistics.median(down)


def selfcheck_rate(cases: int, workers: int, out: Path) -> float:
    """Cases per minute of ``jetpipe selfcheck --cases N --jobs workers`` (cluster included)."""
    t0 = time.perf_counter()
    run_selfcheck(cases, 0, out_dir=out, workers=workers, progress=lambda line: None)
    return cases / (time.perf_counter() - t0) * 60.0


def fleet_data(root: Path) -> list[Path]:
    """Three actuators' datasets of the default campaign."""
    nominal = ModelParams()
    benches = {
        "axis_lag": nominal.with_effect("valve_lag", corner_frequency=25.0),
        "axis_flow": nominal.with_values({"flow.gain_charge": 0.92,
                                          "flow.gain_discharge": 0.92}),
        "axis_leak": nominal.with_effect("leakage", cross_coefficient=5e-10),
    }
    dirs = []
    for i, (name, truth) in enumerate(benches.items()):
        campaign_dataset(truth.with_values({"sensors.noise": True}), root / name, seed=i + 1)
        dirs.append(root / name)
    return dirs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    load0 = os.getloadavg()[0]
    up, down = startup(args.repeats)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        dirs = fleet_data(tmp / "data")
        diagnose(dirs[0], tmp / "warm", workers=1, quiet=True)  # numba cache, imports
        t0 = time.perf_counter()
        fleet = run_fleet(dirs, tmp / "fleet", workers=2, progress=lambda line: None)
        fleet_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        for d in dirs:
            diagnose(d, tmp / "serial" / d.name, workers=2, quiet=True)
        serial_s = time.perf_counter() - t0
        rates = {w: selfcheck_rate(args.cases, w, tmp / f"selfcheck{w}") for w in (1, 2)}
    load1 = os.getloadavg()[0]
    verdicts = ", ".join(f"{r['name']} {r['verdict']['effect']}" for r in fleet["actuators"])
    print("| scale-out on Dask, default campaign (96.4 s at 1 kHz per dataset) | value |")
    print("|---|---|")
    print(f"| LocalCluster start-up, 2 workers, until both warm (median of {args.repeats}) "
          f"| {up:.1f} s (closing: {down:.1f} s) |")
    print(f"| selfcheck, plant truths with deviations, {args.cases} cases, 1 worker "
          f"(in this process) | {rates[1]:.2f} cases/min |")
    print(f"| selfcheck, same cases, 2 workers (LocalCluster, start-up included) "
          f"| {rates[2]:.2f} cases/min ({rates[2] / rates[1]:.2f} x) |")
    print(f"| fleet of 3 datasets, one diagnosis per task, 2 workers | {fleet_s:.1f} s "
          f"({verdicts}) |")
    print(f"| the same 3, one after the other, fits on 2 workers each | {serial_s:.1f} s |")
    print(f"| load average (1 min) before / after, 2 cores | {load0:.1f} / {load1:.1f} |")


if __name__ == "__main__":
    main()
