"""The position PID (jetpipe_ros.control): limits, anti-windup, clamping, a closed-loop step."""

import numpy as np
import pytest
from scipy import signal

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


def test_derivative_acts_on_the_filtered_measurement():
    """kd on the measured position through the docstring's first-order filter: the output is
    -kd d/dt of the position through scipy.signal.lfilter of the backward-Euler filter
    alpha = dt / (tau + dt), whatever the setpoint does (no derivative kick); on a ramp
    y = v t it rises to -kd v with the filter's time constant."""
    kd, tau = 2.0, 0.005
    pid = Pid(PidConfig(kp=0.0, ki=0.0, kd=kd, derivative_filter=tau), DT)
    rng = np.random.default_rng(1)
    y = np.cumsum(rng.normal(0.0, 1e-5, 500))
    setpoint = np.repeat(rng.uniform(-0.02, 0.02, 5), 100)  # steps: no effect with kp = ki = 0
    u = np.array([pid.update(r, yk) for r, yk in zip(setpoint, y)])
    alpha = DT / (tau + DT)
    y_f, _ = signal.lfilter([alpha], [1.0, alpha - 1.0], y, zi=[(1.0 - alpha) * y[0]])
    np.testing.assert_allclose(u, -kd * np.diff(y_f, prepend=y[0]) / DT, rtol=1e-9, atol=1e-12)
    pid.reset()
    v = 0.01  # [m/s]
    ramp = np.array([pid.update(0.0, v * k * DT) for k in range(200)])
    assert ramp[-1] == pytest.approx(-kd * v, rel=1e-9)
    k = round(tau / DT)  # after one time constant: 1 - (1 - alpha)^k (continuous: 1 - 1/e)
    assert ramp[k] == pytest.approx(-kd * v * (1.0 - (1.0 - alpha) ** k), rel=1e-9)


def test_gain_change_keeps_the_integral():
    """A new configuration (what the controller node applies at run time) acts from the next
    sample; the integral carries over (no reset)."""
    pid = Pid(PidConfig(kp=300.0, ki=20.0), DT)
    for _ in range(10):
        pid.update(0.001, 0.0)
    integral = pid.integral
    assert integral == pytest.approx(10 * 0.001 * DT)
    pid.config = PidConfig(kp=100.0, ki=50.0)
    assert pid.update(0.001, 0.0) == pytest.approx(100.0 * 0.001 + 50.0 * (integral + 0.001 * DT))


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
