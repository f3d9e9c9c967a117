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
around :func:`jetpipe_ros.diagnosis.placement.place`. Then once the lag's bench logged with the
position alone (``position_only``), where the recalibration imitates several candidates and the
check of what it imitates refits near the bar (:mod:`jetpipe_ros.diagnosis.collinearity`): its
wall time, and that check's own. Prints markdown tables; compare rows, not machines.
Usage: .venv/bin/python bench/bench_diagnose.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import jetpipe_ros.diagnosis.diagnose as diagnosis_steps
from jetpipe_ros import plant
from jetpipe_ros.campaign import campaign_dataset
from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.model import ModelParams
from jetpipe_ros.plant.logger import log
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


def staged(data: Path, out: Path, stages: tuple[str, ...]) -> tuple[float, dict, dict]:
    """A diagnosis on 2 workers: its wall time [s], the time [s] spent in each of ``stages``
    (functions :mod:`jetpipe_ros.diagnosis.diagnose` calls, by name) and its result."""
    spent = {name: 0.0 for name in stages}
    originals = {name: getattr(diagnosis_steps, name) for name in stages}

    def timing(name):
        def run(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return originals[name](*args, **kwargs)
            finally:
                spent[name] += time.perf_counter() - t0
        return run

    for name in stages:
        setattr(diagnosis_steps, name, timing(name))
    try:
        wall, result = timed(data, out, 2)
    finally:
        for name, f in originals.items():
            setattr(diagnosis_steps, name, f)
    return wall, spent, result


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
        unlisted, placing, found = staged(spring, Path(tmp) / "spring_out", ("place",))
        position = Path(tmp) / "position"
        shutil.copytree(data, position)
        log("position_only", position, 2)
        alone, imitating, by_position = staged(position, Path(tmp) / "position_out",
                                               ("imitations", "with_added_sensors"))
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
    print(f"| of it, placing the gap | {placing['place']:.1f} s | |")
    print(f"| its verdict (truth: unlisted, mechanics) | {found['verdict']['effect']}, "
          f"{found['verdict']['subsystem']} | |")
    print(f"| the lag's bench with the position alone, 2 workers, once: wall | {alone:.1f} s "
          f"| |")
    print(f"| of it, what the recalibration imitates (refitted near the bar) / with the "
          f"pressures it lacks | {imitating['imitations']:.1f} s / "
          f"{imitating['with_added_sensors']:.1f} s | |")
    pv = by_position["verdict"]
    print(f"| its verdict (truth: valve_lag 25 Hz) | {pv['effect']}"
          + (f" {pv['params']['corner_frequency']:.1f} Hz" if "corner_frequency" in pv["params"]
             else "") + " | |")
    total = sum(t for _, t in own)
    print("\n| where the in-process diagnosis spends its time (own time, cProfile) | s | share |")
    print("|---|---|---|")
    for name, t in own[:12]:
        print(f"| `{name}` | {t:.1f} | {100 * t / total:.0f} % |")
    print(f"| everything else | {total - sum(t for _, t in own[:12]):.1f} | "
          f"{100 * (1 - sum(t for _, t in own[:12]) / total):.0f} % |")


if __name__ == "__main__":
    main()
