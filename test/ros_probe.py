"""A test-side ROS node that listens to and publishes contract topics (for test_node_*.py)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from jetpipe_ros.nodes import interface


class Probe:
    """Records every message of the topics it listens to, with its arrival time [s, monotonic].

    Args:
        context: an initialised rclpy context.
        namespace: the namespace the relative topic names resolve in.
        use_sim_time: follow ``/clock``.
    """

    def __init__(self, context: Any, namespace: str = "", use_sim_time: bool = False) -> None:
        self.node = Node("probe", namespace=namespace, context=context, parameter_overrides=[
            Parameter("use_sim_time", Parameter.Type.BOOL, use_sim_time)])
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.received: dict[str, list[tuple[float, Any]]] = {}
        self._publishers: dict[str, Any] = {}
        self.command: dict[str, float] = {}  #: values re-published by :meth:`repeat`

    def listen(self, *names: str, depth: int | None = None) -> None:
        """Record the contract topics ``names``; ``depth`` [messages] replaces the contract's
        history depth, so that a test process slower than the stream falls behind it instead
        of losing samples (the middleware queues them while Python is busy)."""
        for name in names:
            log = self.received.setdefault(name, [])
            t = interface.topic(name)
            qos = t.qos.profile()
            if depth is not None:
                qos.depth = depth
            self.node.create_subscription(t.message_class(), t.name,
                                          lambda msg, log=log: log.append((time.monotonic(), msg)),
                                          qos)

    def publish(self, name: str, value: float) -> None:
        """Publish ``value`` once on the Float64 contract topic ``name``."""
        if name not in self._publishers:
            self._publishers[name] = interface.publisher(self.node, name)
        msg = interface.topic(name).message_class()(data=value)
        self._publishers[name].publish(msg)

    def repeat(self, period: float) -> None:
        """Re-publish :attr:`command` (topic -> value) every ``period`` [s] while spinning."""
        self.node.create_timer(period, lambda: [self.publish(n, v)
                                                for n, v in self.command.items()])

    def spin_for(self, seconds: float) -> None:
        """Process callbacks for ``seconds`` of wall time."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=min(0.01, deadline - time.monotonic()))

    def spin_until(self, done: Callable[[], bool], timeout: float) -> bool:
        """Process callbacks until ``done()`` or ``timeout`` [s]; whether ``done()``."""
        deadline = time.monotonic() + timeout
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
        return done()

    def messages(self, name: str, since: float = 0.0) -> list[Any]:
        """Messages of ``name`` that arrived at or after ``since`` [s, monotonic]."""
        return [m for t, m in self.received.get(name, []) if t >= since]

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
