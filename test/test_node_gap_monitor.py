"""gap_monitor beside actuator_sim and the controller, each in its own process (namespace
/twin1, sensor noise on; the simulator in simulated time at real-time speed, so that a
loaded machine slows it down rather than making it drop samples): the hardware's valve gets a 20 Hz lag while it runs; the
monitor goes from OK to ERROR within a few horizons, captures, and the capture's diagnosis names
the lag. The capture is compared, stamp by stamp, with the messages a test-side node recorded
beside it. The simulator stops while the capture is diagnosed, and the monitor says STALE; a
capture on request then holds the samples it last received."""

from __future__ import annotations

import bisect
import csv
import json
import re

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from ros_probe import Probe
from sensor_msgs.msg import FluidPressure, JointState
from std_srvs.srv import Trigger

from jetpipe_ros.fileio import load_yaml
from jetpipe_ros.model import ModelParams

NS = "/twin1"
STARTUP = 30.0  # [s] the first numba compile of the kernel takes seconds
CAPTURE = 8.0  # [s] length of a capture
AUTO = 8.0  # [s] the gap at ERROR this long starts a capture
DEEP = QoSProfile(depth=30000, reliability=ReliabilityPolicy.RELIABLE,
                  history=HistoryPolicy.KEEP_LAST)


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


@pytest.fixture(scope="module")
def rig(module_launch, tmp_path_factory):
    out = tmp_path_factory.mktemp("captures")
    args = ["--ros-args", "-r", f"__ns:={NS}"]
    sim = module_launch(["-m", "jetpipe_ros.nodes.actuator_sim", *args, "--params-file",
                         "config/actuator.yaml", "-p", "sensors.noise:=true",
                         "-p", "time_mode:=sim"])
    ctl = module_launch(["-m", "jetpipe_ros.nodes.controller", *args, "--params-file",
                         "config/controller.yaml"])
    mon = module_launch(["-m", "jetpipe_ros.nodes.gap_monitor", *args, "--params-file",
                         "config/gap_monitor.yaml", "-p", f"capture_dir:={out}",
                         "-p", f"capture_seconds:={CAPTURE}", "-p", f"auto_capture_after:={AUTO}",
                         "-p", "stale_timeout:=1.0", "-p", "diagnostic_period:=0.25"])
    for proc in (sim, ctl, mon):
        proc.wait_for("started:", STARTUP)
    return sim, ctl, mon, out


class Listener:
    """The test's own record of the actuator's messages and the monitor's diagnostics."""

    def __init__(self, probe: Probe) -> None:
        self.messages: dict[str, dict[int, object]] = {}
        for name, kind in (("joint_states", JointState), ("chamber1/pressure", FluidPressure),
                           ("chamber2/pressure", FluidPressure),
                           ("voltage_applied", JointState),
                           ("twin/joint_states", JointState)):
            log = self.messages.setdefault(name, {})
            probe.node.create_subscription(
                kind, name, lambda m, log=log: log.__setitem__(_ns(m.header.stamp), m), DEEP)
        self.statuses: list[dict[str, DiagnosticStatus]] = []
        probe.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        mine = {s.name.rsplit(": ", 1)[1]: s for s in msg.status
                if s.name.startswith(f"{NS}/gap_monitor: ")}
        if mine:
            self.statuses.append(mine)

    def latest(self, which: str) -> DiagnosticStatus | None:
        return self.statuses[-1][which] if self.statuses else None


