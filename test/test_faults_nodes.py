"""Faults survived by the nodes, with real processes: ``kill -9`` of the recorder, of the
simulator and of the controller mid-campaign; no simulator at start; a bag that cannot be
created; a stream that stops in record mode; a huge load; run-time parameter refusals."""

from __future__ import annotations

import json
import os
import shutil
import signal
import sys
import time

import numpy as np
import pytest
from rosbags.rosbag2 import Reader

from jetpipe_ros.bag import EVENTS_TOPIC, export_bag
from jetpipe_ros.bag.recover import StreamReport, stream_messages
from jetpipe_ros.campaign import load_campaign, run_campaign_offline
from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.model import ModelParams
from jetpipe_ros.nodes.id_recorder import Recorder, stamp_of
from ros_probe import Probe

STARTUP = 30.0  # [s] first numba compile
#: [s] the recorder's peer_timeout in these tests: 15 x the simulator's lock-step kick (0.2 s),
#: so that a loaded machine (CI ran a suite at 0.22 x real time) delaying a kick is not read as
#: the simulator's death.
PEER_TIMEOUT = 3.0

#: Two short experiments, then one long enough to be running when a process is killed.
PLAN = """
settle: {center: 0.2, rest: 0.2}
experiments:
  - {name: charge_1p15V, kind: open_loop, locked: true, role: train, duration: 1.0,
     voltage: {signal: steps, levels: [1.15, -1.15], durations: [0.6, 0.4]}}
  - {name: square_0p6V, kind: open_loop, role: train, duration: 1.0,
     voltage: {signal: square, amplitude: 0.6, frequency: 2.0}}
  - {name: sweep_long, kind: open_loop, locked: true, role: holdout, duration: 120.0,
     voltage: {signal: sine_sweep, amplitude: 1.0, f0: 1.0, f1: 20.0}}
"""
#: An open-loop experiment, then a long closed-loop one (the controller answers each sample).
CLOSED_PLAN = """
settle: {center: 0.2, rest: 0.2}
experiments:
  - {name: charge_1p15V, kind: open_loop, locked: true, role: train, duration: 0.5,
     voltage: {signal: steps, levels: [1.15, -1.15], durations: [0.3, 0.2]}}
  - {name: triangle_long, kind: closed_loop, role: train, duration: 120.0,
     setpoint: {signal: triangle, amplitude: 0.002, frequency: 0.5}}
"""


def unprivileged() -> list[str]:
    """A command prefix under which file permissions hold even for root (tests run as root in
    some containers): the capabilities that bypass them dropped."""
    if os.geteuid() != 0:
        return []
    if shutil.which("setpriv") is None:
        pytest.skip("running as root without setpriv: permissions cannot be tested")
    caps = "-dac_override,-dac_read_search"
    return ["setpriv", f"--bounding-set={caps}", f"--inh-caps={caps}"]


def _sim(launch, ns: str, *extra: str):
    return launch(["-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args", "-r", f"__ns:={ns}",
                   "--params-file", "config/actuator.yaml", "-p", "time_mode:=sim",
                   "-p", "lockstep:=true", "-p", "report_period:=0.0", *extra])


def _rig(launch, ns: str, *sim_extra: str):
    sim = _sim(launch, ns, *sim_extra)
    ctl = launch(["-m", "jetpipe_ros.nodes.controller", "--ros-args", "-r", f"__ns:={ns}",
                  "--params-file", "config/controller.yaml"])
    sim.wait_for("started:", STARTUP)
    ctl.wait_for("started:", STARTUP)
    return sim, ctl


def _recorder(launch, ns: str, bag, plan=None, *extra: str):
    args = ["-m", "jetpipe_ros.nodes.id_recorder", "--ros-args", "-r", f"__ns:={ns}",
            "-p", f"bag:={bag}", "-p", f"peer_timeout:={PEER_TIMEOUT}", *extra]
    if plan is not None:
        args += ["-p", f"campaign_file:={plan}"]
    return launch(args)


def _plan(tmp_path, text: str):
    path = tmp_path / "plan.yaml"
    path.write_text(text)
    return path


def _events(bag) -> list[dict]:
    """The experiment events of a closed bag (after the campaign's own, at its first sample)."""
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic == EVENTS_TOPIC]
        events = [json.loads(raw[8:-1].decode()) for _, _, raw in reader.messages(conns)]
    assert events[0]["event"] == "campaign"
    return [e for e in events if e["event"] == "experiment"]


