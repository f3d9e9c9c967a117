"""id_recorder: run an identification campaign through the topics and record it as a bag.

Records every topic of the contract (``msg_defs/topics.yaml``) to a rosbag2 bag in MCAP
storage (metadata version 9, or 8 with ``bag_version``: :mod:`jetpipe_ros.bag`), the bag's log
times being simulated time: the header stamp of stamped messages, the latest stamp seen for the
others.

``mode: campaign`` (default) runs ``campaign_file`` (default ``config/campaign.yaml``) phase by
phase (:meth:`jetpipe_ros.campaign.Campaign.schedule`) against a simulator in lock-step
(``time_mode: sim``, ``lockstep: true``): in open-loop phases the recorder answers every sample
(``joint_states``) with that sample's ``voltage_cmd``; in closed-loop phases it publishes
``voltage_excitation`` and ``position_setpoint`` and the ``controller`` node, switched to
``pace_on_setpoint`` for the campaign (and back at the end), answers each setpoint. Exactly one
command answers each sample, so the recorder paces every phase and the plan's commands land on
the planned samples. Between phases it switches the rig (:meth:`Phase.rig_changes`: the
simulator's ``mechanics.locked``, and for the regulated friction tests ``chamber.regulated``,
the regulated pressures and the piston's place, set atomically) while the simulator waits. A
phase with a load signal (the friction test's releasing load) publishes each sample's
``load_force`` just before its ``voltage_cmd``; the simulator applies them in arrival order and
reports the load it applied on ``voltage_applied``, which the export reads. Each experiment is
marked on ``/id_recorder/events`` (after a ``campaign`` event at its first sample) so
``jetpipe export BAG DATASET_DIR`` can cut the dataset.
The node exits when the campaign is done. ``mode: record`` only records, until stopped.

SIGINT/SIGTERM close the bag cleanly: every message received up to the signal stays readable.
SIGKILL cannot be caught: the bag then lacks ``metadata.yaml`` and the MCAP footer, but the
writer syncs it at least every second (:data:`jetpipe_ros.bag.writer.SYNC_PERIOD`; also while
idle, from a timer), so ``jetpipe export`` recovers everything recorded up to about a second
before the kill. Dropped messages (gaps in the 1 kHz stamps) are counted and reported with the
kept fraction. A rig without one or both chamber pressure sensors (hardware, or
``actuator_sim``'s ``pressure_sensors``) is recorded as it is: a pressure topic that sends
nothing is not waited for, the report says so, and ``jetpipe export`` leaves its column out.

A peer that dies is detected: in a campaign, no new sample for ``peer_timeout`` seconds (wall
clock) while the simulator still re-publishes its waiting sample means the controller (in a
closed-loop phase) stopped answering; no ``joint_states`` at all means the simulator stopped,
unless, in a closed-loop phase, its latest sample had got no ``voltage_cmd``: then the
controller stopped first (whose turn it was), and the simulator after it (a peer killed
mid-transfer can stall the others' publishers in the middleware).
In record mode, no ``joint_states`` for ``peer_timeout`` after the stream began means it
stopped.
The recorder then logs which peer, marks the running experiment incomplete, closes the bag and
exits with status 1. A campaign that never started (simulator or controller not found, or
stopped before) leaves no bag behind, nor does a recording that received nothing.

Run: ``ros2 run jetpipe_ros id_recorder --ros-args -p bag:=bags/run1`` (exit status 2 on bad
parameters, a bad campaign file or a bag that cannot be created, 1 if the simulator or
controller cannot be reached or stops answering).
"""

from __future__ import annotations

import math
import struct
import sys
import time
from collections import deque
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from rosbags.rosbag2 import WriterError

from jetpipe_ros.bag import BagWriter
from jetpipe_ros.campaign import Campaign, CampaignError, Phase, load_campaign
from jetpipe_ros.dataset.timebase import STREAM_INTERVALS, another_rate, median_interval
from jetpipe_ros.model.params import ParamSpec
from jetpipe_ros.nodes import interface, process
from jetpipe_ros.nodes.parameters import (StartupError, declare, set_explained, skipped_sections,
                                          unknown_overrides, value)
