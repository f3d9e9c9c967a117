"""actuator_sim parameters: bad files stop the process naming the parameter; descriptors; guard."""

from __future__ import annotations

import numpy as np
import pytest

from jetpipe_ros.model import ModelParams, kernel
from jetpipe_ros.nodes.actuator_sim import ActuatorSim
from jetpipe_ros.nodes.parameters import StartupError

EXIT_WITHIN = 60.0  # [s] process start (rclpy, numba import) and exit: 1.5 s alone, 11 s
# for four at once on a loaded 2-core machine; a bound, not a timing check

BAD_FILES = {
    "wrong_type": ("valve:\n  coil_resistance: fast\n", "valve.coil_resistance"),
    "unknown_effect": ("effects:\n  valve_wobble:\n    enabled: true\n",
                       "effects.valve_wobble.enabled"),
    "out_of_range": ("mechanics:\n  mass: 1000.0\n", "mechanics.mass"),
    "bad_choice": ("time_mode: warp\n", "time_mode"),
}


def _params_file(tmp_path, name: str, body: str) -> str:
    indented = "".join(f"    {line}\n" for line in body.splitlines())
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"actuator_sim:\n  ros__parameters:\n{indented}")
    return str(path)


@pytest.fixture(scope="module")
def bad_runs(module_launch, tmp_path_factory):
    """All bad-file processes, started at once so their start-ups overlap."""
    tmp = tmp_path_factory.mktemp("params")
    return {name: module_launch(["-m", "jetpipe_ros.nodes.actuator_sim", "--ros-args",
                                 "--params-file", _params_file(tmp, name, body)])
            for name, (body, _) in BAD_FILES.items()}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_bad_params_file_exits_naming_parameter(bad_runs, case):
    proc = bad_runs[case]
    status = proc.popen.wait(EXIT_WITHIN)
    proc.wait_for("not started", 5.0)  # the output is complete
    assert status == 2
    assert BAD_FILES[case][1] in proc.output
    assert "[ERROR]" in proc.output


def test_good_file_with_integers_and_effect(ros_context, tmp_path):
    path = _params_file(tmp_path, "good", "mechanics:\n  mass: 2\nfriction:\n  exit:\n"
                        "    viscous: [-400, 325, 355]\neffects:\n  valve_lag: {enabled: true}\n")
    node = ActuatorSim(context=ros_context, cli_args=["--ros-args", "--params-file", path])
    try:
        assert node.actuator.params["mechanics.mass"] == 2.0
        assert node.actuator.params["friction.exit.viscous"] == [-400.0, 325.0, 355.0]
        assert node.actuator.params.enabled_effects() == ["valve_lag"]
        mass = node.describe_parameter("mechanics.mass")
        assert not mass.read_only and "[kg]" in mass.description  # rebuilt at run time
        assert node.describe_parameter("integration.sample_time").read_only
        assert (mass.floating_point_range[0].from_value,
                mass.floating_point_range[0].to_value) == (0.01, 100.0)
        assert not node.describe_parameter("command_timeout").read_only
        assert node.describe_parameter("time_mode").read_only
    finally:
        node.destroy_node()


def test_a_section_that_would_not_apply_in_the_namespace_is_refused(ros_context, tmp_path):
    """rcl reads ``actuator_sim:`` as ``/actuator_sim``: in namespace /axis1 it would run at its
    defaults without a word; the node refuses and says how to key the file. ``/**/actuator_sim``
    (what the tools write) applies there."""
    plain = _params_file(tmp_path, "plain", "effects:\n  valve_lag: {enabled: true}\n")
    args = ["--ros-args", "-r", "__ns:=/axis1", "--params-file", plain]
    with pytest.raises(StartupError) as info:
        ActuatorSim(context=ros_context, cli_args=args)
    assert info.value.messages == [
        f"{plain}: section 'actuator_sim' does not apply to /axis1/actuator_sim (a section "
        "without a leading '/' is read from the root namespace), so none of its parameters "
        "would be used; key it '/**/actuator_sim:' (any namespace) or '/axis1/actuator_sim:'"]
    anywhere = tmp_path / "anywhere.yaml"
    anywhere.write_text(ModelParams().with_effect("valve_lag").to_ros_yaml(only_changed=True))
    node = ActuatorSim(context=ros_context,
                       cli_args=["--ros-args", "-r", "__ns:=/axis1", "--params-file",
                                 str(anywhere)])
    try:
        assert node.get_fully_qualified_name() == "/axis1/actuator_sim"
        assert node.actuator.params.enabled_effects() == ["valve_lag"]
    finally:
        node.destroy_node()


def test_all_problems_reported_together(ros_context, tmp_path):
    path = _params_file(tmp_path, "bad", "mechanics:\n  mass: 1000.0\nfoo: 1\n"
                        "command_timeout: abc\n")
    with pytest.raises(StartupError) as info:
        ActuatorSim(context=ros_context, cli_args=["--ros-args", "--params-file", path])
    text = "\n".join(info.value.messages)
    for name in ("mechanics.mass", "'foo'", "command_timeout"):
        assert name in text


def test_non_finite_model_state_resets_instead_of_publishing(ros_context, monkeypatch):
    node = ActuatorSim(context=ros_context)
    try:
        sent = []
        monkeypatch.setattr(node, "_publish", lambda out, stamp: sent.append(out))
        bad = np.full(kernel.N_OUT, np.nan)
        monkeypatch.setattr(node.actuator, "step", lambda u, f: bad)
        node._step()
        assert sent == [] and node._resets == 1
        monkeypatch.undo()
        node._step()
        assert node._resets == 1
        assert node.actuator.time == pytest.approx(node._dt)  # restarted from rest
    finally:
        node.destroy_node()
