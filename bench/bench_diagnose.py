"""Diagnosis speed on the default campaign's dataset (about 1.5 min at 1 kHz), recalibration and
all candidates.

Simulates the default campaign (config/campaign.yaml) on a bench whose parameters are off (flow
map 8 % weaker, friction forces 20 % higher, chamber 1 dead volume 20 % larger) with a 25 Hz
valve lag and sensor noise as the "real" data, then times `diagnose` with its fits on 2 Dask
worker processes (a LocalCluster per diagnosis, its start-up included; median of repeats) and
once with 1 (in this process) for the parallel speed-up, then once more in this process under
cProfile: where a diagnosis spends its time, the functions with the most time of their own
(the compiled kernel's time counts as its caller's, ``Actuator.run``). Then once, with 2
workers, the same bench recorded on the independent plant (``jetpipe_ros.plant``) with a load
spring between rod and frame, a cause on no list: the answer is ``unlisted``, so the diagnosis
also places the gap (replays of each subsystem, each sensor's and the valve's null refitted,
the flow map identified afresh), a step only such answers pay for; its own time is measured
around :func:`jetpipe_ros.diagnosis.placement.place`. Prints markdown tables; compare rows, not
machines.
Usage: .venv/bin/python bench/bench_diagnose.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import tempfile
import time
from pathlib import Path

import jetpipe_ros.diagnosis.diagnose as diagnosis_steps
from jetpipe_ros import plant
from jetpipe_ros.campaign import campaign_dataset
from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.model import ModelParams
from jetpipe_ros.workflows import diagnose


def timed(data: Path, out: Path, workers: int) -> tuple[float, dict]:
    t0 = time.perf_counter()
    result = diagnose(data, out, workers=workers, quiet=True)
    return time.perf_counter() - t0, result


def profiled(data: Path, out: Path) -> list[tuple[str, float]]:
    """An in-process diagnosis' functions by time of their own [s], most first."""
    profile = cProfile.Profile()
    profile.runcall(diagnose, data, out, workers=1, quiet=True)
    stats = pstats.Stats(profile).stats  # {(file, line, name): (cc, nc, tottime, cumtime, ...)}
    own = sorted(((f"{Path(f).parent.name}/{Path(f).name}:{name}" if f != "~" else name, tt)
                  for (f, _, name), (_, _, tt, _, _) in stats.items()),
                 key=lambda item: -item[1])
    return own


def placed(data: Path, out: Path) -> tuple[float, float, dict]:
    """A diagnosis on 2 workers: its wall time [s], the placement's share of it [s] and its
    result."""
    spent = []
    place = diagnosis_steps.place

    def timed_place(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return place(*args, **kwargs)
        finally:
            spent.append(time.perf_counter() - t0)

    diagnosis_steps.place = timed_place
    try:
        wall, result = timed(data, out, 2)
    finally:
        diagnosis_steps.place = place
    return wall, sum(spent), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data"
        nominal = ModelParams()
        bench = {"flow.gain_charge": 0.92, "flow.gain_discharge": 0.92,
                 "chamber.dead_volume_1": nominal["chamber.dead_volume_1"] + 3.5e-6}
        for ph in ("entry", "exit"):
            for q in ("breakaway", "coulomb", "viscous"):
                bench[f"friction.{ph}.{q}"] = [1.2 * c for c in nominal[f"friction.{ph}.{q}"]]
        truth = nominal.with_values(bench).with_effect("valve_lag", corner_frequency=25.0)
        campaign_dataset(truth.with_values({"sensors.noise": True}), data, seed=1)
        seconds = sum(e.t[-1] - e.t[0] for e in read_dataset(data).experiments)
        timed(data, Path(tmp) / "warm", 2)  # numba cache and imports
        walls = []
        for i in range(args.repeats):
            wall, result = timed(data, Path(tmp) / f"out{i}", 2)
            walls.append(wall)
        single, _ = timed(data, Path(tmp) / "single", 1)
        own = profiled(data, Path(tmp) / "profiled")
        spring = Path(tmp) / "spring"
        plant.campaign_dataset(plant.PlantSpec(
            nominal.with_values({**bench, "sensors.noise": True}),
            {"load_spring": {"stiffness": 8e3, "free_position": 0.0}}), spring, seed=1)
        unlisted, placing, found = placed(spring, Path(tmp) / "spring_out")
    med = statistics.median(walls)
    v = result["verdict"]
    print("| diagnosis, default campaign dataset, recalibration + 9 candidates | value | target |")
    print("|---|---|---|")
    print(f"| dataset length | {seconds:.1f} s | |")
    print(f"| wall, 2 Dask workers (median of {args.repeats}) | {med:.1f} s | <= 60 s |")
    print(f"| wall, 1 process (no cluster) | {single:.1f} s | |")
    print(f"| parallel speed-up | {single / med:.2f}x | |")
    knobs = result["calibration"]["knobs"]
    print(f"| verdict (truth: valve_lag 25 Hz) | {v['effect']} "
          f"{v['params'].get('corner_frequency', 0):.1f} Hz, shrinkage "
          f"{100 * result['gap']['shrinkage']:.0f} % | |")
    print(f"| calibration (truth: flow 0.92, friction 1.2, dead volume 1 1.2) | flow "
          f"{knobs['flow_gain_charge']:.3f}/{knobs['flow_gain_discharge']:.3f}, friction "
          f"{knobs['friction_entry']:.2f}/{knobs['friction_exit']:.2f}, dead volume 1 "
          f"{knobs['dead_volume_1']:.2f} | |")
    print(f"| a load spring (on no list), 2 workers, once: wall | {unlisted:.1f} s | |")
    print(f"| of it, placing the gap | {placing:.1f} s | |")
    print(f"| its verdict (truth: unlisted, mechanics) | {found['verdict']['effect']}, "
          f"{found['verdict']['subsystem']} | |")
    total = sum(t for _, t in own)
    print("\n| where the in-process diagnosis spends its time (own time, cProfile) | s | share |")
    print("|---|---|---|")
    for name, t in own[:12]:
        print(f"| `{name}` | {t:.1f} | {100 * t / total:.0f} % |")
    print(f"| everything else | {total - sum(t for _, t in own[:12]):.1f} | "
          f"{100 * (1 - sum(t for _, t in own[:12]) / total):.0f} % |")


if __name__ == "__main__":
    main()
