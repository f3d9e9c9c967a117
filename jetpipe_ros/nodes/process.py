"""Process plumbing shared by the executables: signals, ROS start-up, spinning, start-up errors.

Each executable installs its own SIGINT/SIGTERM handlers (they set an event the spin loop
watches), so it can finish its work (log totals, close a bag) before ROS shuts down. Parameter
files given with ``--params-file`` are checked for keys given twice first (rcl would keep the
last one silently), with the tools' YAML reader (:func:`jetpipe_ros.fileio.load_yaml`).
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from threadpoolctl import threadpool_limits

from jetpipe_ros.fileio import DuplicateKeyError, load_yaml
from jetpipe_ros.nodes.parameters import StartupError

#: Longest a spin call blocks [s]: the stop event and the exit condition are checked this often.
#: (This rclpy's EventsExecutor must never spin without a timeout: it then ignores signals.)
SPIN_TIMEOUT = 0.05


class Stop:
    """Set by SIGINT/SIGTERM: ends :func:`spin` at once, even while callbacks keep coming."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self._wakes: set[Future] = set()

    def set(self) -> None:
        self._event.set()
        for wake in list(self._wakes):
            _complete(wake)

    def is_set(self) -> bool:
        return self._event.is_set()

    def watch(self, wake: Future) -> None:
        """Complete ``wake`` when (or if already) set."""
        self._wakes.add(wake)
        if self.is_set():
            _complete(wake)

    def forget(self, wake: Future) -> None:
        self._wakes.discard(wake)


def _complete(future: Future) -> None:
    if not future.done():
        future.set_result(None)


def start(name: str, args: Sequence[str] | None) -> Stop | None:
    """Route SIGINT/SIGTERM to the returned :class:`Stop` and initialise ROS with ``args``.

    Returns None, after printing why on stderr, if ROS refuses the arguments (a bad
    ``--ros-args`` or a params file it cannot parse).
    """
    problem = check_params_files(sys.argv if args is None else args)
    if problem:
        print(f"{name}: error: {problem}", file=sys.stderr)
        return None
    stop = Stop()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # noqa: BLE001 - rcl raises several types for bad arguments
        print(f"{name}: error: cannot initialise ROS: {exc}", file=sys.stderr)
        return None
    return stop


def check_params_files(args: Sequence[str]) -> str | None:
    """Why a ``--params-file`` among ``args`` is refused (a key given twice), or None. Other
    problems (a missing or malformed file) are left to rcl, which reports them."""
    for flag, path in zip(args, args[1:]):
        if flag == "--params-file":
            try:
                load_yaml(path)
            except DuplicateKeyError as exc:
                return f"{path}: {exc}"
            except Exception:  # noqa: BLE001 - rcl reports what it cannot read
                continue
    return None


def spin(executor: Any, stop: Stop, until: Future | None = None,
         condition: Callable[[], bool] = lambda: False) -> None:
    """Run callbacks until ``stop`` is set, ROS shuts down, ``until`` completes or
    ``condition()`` holds.

    Callbacks run inside the executor's own loop (with the EventsExecutor far cheaper per
    message than one ``spin_once`` per callback). That loop returns at its timeout only once it
    runs out of work, which a lock-step campaign in one process never does: ``stop`` and
    ``until`` end it through a future instead. ``condition`` is checked between calls, at least
    every :data:`SPIN_TIMEOUT` while idle.
    """
    wake = Future()
    stop.watch(wake)
    if until is not None:
        until.add_done_callback(lambda _: _complete(wake))
    try:
        while not wake.done() and rclpy.ok() and not condition():
            executor.spin_until_future_complete(wake, timeout_sec=SPIN_TIMEOUT)
    finally:
        stop.forget(wake)


def startup_failed(name: str, exc: StartupError) -> int:
    """Log every start-up problem of node ``name``; the exit status for bad parameters (2)."""
    logger = rclpy.logging.get_logger(name)
    for message in exc.messages:
        logger.error(message)
    logger.error("not started: fix the parameters above")
    return 2


def run_nodes(name: str, args: Sequence[str] | None,
              builders: Sequence[tuple[str, Callable[[], Node]]], *,
              executor: Callable[[list[Node]], Any] = lambda _: EventsExecutor(),
              work: Callable[[list[Node], Any, Stop], int] | None = None,
              finish: Callable[[list[Node]], None] = lambda _: None) -> int:
    """The life of an executable hosting one or more nodes on one executor; its exit status.

    Starts ROS as ``name`` (2 if it refuses the arguments), builds the nodes from ``builders``
    (node name, constructor) in order (2, the failing node's problems logged under its name, on
    a :class:`StartupError`), adds them to ``executor(nodes)`` and runs
    ``work(nodes, executor, stop)`` for the status, or by default spins until stopped (0).
    ``finish(nodes)`` runs once all were built, however the run ends; every node built is
    destroyed. The executable runs with one BLAS thread from here on, as the ``jetpipe``
    commands do (:mod:`jetpipe_ros.cli`): its matrices are small (a valve's discretisation on a
    parameter change, the gap monitor's predictions), and a thread pool would spin beside the
    1 kHz loop.
    """
    threadpool_limits(1)
    stop = start(name, args)
    if stop is None:
        return 2
    nodes: list[Node] = []
    try:
        for node_name, build in builders:
            try:
                nodes.append(build())
            except StartupError as exc:
                return startup_failed(node_name, exc)
        spinner = executor(nodes)
        for node in nodes:
            spinner.add_node(node)
        if work is not None:
            return work(nodes, spinner, stop)
        spin(spinner, stop)
    except ExternalShutdownException:
        pass
    finally:
        if len(nodes) == len(builders):
            finish(nodes)
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
