"""Campaign recording: lock-step speed and the recorder's kept fraction at 1 kHz in real time.

1. Lock-step: actuator_sim (``time_mode: sim``, ``lockstep: true``), controller and id_recorder
   run the default campaign (``config/campaign.yaml``, or ``--experiments``), first as three
   processes, then composed in one (``composed_campaign``); the figure is the campaign's
   simulated duration over the wall time between the recorder's "campaign running" and
   "campaign done" (simulated s per wall s), with the recorder's kept fraction.
2. Real time: actuator_sim at 1 kHz (``time_mode: realtime``) with the controller holding a
   setpoint; id_recorder in ``mode: record`` for ``--seconds`` (60), then SIGINT; the kept
   fraction of ``joint_states`` samples, counted from the bag's stamps.

Prints a markdown table next to the targets (issue 3: lock-step >= 5x, kept >= 99.9 %).
Processes run in a ROS domain reserved for the run (jetpipe_ros.nodes.domain) with localhost
discovery. Usage:
``.venv/bin/python bench/bench_campaign.py [--seconds 60] [--experiments a,b]``
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from jetpipe_ros.campaign import default_campaign  # noqa: E402
from jetpipe_ros.nodes.domain import reserve_domain  # noqa: E402
from jetpipe_ros.nodes.id_recorder import stamp_of  # noqa: E402

DOMAIN = reserve_domain()  # held until the benchmark ends: no other run shares it
ENV = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN.domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
           PYTHONUNBUFFERED="1",
           PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))


class Node:
    """A node process whose output lines are collected."""

    def __init__(self, module: str, *args: str) -> None:
        self.lines: list[tuple[float, str]] = []
        self.proc = subprocess.Popen(
            [sys.executable, "-m", f"jetpipe_ros.nodes.{module}", "--ros-args", *args],
            cwd=REPO, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append((time.monotonic(), line.rstrip()))

    def wait_for(self, text: str, timeout: float) -> tuple[float, str]:
        """(arrival time [s, monotonic], line) of the first line containing ``text``."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for t, line in self.lines:
                if text in line:
                    return t, line
            time.sleep(0.05)
        raise RuntimeError(f"{text!r} not seen; output:\n" + "\n".join(l for _, l in self.lines))

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(20.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def kept_from_bag(bag: Path) -> tuple[int, int]:
    """(joint_states samples in the bag, samples published over their stamp span)."""
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic.endswith("/joint_states")]
        stamps = np.array([stamp_of(raw) for _, _, raw in reader.messages(connections=conns)])
    return stamps.size, int((stamps[-1] - stamps[0]) // 1_000_000 + 1)


def lockstep(work: Path, experiments: list[str] | None, lead: int,
             composed: bool) -> dict[str, float]:
    """Run the campaign in lock-step, in three processes or composed in one; its figures."""
    plan = default_campaign()
    extra: list[str] = []
    if experiments:
        plan = plan.select(experiments)
        path = work / "plan.yaml"
        path.write_text(plan.to_yaml())
        extra = ["-p", f"id_recorder:campaign_file:={path}"]
    bag = work / ("composed" if composed else "lockstep")
    recorder_args = ["-p", f"id_recorder:bag:={bag}", "-p", f"id_recorder:lead:={lead}", *extra]
    nodes: list[Node] = []
    try:
        if composed:
            rec = Node("composed_campaign", "--params-file", str(REPO / "config/actuator.yaml"),
                       "--params-file", str(REPO / "config/controller.yaml"),
                       "-p", "actuator_sim:report_period:=0.0", *recorder_args)
            nodes.append(rec)
        else:
            nodes.append(Node("actuator_sim", "--params-file",
                              str(REPO / "config/actuator.yaml"), "-p", "time_mode:=sim",
                              "-p", "lockstep:=true", "-p", "report_period:=0.0"))
            nodes.append(Node("controller", "--params-file",
                              str(REPO / "config/controller.yaml")))
            for node in nodes:
                node.wait_for("started:", 60.0)
            rec = Node("id_recorder", *recorder_args)
            nodes.append(rec)
        start, _ = rec.wait_for("campaign running", 60.0)
        end, _ = rec.wait_for("campaign done", 3600.0)
        rec.proc.wait(30.0)
        _, line = rec.wait_for("joint_states samples", 5.0)
    finally:
        for node in reversed(nodes):
            node.stop()
    kept = float(re.search(r"kept ([0-9.]+) %", line).group(1))
    simulated = plan.total_duration()
    return {"simulated": simulated, "wall": end - start, "speed": simulated / (end - start),
            "kept": kept}


def realtime(work: Path, seconds: float) -> dict[str, float]:
    """Record a real-time simulator for ``seconds``; the kept fraction."""
    sim = Node("actuator_sim", "--params-file", str(REPO / "config/actuator.yaml"),
               "-p", "report_period:=0.0")
    ctl = Node("controller", "--params-file", str(REPO / "config/controller.yaml"))
    rec = None
    bag = work / "realtime"
    try:
        sim.wait_for("started:", 60.0)
        ctl.wait_for("started:", 60.0)
        rec = Node("id_recorder", "-p", "mode:=record", "-p", f"bag:={bag}")
        rec.wait_for("started:", 60.0)
        time.sleep(seconds)
        rec.stop()
        _, line = rec.wait_for("joint_states samples", 5.0)
    finally:
        for node in (rec, ctl, sim):
            if node is not None:
                node.stop()
    n, expected = kept_from_bag(bag)
    return {"seconds": seconds, "kept": 100.0 * n / expected, "samples": n,
            "expected": expected, "line": line}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="real-time run [s]")
    parser.add_argument("--experiments", default="", help="comma-separated subset")
    parser.add_argument("--lead", type=int, default=4, help="id_recorder lead [samples]")
    args = parser.parse_args()
    experiments = [e for e in args.experiments.split(",") if e] or None
    with tempfile.TemporaryDirectory(prefix="jetpipe-bench-") as tmp:
        work = Path(tmp)
        runs = {composed: lockstep(work, experiments, args.lead, composed)
                for composed in (False, True)}
        rt = realtime(work, args.seconds)
    print("| figure | value | target |")
    print("|---|---|---|")
    for composed, ls in runs.items():
        how = ("composed_campaign (one process)" if composed
               else "actuator_sim + controller + id_recorder (three processes)")
        print(f"| campaign in lock-step, {how}, {ls['simulated']:.1f} s simulated, lead "
              f"{args.lead} | {ls['speed']:.2f} x real time ({ls['wall']:.1f} s wall), kept "
              f"{ls['kept']:.3f} % | >= 5 x, >= 99.9 % |")
    print(f"| recorder at 1 kHz, {rt['seconds']:.0f} s real time: samples kept | "
          f"{rt['kept']:.3f} % ({rt['samples']} of {rt['expected']}) | >= 99.9 % |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