from jetpipe_ros.package_data import PackageDataError, share_file

NODE_NAME = "id_recorder"
NODE_SPECS: dict[str, ParamSpec] = {s.name: s for s in [
    ParamSpec("mode", "campaign", "Run the campaign and record, or only record until stopped",
              choices=("campaign", "record")),
    ParamSpec("campaign_file", "", "Campaign YAML; a relative path not found is looked up "
              "among the package's data (config/campaign_identification.yaml works wherever "
              "installed); empty: the package's config/campaign.yaml"),
    ParamSpec("bag", "", "Bag directory to create; empty: bags/campaign_<date>_<time>"),
    ParamSpec("bag_version", 9, "rosbag2 metadata version: 9 (Jazzy and later) or 8 (also "
              "for Humble's and Iron's ros2 bag)", "", 8, 9),
    ParamSpec("simulator_node", "actuator_sim", "Simulator node (same namespace)"),
    ParamSpec("controller_node", "controller", "Controller node (same namespace)"),
    ParamSpec("wait_timeout", 30.0, "Longest wait for the simulator and controller", "s",
              0.1, 600.0),
    ParamSpec("peer_timeout", 5.0, "A running campaign stops (status 1, experiment marked "
              "incomplete) after this long without a new sample; record mode, without "
              "joint_states once the stream began (more than the simulator's lockstep_kick)", "s",
              0.5, 3600.0),
    ParamSpec("sample_time", 0.001, "Period of the stamped streams (gap counting)", "s",
              1e-5, 1.0),
    ParamSpec("lead", 4, "Open-loop phases: commands sent ahead of the samples (pipelining; "
              "the simulator still steps once per command)", "samples", 1, 8),
    ParamSpec("queue_depth", 1000, "Depth of the recording subscriptions' queues",
              "messages", 10, 100000),
]}
NS = 1_000_000_000
#: A kick of the sample answered last is taken as a lost command only this long [s, wall]
#: after the answer (the simulator kicks every lockstep_kick, 0.2 s by default).
KICK_GUARD = 0.1
#: Message types whose CDR payload starts with a time stamp (header.stamp or clock).
STAMPED = ("sensor_msgs/msg/FluidPressure", "sensor_msgs/msg/JointState",
           "rosgraph_msgs/msg/Clock")
_STAMP = struct.Struct("<iI")  # after the 4-byte CDR encapsulation header (little endian)


def stamp_of(data: bytes) -> int:
    """The stamp [ns] at the start of a little-endian CDR message (header or clock)."""
    sec, nanosec = _STAMP.unpack_from(data, 4)
    return sec * NS + nanosec