def _streamed_events(bag) -> list[dict]:
    """Events readable from the MCAP file of a bag being written (as after a crash)."""
    (mcap,) = bag.glob("*.mcap")
    return [json.loads(raw[8:-1].decode()) for topic, _, _, raw in stream_messages(mcap)
            if topic == EVENTS_TOPIC]


def _tail(process, n: int = 12) -> str:
    """The last ``n`` lines a process printed (pytest cuts a long assertion message)."""
    return "\n".join(process.lines[-n:])


def _wait(condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"{what} not within {timeout} s")
        time.sleep(0.1)


def test_recorder_killed_mid_campaign_leaves_a_recoverable_bag(launch, tmp_path):
    """kill -9 of id_recorder while the third experiment runs: no metadata.yaml, no footer;
    ``jetpipe export`` recovers the two experiments completed before (equal to the offline
    runner) and says it recovered the bag; the joint_states samples are a gap-free prefix."""
    plan = _plan(tmp_path, PLAN)
    sim, _ = _rig(launch, "/kr", "-p", "report_period:=0.5")  # its step count every 0.5 s
    bag = tmp_path / "killed"
    rec = _recorder(launch, "/kr", bag, plan)
    rec.wait_for("experiment sweep_long", STARTUP + 60.0)
    # The second experiment's end is on disk while the recorder runs (synced within 1 s).
    _wait(lambda: any(e.get("name") == "square_0p6V" for e in _streamed_events(bag)), 30.0,
          "the event of square_0p6V readable from the MCAP stream")
    rec.popen.send_signal(signal.SIGKILL)
    assert rec.popen.wait(10.0) == -signal.SIGKILL
    killed_at = len(sim.lines)
    assert not (bag / "metadata.yaml").exists()
    with pytest.raises(Exception):  # noqa: B017 - whatever rosbags raises: it cannot open it
        with Reader(bag):
            pass

    report = StreamReport(next(bag.glob("*.mcap")))
    stamps = np.array([stamp_of(raw) for topic, _, _, raw in
                       stream_messages(report.path, report) if topic.endswith("/joint_states")])
    assert not report.closed
    steps = np.diff(np.unique(stamps))
    assert np.all(steps == 1_000_000)  # every sample up to the last synced one

    messages: list[str] = []
    data = read_dataset(export_bag(bag, tmp_path / "data", progress=messages.append))
    assert any("not closed" in m for m in messages), messages
    assert any(m.startswith("recovered ") for m in messages), messages
    assert [e.name for e in data.entries] == ["charge_1p15V", "square_0p6V"]
    offline = {e.name: x for e, x in
               read_dataset(run_campaign_offline(ModelParams(), load_campaign(plan),
                                                 tmp_path / "off"))}
    for entry, ros in data:
        off = offline[entry.name]
        assert entry.extra["missing_samples"] == 0
        assert ros.t.size == off.t.size
        assert np.max(np.abs(ros.u - off.u)) < 1e-9, entry.name
        assert np.max(np.abs(ros.p1 - off.p1)) < 1.0, entry.name
        assert np.max(np.abs(ros.y - off.y)) < 1e-6, entry.name
    # In lock-step the simulator steps only on commands: once the recorder is gone it stops.
    # Its reports after the kill (every 0.5 s), past the first (which holds the last commands
    # before the kill), count at most the few still in flight (a loaded machine delivered one a
    # report late), then none (running on, it would step about 500 per report).
    _wait(lambda: len(_step_reports(sim, killed_at)) >= 4, 20.0, "four step reports")
    reports = _step_reports(sim, killed_at)
    assert reports[-2:] == [0, 0] and sum(reports[1:]) <= 20, reports
    sim.popen.send_signal(signal.SIGTERM)
    line = sim.wait_for("total: stepped", 20.0)
    stepped = int(line.split("stepped ")[1].split()[0])
    recovered = int((stamps.max() - 0) // 1_000_000)
    assert 0 < recovered <= stepped


def _step_reports(sim, start: int) -> list[int]:
    """Samples stepped per periodic report of the simulator, from its output line ``start``."""
    return [int(line.split("stepped ")[1].split()[0]) for line in sim.lines[start:]
            if "stepped " in line and "total:" not in line]


def test_simulator_killed_mid_campaign(launch, tmp_path):
    """kill -9 of actuator_sim: the recorder names it, marks the running experiment
    incomplete, closes a readable bag and exits 1; the export keeps the complete ones."""
    plan = _plan(tmp_path, PLAN)
    sim, _ = _rig(launch, "/ks")
    bag = tmp_path / "sim_killed"
    rec = _recorder(launch, "/ks", bag, plan)
    rec.wait_for("experiment sweep_long", STARTUP + 60.0)
    sim.popen.send_signal(signal.SIGKILL)
    assert rec.popen.wait(30.0) == 1, rec.output
    assert "simulator actuator_sim stopped publishing" in rec.output, _tail(rec)
    assert "campaign incomplete" in rec.output
    events = _events(bag)  # closed: metadata.yaml and footer written
    assert [(e["name"], e["complete"]) for e in events] == [
        ("charge_1p15V", True), ("square_0p6V", True), ("sweep_long", False)]
    data = read_dataset(export_bag(bag, tmp_path / "data", progress=lambda _: None))
    assert [e.name for e in data.entries] == ["charge_1p15V", "square_0p6V"]


def test_both_streams_silent_in_a_closed_loop_name_the_peer_whose_turn_it_was(ros_context,
                                                                             tmp_path):
    """The recorder's verdict when the simulator falls silent too, its timings set by hand: a
    controller killed with SIGKILL once stalled the simulator's publishers (its re-published
    samples stopped with the controller's answers; the recorder named the simulator: seen twice
    in some thirty runs of the ROS tests). In a closed-loop phase the loop alternates a sample
    and the controller's answer, so the peer whose turn it was stopped: a sample after the
    latest answer waited on the controller, an answer after the latest sample on the simulator.
    In an open-loop phase the recorder answers itself: silence is the simulator's."""
    rec = Recorder(context=ros_context, cli_args=[
        "--ros-args", "-p", f"bag:={tmp_path / 'bag'}", "-p", f"peer_timeout:={PEER_TIMEOUT}",
        "-p", f"campaign_file:={_plan(tmp_path, CLOSED_PLAN)}"])
    try:
        rec.ready = True
        phases = {p.command.closed_loop: i for i, p in enumerate(rec._phases)}
        now = time.monotonic()
        said = {}
        for loop, (answer, sample) in (("closed", (10.0, 9.9)), ("answered", (9.8, 9.9)),
                                       ("open", (10.0, 9.9))):
            rec._index = phases[loop != "open"]
            rec.failure = None
            rec.commanded, rec.heard = now - answer, now - sample
            rec.progressed = rec.heard
            rec._watch()
            said[loop] = rec.failure
        assert said["closed"].startswith("controller controller stopped answering: the "
                                         "simulator's latest sample got no voltage_cmd")
        assert said["answered"].startswith("simulator actuator_sim stopped publishing")
        assert said["open"].startswith("simulator actuator_sim stopped publishing")
        # the simulator still re-publishing (heard lately), no new sample: the controller
        rec.failure, rec._index = None, phases[True]
        rec.heard, rec.progressed = now, now - 9.9
        rec._watch()
        assert rec.failure.startswith("controller controller stopped answering: the simulator "
                                      "waits for its voltage_cmd")
    finally:
        rec.ready = False  # nothing recorded: no bag kept
        rec.close()
        rec.destroy_node()


def test_controller_killed_in_a_closed_loop_phase(launch, tmp_path):
    plan = _plan(tmp_path, CLOSED_PLAN)
    _, ctl = _rig(launch, "/kc")
    bag = tmp_path / "ctl_killed"
    rec = _recorder(launch, "/kc", bag, plan)
    rec.wait_for("experiment triangle_long", STARTUP + 60.0)
    ctl.popen.send_signal(signal.SIGKILL)
    assert rec.popen.wait(30.0) == 1, rec.output
    assert "controller controller stopped answering" in rec.output, _tail(rec)
    events = _events(bag)
    assert [(e["name"], e["complete"]) for e in events] == [
        ("charge_1p15V", True), ("triangle_long", False)]
    # The export keeps the complete experiment, sample for sample as the offline runner
    # records it, and not the interrupted one.
    data = read_dataset(export_bag(bag, tmp_path / "data", progress=lambda _: None))
    assert [e.name for e in data.entries] == ["charge_1p15V"]
    (entry, ros), = list(data)
    off = dict((e.name, x) for e, x in read_dataset(run_campaign_offline(
        ModelParams(), load_campaign(plan), tmp_path / "off")))["charge_1p15V"]
    assert entry.extra["missing_samples"] == 0 and ros.t.size == off.t.size
    assert np.max(np.abs(ros.u - off.u)) < 1e-9
    assert np.max(np.abs(ros.p1 - off.p1)) < 1.0 and np.max(np.abs(ros.p2 - off.p2)) < 1.0


def test_no_simulator_at_start_leaves_no_bag(launch, tmp_path):
    bag = tmp_path / "new" / "bag"
    rec = _recorder(launch, "/nosim", bag, None, "-p", "wait_timeout:=1.0")
    assert rec.popen.wait(STARTUP) == 1, rec.output
    assert "not found within 1 s" in rec.output
    assert not (tmp_path / "new").exists()  # nor the parent it made
    # The same command can simply be run again.
    rec = _recorder(launch, "/nosim", bag, None, "-p", "wait_timeout:=1.0")
    assert rec.popen.wait(STARTUP) == 1 and "exists" not in rec.output


def test_bag_in_a_read_only_directory(launch, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    # Given, and by default (bags/campaign_<date>_<time> in the current directory).
    for bag in (["-p", f"bag:={ro / 'bag'}"], []):
        rec = launch([*unprivileged(), sys.executable, "-m", "jetpipe_ros.nodes.id_recorder",
                      "--ros-args", *bag], python=False, cwd=ro)
        assert rec.popen.wait(STARTUP) == 2, rec.output
        assert "cannot create" in rec.output and "Permission denied" in rec.output
        assert "Traceback" not in rec.output
    assert list(ro.iterdir()) == []


def test_record_mode_stops_when_the_stream_stops(launch, tmp_path):
    sim = launch(["-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args", "-r", "__ns:=/rs",
                  "-p", "report_period:=0.0"])
    sim.wait_for("started:", STARTUP)
    bag = tmp_path / "rs"
    rec = _recorder(launch, "/rs", bag, None, "-p", "mode:=record")
    rec.wait_for("started: record only", STARTUP)
    _wait(lambda: any(True for _ in stream_messages(next(bag.glob("*.mcap")))), 30.0,
          "recorded data on disk")
    sim.popen.send_signal(signal.SIGKILL)
    assert rec.popen.wait(30.0) == 1, rec.output
    assert "the stream stopped" in rec.output
    with Reader(bag) as reader:
        assert reader.message_count > 0


def test_huge_load_is_clipped_with_a_warning(launch, ros_context):
    sim = launch(["-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args", "-r", "__ns:=/load",
                  "-p", "report_period:=0.0"])
    sim.wait_for("started:", STARTUP)
    probe = Probe(ros_context, namespace="/load")
    try:
        probe.listen("friction_force", "voltage_applied")
        probe.command = {"load_force": 1e308}
        probe.repeat(0.05)
        assert probe.spin_until(lambda: "beyond 19558.8 N" in sim.output, 20.0), sim.output
        since = time.monotonic()
        assert probe.spin_until(lambda: len(probe.messages("voltage_applied", since)) > 50, 20.0)
        loads = [m.effort[1] for m in probe.messages("voltage_applied", since)]
        assert max(abs(x) for x in loads) == pytest.approx(19558.8, rel=1e-6)
        friction = [m.data for m in probe.messages("friction_force", since)]
        assert np.all(np.isfinite(friction)) and max(abs(f) for f in friction) < 19558.8
    finally:
        probe.close()


def test_run_time_parameter_refusals_name_parameter_and_types(launch, ros_context):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    sim = launch(["-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args", "-r", "__ns:=/par",
                  "-p", "report_period:=0.0"])
    sim.wait_for("started:", STARTUP)
    probe = Probe(ros_context, namespace="/par")
    try:
        client = AsyncParameterClient(probe.node, "actuator_sim")
        assert probe.spin_until(client.services_are_ready, 20.0)

        def set_(*params):
            future = client.set_parameters(list(params))
            assert probe.spin_until(future.done, 20.0)
            return future.result().results[0]

        wrong = set_(Parameter("mechanics.mass", value="heavy"))
        assert not wrong.successful
        assert wrong.reason == ("parameter mechanics.mass: expected a floating-point number, got "
                                "a string ('heavy')")
        unknown = set_(Parameter("mechanics.mas", value=2.0))
        assert not unknown.successful and "'mechanics.mas'" in unknown.reason
        widened = set_(Parameter("mechanics.mass", value=2))  # YAML/CLI integers for doubles
        assert widened.successful, widened.reason
        assert set_(Parameter("mechanics.mass", value=-1.0)).successful is False
    finally:
        probe.close()


def test_params_file_with_a_key_twice_is_refused(launch, tmp_path):
    """rcl keeps the last of two equal keys silently; the nodes refuse the file."""
    path = tmp_path / "twice.yaml"
    path.write_text("actuator_sim:\n  ros__parameters:\n    mechanics:\n      mass: 2e0\n"
                    "      stroke: 0.05\n      mass: 3.0\n")
    sim = launch(["-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args", "--params-file",
                  str(path)])
    assert sim.popen.wait(STARTUP) == 2, sim.output
    assert f"{path}: line 6, column 7: key 'mass' given twice (first at line 4)" in sim.output
