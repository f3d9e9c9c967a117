"""config/actuator.yaml and msg_defs/topics.yaml: the shipped data files match the code."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from jetpipe_ros.model import EFFECTS, SPECS, ModelParams, load_params
from jetpipe_ros.model.params import flatten
from jetpipe_ros.nodes import interface
from jetpipe_ros.nodes.actuator_sim import NODE_SPECS
from jetpipe_ros.package_data import PackageDataError, share_file

REPO = Path(__file__).resolve().parent.parent
CONFIG = REPO / "config" / "actuator.yaml"


def _ros_parameters() -> dict:
    return flatten(yaml.safe_load(CONFIG.read_text())["/**/actuator_sim"]["ros__parameters"])


def test_config_loads_and_equals_model_defaults():
    params = load_params(CONFIG, ignore=tuple(NODE_SPECS))
    assert dict(params) == dict(ModelParams())
    assert params.enabled_effects() == []


def test_config_lists_every_parameter_once():
    names = set(_ros_parameters())
    assert names == set(SPECS) | set(NODE_SPECS)
    for effect in EFFECTS:
        assert f"effects.{effect}.enabled" in names


def test_config_node_parameters_are_the_node_defaults():
    values = _ros_parameters()
    for name, spec in NODE_SPECS.items():
        assert values[name] == spec.default, name
        assert type(values[name]) is spec.kind, name


def test_contract_is_design_section_4():
    topics = interface.load_topics()
    assert set(topics) == {"voltage_cmd", "load_force", "position", "chamber1/pressure",
                           "chamber2/pressure", "friction_force", "joint_states",
                           "position_setpoint", "/clock", "voltage_applied",
                           "voltage_excitation"}
    assert topics["chamber1/pressure"].type == "sensor_msgs/msg/FluidPressure"
    assert topics["joint_states"].type == "sensor_msgs/msg/JointState"
    assert topics["voltage_cmd"].direction == "controller, id_recorder -> actuator_sim"
    # The measured signals' topics the nodes and the bag export share are the contract's.
    assert set(interface.SENSOR_TOPICS.values()) <= set(topics)
    for topic in topics.values():
        assert topic.name == "/clock" or not topic.name.startswith("/"), topic.name
        assert topic.unit and topic.meaning and topic.publishers and topic.subscribers
        assert topic.message_class().__name__ == topic.type.split("/")[-1]
        profile = topic.qos.profile()
        assert profile.depth == topic.qos.depth >= 1


def test_contract_found_from_the_source_tree():
    assert share_file(interface.CONTRACT) == REPO / "msg_defs" / "topics.yaml"


def test_missing_data_file_names_where_it_was_looked_for():
    with pytest.raises(PackageDataError, match=r"config/nope.yaml not found; looked in: .*"
                                               r"config/nope.yaml"):
        share_file("config/nope.yaml")
