"""actuator_sim in time_mode sim: publishes /clock, stamps with it, runs faster than real time."""

from __future__ import annotations

import re

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


FLAT_OUT = re.compile(r"stepped (\d+) samples in [\d.]+ s: .* over (\d+) timer ticks")


def test_clock_runs_faster_than_real_time(sim, probe):
    """Flat out (real_time_factor 0) the simulator is not paced by the wall clock: each timer
    tick (every millisecond at most) steps max_catch_up = 50 samples, 50 ms of simulated time,
    counted in its own report over two report periods. How fast that is in wall time depends
    on the CPU it gets (about 4 x real time on an idle 2-core machine: bench/bench_node.py);
    paced at 1 x real time it stepped 1000 samples over 736 ticks of a loaded machine."""
    client = AsyncParameterClient(probe.node, "/actuator_sim")
    assert client.wait_for_services(10.0)
    mark = len(sim.lines)
    future = client.set_parameters([Parameter("report_period", value=1.0)])
    assert probe.spin_until(future.done, 10.0)
    assert all(r.successful for r in future.result().results)
    for _ in range(2):  # the first may also cover the time before the change
        line = sim.wait_for("stepped", 30.0, start=mark)
        mark = next(i for i in range(mark, len(sim.lines)) if sim.lines[i] == line) + 1
    samples, ticks = (int(x) for x in FLAT_OUT.search(line).groups())
    assert ticks > 0 and samples == 50 * ticks, line
    future = client.set_parameters([Parameter("report_period", value=0.0)])
    assert probe.spin_until(future.done, 10.0)


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
