"""actuator_sim in time_mode sim: publishes /clock, stamps with it, runs faster than real time."""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from ros_probe import Probe

STARTUP = 30.0  # [s] see test_node_sim.py


@pytest.fixture(scope="module")
def sim(module_launch):
    proc = module_launch(["-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args",
                          "--params-file", "config/actuator.yaml",
                          "-p", "time_mode:=sim", "-p", "real_time_factor:=0.0",
                          "-p", "use_sim_time:=true"])
    proc.wait_for("started: time_mode sim", STARTUP)
    return proc


@pytest.fixture(scope="module")
def probe(sim, ros_context):
    probe = Probe(ros_context, use_sim_time=True)
    probe.listen("/clock", "joint_states")
    assert probe.spin_until(lambda: probe.messages("/clock") and probe.messages("joint_states"),
                            15.0), f"no /clock from the simulator; its output:\n{sim.output}"
    yield probe
    probe.close()


def _seconds(t) -> float:
    return t.sec + 1e-9 * t.nanosec


WINDOW = 3.0  # [s] of wall time per speed measurement: long enough to average out stalls


def _cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` so far [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _speed(probe: Probe, pid: int, window: float = WINDOW) -> tuple[float, float]:
    """(simulated seconds per wall second, the simulator's CPU share [cores]) over ``window``
    [s]: the simulated time /clock advanced (samples stepped, not messages received) over the
    wall time between the two readings."""
    probe.spin_for(0.2)
    t0, cpu0 = time.monotonic(), _cpu_seconds(pid)
    start = _seconds(probe.messages("/clock")[-1].clock)
    probe.spin_for(window)
    wall = time.monotonic() - t0
    simulated = _seconds(probe.messages("/clock")[-1].clock) - start
    return simulated / wall, (_cpu_seconds(pid) - cpu0) / wall


def _oversubscribed() -> bool:
    """More runnable work than cores on this machine (1-minute load average)."""
    return os.getloadavg()[0] > (os.cpu_count() or 1)


def test_clock_runs_faster_than_real_time(sim, probe):
    """As fast as it can: about 4x real time on the idle 2-core machine; a simulator paced to
    the wall clock stays <= 1. Flat out it is bound by the CPU it gets: on a machine loaded
    beyond its cores (three other test suites on two cores gave 0.95-2.6x), when it got under
    half a core, what is checked is more than 1.5 simulated seconds per CPU second (it would
    be faster than real time on a core of its own)."""
    speed, share = _speed(probe, sim.popen.pid)
    if _oversubscribed() and share < 0.5:
        assert speed / share > 1.5
    else:
        assert speed > 1.05


def test_subscriber_with_use_sim_time_follows_clock(probe):
    now = probe.node.get_clock().now().nanoseconds * 1e-9
    latest = _seconds(probe.messages("/clock")[-1].clock)
    assert 1.0 < now < 1e6  # not wall time (1.7e9 s), not zero: simulated seconds
    # The node clock takes every /clock; the recorded list may trail it under load.
    assert now >= latest - 0.5
    # It moves with /clock, however fast the loaded machine lets the simulator run.
    assert probe.spin_until(lambda: probe.node.get_clock().now().nanoseconds * 1e-9 > now + 0.5,
                            30.0)


def test_stamps_are_simulated_time(probe):
    joints = probe.messages("joint_states")[-200:]
    stamps = [_seconds(m.header.stamp) for m in joints]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert stamps[-1] == pytest.approx(_seconds(probe.messages("/clock")[-1].clock), abs=0.5)


REPORT = re.compile(r"stepped (\d+) samples in ([\d.]+) s: .*\((\d+) samples dropped\)")


def test_real_time_factor_can_be_set(sim, probe):
    """Set to 2 at run time, the simulator is paced at 2 x real time, counted in its own
    samples over two 3-s report periods: those stepped plus those a starved process had to
    drop (a backlog beyond max_catch_up) make 2 per millisecond of wall time (within what a
    preempted tick shifts the report's clock: 1.6-2.1), and those stepped never exceed it
    (flat out it ran at about 4 on an idle machine)."""
    client = AsyncParameterClient(probe.node, "/actuator_sim")
    assert client.wait_for_services(10.0)
    mark = len(sim.lines)
    future = client.set_parameters([Parameter("real_time_factor", value=2.0),
                                    Parameter("report_period", value=3.0)])
    assert probe.spin_until(future.done, 10.0)
    assert all(r.successful for r in future.result().results)
    reports = []
    for _ in range(3):  # the first also covers the time before the change
        line = sim.wait_for("stepped", 30.0, start=mark)
        mark = next(i for i in range(mark, len(sim.lines)) if sim.lines[i] == line) + 1
        reports.append([float(x) for x in REPORT.search(line).groups()])
    stepped = reports[1][0] + reports[2][0]
    wall = reports[1][1] + reports[2][1]
    dropped = reports[2][2] - reports[0][2]
    assert 1.6 < (stepped + dropped) * 1e-3 / wall < 2.1
    assert stepped * 1e-3 / wall < 2.1
    future = client.set_parameters([Parameter("report_period", value=0.0)])
    assert probe.spin_until(future.done, 10.0)
    assert sim.popen.poll() is None
