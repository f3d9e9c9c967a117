"""The position PID (jetpipe_ros.control): limits, anti-windup, clamping, a closed-loop step."""

import numpy as np
import pytest

from jetpipe_ros.control import Pid, PidConfig
from jetpipe_ros.model import Actuator, ParameterError
from jetpipe_ros.model import kernel as k

DT = 1e-3


def test_output_limit_and_anti_windup():
    pid = Pid(PidConfig(kp=300.0, ki=20.0, output_limit=2.0), DT)
    for _ in range(2000):  # 2 s saturated: far from the setpoint, piston not moving
        assert pid.update(0.02, 0.0) == 2.0
    assert pid.integral == pytest.approx(0.0)  # never integrated while saturated
    # The output leaves the limit as soon as the error allows.
    assert pid.update(0.0, 0.001) == pytest.approx(-300.0 * 0.001 - 20.0 * 0.001 * DT)


def test_setpoint_clamped_to_stroke():
    pid = Pid(PidConfig(kp=100.0, ki=0.0), DT)
    assert pid.clamp(0.1) == 0.024 and pid.clamp(-1.0) == -0.024
    assert pid.update(0.1, 0.0) == pytest.approx(100.0 * 0.024)


def test_deadband_and_friction_compensation():
    pid = Pid(PidConfig(kp=100.0, ki=0.0, deadband=1e-4, friction_compensation=0.2), DT)
    assert pid.update(5e-5, 0.0) == 0.0
    assert pid.update(0.001, 0.0) == pytest.approx(100.0 * 0.001 + 0.2)


def test_bad_config_names_the_parameter():
    with pytest.raises(ParameterError, match="parameter kp"):
        PidConfig(kp=-1.0)
    with pytest.raises(ParameterError, match="setpoint_min"):
        PidConfig(setpoint_min=0.01, setpoint_max=0.0)
    with pytest.raises(ParameterError, match="c.yaml: unknown controller parameter"):
        PidConfig.from_mapping({"kq": 1.0}, "c.yaml")


@pytest.mark.parametrize("target", [0.01, -0.01, 0.02])
def test_step_settles_with_the_model(target):
    """Default gains on the nominal model: within +-0.5 mm of a step after 0.3 s, no wind-up
    overshoot beyond 0.5 mm."""
    act = Actuator()
    pid = Pid(PidConfig(), DT)
    out = act.outputs()
    y = []
    for _ in range(1000):
        out = act.step(pid.update(target, out[k.OUT_Y_MEAS]))
        y.append(out[k.OUT_Y])
    y = np.array(y)
    assert np.all(np.abs(y[300:] - target) < 5e-4)
    assert np.max(np.sign(target) * (y - target)) < 5e-4


def test_config_file_is_the_default():
    import yaml
    from pathlib import Path

    from jetpipe_ros.control import SPECS

    path = Path(__file__).resolve().parent.parent / "config" / "controller.yaml"
    values = yaml.safe_load(path.read_text())["/**/controller"]["ros__parameters"]
    assert PidConfig.from_mapping({n: values[n] for n in SPECS}) == PidConfig()
    assert values["enabled"] is True and values["sample_time"] == 0.001
