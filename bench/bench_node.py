"""actuator_sim in real time: message rate, inter-arrival period and CPU, seen from outside.

Starts the simulator in its own process (real-time mode), subscribes to ``position`` from this
process while commanding a +-0.5 V, 0.5 Hz square wave at 100 Hz, and prints a markdown table:
rate, period p50/p99/max, and the simulator's CPU use in % of one core (utime + stime from
/proc/<pid>/stat over the window), next to the targets. The simulator's own report of its
achieved step rate and overruns follows the table.
Usage: .venv/bin/python bench/bench_node.py [--seconds 60] [--executor events|single]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from jetpipe_ros.nodes.domain import reserve_domain  # noqa: E402

WARM_UP = 2.0  # [s] after the first message: discovery settles, caches warm
TICKS = os.sysconf("SC_CLK_TCK")  # /proc/<pid>/stat time unit [1/s]


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` so far [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS  # utime, stime (fields 14, 15)


def start_sim(executor: str) -> tuple[subprocess.Popen, list[str]]:
    """The simulator process and the list its output lines are collected into."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]), PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args", "--params-file",
         str(REPO / "config" / "actuator.yaml"), "-p", f"executor:={executor}",
         "-p", "report_period:=0.0"],
        cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []

    def read() -> None:
        for line in proc.stdout:
            lines.append(line)

    threading.Thread(target=read, daemon=True).start()
    return proc, lines


def measure(proc: subprocess.Popen, seconds: float) -> dict[str, float]:
    """Subscribe to ``position`` for ``seconds`` after the warm-up; the figures."""
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.signals import SignalHandlerOptions

    from jetpipe_ros.nodes import interface

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_node")
    arrivals: list[int] = []
    interface.subscription(node, "position", lambda _: arrivals.append(time.perf_counter_ns()))
    command = interface.publisher(node, "voltage_cmd")
    msg_class = interface.topic("voltage_cmd").message_class()
    node.create_timer(0.01, lambda: command.publish(
        msg_class(data=0.5 if int(time.monotonic()) % 2 else -0.5)))
    executor = EventsExecutor()
    executor.add_node(node)

    def spin_until(deadline: float) -> None:
        while time.monotonic() < deadline:
            if proc.poll() is not None:
                raise SystemExit(f"actuator_sim exited with status {proc.returncode}")
            executor.spin_once(timeout_sec=0.1)

    deadline = time.monotonic() + 60.0
    while not arrivals and time.monotonic() < deadline:
        spin_until(time.monotonic() + 0.1)
    if not arrivals:
        raise SystemExit("no position message within 60 s")
    spin_until(time.monotonic() + WARM_UP)
    first = len(arrivals)
    cpu0, wall0, own0 = cpu_seconds(proc.pid), time.monotonic(), time.process_time()
    spin_until(wall0 + seconds)
    cpu1, wall1, own1 = cpu_seconds(proc.pid), time.monotonic(), time.process_time()
    window = np.array(arrivals[first:], dtype=np.int64)
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()
    period_ms = np.diff(window) / 1e6
    wall = wall1 - wall0
    return {"rate": (window.size - 1) / ((window[-1] - window[0]) / 1e9),
            "messages": window.size, "p50": float(np.percentile(period_ms, 50)),
            "p99": float(np.percentile(period_ms, 99)), "max": float(period_ms.max()),
            "cpu": 100.0 * (cpu1 - cpu0) / wall, "own_cpu": 100.0 * (own1 - own0) / wall}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="measurement window [s]")
    parser.add_argument("--executor", choices=("events", "single"), default="events",
                        help="rclpy executor of the simulator")
    args = parser.parse_args()
    domain = reserve_domain()  # held until the benchmark ends: no other run shares it
    os.environ["ROS_DOMAIN_ID"] = str(domain.domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    proc, lines = start_sim(args.executor)
    try:
        r = measure(proc, args.seconds)
    finally:
        proc.terminate()
        try:
            proc.wait(10.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    time.sleep(0.2)  # let the reader thread take the last lines
    print(f"| actuator_sim, realtime, {args.executor} executor, {args.seconds:.0f} s, "
          f"{os.cpu_count()} cores | measured | target |")
    print("|---|---|---|")
    print(f"| position rate | {r['rate']:.1f} Hz ({r['messages']} messages) | >= 999 Hz |")
    print(f"| period p50 / p99 / max | {r['p50']:.3f} / {r['p99']:.3f} / {r['max']:.2f} ms "
          "| p99 <= 1.3 ms |")
    print(f"| simulator CPU (one core) | {r['cpu']:.1f} % | <= 50 % |")
    print(f"| subscriber CPU (this process) | {r['own_cpu']:.1f} % | - |")
    report = [line.strip() for line in lines if "total: stepped" in line]
    print(f"\nsimulator: {report[-1].split(']: ', 1)[-1] if report else 'no report'}")


if __name__ == "__main__":
    main()
