"""gap_monitor: the model beside the hardware, saying live where the hardware departs from it.

Subscribes to an actuator's outputs (relative names, so ``-r __ns:=/axis1`` watches that axis):
``voltage_applied`` (the command [V] and load [N] applied over the sample ending at the stamp),
``joint_states`` (position [m]) and ``chamber1/pressure``, ``chamber2/pressure`` [Pa], all
stamped; the messages of one stamp make a sample. A rig without one or both pressure sensors
says so (``pressure_sensors``): those chambers are simulated and their topics not subscribed.
Each sample goes through the twin
(:class:`jetpipe_ros.twin.Twin`: the model restarted from the measurements every ``horizon``),
whose predictions are published at once, with the measurement's stamp, on
``twin/joint_states`` and ``twin/chamber1/pressure``, ``twin/chamber2/pressure``. Every
``diagnostic_period`` it publishes on ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``) the
rolling gap per signal with its level (OK / WARN / ERROR, judged against the measured noise
floor: :mod:`jetpipe_ros.twin.gap`), what happened to the inputs (samples lost, late, pauses),
STALE when no sample came for ``stale_timeout`` s (a dead publisher), and the latest capture.

Capture: the service ``~/capture`` (``std_srvs/Trigger``), or the gap at ERROR for
``auto_capture_after`` s of samples, writes the last ``capture_seconds`` of samples (both in the
samples' own time) as a dataset under
``capture_dir`` and runs ``jetpipe diagnose`` on it in a separate process; both run in a thread
from a copy of the samples, so the subscriptions never wait and the stream goes on into the
twin and the next capture. The verdict (effect, subsystem, shrinkage, report) is published as
the capture's diagnostic status when the diagnosis ends.

Run: ``ros2 run jetpipe_ros gap_monitor --ros-args --params-file config/gap_monitor.yaml``.
Exit status 2 on bad parameters (an unreadable model file names the file and parameter).
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from std_srvs.srv import Trigger

from jetpipe_ros.children import die_with_parent
from jetpipe_ros.model import ModelParams, ParameterError, load_params
from jetpipe_ros.model.params import ParamSpec
from jetpipe_ros.nodes import interface, process
from jetpipe_ros.nodes.parameters import (StartupError, declare, set_explained, skipped_sections,
                                          unknown_overrides, value)
from jetpipe_ros.twin import Level, Settings, Twin
from jetpipe_ros.twin.capture import Recent, write_capture
from jetpipe_ros.twin.gap import MIN_HISTORY

NODE_NAME = "gap_monitor"
NS = 1_000_000_000
NODE_SPECS: dict[str, ParamSpec] = {s.name: s for s in [
    ParamSpec("model_file", "", "Model parameter YAML (empty: the nominal model), e.g. "
              "config/actuator.yaml or a diagnosis' augmented.yaml"),
    ParamSpec("model_node", "actuator_sim", "Node name the model file's parameters are under"),
    ParamSpec("sample_time", 0.001, "Sample time of the measurements", "s", 1e-5, 1.0),
    ParamSpec("pressure_sensors", "p1,p2", "The chamber pressures the hardware measures beside "
              "the position (the others are simulated, not waited for, and no column of a "
              "capture)", choices=interface.PRESSURE_SENSORS),
    ParamSpec("horizon", 1.0, "Time between restarts of the model from the measurements", "s",
              0.02, 60.0),
    ParamSpec("warmup", 0.05, "Held start of each horizon (the valve sees the command)", "s",
              0.001, 10.0),
    ParamSpec("window", 5.0, "Rolling window of the gap", "s", 0.02, 3600.0),
    ParamSpec("history", 30.0, "Time over which the noise-only spread is measured", "s", 0.02,
              36000.0),
    ParamSpec("max_gap", 0.0255, "Longest run of lost samples filled with the command held; "
              "a longer one pauses the comparison (0: pause at any lost sample)", "s", 0.0,
              10.0),
    ParamSpec("stale_timeout", 2.0, "STALE after this long without a sample (wall clock)", "s",
              0.01, 3600.0),
    ParamSpec("diagnostic_period", 1.0, "Period of the /diagnostics messages (wall clock)", "s",
              0.05, 60.0),
    ParamSpec("capture_seconds", 20.0, "A capture holds the last this many seconds", "s", 3.0,
              3600.0),
    ParamSpec("capture_dir", "captures", "Directory the captures are written in, one folder "
              "each"),
    ParamSpec("auto_capture_after", 10.0, "Capture once the gap has stayed at ERROR this long "
              "in the samples' time (0: never)", "s", 0.0, 86400.0),
    ParamSpec("diagnose", True, "Diagnose each capture (jetpipe diagnose, separate process)"),
    ParamSpec("diagnose_jobs", 1, "Worker processes of that diagnosis (1: one process)", "",
              1, 64),
]}
#: Parameters that may change while it runs.
DYNAMIC = ("stale_timeout", "auto_capture_after", "diagnose")
#: Samples waiting for their other messages before the oldest is given up on (2 s at 1 kHz:
#: under load the executor may take one topic's queued messages well ahead of another's).
PENDING = 2000
WARN_PERIOD = 5.0  #: throttle of repeated warnings [s]
#: The messages of a sample (bit of each in the mask).
PARTS = {"voltage_applied": 1, "joint_states": 2, "chamber1/pressure": 4,
         "chamber2/pressure": 8}
#: Commands after which a sensor topic that has sent nothing is said to be silent (0.2 s at
#: 1 kHz: a publisher that exists has sent by then).
SILENT_AFTER = 200
#: Reader queue of each subscription [messages]: 1 s at 1 kHz, so that a slow callback (a
#: horizon being scored, a capture being copied) loses nothing.
QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                 history=HistoryPolicy.KEEP_LAST)


class GapMonitor(Node):
    """The node; raises :class:`StartupError` on bad parameters."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        static = [s for s in NODE_SPECS.values() if s.name not in DYNAMIC]
        errors = declare(self, static, read_only=True)
        errors += declare(self, [NODE_SPECS[n] for n in DYNAMIC], read_only=False)
        errors += [f"unknown parameter {n!r}" for n in unknown_overrides(self, NODE_SPECS)]
        errors += skipped_sections(self, kwargs.get("cli_args"))
        if errors:
            raise StartupError(errors)
        self.opts = {n: value(self, n) for n in NODE_SPECS}
        params = self._model()
        try:
            settings = Settings(dt=self.opts["sample_time"], horizon=self.opts["horizon"],
                                warmup=self.opts["warmup"], window=self.opts["window"],
                                history=self.opts["history"], max_gap=self.opts["max_gap"])
        except ValueError as exc:
            raise StartupError([f"parameters: {exc}"]) from None
        self.twin = Twin(params, settings)
        self._sensors = ("y", *interface.measured_pressures(self.opts["pressure_sensors"]))
        self._topics = ["voltage_applied", *(interface.SENSOR_TOPICS[s] for s in self._sensors)]
        self._complete = sum(PARTS[name] for name in self._topics)  # mask of a whole sample
        self.recent = Recent(self.opts["capture_seconds"], settings.dt)
        self._t0_ns: int | None = None
        self._last_ns = -1  # stamp of the latest sample given to the twin [ns]
        self._pending: dict[int, list[float]] = {}
        self._dropped = 0  # samples given up: no command
        self._incomplete = 0  # samples given to the twin with a measurement missing
        self._late_messages = 0
        self._messages = dict.fromkeys(self._topics, 0)  # messages received per topic
        self._failures = 0  # messages whose handling failed (logged)
        self._last_wall: float | None = None  # monotonic time of the latest sample [s]
        self._captured_this_error = False
        self._capture_lock = threading.Lock()
        self._capture: dict[str, Any] = {"level": Level.OK, "message": "no capture yet"}
        self._capture_thread: threading.Thread | None = None
        self._diagnosis: subprocess.Popen | None = None
        self._captures = 0
        for name in self._topics:
            msg_class = interface.topic(name).message_class()
            self.create_subscription(msg_class, name,
                                     lambda msg, name=name: self._guarded(name, msg), QOS)
        sensor_qos = interface.topic("joint_states").qos.profile()
        self._pub_joint = self.create_publisher(JointState, "twin/joint_states", sensor_qos)
        self._pub_p = [self.create_publisher(FluidPressure, f"twin/chamber{i}/pressure",
                                             sensor_qos) for i in (1, 2)]
        self._msg_joint = JointState(name=["piston"])
        self._msg_p = [FluidPressure(), FluidPressure()]
        self._pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_service(Trigger, "~/capture", self._on_capture)
        self.create_timer(self.opts["diagnostic_period"], self._tick)
        self.add_on_set_parameters_callback(self._check_update)
        self._name = self.get_fully_qualified_name()
        model = self.opts["model_file"] or "the nominal model"
        self.get_logger().info(
            f"started: model {model}, sensors {', '.join(self._sensors)}, horizon "
            f"{settings.horizon:g} s, window "
            f"{settings.window:g} s, capture {self.opts['capture_seconds']:g} s into "
            f"{self.opts['capture_dir']}")

    def _model(self) -> ModelParams:
        path = self.opts["model_file"]
        if not path:
            return ModelParams()
        try:
            return load_params(path, self.opts["model_node"])
        except ParameterError as exc:
            raise StartupError([f"parameter model_file: {exc}"]) from None

    # -- parameters -------------------------------------------------------------------------

    def set_parameters_atomically(self, parameter_list: list[Parameter[Any]]) -> Any:
        """rclpy's, with rejections naming the parameter and the types (remote sets)."""
        return set_explained(self, parameter_list, super().set_parameters_atomically)

    def _check_update(self, params: list[Parameter[Any]]) -> SetParametersResult:
        for p in params:
            if p.name in DYNAMIC:
                self.opts[p.name] = p.value
        return SetParametersResult(successful=True)

    # -- samples ----------------------------------------------------------------------------

    def _guarded(self, name: str, msg: Any) -> None:
        """:meth:`_on_message`, a failure (a publish the middleware refuses) logged and
        counted, never raised into the executor, which would end the node."""
        try:
            self._on_message(name, msg)
        except Exception as exc:  # noqa: BLE001 - the monitor must outlive any one sample
            self._failures += 1
            self.get_logger().error(f"sample at {name} not handled: {exc}",
                                    throttle_duration_sec=WARN_PERIOD)

    def _on_message(self, name: str, msg: Any) -> None:
        self._messages[name] += 1
        stamp = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
        if stamp <= self._last_ns:
            self._late_messages += 1
            return
        row = self._pending.get(stamp)
        if row is None:
            row = self._pending[stamp] = [math.nan] * 5 + [0]
        if name == "voltage_applied":
            row[0] = _at(msg.position, 0)
            row[1] = _at(msg.effort, 1)
            if not math.isfinite(row[1]):
                row[1] = 0.0
        elif name == "joint_states":
            row[2] = _at(msg.position, 0)
        else:
            row[3 if name == "chamber1/pressure" else 4] = msg.fluid_pressure
        row[5] = int(row[5]) | PARTS[name]
        if row[5] == self._complete:
            self._flush(stamp)
        elif len(self._pending) > PENDING:
            self._flush(next(iter(self._pending)))  # the oldest: stamps come in order

    def _flush(self, upto: int) -> None:
        """Give the twin every pending sample up to stamp ``upto`` [ns], in order; one without
        its command is dropped (the twin fills it), one without a measurement has NaN there."""
        first = next(iter(self._pending))
        stamps = [first] if first == upto else sorted(s for s in self._pending if s <= upto)
        for stamp in stamps:
            row = self._pending.pop(stamp)
            if not math.isfinite(row[0]):
                self._dropped += 1
                continue
            if row[5] != self._complete:
                self._incomplete += 1
            self._sample(stamp, row)

    def _sample(self, stamp: int, row: list[float]) -> None:
        if self._t0_ns is None:
            self._t0_ns = stamp
        self._last_ns = stamp
        self._last_wall = time.monotonic()
        t = (stamp - self._t0_ns) / NS
        u, f, y, p1, p2 = row[:5]
        pred = self.twin.feed_one(t, u, f, y, p1, p2)
        self.recent.add((t, u, f, y, p1, p2))
        sec, nanosec = divmod(stamp, NS)
        if math.isfinite(pred[0]):
            j = self._msg_joint
            j.header.stamp.sec, j.header.stamp.nanosec = sec, nanosec
            j.position = [float(pred[0])]
            self._pub_joint.publish(j)
        for i in (0, 1):
            if math.isfinite(pred[1 + i]):
                m = self._msg_p[i]
                m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
                m.fluid_pressure = float(pred[1 + i])
                self._pub_p[i].publish(m)

    # -- diagnostics ------------------------------------------------------------------------

    def _tick(self) -> None:
        try:
            self._report()
        except Exception as exc:  # noqa: BLE001 - as _guarded: log, go on
            self.get_logger().error(f"diagnostics not published: {exc}",
                                    throttle_duration_sec=WARN_PERIOD)

    def _report(self) -> None:
        """Auto capture when due; the statuses on /diagnostics."""
        now = time.monotonic()
        if self.twin.level == Level.ERROR:
            # How long in the samples' own time: a monitor that falls behind on a loaded
            # machine would otherwise count wall-clock seconds of fewer samples, and the capture
            # of the latest samples reach back to before the gap went bad.
            after = self.opts["auto_capture_after"]
            if after > 0.0 and not self._captured_this_error and self.twin.level_held() >= after:
                ok, message = self.capture(f"gap at ERROR for {after:g} s")
                self._captured_this_error = ok
                self.get_logger().warning(f"auto capture: {message}")
        else:
            self._captured_this_error = False
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        array.status = [self._gap_status(now), self._capture_status()]
        self._pub_diag.publish(array)

    def _gap_status(self, now: float) -> DiagnosticStatus:
        twin, c = self.twin, self.twin.counters
        status = DiagnosticStatus(name=f"{self._name}: gap", hardware_id=self.get_namespace())
        values = {}
        for g in twin.judged:
            values[f"{g.signal} gap [%]"] = f"{g.gap:.3f}"
            values[f"{g.signal} level"] = g.level.name
            values[f"{g.signal} z"] = f"{g.z:.2f}" if math.isfinite(g.z) else "inf"
            values[f"{g.signal} z bar"] = f"{g.bar:.2f}"
            values[f"{g.signal} model nrmse [%]"] = f"{100 * math.sqrt(g.mse):.3f}"
            values[f"{g.signal} noise nrmse [%]"] = f"{100 * math.sqrt(g.floor):.3f}"
        values.update({"samples": str(c.samples), "samples filled (lost)": str(c.filled),
                       "samples without command": str(self._dropped),
                       "samples without a measurement": str(self._incomplete),
                       "samples late": str(c.late),
                       "late messages": str(self._late_messages), "pauses": str(c.paused),
                       "handling failures": str(self._failures),
                       "paused [s]": f"{c.paused_s:.3f}", "horizons scored": str(c.horizons),
                       "not compared at start [s]": f"{c.unsettled_s:.3f}",
                       "captures": str(self._captures)})
        interval = twin.interval()
        if interval is not None:
            values["stamp interval [ms]"] = f"{interval * 1e3:.4g}"
        if twin.level_since is not None:
            values["level since t [s]"] = f"{twin.level_since:.3f}"
        if twin.t_last is not None:
            values["latest sample t [s]"] = f"{twin.t_last:.3f}"
        status.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        silent = None if self._last_wall is None else now - self._last_wall
        waiting = self._silent_topics()
        hint = (f"no message on {', '.join(waiting)} beside {self._messages['voltage_applied']} "
                f"commands: a sample waits for it; a rig without that sensor says so with "
                f"pressure_sensors (now {self.opts['pressure_sensors']})" if waiting else "")
        if self._last_wall is None or (silent is not None
                                       and silent > self.opts["stale_timeout"]):
            status.level = _byte(Level.STALE)
            status.message = ("no samples yet" if silent is None else
                              f"no samples for {silent:.1f} s: is the actuator publishing?")
            if hint:
                status.message += f"; {hint}"
            return status
        level = twin.level
        if not twin.judged:
            status.message = (f"judging after {MIN_HISTORY} scored horizons; "
                              f"{c.horizons} so far")
        else:
            worst = [g for g in twin.judged if g.level == level]
            status.message = f"{level.name}: " + "; ".join(g.describe() for g in worst)
        if twin.settling_since is not None:
            status.message = (f"not compared yet: where the chambers no sensor measures started "
                              f"still matters (since t = {twin.settling_since:.3f} s); "
                              + status.message)
        if twin.paused_since is not None:
            level = max(level, Level.WARN)
            status.message = (f"comparison paused: measurements missing after "
                              f"t = {twin.paused_since:.3f} s; " + status.message)
        if (mismatch := twin.rate_mismatch()) is not None:
            level = max(level, Level.WARN)
            status.message = f"{mismatch}; {status.message}"
        if hint:
            level = max(level, Level.WARN)
            status.message = f"{hint}; {status.message}"
        status.level = _byte(level)
        return status

    def _silent_topics(self) -> list[str]:
        """The sensor topics without a message after :data:`SILENT_AFTER` commands."""
        if self._messages["voltage_applied"] < SILENT_AFTER:
            return []
        return [n for n in self._topics[1:] if self._messages[n] == 0]

    def _capture_status(self) -> DiagnosticStatus:
        with self._capture_lock:
            info = dict(self._capture)
        status = DiagnosticStatus(name=f"{self._name}: capture", level=_byte(info["level"]),
                                  message=info["message"], hardware_id=self.get_namespace())
        status.values = [KeyValue(key=k, value=str(v)) for k, v in info.items()
                         if k not in ("level", "message")]
        return status

    # -- capture ----------------------------------------------------------------------------

    def _on_capture(self, request: Any, response: Any) -> Any:
        response.success, response.message = self.capture("requested")
        return response

    def capture(self, reason: str) -> tuple[bool, str]:
        """Start a capture of the latest samples; (started, what happens or why not)."""
        if self._capture_thread is not None and self._capture_thread.is_alive():
            return False, "a capture is in progress; try again when it is done"
        rows = self.recent.snapshot()
        dt = self.twin.settings.dt
        if rows.shape[0] * dt < 3.0:
            return False, (f"only {rows.shape[0] * dt:.2f} s of samples held; a capture needs "
                           f"3 s")
        self._captures += 1
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        tag = re.sub(r"[^A-Za-z0-9_]+", "_", self._name).strip("_")
        folder = Path(self.opts["capture_dir"]) / f"{stamp}_{tag}_{self._captures}"
        with self._capture_lock:
            self._capture = {"level": Level.OK, "message": f"writing {folder}",
                             "folder": str(folder), "reason": reason}
        self._capture_thread = threading.Thread(
            target=self._write_and_diagnose, args=(rows, folder, reason), daemon=True)
        self._capture_thread.start()
        return True, (f"capturing {rows.shape[0] * dt:.1f} s into {folder} ({reason})")

    def _set_capture(self, **info: Any) -> None:
        with self._capture_lock:
            self._capture.update(info)

    def _write_and_diagnose(self, rows: np.ndarray, folder: Path, reason: str) -> None:
        dataset = folder / "dataset"
        try:
            folder.mkdir(parents=True, exist_ok=False)
            write_capture(rows, dataset, note={"reason": reason, "monitor": self._name,
                                               "stamp_origin_ns": self._t0_ns},
                          sensors=self._sensors)
        except Exception as exc:  # noqa: BLE001 - reported, never raised into the node
            self._set_capture(level=Level.ERROR, message=f"capture failed: {exc}")
            self.get_logger().error(f"capture into {folder} failed: {exc}")
            return
        span = f"{rows[0, 0]:.3f}-{rows[-1, 0]:.3f} s"
        self._set_capture(message=f"dataset written: {dataset} ({rows.shape[0]} samples, "
                                  f"{span})", dataset=str(dataset), samples=rows.shape[0],
                          span=span)
        self.get_logger().info(f"capture written: {dataset} ({rows.shape[0]} samples)")
        if not self.opts["diagnose"]:
            return
        self._set_capture(message=f"diagnosing {dataset}")
        self._run_diagnosis(dataset, folder / "diagnosis")

    def _run_diagnosis(self, dataset: Path, out: Path) -> None:
        argv = [sys.executable, "-m", "jetpipe_ros.cli", "diagnose", str(dataset), "--out",
                str(out), "--jobs", str(self.opts["diagnose_jobs"]), "--quiet"]
        if self.opts["model_file"]:
            argv += ["--params", self.opts["model_file"]]
        log = out.parent / "diagnose.log"
        with open(log, "w") as handle:
            # Ends with this node even when it is killed (SIGKILL): the kernel signals the
            # child when the thread that started it ends, and this thread waits for it.
            proc = subprocess.Popen(argv, stdout=handle, stderr=subprocess.STDOUT,
                                    preexec_fn=die_with_parent)
            self._diagnosis = proc
            try:  # below the monitor and the hardware's own processes
                os.setpriority(os.PRIO_PROCESS, proc.pid, 10)
            except OSError:
                pass
            status = proc.wait()
        self._diagnosis = None
        try:
            doc = json.loads((out / "diagnosis.json").read_text())
            verdict, gap = doc["verdict"], doc["gap"]
        except (OSError, ValueError, KeyError) as exc:
            self._set_capture(level=Level.ERROR, message=(
                f"diagnosis failed (exit status {status}): {exc}; see {log}"))
            return
        shrinkage = gap.get("shrinkage", math.nan)
        message = (f"verdict: {verdict['effect']} (subsystem {verdict['subsystem']}, "
                   f"confidence {verdict.get('confidence', math.nan):.2f}), held-out gap "
                   f"{gap.get('nominal', math.nan):.2f} % -> {gap.get('augmented', math.nan):.2f} "
                   f"% (shrinkage {100 * shrinkage:.0f} %); report {out / 'report.html'}")
        self._set_capture(level=Level.OK, message=message, effect=verdict["effect"],
                          subsystem=verdict["subsystem"], shrinkage=f"{shrinkage:.3f}",
                          params=json.dumps(verdict.get("params", {})),
                          report=str(out / "report.html"),
                          augmented=str(out / "augmented.yaml"))
        self.get_logger().info(message)

    def finish(self) -> None:
        """Stop a diagnosis still running (it is this node's child)."""
        proc = self._diagnosis
        if proc is not None and proc.poll() is None:
            proc.terminate()


def _at(values: Sequence[float], i: int) -> float:
    return float(values[i]) if len(values) > i else math.nan


def _byte(level: Level) -> bytes:
    return bytes([int(level)])


def main(args: Sequence[str] | None = None) -> int:
    """Run the monitor until Ctrl-C or SIGTERM; 0, or 2 on bad parameters."""
    return process.run_nodes(NODE_NAME, args, [(NODE_NAME, GapMonitor)],
                             finish=lambda nodes: nodes[0].finish())


if __name__ == "__main__":
    sys.exit(main())
