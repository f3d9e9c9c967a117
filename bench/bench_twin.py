"""gap_monitor beside actuator_sim at 1 kHz: its CPU, its latency, the samples it keeps.

Starts actuator_sim (real time, sensor noise on), the controller and gap_monitor, each in its
own process, and from this process steps the position setpoint at random every 0.35 s while it
listens to ``joint_states`` (the measurement) and ``twin/joint_states`` (the monitor's
prediction of the same stamp). Over the window it measures, and prints as a markdown table:
the CPU of the monitor and of the simulator (utime + stime from /proc/<pid>/stat, % of one
core), the latency from a measurement's arrival here to the arrival here of the prediction with
its stamp (p50 / p99 / max: the monitor's work plus one extra hop), and the samples kept: the
stamps predicted over those measured, with the monitor's own counts from ``/diagnostics``.
Usage: .venv/bin/python bench/bench_twin.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from jetpipe_ros.nodes.domain import reserve_domain  # noqa: E402

WARM_UP = 8.0  # [s] after the first prediction: discovery settles, the monitor judges
TICKS = os.sysconf("SC_CLK_TCK")  # /proc/<pid>/stat time unit [1/s]


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` so far [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def start(module: str, *args: str) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]), PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-m", module, "--ros-args", *args], cwd=REPO,
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)


def measure(procs: dict[str, subprocess.Popen], seconds: float) -> dict:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.experimental import EventsExecutor
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import JointState

    from jetpipe_ros.nodes import interface

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_twin")
    deep = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE,
                      history=HistoryPolicy.KEEP_LAST)
    measured: dict[int, int] = {}
    predicted: dict[int, int] = {}

    def stamp(m) -> int:
        return m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec

    node.create_subscription(JointState, "joint_states",
                             lambda m: measured.__setitem__(stamp(m), time.perf_counter_ns()),
                             deep)
    node.create_subscription(JointState, "twin/joint_states",
                             lambda m: predicted.__setitem__(stamp(m), time.perf_counter_ns()),
                             deep)
    diag: list = []
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: diag.append(m), 10)
    setpoint = interface.publisher(node, "position_setpoint")
    msg_class = interface.topic("position_setpoint").message_class()
    rng = np.random.default_rng(5)
    level = [0.0]
    node.create_timer(0.35, lambda: level.__setitem__(0, float(rng.uniform(-0.018, 0.018))))
    node.create_timer(0.01, lambda: setpoint.publish(msg_class(data=level[0])))
    executor = EventsExecutor()
    executor.add_node(node)

    def spin_until(deadline: float) -> None:
        while time.monotonic() < deadline:
            for name, p in procs.items():
                if p.poll() is not None:
                    raise SystemExit(f"{name} exited with status {p.returncode}")
            executor.spin_once(timeout_sec=0.05)

    deadline = time.monotonic() + 90.0
    while not predicted and time.monotonic() < deadline:
        spin_until(time.monotonic() + 0.1)
    if not predicted:
        raise SystemExit("no prediction from gap_monitor within 90 s")
    spin_until(time.monotonic() + WARM_UP)
    cpu0 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
    wall0 = time.monotonic()
    first = max(measured)
    spin_until(wall0 + seconds)
    cpu1 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
    wall = time.monotonic() - wall0
    last = max(measured) - 100_000_000  # predictions of the latest 0.1 s may be under way
    spin_until(time.monotonic() + 1.0)
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()
    window = [s for s in measured if first < s <= last]
    lat = np.array([(predicted[s] - measured[s]) / 1e6 for s in window if s in predicted])
    status = {}
    for m in reversed(diag):
        gap = [s for s in m.status if s.name.endswith("gap_monitor: gap")]
        if gap:
            status = {kv.key: kv.value for kv in gap[0].values}
            status["level"] = gap[0].level[0]
            status["message"] = gap[0].message
            break
    return {"cpu": {n: 100.0 * (cpu1[n] - cpu0[n]) / wall for n in procs},
            "measured": len(window), "predicted": int(lat.size),
            "lat": [float(np.percentile(lat, 50)), float(np.percentile(lat, 99)),
                    float(lat.max())] if lat.size else [np.nan] * 3,
            "status": status}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="measurement window [s]")
    args = parser.parse_args()
    domain = reserve_domain()
    os.environ["ROS_DOMAIN_ID"] = str(domain.domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    cfg = REPO / "config"
    procs = {
        "actuator_sim": start("jetpipe_ros.nodes.actuator_sim", "--params-file",
                              str(cfg / "actuator.yaml"), "-p", "sensors.noise:=true",
                              "-p", "report_period:=0.0"),
        "controller": start("jetpipe_ros.nodes.controller", "--params-file",
                            str(cfg / "controller.yaml")),
        "gap_monitor": start("jetpipe_ros.nodes.gap_monitor", "--params-file",
                             str(cfg / "gap_monitor.yaml"), "-p", "auto_capture_after:=0.0"),
    }
    try:
        r = measure(procs, args.seconds)
    finally:
        for p in procs.values():
            p.terminate()
        for p in procs.values():
            try:
                p.wait(10.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    s = r["status"]
    load = os.getloadavg()[0]
    print(f"| gap_monitor beside actuator_sim + controller, realtime 1 kHz, {args.seconds:.0f} "
          f"s, {os.cpu_count()} cores, load average {load:.1f} | measured | target |")
    print("|---|---|---|")
    print(f"| gap_monitor CPU (one core) | {r['cpu']['gap_monitor']:.1f} % | < 50 % |")
    print(f"| actuator_sim CPU / controller CPU | {r['cpu']['actuator_sim']:.1f} % / "
          f"{r['cpu']['controller']:.1f} % | - |")
    p50, p99, mx = r["lat"]
    print(f"| latency measurement -> prediction p50 / p99 / max (seen by a third process) | "
          f"{p50:.2f} / {p99:.2f} / {mx:.1f} ms | - |")
    kept = 100.0 * r["predicted"] / max(r["measured"], 1)
    print(f"| samples predicted / measured in the window | {r['predicted']} / {r['measured']} "
          f"({kept:.3f} %) | >= 99.9 % |")
    if s:
        print(f"| monitor's counts since start: samples, filled, without command, without a "
              f"measurement, late, pauses | {s.get('samples')}, "
              f"{s.get('samples filled (lost)')}, {s.get('samples without command')}, "
              f"{s.get('samples without a measurement')}, {s.get('samples late')}, "
              f"{s.get('pauses')} | - |")
        print(f"\nmonitor's gap status (level {s['level']}): {s['message']}")


if __name__ == "__main__":
    main()
