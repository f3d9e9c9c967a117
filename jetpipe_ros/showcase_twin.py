"""The twin beside the hardware, shown: a live gap, an effect switched on, captured, named.

1. ``actuator_sim`` stands in for the hardware (the nominal model with sensor noise, simulated
   time at real-time speed) under the ``controller``, which this script feeds random position
   steps; ``gap_monitor`` runs the nominal model beside it;
2. the monitor's gap status is printed every second: OK once it has judged;
3. a 20 Hz valve lag is switched on in the running simulator (what ``ros2 param set`` does);
4. the monitor goes to ERROR, and once the gap has stayed there it captures the last seconds
   and diagnoses them in a separate process; the verdict is printed beside the truth.

ROS traffic stays on this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless set) and
in the namespace ``/showcase_twin``; every process started here is stopped on exit.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path
from jetpipe_ros import fileio
from jetpipe_ros.children import Nodes
from jetpipe_ros.nodes.gap_watch import Watch
from jetpipe_ros.model import compile_kernel
from jetpipe_ros.package_data import share_file

NAMESPACE = "/showcase_twin"
EFFECT = {"effects.valve_lag.enabled": True, "effects.valve_lag.corner_frequency": 20.0}
STARTUP = 60.0  #: [s] longest wait for a node to start (first numba compile)
CAPTURE = 10.0  #: [s] length of the capture
AUTO = 10.0  #: [s] the gap at ERROR this long starts the capture
LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


def _line(watch: Watch, t0: float) -> tuple[int, str]:
    level, message, _ = watch.status.get("gap", (3, "no status yet", {}))
    print(f"  {time.monotonic() - t0:5.1f} s  {LEVELS.get(level, level):5s} {message}")
    return level, message


def run(out: Path) -> int:
    print("Compiling the model (first run only; cached) ...", flush=True)
    print(f"  ready in {compile_kernel():.0f} s", flush=True)
    nodes = Nodes(out / "logs", NAMESPACE)
    for name, args in (
        ("actuator_sim", [
            "--params-file", str(share_file("config/actuator.yaml")),
            "-p", "sensors.noise:=true", "-p", "time_mode:=sim", "-p", "report_period:=0.0"]),
        ("controller", ["--params-file", str(share_file("config/controller.yaml"))]),
        ("gap_monitor", [
            "--params-file", str(share_file("config/gap_monitor.yaml")),
            "-p", f"capture_dir:={out / 'captures'}", "-p", f"capture_seconds:={CAPTURE}",
            "-p", f"auto_capture_after:={AUTO}"])):
        nodes.start(name, args)
    print("Stand-in hardware: actuator_sim (nominal model, sensor noise) under the controller; "
          "gap_monitor runs the nominal model beside it")
    watch = Watch(NAMESPACE)
    try:
        t0 = time.monotonic()
        level = 3
        while time.monotonic() - t0 < STARTUP + 30:
            watch.spin(1.0)
            level, message = _line(watch, t0)
            if "y level" in watch.status.get("gap", (0, "", {}))[2]:
                break
        for _ in range(3):
            watch.spin(1.0)
            level, _ = _line(watch, t0)
        print(f"\nros2 param set {NAMESPACE}/actuator_sim effects.valve_lag.corner_frequency 20.0 "
              f"&& ... effects.valve_lag.enabled true  (the hardware's valve gets a 20 Hz lag)")
        watch.set_parameters("actuator_sim", EFFECT)
        shown = ""
        while time.monotonic() - t0 < 600:
            watch.spin(1.0)
            _line(watch, t0)
            cap = watch.status.get("capture", (0, "", {}))
            if "verdict" in cap[1] or "failed" in cap[1]:
                break
            if cap[1] != shown and cap[1].startswith(("writing", "dataset", "diagnosing")):
                print(f"         capture: {cap[1]}")
                shown = cap[1]
        level, message, info = watch.status.get("capture", (2, "no capture", {}))
        print(f"\nCapture and diagnosis: {message}")
        named = info.get("effect") == "valve_lag"
        print(f"Truth: valve_lag (20 Hz corner), switched on while it ran; the diagnosis of the "
              f"capture {'names it' if named else 'does NOT name it'}"
              f"{' (' + info.get('params', '') + ')' if named else ''}")
        print(f"\nResults in {out}: captures/ (dataset, diagnosis/report.html, augmented.yaml), "
              f"logs/")
        return 0 if named else 1
    finally:
        watch.close()
        nodes.stop()


def main(argv: list[str] | None = None) -> int:
    """Run the twin showcase; returns the exit status (1 if the verdict misses the effect)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/showcase_twin", help="output directory")
    args = parser.parse_args(argv)
    try:
        out = fileio.output_dir(args.out, "--out").resolve()
    except fileio.FileError as exc:
        print(f"showcase_twin: error: {exc}", file=sys.stderr)
        return 2
    for stale in ("captures", "logs"):  # a previous run's results
        shutil.rmtree(out / stale, ignore_errors=True)
    return run(out)


if __name__ == "__main__":
    raise SystemExit(main())
