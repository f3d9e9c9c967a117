"""The topic contract (``msg_defs/topics.yaml``): topic names, types, units, direction and QoS.

Nodes create their publishers and subscriptions by topic name through :func:`publisher` and
:func:`subscription`, so a type or a QoS is written only in the contract; tests list the topics
with :func:`load_topics`. rclpy and the message packages are imported only when a ROS object
is made, so the contract can be read without ROS.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import yaml

from jetpipe_ros.fileio import load_yaml
from jetpipe_ros.package_data import share_file
from jetpipe_ros.topics import SENSOR_TOPICS

CONTRACT = "msg_defs/topics.yaml"
#: The values of a node's ``pressure_sensors`` parameter: the chamber pressures a rig measures
#: beside the position (many have none, or one).
PRESSURE_SENSORS = ("p1,p2", "p1", "p2", "none")


def measured_pressures(setting: str) -> tuple[str, ...]:
    """The pressure signals (``p1``, ``p2``) of a ``pressure_sensors`` value."""
    return () if setting == "none" else tuple(setting.split(","))


class ContractError(RuntimeError):
    """The topic contract is malformed or names an unknown topic (a missing contract file:
    :class:`~jetpipe_ros.package_data.PackageDataError`)."""


@dataclass(frozen=True)
class Qos:
    """A QoS profile as data: reliability (reliable | best_effort), history, depth [messages]."""

    reliability: str
    history: str
    depth: int

    def profile(self) -> Any:
        """The ``rclpy.qos.QoSProfile``."""
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

        return QoSProfile(depth=self.depth,
                          reliability=ReliabilityPolicy[self.reliability.upper()],
                          history=HistoryPolicy[self.history.upper()])


@dataclass(frozen=True)
class Topic:
    """One topic of the contract; ``name`` is relative except ``/clock``."""

    name: str
    type: str  #: e.g. ``std_msgs/msg/Float64``
    unit: str
    meaning: str
    publishers: tuple[str, ...]
    subscribers: tuple[str, ...]
    qos: Qos

    @property
    def direction(self) -> str:
        """Who talks to whom, e.g. ``controller, id_recorder -> actuator_sim``."""
        return f"{', '.join(self.publishers)} -> {', '.join(self.subscribers)}"

    def message_class(self) -> type:
        """The Python message class (imports the message package)."""
        package, _, name = self.type.split("/")
        return getattr(importlib.import_module(f"{package}.msg"), name)


def _parse(path: Path) -> dict[str, Topic]:
    try:
        doc = load_yaml(path)
        profiles = {key: Qos(**spec) for key, spec in doc["qos"].items()}
        topics = {}
        for entry in doc["topics"]:
            entry = dict(entry)
            entry["qos"] = profiles[entry["qos"]]
            entry["publishers"] = tuple(entry["publishers"])
            entry["subscribers"] = tuple(entry["subscribers"])
            topic = Topic(**entry)
            topics[topic.name] = topic
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise ContractError(f"{path}: malformed topic contract: {exc!r}") from exc
    return topics


@cache
def load_topics() -> dict[str, Topic]:
    """All topics of the contract by name, in contract order."""
    return _parse(share_file(CONTRACT))


def topic(name: str) -> Topic:
    """One topic of the contract by its name."""
    topics = load_topics()
    if name not in topics:
        raise ContractError(f"topic {name!r} is not in the contract; known: {', '.join(topics)}")
    return topics[name]


def publisher(node: Any, name: str) -> Any:
    """Create the publisher of contract topic ``name`` on ``node`` (an ``rclpy.node.Node``)."""
    t = topic(name)
    return node.create_publisher(t.message_class(), t.name, t.qos.profile())


def subscription(node: Any, name: str, callback: Callable[[Any], None]) -> Any:
    """Create a subscription to contract topic ``name`` on ``node`` calling ``callback``."""
    t = topic(name)
    return node.create_subscription(t.message_class(), t.name, callback, t.qos.profile())
