"""The package's ROS nodes started as child processes (showcases, benchmarks): started, waited
for by what they print, and always stopped. No ROS import: the nodes run in their own
processes."""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

#: prctl(2) option: the signal the kernel sends this process when its parent dies.
_PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Ask the kernel to SIGTERM this process when its parent dies (Linux; elsewhere nothing).

    Meant as ``preexec_fn`` of a child: a parent killed without the chance to stop its
    children (SIGKILL, or a test runner ended by SIGTERM, which runs no finalizer) would
    otherwise leave them running, still talking in their ROS domain. The kernel watches the
    *thread* that started the child: start it from one that lives as long as the parent, or
    that waits for the child (then it ends after it)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):  # no prctl: the parent's own stop() remains
        return


class Nodes:
    """Node executables of this package run as child processes in one namespace, each with its
    output in ``logs/<name>.log``; ROS traffic stays on this machine unless the environment
    says otherwise (``ROS_AUTOMATIC_DISCOVERY_RANGE``)."""

    def __init__(self, logs: Path, namespace: str) -> None:
        self.logs = logs
        self.namespace = namespace
        logs.mkdir(parents=True, exist_ok=True)
        self.env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self, name: str, ros_args: list[str]) -> subprocess.Popen:
        """Start node module ``jetpipe_ros.nodes.<name>`` in the namespace."""
        log = (self.logs / f"{name}.log").open("w")
        proc = subprocess.Popen(
            [sys.executable, "-m", f"jetpipe_ros.nodes.{name}", "--ros-args",
             "-r", f"__ns:={self.namespace}", *ros_args],
            stdout=log, stderr=subprocess.STDOUT, env=self.env, preexec_fn=die_with_parent)
        self.procs[name] = proc
        return proc

    def wait_for(self, name: str, text: str, timeout: float) -> str:
        """The first line of ``name``'s log containing ``text``; RuntimeError on timeout."""
        deadline = time.monotonic() + timeout
        path = self.logs / f"{name}.log"
        while time.monotonic() < deadline:
            for line in path.read_text().splitlines():
                if text in line:
                    return line
            if self.procs[name].poll() is not None:
                break
            time.sleep(0.2)
        raise RuntimeError(f"{name} did not print {text!r}; see {path}")

    def stop(self) -> None:
        """SIGTERM every process still running, then wait (kill after 10 s)."""
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.terminate()
        for proc in self.procs.values():
            try:
                proc.wait(10.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
