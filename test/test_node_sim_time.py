"""actuator_sim in time_mode sim: publishes /clock, stamps with it, runs faster than real time."""

from __future__ import annotations

import time

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


def _speed(probe: Probe, window: float) -> float:
    """Simulated seconds per wall second over ``window`` [s], from /clock."""
    probe.spin_for(0.2)
    t0 = time.monotonic()
    start = _seconds(probe.messages("/clock")[-1].clock)
    probe.spin_for(window)
    wall = time.monotonic() - t0
    return (_seconds(probe.messages("/clock")[-1].clock) - start) / wall


def test_clock_runs_faster_than_real_time(probe):
    assert _speed(probe, 1.5) > 1.5


def test_subscriber_with_use_sim_time_follows_clock(probe):
    now = probe.node.get_clock().now().nanoseconds * 1e-9
    latest = _seconds(probe.messages("/clock")[-1].clock)
    assert 1.0 < now < 1e6  # not wall time (1.7e9 s), not zero: simulated seconds
    # The node clock takes every /clock; the recorded list may trail it under load.
    assert now >= latest - 0.5
    probe.spin_for(0.5)
    assert probe.node.get_clock().now().nanoseconds * 1e-9 > now + 0.5  # faster than wall


def test_stamps_are_simulated_time(probe):
    joints = probe.messages("joint_states")[-200:]
    stamps = [_seconds(m.header.stamp) for m in joints]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert stamps[-1] == pytest.approx(_seconds(probe.messages("/clock")[-1].clock), abs=0.5)


def test_real_time_factor_can_be_set(sim, probe):
    client = AsyncParameterClient(probe.node, "/actuator_sim")
    assert client.wait_for_services(10.0)
    future = client.set_parameters([Parameter("real_time_factor", value=2.0)])
    assert probe.spin_until(future.done, 10.0)
    assert future.result().results[0].successful
    assert _speed(probe, 1.5) == pytest.approx(2.0, rel=0.2)
    assert sim.popen.poll() is None
