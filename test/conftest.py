"""Shared fixtures. ROS tests get a private ROS domain and processes that are always stopped."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from threadpoolctl import threadpool_limits

from jetpipe_ros.children import die_with_parent
from jetpipe_ros.nodes.domain import reserve_domain

REPO = Path(__file__).resolve().parent.parent


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark ``ros`` every test that talks ROS (it takes a ROS domain): ``scripts/test.sh``
    runs those one at a time, and the rest on every core."""
    for item in items:
        if "ros_domain" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.ros)


@pytest.fixture(scope="session", autouse=True)
def one_blas_thread() -> Iterator[None]:
    """One BLAS thread in the test processes, as the tools run (:mod:`jetpipe_ros.cli`): a test
    that calls the diagnosis's parts directly would otherwise run their small matrices on a
    spinning thread pool beside the other test worker (a placement: 76-78 s against 15-17 s).
    Set when the first test starts, after collection has loaded every BLAS library (a limit
    reaches only the libraries loaded when it is set)."""
    with threadpool_limits(1):
        yield


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "ros: talks ROS (starts nodes or an rclpy context)")


@pytest.fixture(scope="session")
def ros_domain() -> Iterator[int]:
    """Isolate this test run's ROS traffic: a domain id of its own, localhost discovery only.

    The domain is reserved for the whole session (:func:`jetpipe_ros.nodes.domain.
    reserve_domain`: a lock file per domain, held until the run ends or dies), so two runs at
    once, from two checkouts or two CI jobs, never share one. Set in ``os.environ`` before any
    ``rclpy.init`` of the run, inherited by subprocesses.
    """
    names = ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")
    saved = {name: os.environ.get(name) for name in names}
    with reserve_domain() as reservation:
        os.environ["ROS_DOMAIN_ID"] = str(reservation.domain)
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        yield reservation.domain
    for name, old in saved.items():
        if old is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = old


class Process:
    """A child process whose merged stdout/stderr is collected line by line."""

    def __init__(self, argv: list[str], env: dict[str, str] | None = None,
                 cwd: Path = REPO) -> None:
        self.argv = argv
        self.lines: list[str] = []
        self._changed = threading.Condition()
        self._eof = False
        self.popen = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE,
                                      stderr=subprocess.STDOUT, text=True, bufsize=1,
                                      preexec_fn=die_with_parent)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()
        with self._changed:
            self._eof = True
            self._changed.notify_all()

    @property
    def output(self) -> str:
        """Everything printed so far."""
        return "\n".join(self.lines)

    def wait_for(self, text: str, timeout: float, start: int = 0) -> str:
        """The first output line from line ``start`` on containing ``text``.

        Fails the test after ``timeout`` [s] or when the process has ended without it.
        """
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                for line in self.lines[start:]:
                    if text in line:
                        return line
                left = deadline - time.monotonic()
                if left <= 0 or self._eof:
                    pytest.fail(f"{text!r} not printed by {' '.join(self.argv)} within "
                                f"{timeout} s (exit status {self.popen.poll()}); output:\n"
                                f"{self.output}")
                self._changed.wait(left)

    def stop(self, timeout: float = 5.0) -> int:
        """Terminate (SIGTERM), kill if still alive after ``timeout`` [s]; the exit status."""
        if self.popen.poll() is None:
            self.popen.terminate()
            try:
                self.popen.wait(timeout)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait()
        return self.popen.returncode


class Launcher:
    """Starts processes in the test's ROS domain (repo on PYTHONPATH); stops them all."""

    def __init__(self) -> None:
        self.started: list[Process] = []

    def __call__(self, args: list[str], python: bool = True, cwd: Path = REPO,
                 env: dict[str, str | None] | None = None) -> Process:
        """Start ``python args...`` (or ``args`` as is, if ``python`` is false).

        ``env`` adds to the environment; a None value removes that variable.
        """
        full_env = dict(os.environ)
        full_env["PYTHONPATH"] = os.pathsep.join(
            [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
        full_env["PYTHONUNBUFFERED"] = "1"
        for name, value in (env or {}).items():  # None unsets
            if value is None:
                full_env.pop(name, None)
            else:
                full_env[name] = value
        proc = Process([sys.executable, *args] if python else args, full_env, cwd)
        self.started.append(proc)
        return proc

    def stop_all(self) -> None:
        for proc in self.started:
            proc.stop()


@pytest.fixture(scope="session")
def compiled_kernel() -> None:
    """The model's kernel compiled into numba's cache before any node starts: on a fresh clone
    the first node would otherwise compile it within its start-up wait (54 s measured on a
    loaded machine, against 30 s allowed)."""
    from jetpipe_ros.model import compile_kernel

    compile_kernel()


@pytest.fixture
def launch(ros_domain: int, compiled_kernel: None) -> Iterator[Launcher]:
    """Start processes for one test; all are stopped at its end."""
    launcher = Launcher()
    try:
        yield launcher
    finally:
        launcher.stop_all()


@pytest.fixture(scope="module")
def module_launch(ros_domain: int, compiled_kernel: None) -> Iterator[Launcher]:
    """Start processes shared by a test module; all are stopped at its end."""
    launcher = Launcher()
    try:
        yield launcher
    finally:
        launcher.stop_all()


@pytest.fixture(scope="module")
def ros_context(ros_domain: int) -> Iterator[object]:
    """An initialised rclpy context for this module's test-side nodes."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)
