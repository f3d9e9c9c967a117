"""Faults survived, measured: what a campaign keeps when a process dies, how fast it is noticed.

1. ``kill -9`` of id_recorder at random moments of the default campaign (three processes,
   lock-step): the bag (no metadata.yaml, no footer) is recovered by ``jetpipe export``; the
   figures are how much of what the simulator had stepped before the kill is missing from the
   recovered bag (simulated samples), how long before the kill the last recovered sample was
   published (wall clock, seen by a probe subscribing to ``joint_states`` in this process), and
   how many experiments were exported (the one running at the kill is not).
2. ``kill -9`` of actuator_sim, and of the controller during the closed-loop stick-slip
   experiment: the recorder's exit status and the wall time from the kill to its exit
   (``peer_timeout`` 5 s by default, plus closing the bag).
3. No simulator at start: exit status, time (``wait_timeout``) and whether a bag is left.

Processes run in ROS domain 150 (outside the 1-100 the tests use) with localhost discovery. Usage:
``.venv/bin/python bench/bench_faults.py [--kills 5] [--seed 0]``
"""

from __future__ import annotations

import argparse
import os
import random
import re
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))

import bench_campaign  # noqa: E402
from bench_campaign import Node  # noqa: E402

from jetpipe_ros.bag import export_bag  # noqa: E402
from jetpipe_ros.bag.recover import stream_messages  # noqa: E402
from jetpipe_ros.nodes.id_recorder import stamp_of  # noqa: E402

bench_campaign.ENV["ROS_DOMAIN_ID"] = "150"  # outside the tests' 1-100
NS = 1_000_000_000


