"""Friction: the paper's worked example (Sec. 4.2.3), the fitted regions and Eq. 15."""

import dataclasses

import numpy as np
import pytest

from jetpipe_ros.model.actuator import build_constants
from jetpipe_ros.model.friction import (friction_parameters, sliding_friction, static_friction,
                                        stribeck_force)
from jetpipe_ros.model.params import ModelParams

PLANES = build_constants(ModelParams()).planes
BAR = 1e5


def test_worked_example_entry_phase():
    f_s, v_s, f_v, f_c = friction_parameters(PLANES, -1.0, 1.0 * BAR, 6.93 * BAR)
    assert f_s == pytest.approx(-95, abs=1.0)
    assert v_s == pytest.approx(-0.015, abs=2e-4)
    assert f_v == pytest.approx(3440, abs=10)
    assert f_c == pytest.approx(-56, abs=1.0)


def test_exit_planes_in_their_region():
    f_s, v_s, f_v, f_c = friction_parameters(PLANES, 1.0, 6.89 * BAR, 1.0 * BAR)
    assert f_s == pytest.approx(26.39 + 12.4 * 6.89 - 14.43)
    assert v_s == pytest.approx(0.00928 + 0.00122 * 6.89 - 0.00097)
    assert f_v == pytest.approx(-407.6 + 325.8 * 6.89 + 355.6)
    assert f_c == pytest.approx(26.16 + 8.575 * 6.89 - 11.72)


def test_outside_fitted_region_uses_mean_pressure():
    outside = friction_parameters(PLANES, -1.0, 7.0 * BAR, 3.0 * BAR)
    mean = friction_parameters(PLANES, -1.0, 5.0 * BAR, 5.0 * BAR)
    assert outside == pytest.approx(mean)


@pytest.mark.parametrize("direction", [-1.0, 1.0])
def test_parameters_keep_their_physical_side(direction):
    for p1 in np.linspace(0.5, 11, 12):
        for p2 in np.linspace(0.5, 11, 12):
            f_s, v_s, f_v, f_c = friction_parameters(PLANES, direction, p1 * BAR, p2 * BAR)
            assert direction * f_c >= 1.0
            assert direction * f_s >= 1.0
            assert direction * v_s >= 1e-4
            assert f_v >= 0.0


def test_stribeck_curve_limits():
    f_s, v_s, f_v, f_c = friction_parameters(PLANES, -1.0, 1.0 * BAR, 6.93 * BAR)
    assert stribeck_force(0.0, f_s, v_s, f_c) == pytest.approx(f_s)
    assert stribeck_force(-1.0, f_s, v_s, f_c) == pytest.approx(f_c)
    assert sliding_friction(-0.1, f_s, v_s, f_v, f_c) == pytest.approx(
        f_c + (f_s - f_c) * np.exp(-((0.1 / 0.015) ** 2)) - 0.1 * f_v, rel=1e-2)


def test_static_friction_eq15():
    assert static_friction(30.0, -95.0) == 30.0
    assert static_friction(-200.0, -95.0) == -95.0
    assert static_friction(200.0, 60.0) == 60.0


def test_planes_of_tests_with_one_side_at_atmosphere():
    """Exit tests with p2 at atmosphere: collinear pressures fix the slope along the mean
    pressure only, split equally (c1 = c2), and reproduce the tests."""
    from jetpipe_ros.identify.friction import FrictionTest, fit_planes

    tests = [FrictionTest(name=f"t{p1}", phase="exit", p1_bar=p1, p2_bar=1.0,
                          values={"breakaway": 5.0 + 2.0 * p1, "stribeck_velocity": 0.01,
                                  "viscous": 100.0, "coulomb": 4.0 + 1.5 * p1},
                          v=np.zeros(0), force=np.zeros(0), rms_error=0.0, rms_position=0.0)
             for p1 in (2.0, 4.0, 6.0)]
    planes, errors = fit_planes(tests)
    assert planes["coulomb"][1] == pytest.approx(planes["coulomb"][2])
    assert planes["coulomb"][1] == pytest.approx(1.5)  # d/dp1 at p2 fixed: 1.5 N/bar
    assert max(errors.values()) < 1e-9
    assert planes["viscous"] == pytest.approx([100.0, 0.0, 0.0], abs=1e-9)


def test_planes_weigh_each_test_by_its_standard_error():
    """A low-pressure test that cannot place its Stribeck velocity (standard error 200 % of
    a value 60 % off) neither moves the plane nor counts in its error; the determined tests'
    planes come out exact."""
    from jetpipe_ros.identify.friction import FrictionTest, fit_planes

    def test(p1, p2, v_s, se):
        return FrictionTest(name=f"t{p1}_{p2}", phase="exit", p1_bar=p1, p2_bar=p2,
                            values={"breakaway": 5.0 + 2.0 * p1, "stribeck_velocity": v_s,
                                    "viscous": 100.0 + 10.0 * p2, "coulomb": 4.0 + p1},
                            v=np.zeros(0), force=np.zeros(0), rms_error=0.0, rms_position=0.0,
                            errors={"breakaway": 0.1, "stribeck_velocity": se,
                                    "viscous": 1.0, "coulomb": 0.1})

    exact = [test(p1, p2, 0.01 + 0.001 * p1, 1e-4) for p1, p2 in ((4, 1), (6, 1), (8, 3), (9, 5))]
    weak = test(1.8, 1.0, 0.4 * (0.01 + 0.0018), 0.02)
    planes, errors = fit_planes(exact + [weak])
    assert planes["stribeck_velocity"] == pytest.approx([0.01, 0.001, 0.0], abs=2e-5)
    assert errors["stribeck_velocity"] < 0.01  # judged on the four that determine it
    unweighted, _ = fit_planes([dataclasses.replace(t, errors={}) for t in exact + [weak]])
    assert abs(unweighted["stribeck_velocity"][0] - 0.01) > 1e-3  # the weak test pulls it
