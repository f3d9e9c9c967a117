"""Parameter schema: loading, validation errors that name the parameter, ROS YAML round trip."""

import pytest

from jetpipe_ros.fileio import section_applies
from jetpipe_ros.model import SPECS, ModelParams, ParameterError, load_params


def write(tmp_path, text):
    path = tmp_path / "p.yaml"
    path.write_text(text)
    return path


def test_ros_layout_and_plain_nesting_load_the_same(tmp_path):
    ros = write(tmp_path, "actuator_sim:\n  ros__parameters:\n    effects:\n      valve_lag:\n"
                          "        enabled: true\n        corner_frequency: 25.0\n")
    params = load_params(ros)
    assert params.enabled_effects() == ["valve_lag"]
    assert params["effects.valve_lag.corner_frequency"] == 25.0
    plain = write(tmp_path, "effects: {valve_lag: {enabled: true, corner_frequency: 25.0}}\n")
    assert dict(load_params(plain)) == dict(params)


@pytest.mark.parametrize(("key", "node", "applies"), [
    ("actuator_sim", "/actuator_sim", True),  # rcl reads it from the root namespace
    ("actuator_sim", "/axis1/actuator_sim", False),  # ... so not in /axis1
    ("/**", "/axis1/actuator_sim", True),
    ("/**/actuator_sim", "/actuator_sim", True),
    ("/**/actuator_sim", "/plant/axis1/actuator_sim", True),
    ("/**/actuator_sim", "/axis1/controller", False),
    ("/axis1/actuator_sim", "/axis2/actuator_sim", False),
    ("/*/actuator_sim", "/axis2/actuator_sim", True),
    ("/*/actuator_sim", "/actuator_sim", False),  # * is one level, /** any number
])
def test_ros_sections_apply_as_rcl_matches_them(key, node, applies):
    assert section_applies(key, node) == applies


def test_every_section_for_the_node_is_read_offline(tmp_path):
    """Offline there is no namespace: sections for the node in any namespace are read in the
    file's order (a later one wins, as in rcl); a file without one names its sections."""
    path = write(tmp_path, "/**:\n  ros__parameters: {mechanics: {mass: 2.0}}\n"
                           "controller:\n  ros__parameters: {kp: 300.0}\n"
                           "/axis1/actuator_sim:\n  ros__parameters:\n"
                           "    mechanics: {mass: 3.0}\n    effects: {valve_lag: {enabled: true}}\n")
    params = load_params(path)
    assert params["mechanics.mass"] == 3.0 and params.enabled_effects() == ["valve_lag"]
    other = write(tmp_path, "controller:\n  ros__parameters: {kp: 300.0}\n")
    with pytest.raises(ParameterError, match="no ros__parameters section for actuator_sim "
                                             r"\(sections: controller\)"):
        load_params(other)


def test_round_trip_through_ros_yaml(tmp_path):
    params = ModelParams().with_effect("leakage", cross_coefficient=1e-9)
    path = write(tmp_path, params.to_ros_yaml())
    assert dict(load_params(path)) == dict(params)
    changed = write(tmp_path, params.to_ros_yaml(only_changed=True))
    assert dict(load_params(changed)) == dict(params)


@pytest.mark.parametrize(("text", "names"), [
    ("effects: {valve_wobble: {enabled: true}}", ["valve_wobble", "known effects"]),
    ("mechanics: {mass: heavy}", ["mechanics.mass", "number"]),
    ("mechanics: {mass: -1.0}", ["mechanics.mass", "out of range"]),
    ("sensors: {noise: 1}", ["sensors.noise", "true or false"]),
    ("friction: {entry: {viscous: [1, 2]}}", ["friction.entry.viscous", "3 numbers"]),
    ("valve: {coil_resistnce: 190}", ["valve.coil_resistnce", "unknown parameter"]),
])
def test_bad_values_name_the_file_and_parameter(tmp_path, text, names):
    path = write(tmp_path, text)
    with pytest.raises(ParameterError) as err:
        load_params(path)
    message = str(err.value)
    assert str(path) in message
    for name in names:
        assert name in message


def test_unreadable_and_invalid_yaml(tmp_path):
    with pytest.raises(ParameterError, match="cannot read"):
        load_params(tmp_path / "missing.yaml")
    with pytest.raises(ParameterError, match="not valid YAML"):
        load_params(write(tmp_path, "a: [1, 2"))


def test_every_spec_has_description_and_valid_default():
    for spec in SPECS.values():
        assert spec.description
        ModelParams({spec.name: spec.default})


def test_with_values_checks_the_changes_and_copies():
    base = ModelParams({"mechanics.mass": 2.0})
    changed = base.with_values({"valve.delay": 0.003, "chamber.regulated": True})
    assert dict(changed) == dict(ModelParams({**base, "valve.delay": 0.003,
                                              "chamber.regulated": True}))
    assert base["valve.delay"] == 0.002 and not base["chamber.regulated"]
    changed["flow.coefficients"][0] = 99.0  # a list is the copy's own
    assert base["flow.coefficients"][0] != 99.0
    with pytest.raises(ParameterError, match="mechanics.mass"):
        base.with_values({"mechanics.mass": -1.0})
    with pytest.raises(ParameterError, match="valve.dealy"):
        base.with_values({"valve.dealy": 0.003})