class Arrivals:
    """When [s, monotonic] each joint_states sample (by stamp) reached this process."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node as RosNode
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        os.environ.update(ROS_DOMAIN_ID=bench_campaign.ENV["ROS_DOMAIN_ID"],
                          ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        rclpy.init()
        self.times: dict[int, float] = {}
        self.node = RosNode("bench_faults_probe")
        qos = QoSProfile(depth=10000, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE)
        self.node.create_subscription(JointState, "/joint_states", self._on, qos, raw=True)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        threading.Thread(target=self._spin, daemon=True).start()

    def _on(self, data: bytes) -> None:
        self.times.setdefault(stamp_of(data), time.monotonic())

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        import rclpy

        self._stop.set()
        time.sleep(0.1)
        self.node.destroy_node()
        rclpy.try_shutdown()


def rig() -> list[Node]:
    sim = Node("actuator_sim", "--params-file", str(REPO / "config/actuator.yaml"),
               "-p", "time_mode:=sim", "-p", "lockstep:=true", "-p", "report_period:=0.0")
    ctl = Node("controller", "--params-file", str(REPO / "config/controller.yaml"))
    for node in (sim, ctl):
        node.wait_for("started:", 120.0)
    return [sim, ctl]


def stop(nodes: list[Node]) -> None:
    for node in reversed(nodes):
        node.stop()


def kill_recorder(work: Path, after: float, arrivals: Arrivals) -> dict[str, float]:
    """kill -9 the recorder ``after`` wall seconds into the campaign; what was recovered."""
    arrivals.times.clear()
    nodes = rig()
    bag = work / f"killed_{after:.1f}"
    try:
        rec = Node("id_recorder", "-p", f"bag:={bag}")
        nodes.append(rec)
        start, _ = rec.wait_for("campaign running", 120.0)
        time.sleep(max(0.0, start + after - time.monotonic()))
        rec.proc.send_signal(signal.SIGKILL)
        killed = time.monotonic()
        rec.proc.wait(10.0)
        started = [line.split("experiment ")[1].split()[0] for _, line in rec.lines
                   if "] experiment " in line or ": experiment " in line]
        sim = nodes[0]
        sim.stop()  # SIGINT: it logs how many samples it stepped
        _, line = sim.wait_for("total: stepped", 20.0)
        stepped = int(re.search(r"stepped (\d+) samples", line).group(1))
    finally:
        stop(nodes)
    (mcap,) = bag.glob("*.mcap")
    stamps = [stamp_of(raw) for topic, _, _, raw in stream_messages(mcap)
              if topic.endswith("/joint_states")]
    last = max(stamps) // 1_000_000 if stamps else 0
    seen = arrivals.times.get(max(stamps)) if stamps else None
    notes: list[str] = []
    try:
        exported = len(export_bag(bag, work / f"data_{after:.1f}", progress=notes.append)
                       .joinpath("dataset.yaml").read_text().split("- file:")) - 1
    except Exception as exc:  # noqa: BLE001 - reported
        exported, notes = 0, [str(exc)]
    speed = stepped / 1000.0 / (killed - start)  # simulated s per wall s
    return {"after": after, "stepped": stepped, "recovered": last + 1,
            "lost_samples": stepped - (last + 1),
            "lost_wall": killed - seen if seen is not None else float("nan"),
            "started": len(started), "exported": exported, "speed": speed}


def kill_peer(work: Path, which: str) -> dict[str, float]:
    """kill -9 the simulator (mid-campaign) or the controller (in stick_slip)."""
    nodes = rig()
    try:
        rec = Node("id_recorder", "-p", f"bag:={work / f'peer_{which}'}")
        nodes.append(rec)
        rec.wait_for("campaign running", 120.0)
        rec.wait_for("experiment stick_slip" if which == "controller"
                     else "experiment charge_1p15V", 600.0)
        time.sleep(0.5)
        victim = nodes[0] if which == "simulator" else nodes[1]
        victim.proc.send_signal(signal.SIGKILL)
        killed = time.monotonic()
        status = rec.proc.wait(120.0)
        exited = time.monotonic()
        reason = next(line for _, line in rec.lines if "ERROR" in line)
    finally:
        stop(nodes)
    return {"status": status, "detected_s": exited - killed, "reason": reason.split("]: ")[-1]}


def no_simulator(work: Path) -> dict[str, float]:
    bag = work / "nosim" / "bag"
    t0 = time.monotonic()
    rec = Node("id_recorder", "-p", f"bag:={bag}", "-p", "wait_timeout:=5.0")
    status = rec.proc.wait(120.0)
    return {"status": status, "seconds": time.monotonic() - t0,
            "left": (work / "nosim").exists()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kills", type=int, default=5, help="recorder kills")
    parser.add_argument("--seed", type=int, default=0, help="seed of the kill moments")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory(prefix="jetpipe-faults-") as tmp:
        work = Path(tmp)
        print("| kill -9 of id_recorder after [s wall] | stepped | recovered | lost [samples] "
              "| last recovered sample, before the kill [s wall] | experiments started / "
              "exported |")
        print("|---|---|---|---|---|---|", flush=True)
        kills = []
        arrivals = Arrivals() if args.kills else None
        for _ in range(args.kills):
            k = kill_recorder(work, rng.uniform(2.0, 25.0), arrivals)
            kills.append(k)
            print(f"| {k['after']:.1f} | {k['stepped']} | {k['recovered']} | "
                  f"{k['lost_samples']} | {k['lost_wall']:.2f} | {k['started']} / "
                  f"{k['exported']} |", flush=True)
        if arrivals is not None:
            arrivals.close()
        peers = {w: kill_peer(work, w) for w in ("simulator", "controller")}
        nosim = no_simulator(work)
    if kills:
        lost = np.array([k["lost_wall"] for k in kills])
        print(f"\nlast recovered sample before the kill: median {np.nanmedian(lost):.2f} s, "
              f"max {np.nanmax(lost):.2f} s "
              f"(campaign pace {np.median([k['speed'] for k in kills]):.2f} x real time)")
    for which, p in peers.items():
        print(f"kill -9 of the {which}: recorder exit {p['status']} after {p['detected_s']:.1f}"
              f" s: {p['reason']}")
    print(f"no simulator at start: exit {nosim['status']} after {nosim['seconds']:.1f} s, "
          f"bag left: {nosim['left']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