class Recorder(Node):
    """The recorder node; raises :class:`StartupError` on bad parameters or campaign."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        errors = declare(self, NODE_SPECS.values(), read_only=True)
        errors += [f"unknown parameter {n!r}" for n in unknown_overrides(self, NODE_SPECS)]
        errors += skipped_sections(self, kwargs.get("cli_args"))
        if errors:
            raise StartupError(errors)
        self.opts = {n: value(self, n) for n in NODE_SPECS}
        self.campaign: Campaign | None = None
        if self.opts["mode"] == "campaign":
            try:
                self.campaign = load_campaign(
                    _campaign_path(self.opts["campaign_file"] or "config/campaign.yaml"))
            except CampaignError as exc:
                raise StartupError([str(exc)]) from exc
        self._dt_ns = round(self.opts["sample_time"] * NS)
        bag = self.opts["bag"].strip() or f"bags/campaign_{datetime.now():%Y%m%d_%H%M%S}"
        if Path(bag).exists():
            raise StartupError([f"parameter bag: {bag} exists; give a new directory"])

        topics = interface.load_topics()
        self._names = {t.name: self.resolve_topic_name(t.name) for t in topics.values()}
        try:
            self.bag = BagWriter(bag, {self._names[t.name]: t.type for t in topics.values()},
                                 self.opts["bag_version"])
        except (OSError, WriterError) as exc:
            where = exc.filename if isinstance(exc, OSError) and exc.filename else bag
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            raise StartupError([f"parameter bag: cannot create {bag}: {where}: {why}"]) from None
        self._now_ns = 0  # latest stamp seen [ns, simulated]
        self._last: dict[str, int] = {}  # latest stamp per stamped topic
        self._first: dict[str, int] = {}
        self.dropped: dict[str, int] = {}
        #: joint_states' latest stamp intervals [ns]: its rate, checked against sample_time
        self._intervals: deque[int] = deque(maxlen=STREAM_INTERVALS)
        self.heard: float | None = None  # wall time [s] of the latest joint_states message
        self.commanded: float | None = None  # wall time [s] of the latest voltage_cmd heard
        self.progressed = time.monotonic()  # wall time [s] of the latest new sample
        self.failure: str | None = None  # why the recording stopped early (a peer died)
        depth = QoSProfile(depth=self.opts["queue_depth"], history=HistoryPolicy.KEEP_LAST,
                           reliability=ReliabilityPolicy.RELIABLE)
        for t in topics.values():
            name = self._names[t.name]
            cb = (self._stamped(name) if t.type in STAMPED else self._unstamped(name))
            self.create_subscription(t.message_class(), t.name, cb, depth, raw=True)

        # Campaign state.
        self._pubs = {n: interface.publisher(self, n) for n in (
            "voltage_cmd", "position_setpoint", "voltage_excitation", "load_force")}
        self._msg = interface.topic("voltage_cmd").message_class()()
        self._phases: list[Phase] = self.campaign.schedule() if self.campaign else []
        self._index = 0  # current phase
        self._start_ns: int | None = None  # stamp of the current phase's first sample
        self._answered = -1  # latest stamp answered [ns]
        self._answered_at = 0.0  # when [s, monotonic]
        self._kicks = 0  # kicks of the sample answered last since the answer
        self.resent = 0  # answers sent again because the simulator still waited
        self._sent = -1  # highest row of the current phase whose command was sent
        self._held: int | None = None  # a sample waiting while the rig is switched
        self._busy = False  # a parameter change is in flight
        self._rig: dict[str, Any] = {}  # the simulator's rig parameters as last set
        self._paced = False  # the controller was switched to pace_on_setpoint
        self._load = 0.0
        self.ready = False  # campaign mode: the simulator and controller are set up
        self.done = False
        self.finished = Future()  #: completed when the campaign is done
        self.wall_start = time.monotonic()
        self.sim_start_ns: int | None = None
        self._sim_params = AsyncParameterClient(self, self.opts["simulator_node"])
        self._ctl_params = AsyncParameterClient(self, self.opts["controller_node"])
        self.create_timer(0.1, self._watch, clock=Clock(clock_type=ClockType.STEADY_TIME))
        what = (f"campaign {self.campaign.source}: {len(self.campaign.experiments)} "
                f"experiments, {self.campaign.total_duration():.1f} s simulated"
                if self.campaign else "record only")
        self.get_logger().info(f"started: {what}; bag {self.bag.path}")

    def set_parameters_atomically(self, parameter_list: list[Parameter[Any]]) -> Any:
        """rclpy's, with rejections naming the parameter and the types (remote sets)."""
        return set_explained(self, parameter_list, super().set_parameters_atomically)

    # -- recording --------------------------------------------------------------------------

    def _stamped(self, name: str):
        is_joint_states = name == self._names["joint_states"]

        def callback(data: bytes) -> None:
            if self.bag.closed:
                return
            stamp = stamp_of(data)
            if is_joint_states:  # the simulator's own (/clock may come from anyone)
                self.heard = time.monotonic()
            last = self._last.get(name)
            if last is not None and stamp <= last:  # re-published while the sim waits
                if is_joint_states and self.driving:
                    self._on_kick(stamp)
                return
            if is_joint_states:
                self.progressed = self.heard
            if last is None:
                self._first[name] = stamp
                if is_joint_states and not self.campaign:  # record mode: data flows from here
                    self.get_logger().info(f"recording: first {name} sample")
            else:
                if is_joint_states:
                    self._intervals.append(stamp - last)
                if stamp - last > self._dt_ns:
                    self.dropped[name] = (self.dropped.get(name, 0)
                                          + round((stamp - last) / self._dt_ns) - 1)
            self._last[name] = stamp
            self._now_ns = max(self._now_ns, stamp)
            if self.sim_start_ns is None:
                self.sim_start_ns = stamp
            self.bag.write(name, stamp, data)
            if is_joint_states and self.driving:
                self._on_sample(stamp)
        return callback

    def _unstamped(self, name: str):
        is_command = name == self._names["voltage_cmd"]

        def callback(data: bytes) -> None:
            if is_command:
                self.commanded = time.monotonic()
            if not self.bag.closed:
                self.bag.write(name, self._now_ns, data)
        return callback

    def _watch(self) -> None:
        """Every 0.1 s (wall clock): sync the bag if due; stop if a peer stopped answering."""
        if self.bag.closed:
            return
        self.bag.sync_if_due()
        if self.failure is not None:
            return
        now = time.monotonic()
        timeout = self.opts["peer_timeout"]
        sim, js = self.opts["simulator_node"], self._names["joint_states"]
        if self.driving:
            if now - max(self.heard or 0.0, self.progressed) > timeout:
                if self._owed_by_controller():
                    self._fail(f"controller {self.opts['controller_node']} stopped answering: "
                               f"the simulator's latest sample got no voltage_cmd, and nothing "
                               f"more came on {js} for {timeout:g} s (the simulator stalled or "
                               f"stopped after it; killed or hung?)")
                else:
                    self._fail(f"simulator {sim} stopped publishing: nothing on {js} for "
                               f"{timeout:g} s (killed or hung?)")
            elif now - self.progressed > timeout:
                phase = self._phases[self._index]
                if self._busy:
                    what = (f"simulator {sim} did not complete a rig switch (parameter "
                            f"change) within {timeout:g} s")
                elif phase.command.closed_loop:
                    self._paced = False  # nobody left to give its pace back to
                    what = (f"controller {self.opts['controller_node']} stopped answering: "
                            f"the simulator waits for its voltage_cmd, no new sample for "
                            f"{timeout:g} s (killed or hung?)")
                else:
                    what = (f"simulator {sim} publishes but takes no voltage_cmd: no new "
                            f"sample for {timeout:g} s")
                self._fail(what)
        elif self.campaign is None and self.heard is not None and now - self.heard > timeout:
            self._fail(f"the stream stopped: nothing on {js} for {timeout:g} s (simulator "
                       f"{sim} killed or hung?)")

    def _owed_by_controller(self) -> bool:
        """In a closed-loop phase, both streams silent: True when the controller owed the next
        message. The loop alternates a sample (joint_states) and the controller's answer
        (voltage_cmd), so the peer that stopped is the one whose turn it was: a sample heard
        after the latest command waited for the controller. The simulator's re-published
        samples usually tell the same (it keeps publishing while it waits), but a peer killed
        mid-transfer can stall the others' publishers in the middleware for seconds (this
        node's too, publishing the setpoint to a dead controller: it then hears nothing)."""
        phase = self._phases[self._index]
        return (phase.command.closed_loop and not self._busy and self.heard is not None
                and (self.commanded is None or self.commanded < self.heard))

    def _fail(self, why: str) -> None:
        """A peer died: record why and end the run (the caller closes the bag)."""
        self.failure = why
        if not self.finished.done():
            self.finished.set_result(None)

    @property
    def driving(self) -> bool:
        """True while the campaign runs (samples are answered)."""
        return self.ready and not self.done

    def drained(self) -> bool:
        """True when every stamped stream has reached the latest stamp seen (a pressure topic
        that has sent nothing is a sensor the rig lacks, not a stream to wait for)."""
        streams = [self._names[t] for t in ("joint_states", "voltage_applied")]
        streams += [n for n in self._pressure_topics() if n in self._last]
        return all(self._last.get(n) == self._now_ns for n in streams)

    def _pressure_topics(self) -> list[str]:
        """The chamber pressure topics, resolved in the node's namespace."""
        return [self._names[interface.SENSOR_TOPICS[p]] for p in ("p1", "p2")]

    def kept(self) -> tuple[int, int]:
        """(samples recorded, samples published) of joint_states, from its stamps."""
        name = self._names["joint_states"]
        if name not in self._first:
            return 0, 0
        expected = (self._last[name] - self._first[name]) // self._dt_ns + 1
        return self.bag.counts[name], int(expected)

    def report(self) -> None:
        """Log counts, drops and (campaign) speed."""
        kept, expected = self.kept()
        fraction = kept / expected if expected else math.nan
        drops = ", ".join(f"{n} {d}" for n, d in sorted(self.dropped.items()) if d) or "none"
        wall = time.monotonic() - self.wall_start
        sim = ((self._now_ns - self.sim_start_ns) / NS
               if self.sim_start_ns is not None else 0.0)
        self.get_logger().info(
            f"recorded {kept} of {expected} joint_states samples (kept {100 * fraction:.3f} "
            f"%), dropped: {drops}; {sim:.2f} s simulated in {wall:.2f} s wall "
            f"({sim / max(wall, 1e-9):.2f} x real time); answers re-sent {self.resent}; bag "
            f"{self.bag.path}")
        interval = median_interval(self._intervals)
        if interval is not None and another_rate(interval, self._dt_ns):
            self.get_logger().warning(
                f"joint_states came every {interval / 1e6:.3g} ms, but sample_time is "
                f"{self._dt_ns / 1e6:.3g} ms: the drops above are counted on that grid; set "
                f"sample_time:={interval / 1e9:.3g} (jetpipe export takes the rate from the "
                f"stamps)")
        silent = [n for n in self._pressure_topics() if n not in self._last]
        if silent and kept:
            self.get_logger().info(
                f"nothing on {' or '.join(silent)}: a rig without "
                f"{'these pressure sensors' if len(silent) > 1 else 'that pressure sensor'}; "
                f"jetpipe export leaves {'their columns' if len(silent) > 1 else 'its column'} "
                f"out")

    # -- start-up ---------------------------------------------------------------------------

    def connect(self, spin) -> None:
        """Wait for the simulator (and controller) to be reachable; raise RuntimeError."""
        deadline = time.monotonic() + self.opts["wait_timeout"]
        sim = self.opts["simulator_node"]

        def wait(what: str, ok) -> None:
            while not ok():
                if time.monotonic() > deadline:
                    raise RuntimeError(f"{what} not found within {self.opts['wait_timeout']:g}"
                                       f" s")
                spin(0.05)

        wait(f"simulator publishing {self._names['joint_states']}",
             lambda: self.count_publishers(self._names["joint_states"]) > 0
             and self.count_publishers(self._names["voltage_applied"]) > 0)
        wait(f"simulator subscribing {self._names['voltage_cmd']}",
             lambda: self._pubs["voltage_cmd"].get_subscription_count() > 0)
        wait(f"parameter services of {sim} (is it running?)",
             lambda: self._sim_params.services_are_ready())
        assert self.campaign is not None
        if any(p.command.closed_loop for p in self._phases):
            wait(f"controller node {self.opts['controller_node']} (needed by the closed-loop "
                 f"phases; set settle.center: 0 and use open_loop experiments only to run "
                 f"without it)", lambda: self._ctl_params.services_are_ready())
            self._set(self._ctl_params, "enabled", False, spin)  # enabling resets the PID
            self._set(self._ctl_params, "pace_on_setpoint", True, spin)
            self._set(self._ctl_params, "enabled", True, spin)
            self._paced = True
        self._set(self._sim_params, "mechanics.locked", False, spin)
        self._set(self._sim_params, "chamber.regulated", False, spin)
        self._rig = {"mechanics.locked": False, "chamber.regulated": False}
        self.wall_start = self.progressed = time.monotonic()
        self.ready = True
        self.get_logger().info("simulator found; campaign running")

    def _set(self, client: AsyncParameterClient, name: str, v: Any, spin) -> None:
        future = client.set_parameters([Parameter(name, value=v)])
        deadline = time.monotonic() + self.opts["wait_timeout"]
        while not future.done():
            if time.monotonic() > deadline:
                raise RuntimeError(f"cannot set {name} = {v}: no answer within "
                                   f"{self.opts['wait_timeout']:g} s")
            spin(0.05)
        result = future.result().results[0]
        if not result.successful:
            raise RuntimeError(f"cannot set {name} = {v}: {result.reason}")

    # -- the campaign -----------------------------------------------------------------------

    def _on_kick(self, stamp: int) -> None:
        """The simulator re-published a sample: it is still waiting for its command.

        A kick of the sample answered last may have been sent before the answer reached the
        simulator (a stall longer than the simulator's ``lockstep_kick``: of the recorder, which
        then finds the kicks queued behind the sample it answers, or of a process hosting both,
        whose kick timer fires once before the queued commands are taken): answering it again
        would step the simulator twice. So the answer is sent again only at the second kick
        after it and at least :data:`KICK_GUARD` after it; a lost answer costs two kick periods.
        """
        if stamp > self._answered:
            self._on_sample(stamp)
            return
        if stamp == self._answered:
            self._kicks += 1
        if (stamp == self._answered and not self._busy and self._start_ns is not None
                and self._kicks >= 2 and time.monotonic() - self._answered_at >= KICK_GUARD):
            self.resent += 1
            # The simulator lacks this sample's command (a race at a switch): send it again.
            self._sent = (stamp - self._start_ns) // self._dt_ns - 1
            self._answered = stamp - 1
            self._on_sample(stamp)

    def _on_sample(self, stamp: int) -> None:
        if stamp <= self._answered:
            return
        if self._busy:
            self._held = stamp
            return
        phase = self._phases[self._index]
        if self._start_ns is None:  # entering the phase
            if self._switch(phase):
                self._held = stamp
                return
            self._start_ns = stamp
            self._sent = -1
            if self._index == 0:  # marks a campaign's bag, even one killed before its first end
                self.bag.event(stamp, event="campaign", source=str(self.campaign.source),
                               experiments=len(self.campaign.experiments))
            if phase.experiment is not None:
                self.get_logger().info(f"experiment {phase.label} ({phase.samples} samples)")
        row = (stamp - self._start_ns) // self._dt_ns
        if row >= phase.samples:
            self._finish(phase)
            if not self.done:
                self._on_sample(stamp)
            return
        cmd = phase.command
        if cmd.closed_loop:  # the controller answers the setpoint with this sample's position
            self._publish("voltage_excitation", float(cmd.excitation[row]))
            self._publish("position_setpoint", float(cmd.setpoint[row]))
            self._sent = row
        else:  # keep `lead` commands in flight, never beyond the phase
            last = min(row + self.opts["lead"], phase.samples) - 1
            for r in range(max(row, self._sent + 1), last + 1):
                if cmd.load is not None:  # the sample's load first: applied in arrival order
                    self._load = float(cmd.load[r])
                    self._publish("load_force", self._load)
                self._publish("voltage_cmd", float(cmd.voltage[r]))
            self._sent = max(self._sent, last)
        self._answered = stamp
        self._answered_at = time.monotonic()
        self._kicks = 0

    def _publish(self, name: str, v: float) -> None:
        self._msg.data = v
        self._pubs[name].publish(self._msg)

    def _switch(self, phase: Phase) -> bool:
        """Set the rig up for ``phase``; True if a parameter change is now in flight (the
        phase then starts in :meth:`_resume`)."""
        if phase.command.load is None and phase.load_force != self._load:
            self._load = phase.load_force
            self._publish("load_force", self._load)
        changes = phase.rig_changes(self._rig)
        if not changes:
            return False
        self._busy = True
        self._rig.update(changes)

        def done(future) -> None:
            result = future.result().result
            if not result.successful:
                self.get_logger().error(f"rig switch refused: {result.reason}")
            self._busy = False
            held, self._held = self._held, None
            if held is not None:
                self._resume(held)

        self._sim_params.set_parameters_atomically(
            [Parameter(name, value=v) for name, v in changes.items()]).add_done_callback(done)
        return True

    def _resume(self, stamp: int) -> None:
        """The rig is set: start the current phase at the waiting sample ``stamp``."""
        self._start_ns = stamp
        self._sent = -1
        phase = self._phases[self._index]
        if phase.experiment is not None:
            self.get_logger().info(f"experiment {phase.label} ({phase.samples} samples)")
        self._on_sample(stamp)

    def _finish(self, phase: Phase, complete: bool = True) -> None:
        """Close the current phase; mark an experiment in the bag."""
        if phase.experiment is not None and self._start_ns is not None:
            e = phase.experiment
            samples = phase.samples if complete else int(
                (self._answered - self._start_ns) // self._dt_ns + 1)
            self.bag.event(self._now_ns, event="experiment", name=e.name, kind=e.kind,
                           locked=e.locked, role=e.role, load_force=e.load_force,
                           regulated=e.regulated is not None,
                           start_ns=self._start_ns, samples=samples,
                           dt=self.opts["sample_time"], complete=complete)
        if not complete:
            return
        self._index += 1
        self._start_ns = None
        if self._index == len(self._phases):
            self.done = True
            self.finished.set_result(None)
            self.bag.event(self._now_ns, event="campaign_done")
            self.get_logger().info("campaign done")

    def close(self) -> None:
        """Mark an interrupted experiment, report, close the bag (idempotent). A campaign that
        never started, or a recording that received nothing, leaves no bag."""
        if self.bag.closed:
            return
        started = self.ready if self.campaign is not None else any(self.bag.counts.values())
        if not started:
            self.bag.discard()
            self.get_logger().info(f"nothing recorded; bag {self.bag.path} not kept")
            return
        if self.campaign is not None and not self.done and self._index < len(self._phases):
            phase = self._phases[self._index]
            self._finish(phase, complete=False)
            what = (f"experiment {phase.label} marked incomplete" if phase.experiment is not None
                    else "between experiments")
            self.get_logger().warning(
                f"campaign incomplete: stopped in phase {phase.label} ({self._index + 1} of "
                f"{len(self._phases)}), {what}")
        self.report()
        self.bag.close()

    def release_controller(self, spin) -> None:
        """Give the controller back its own pace (answering positions), best effort."""
        if self._paced:
            self._paced = False
            future = self._ctl_params.set_parameters(
                [Parameter("pace_on_setpoint", value=False)])
            deadline = time.monotonic() + 2.0
            while not future.done() and time.monotonic() < deadline:
                spin(0.05)


def _campaign_path(name: str) -> Path:
    """The campaign file ``name`` as given, or, if it is relative and not there, the package's
    data file of that relative path (``config/campaign_identification.yaml``)."""
    path = Path(name)
    if path.is_file() or path.is_absolute():
        return path
    try:
        return share_file(name)
    except PackageDataError:
        return path  # load_campaign names it as given


def run(node: Recorder, executor: Any, stop: process.Stop) -> int:
    """Run the recorder's work on ``executor`` (which spins ``node`` and any nodes sharing its
    process) until the campaign is done or ``stop`` is set; close the bag whatever happens.
    Returns 0, or 1 if the simulator or controller cannot be reached."""

    def spin_once(timeout: float) -> None:
        if stop.is_set():
            raise KeyboardInterrupt
        executor.spin_once(timeout_sec=timeout)

    status = 0
    try:
        if node.campaign is not None:
            node.connect(spin_once)
        process.spin(executor, stop, until=node.finished)
        if node.failure is not None:
            raise RuntimeError(node.failure)
        if node.done:  # the last sample's other topics are still on the way: wait up to 1 s
            drain = time.monotonic() + 1.0
            process.spin(executor, stop,
                         condition=lambda: node.drained() or time.monotonic() > drain)
    except RuntimeError as exc:
        rclpy.logging.get_logger(NODE_NAME).error(str(exc))
        status = 1
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.release_controller(lambda t: executor.spin_once(timeout_sec=t))
        node.close()
    return status


def main(args: Sequence[str] | None = None) -> int:
    """Run until the campaign is done, or Ctrl-C/SIGTERM; 0, 1 (no simulator) or 2."""
    return process.run_nodes(NODE_NAME, args, [(NODE_NAME, Recorder)],
                             work=lambda nodes, executor, stop: run(nodes[0], executor, stop))


if __name__ == "__main__":
    sys.exit(main())
