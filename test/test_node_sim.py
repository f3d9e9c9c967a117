"""actuator_sim in its own process, driven over topics (real-time mode, namespace /axis1).

One simulator process serves the whole module; the tests run in file order, the first one
while the actuator is still at rest.
"""

from __future__ import annotations

import math
import time

import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from ros_probe import Probe

NS = "/axis1"
STARTUP = 30.0  # [s] generous: the first numba compile of the kernel takes seconds
P_REST = 416480.0  # [Pa] initial chamber pressure of config/actuator.yaml
AREA = 0.005433  # [m^2] piston area of config/actuator.yaml
SENSORS = ("position", "chamber1/pressure", "chamber2/pressure", "joint_states")


@pytest.fixture(scope="module")
def sim(module_launch):
    """The simulator under test; ``mechanics.mass:=1`` checks an integer is taken as 1.0 kg."""
    proc = module_launch(["-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args",
                          "-r", f"__ns:={NS}", "--params-file", "config/actuator.yaml",
                          "-p", "mechanics.mass:=1", "-p", "report_period:=1.0"])
    proc.wait_for("started:", STARTUP)
    return proc


@pytest.fixture(scope="module")
def probe(sim, ros_context):
    probe = Probe(ros_context, namespace=NS)
    probe.listen(*SENSORS)
    probe.repeat(0.01)
    assert probe.spin_until(lambda: all(probe.messages(n) for n in SENSORS), 15.0), \
        f"no sensor messages from the simulator; its output:\n{sim.output}"
    yield probe
    probe.close()


def _stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def test_positive_voltage_moves_piston_positive(probe):
    p1_rest = probe.messages("chamber1/pressure")[0].fluid_pressure
    p2_rest = probe.messages("chamber2/pressure")[0].fluid_pressure
    assert p1_rest == pytest.approx(P_REST, abs=2000.0)
    assert p2_rest == pytest.approx(P_REST, abs=2000.0)
    y0 = probe.messages("position")[-1].data

    t0 = time.monotonic()
    probe.command["voltage_cmd"] = 1.0
    probe.spin_for(1.5)
    del probe.command["voltage_cmd"]

    y = [m.data for m in probe.messages("position", t0)]
    p1 = [m.fluid_pressure for m in probe.messages("chamber1/pressure", t0)]
    p2 = [m.fluid_pressure for m in probe.messages("chamber2/pressure", t0)]
    joints = probe.messages("joint_states", t0)
    assert min(len(y), len(p1), len(joints)) > 300  # of 1500; a busy test process drops some
    assert all(math.isfinite(v) for v in y + p1 + p2)
    assert all(1e4 < p < 1.2e6 for p in p1 + p2)
    assert y[-1] > y0 + 0.01  # towards the +25 mm end stop
    assert p1[-1] > p2[-1] + 1e5
    stamps = [_stamp_ns(m) for m in joints]
    steps = sorted(b - a for a, b in zip(stamps, stamps[1:]))
    assert steps[0] > 0  # strictly increasing
    assert steps[len(steps) // 2] == 1_000_000  # 1 ms between samples
    last = joints[-1]
    assert list(last.name) == ["piston"]
    assert last.position[0] == pytest.approx(y[-1], abs=1e-3)
    assert last.effort[0] == pytest.approx(AREA * (p1[-1] - p2[-1]), rel=0.05)
    assert max(m.velocity[0] for m in joints) > 0.01
    assert probe.messages("chamber1/pressure")[-1].header.frame_id == "actuator"


def test_command_timeout_zeroes_valve(sim, probe):
    mark = len(sim.lines)
    probe.publish("voltage_cmd", 0.2)
    probe.spin_for(0.1)
    line = sim.wait_for("no voltage_cmd for 0.5 s", 5.0, start=mark)
    assert "commanding 0 V" in line


def test_bad_commands_are_survived(sim, probe):
    mark = len(sim.lines)
    t0 = time.monotonic()
    for value in (math.nan, math.inf, 100.0, -math.inf, -100.0, math.nan):
        probe.publish("voltage_cmd", value)
        probe.publish("load_force", math.nan)
        probe.spin_for(0.1)
    probe.spin_for(0.4)
    assert sim.popen.poll() is None, sim.output
    y = [m.data for m in probe.messages("position", t0)]
    p = [m.fluid_pressure for m in probe.messages("chamber1/pressure", t0)]
    assert min(len(y), len(p)) > 300  # of 1000
    assert all(math.isfinite(v) for v in y + p)
    sim.wait_for("ignoring non-finite voltage_cmd", 2.0, start=mark)
    sim.wait_for("beyond valve.command_limit 3.4 V; clipped", 2.0, start=mark)
    sim.wait_for("ignoring non-finite load_force", 2.0, start=mark)
    assert "not finite" not in "\n".join(sim.lines[mark:])


def test_runtime_parameter_changes(probe):
    client = AsyncParameterClient(probe.node, f"{NS}/actuator_sim")
    assert client.wait_for_services(10.0)

    def set_one(name, value):
        future = client.set_parameters([Parameter(name, value=value)])
        assert probe.spin_until(future.done, 10.0)
        return future.result().results[0]

    read_only = set_one("integration.sample_time", 0.002)
    assert not read_only.successful and "read-only" in read_only.reason
    model = set_one("valve.coil_resistance", 200.0)  # rebuilds the model, keeps its state
    assert model.successful, model.reason
    bad_model = set_one("mechanics.mass", -1.0)
    assert not bad_model.successful and "mechanics.mass" in bad_model.reason
    bad = set_one("command_timeout", -1.0)
    assert not bad.successful and "command_timeout" in bad.reason
    good = set_one("command_timeout", 0.4)
    assert good.successful, good.reason
    refused = set_one("use_sim_time", True)
    assert not refused.successful and "time_mode sim" in refused.reason


def test_step_rate_reported(sim):
    line = sim.wait_for("stepped", 5.0)
    assert "Hz" in line and "overruns" in line


def test_namespace_moves_topics(probe):
    def names():
        return {name for name, _ in probe.node.get_topic_names_and_types()}

    expected = {f"{NS}/{t}" for t in (*SENSORS, "friction_force", "voltage_cmd", "load_force")}
    assert probe.spin_until(lambda: expected <= names(), 5.0), names()
    assert not {"/position", "/voltage_cmd", "/joint_states"} & names()
