"""Valve chain against the numbers of docs/model.md (and the paper's Sec. 2)."""

import numpy as np
import pytest
from scipy import signal

from jetpipe_ros.model import ModelParams, build_constants, simulate
from jetpipe_ros.model.valve import (U_EQ_MAX, U_EQ_MIN, jetpipe_position, jetpipe_tf,
                                     midpoint_voltage, valve_tf)

P = ModelParams()
DELAY = 0.002


def step_metrics(t, y):
    """Overshoot, 10-90 % rise, and 5 % settling time of a unit step response."""
    r10 = t[np.argmax(y >= 0.1)]
    r90 = t[np.argmax(y >= 0.9)]
    outside = np.flatnonzero(np.abs(y - 1.0) > 0.05)
    return y.max() - 1.0, r90 - r10, t[outside[-1] + 1]


def test_eq10_coefficients_from_table1():
    num, den = jetpipe_tf(P)
    assert num[0] * 1e3 == pytest.approx(4.963e8, rel=1e-3)  # mm/V
    assert den[1:] == pytest.approx([1.207e4, 2.43e6, 1.419e9], rel=2e-3)


def test_chain_has_unit_dc_gain_and_gain_peak_at_49_7_hz():
    num, den = valve_tf(P)
    assert np.polyval(num, 0) / np.polyval(den, 0) == pytest.approx(1.0)
    w = 2 * np.pi * np.linspace(1, 200, 200_000)
    _, resp = signal.freqs(num, den, w)
    assert w[np.argmax(np.abs(resp))] / (2 * np.pi) == pytest.approx(49.7, abs=0.2)


def test_step_overshoot_rise_and_settling():
    num, den = valve_tf(P)
    t = np.arange(0, 0.1, 1e-6)
    _, y = signal.step((num, den), T=t)
    overshoot, rise, settle = step_metrics(t + DELAY, y)
    assert overshoot == pytest.approx(0.21, abs=0.006)
    assert rise == pytest.approx(4.7e-3, abs=0.1e-3)
    assert settle == pytest.approx(25.5e-3, abs=0.2e-3)


def test_kernel_valve_matches_continuous_chain_with_delay():
    """The discretised chain in the kernel reproduces the continuous step response."""
    u = np.full(100, 0.75)
    trace = simulate(P.with_values({"mechanics.locked": True}), u)
    num, den = valve_tf(P)
    # A sample reports the u_eq its last sub-step used, taken at that sub-step's start.
    t = trace.t - P["integration.sample_time"] / P["integration.substeps"]
    tc = np.arange(0, t[-1], 1e-5)
    _, y = signal.step((num, den), T=tc)
    expected = np.where(t >= DELAY, 0.75 * np.interp(t - DELAY, tc, y), 0.0)
    assert np.max(np.abs(trace.u_eq - expected)) < 1e-3


def test_extra_delay_shifts_the_valve_response():
    u = np.full(60, 0.5)
    base = simulate(P, u).u_eq
    late = simulate(P.with_effect("valve_delay", delay=0.003), u).u_eq
    np.testing.assert_allclose(late[3:], base[:-3], atol=1e-9)


def test_jetpipe_characteristic_bounds_and_sign():
    assert (U_EQ_MIN, U_EQ_MAX) == pytest.approx((-2.8, 3.0))
    assert midpoint_voltage(0.0) == pytest.approx(-0.03)
    assert jetpipe_position(3.4) == pytest.approx(1e-3)
    assert jetpipe_position(-3.4) == pytest.approx(-1e-3)
    assert jetpipe_position(1.0) > 0 > jetpipe_position(-1.0)


def test_discretisation_is_shared_by_equal_chain_parameters():
    """Models differing elsewhere (here an experiment's initial state) reuse one discretisation;
    a chain parameter or the sub-step makes a new one."""
    base = build_constants(P)
    other = build_constants(P.with_values({"chamber.initial_pressure_1": 2e5}))
    assert other.valve_a is base.valve_a
    for change in ({"valve.lag_pole": 150.0}, {"integration.substeps": 8}):
        assert build_constants(P.with_values(change)).valve_a is not base.valve_a