def _values(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def _level(status: DiagnosticStatus | None) -> int:
    return -1 if status is None else status.level[0]


def test_effect_switched_on_is_flagged_captured_and_named(rig, ros_context):
    sim, ctl, mon, out = rig
    probe = Probe(ros_context, namespace=NS)
    listener = Listener(probe)
    rng = np.random.default_rng(7)
    probe.command["position_setpoint"] = 0.0
    probe.repeat(0.001)
    probe.node.create_timer(0.35, lambda: probe.command.__setitem__(
        "position_setpoint", float(rng.uniform(-0.018, 0.018))))
    try:
        # The nominal model beside nominal hardware: judged OK once it has the history.
        def judged():
            s = listener.latest("gap")
            return s is not None and "y level" in _values(s)
        assert probe.spin_until(judged, 60.0), f"never judged; monitor:\n{mon.output}"
        probe.spin_for(2.0)
        before = listener.latest("gap")
        assert _level(before) == DiagnosticStatus.OK[0], (before.message, _values(before))
        assert float(_values(before)["y gap [%]"]) < 1.0

        client = AsyncParameterClient(probe.node, f"{NS}/actuator_sim")
        assert client.wait_for_services(10.0)
        future = client.set_parameters([
            Parameter("effects.valve_lag.corner_frequency", value=20.0),
            Parameter("effects.valve_lag.enabled", value=True)])
        assert probe.spin_until(future.done, 10.0)
        assert all(r.successful for r in future.result().results)
        # The stamp from which the lag acts, as the simulator says it.
        switched_at = float(re.search(r"acting from the sample stamped ([0-9.]+) s", sim.wait_for(
            "model parameters changed", 10.0)).group(1))

        def error():
            return _level(listener.latest("gap")) == DiagnosticStatus.ERROR[0]
        assert probe.spin_until(error, 30.0), listener.latest("gap").message
        flagged = _values(listener.latest("gap"))
        assert max(float(flagged[f"{s} gap [%]"]) for s in ("y", "p1", "p2")) > 2.0

        # The gap stays at ERROR: a capture, then its diagnosis in a separate process.
        def diagnosing():
            s = listener.latest("capture")
            return s is not None and ("diagnosing" in s.message or "verdict" in s.message
                                      or "failed" in s.message)
        assert probe.spin_until(diagnosing, 60.0), mon.output

        # The hardware dies: STALE. (Stopped here, so that the diagnosis does not share the
        # machine's cores with the simulator and the controller: 54 s beside them, 14 s alone.)
        sim.stop()
        ctl.stop()
        assert probe.spin_until(
            lambda: _level(listener.latest("gap")) == DiagnosticStatus.STALE[0], 20.0)
        assert "no samples for" in listener.latest("gap").message

        def verdict():
            s = listener.latest("capture")
            return s is not None and ("verdict" in s.message or "failed" in s.message)
        assert probe.spin_until(verdict, 240.0), mon.output
        capture = listener.latest("capture")
        info = _values(capture)
        assert info["effect"] == "valve_lag", capture.message
        assert info["subsystem"] == "valve"
        assert float(info["shrinkage"]) > 0.5
        assert json.loads(info["params"])["corner_frequency"] == pytest.approx(20.0, rel=0.3)

        # Every sample of the capture's window is there, equal to what was published.
        dataset = out.joinpath(info["dataset"]).resolve()
        index = load_yaml(dataset / "dataset.yaml")["experiments"]
        assert [e["role"] for e in index][:3] == ["train", "train", "holdout"]
        origin = index[0]["stamp_origin_ns"]
        # Flagged within three horizons of the switch, counted in the samples' own time (a
        # status read when the switch was made may speak of samples a second old: the monitor
        # falls behind on a loaded machine and catches up).
        horizon = load_yaml("config/gap_monitor.yaml")["/**/gap_monitor"]["ros__parameters"][
            "horizon"]
        late = float(flagged["level since t [s]"]) - (switched_at - origin / 1e9)
        assert 0.0 < late <= 3 * horizon, late
        # The capture holds samples after the switch only: at ERROR for AUTO s of samples, the
        # last CAPTURE s of them.
        assert origin / 1e9 + index[0]["captured_from_s"] > switched_at
        rows = []
        for e in index:
            with open(dataset / e["file"]) as f:
                for r in csv.DictReader(f):
                    rows.append((origin + round((e["captured_from_s"] + float(r["t"])) * 1e9),
                                 r))
        stamps = [s for s, _ in rows]
        recorded = sorted(s for s in listener.messages["joint_states"]
                          if stamps[0] <= s <= stamps[-1])
        assert stamps == sorted(stamps)
        # The test's own listener may lose messages on a loaded machine (it is a Python
        # subscriber like any other; on a machine running other work it lost a third): what the
        # capture holds beyond it is at most what it visibly missed of the regular 1 kHz stream
        # (the holes in its own stamps); every sample the listener got is in the capture, but
        # what the transport lost on the way to the monitor (a sample short of a message is not
        # written).
        missed_here = set(stamps) - set(recorded)
        step = float(np.median(np.diff(recorded)))
        holes = sum(round(d / step) - 1 for d in np.diff(recorded)) + round(
            (recorded[0] - stamps[0]) / step) + round((stamps[-1] - recorded[-1]) / step)
        assert len(missed_here) <= holes, (len(missed_here), holes)
        counts = _values(listener.latest("gap"))
        lost = sum(int(counts[k]) for k in ("samples without command", "samples without a "
                                            "measurement", "samples filled (lost)"))
        assert len(set(recorded) - set(stamps)) <= lost, (len(recorded), len(stamps))
        # and every sample the monitor received in the window's CAPTURE s, a message short or
        # not, is there (fewer where samples were lost on the way to it).
        received = index[0]["received_rows"]
        assert received <= int(CAPTURE * 1000) and stamps[-1] - stamps[0] < CAPTURE * 1e9
        assert len(stamps) == received - 1 - index[0]["incomplete_rows"]
        applied = listener.messages["voltage_applied"]
        applied_stamps = sorted(applied)
        checked = 0
        # Every row the listener also got (on a loaded machine it lost up to 88 % of a stream:
        # a sparse sample of the rows then held too few of them to tell).
        for stamp, r in rows:
            if stamp not in listener.messages["joint_states"] or stamp not in \
                    listener.messages["chamber1/pressure"]:
                continue  # the listener missed it
            y = listener.messages["joint_states"][stamp].position[0]
            p1 = listener.messages["chamber1/pressure"][stamp].fluid_pressure
            assert float(r["y"]) == pytest.approx(y, rel=1e-8, abs=1e-12)
            assert float(r["p1"]) == pytest.approx(p1, rel=1e-8)
            at = bisect.bisect_right(applied_stamps, stamp)
            following = applied_stamps[at] if at < len(applied_stamps) else None
            if following is not None and following - stamp <= 1_000_000:  # the next sample
                assert float(r["u"]) == pytest.approx(applied[following].position[0], abs=1e-8)
            checked += 1
        assert checked >= 20, (checked, len(rows))
        # The twin's predictions carry the measurements' stamps. That it predicts every sample
        # is the twin core's test (test_twin); how many reach a listener depends on the load
        # (the listener lost 12 % of them on a machine loaded 4x beyond its cores; on an idle
        # one the monitor predicts 100 %: bench/bench_twin.py).
        predicted = [s for s in listener.messages["twin/joint_states"]
                     if stamps[0] <= s <= stamps[-1]]
        # (A sample the capture leaves out, a measurement short or its next sample lost, was
        # predicted all the same.)
        assert predicted and len(set(predicted) - set(stamps)) <= index[0]["incomplete_rows"]

        # A capture on request, without diagnosis: the samples held when the hardware died.
        params = AsyncParameterClient(probe.node, f"{NS}/gap_monitor")
        assert params.wait_for_services(10.0)
        done = params.set_parameters([Parameter("diagnose", value=False)])
        assert probe.spin_until(done.done, 10.0)
        trigger = probe.node.create_client(Trigger, f"{NS}/gap_monitor/capture")
        assert trigger.wait_for_service(10.0)
        answer = trigger.call_async(Trigger.Request())
        assert probe.spin_until(answer.done, 10.0)
        assert answer.result().success, answer.result().message
        assert probe.spin_until(lambda: "dataset written" in listener.latest("capture").message,
                                30.0)
        # The last CAPTURE s of samples: all of them, bar what the monitor counts as lost.
        held = int(re.search(r"\((\d+) samples", listener.latest("capture").message).group(1))
        counts = _values(listener.latest("gap"))
        lost = int(counts["samples filled (lost)"]) + int(counts["samples without command"]) \
            + round(float(counts["paused [s]"]) * 1000)
        assert CAPTURE * 1000 - lost <= held <= CAPTURE * 1000, (held, lost)
    finally:
        probe.close()


@pytest.mark.parametrize("given, said", [
    ("model_file:=no/such/model.yaml", "parameter model_file: no/such/model.yaml: cannot read"),
    ("pressure_sensors:=p3", "parameter pressure_sensors must be one of")])
def test_a_bad_parameter_is_a_startup_error_naming_it(launch, given, said):
    mon = launch(["-m", "jetpipe_ros.nodes.gap_monitor", "--ros-args", "-p", given])
    assert mon.popen.wait(STARTUP) == 2
    assert said in mon.output
    assert "not started" in mon.output


@pytest.mark.parametrize("pressure_sensors", ["none", "p1,p2"])
def test_a_rig_without_pressure_sensors_is_followed_sample_by_sample(launch, ros_context,
                                                                      pressure_sensors):
    """A rig that publishes its command and position only. Declared (``pressure_sensors:
    none``), a sample is whole with those two, so each is given to the twin at once; the
    chambers are simulated and the twin predicts the position of the samples, with their
    stamps. Not declared, every sample waits for the pressures (until 2,000 are pending), and
    the gap status says which topic it waits for and which parameter to set."""
    from twin_data import hardware

    ns = "/twin2"
    mon = launch(["-m", "jetpipe_ros.nodes.gap_monitor", "--ros-args", "-r", f"__ns:={ns}",
                  "-p", f"pressure_sensors:={pressure_sensors}",
                  "-p", "diagnostic_period:=0.2"])
    mon.wait_for("started:", STARTUP)
    declared = pressure_sensors == "none"
    assert ("sensors y, horizon" if declared else "sensors y, p1, p2, horizon") in mon.output
    probe = Probe(ros_context, namespace=ns)
    statuses: list[DiagnosticStatus] = []
    probe.node.create_subscription(
        DiagnosticArray, "/diagnostics",
        lambda m: statuses.extend(s for s in m.status if s.name == f"{ns}/gap_monitor: gap"),
        100)
    predicted: set[int] = set()
    probe.node.create_subscription(JointState, "twin/joint_states",
                                   lambda m: predicted.add(_ns(m.header.stamp)), DEEP)
    try:
        # Reliable and deep, so that a loaded machine delays the stream rather than losing it.
        command = probe.node.create_publisher(JointState, "voltage_applied", DEEP)
        position = probe.node.create_publisher(JointState, "joint_states", DEEP)
        assert probe.spin_until(lambda: command.get_subscription_count() > 0
                                and position.get_subscription_count() > 0, STARTUP)
        rows = hardware(ModelParams(), 0.5)
        start = 1_000_000_000
        for k, (t, u, f, y, _, _) in enumerate(rows):
            stamp = start + round(t * 1e9)
            sec, nanosec = divmod(stamp, 1_000_000_000)
            a = JointState(name=["valve", "load"], position=[u, 0.0], effort=[0.0, f])
            b = JointState(name=["piston"], position=[y])
            for msg in (a, b):
                msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
            command.publish(a)
            position.publish(b)
            if k % 50 == 49:
                probe.spin_for(0.02)
        if not declared:
            def said():
                return bool(statuses) and "no message on chamber1/pressure, " \
                    "chamber2/pressure beside" in statuses[-1].message
            assert probe.spin_until(said, 60.0), statuses[-1:] and statuses[-1].message
            assert "pressure_sensors (now p1,p2)" in statuses[-1].message
            assert _values(statuses[-1])["samples"] == "0" and not predicted
            return

        def counted():  # every sample whose two messages both arrived
            return bool(statuses) and int(_values(statuses[-1])["samples"]) >= 0.9 * len(rows)
        assert probe.spin_until(counted, 60.0), (statuses[-1:] and _values(statuses[-1]),
                                                 mon.output)
        values = _values(statuses[-1])
        assert values["samples without a measurement"] == "0"
        assert values["samples without command"] == "0"
        assert values["stamp interval [ms]"] == "1"
        assert "no message on" not in statuses[-1].message
        # The predictions go out best-effort, as sensor data: a loaded machine may lose some
        # on the way to this listener (12 % at four times its cores, the test above).
        assert probe.spin_until(lambda: len(predicted) >= 0.5 * (len(rows) - 1), 30.0), \
            len(predicted)
        stamps = {start + round(t * 1e9) for t in rows[:, 0]}
        assert predicted <= stamps
    finally:
        probe.close()
