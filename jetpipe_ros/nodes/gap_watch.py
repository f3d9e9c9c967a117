"""The twin showcase's own ROS node: it drives the controller and reads the monitor's verdicts."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from jetpipe_ros.nodes import interface


class Watch:
    """A ROS node in ``namespace`` that steps the position setpoint at random every 0.35 s
    (+-18 mm), keeps the latest ``gap_monitor`` statuses of that namespace from
    ``/diagnostics`` (:attr:`status`: name -> (level, message, values)) and sets parameters
    of the namespace's nodes."""

    def __init__(self, namespace: str) -> None:
        rclpy.init()
        self.namespace = namespace
        self.node = rclpy.create_node("gap_watch", namespace=namespace)
        self.status: dict[str, Any] = {}
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10)
        pub = interface.publisher(self.node, "position_setpoint")
        msg = interface.topic("position_setpoint").message_class()()
        rng = np.random.default_rng(11)

        def step() -> None:
            msg.data = float(rng.uniform(-0.018, 0.018))

        self.node.create_timer(0.35, step)
        self.node.create_timer(0.01, lambda: pub.publish(msg))
        self.executor = EventsExecutor()
        self.executor.add_node(self.node)

    def _on_diag(self, msg: Any) -> None:
        for s in msg.status:
            if s.name.startswith(f"{self.namespace}/gap_monitor: "):
                self.status[s.name.rsplit(": ", 1)[1]] = (
                    s.level[0], s.message, {kv.key: kv.value for kv in s.values})

    def spin(self, seconds: float) -> None:
        """Process callbacks for ``seconds`` of wall time."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def set_parameters(self, node: str, values: dict[str, Any]) -> None:
        """Set ``values`` on ``node`` of the namespace at once; RuntimeError if refused."""
        client = AsyncParameterClient(self.node, f"{self.namespace}/{node}")
        if not client.wait_for_services(10.0):
            raise RuntimeError(f"{node}: no parameter service")
        future = client.set_parameters([Parameter(k, value=v) for k, v in values.items()])
        deadline = time.monotonic() + 10.0
        while not future.done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        results = future.result().results if future.done() else []
        if not results or not all(r.successful for r in results):
            raise RuntimeError(f"{node}: parameters refused: {results}")

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown()
