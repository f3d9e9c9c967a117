"""Each unmodelled effect of DESIGN.md section 3 switches on from parameters and acts as named."""

import numpy as np
import pytest
from scipy import optimize

from jetpipe_ros.model import EFFECTS, ModelParams, simulate
from jetpipe_ros.model.flow import flow_polynomial
from jetpipe_ros.model.params import FLOW_COEFFICIENTS

P = ModelParams()
LOCKED = P.with_values({"mechanics.locked": True})
T = np.arange(0, 3, 1e-3)
RICH = 0.8 * np.sign(np.sin(2 * np.pi * 0.7 * T)) + 0.3 * np.sin(2 * np.pi * 9 * T)


def test_all_effects_are_off_by_default():
    assert P.enabled_effects() == []
    assert set(EFFECTS) == {"valve_delay", "valve_lag", "valve_hysteresis", "supply_pressure",
                            "thermal", "leakage", "friction_dynamics", "moving_mass",
                            "sensor_dynamics"}


@pytest.mark.parametrize("effect", list(EFFECTS))
def test_each_effect_changes_the_response(effect):
    base = simulate(P, RICH)
    # The mass hardly shows behind ~3000 N s/m of viscous friction: use the largest typical.
    params = P.with_effect("moving_mass", mass=5.0) if effect == "moving_mass" else \
        P.with_values({f"effects.{effect}.enabled": True})
    other = simulate(params, RICH)
    gap = max(np.abs(other.y_meas - base.y_meas).max() / 1e-3,
              np.abs(other.p1_meas - base.p1_meas).max() / 1e4)
    assert gap > (0.005 if effect == "moving_mass" else 0.01), f"{effect} left no trace"


def test_valve_lag_attenuates_like_a_first_order_lag():
    u = 0.3 * np.sin(2 * np.pi * 30 * T[:1000])
    base = simulate(LOCKED, u).u_eq[500:]
    lagged = simulate(LOCKED.with_effect("valve_lag", corner_frequency=30.0), u).u_eq[500:]
    assert np.ptp(lagged) / np.ptp(base) == pytest.approx(1 / np.sqrt(2), rel=0.03)


def test_hysteresis_offsets_the_flow_by_half_width_after_a_reversal():
    u = np.concatenate([np.linspace(0, 2, 400), np.linspace(2, 0, 400), np.zeros(200)])
    trace = simulate(LOCKED.with_effect("valve_hysteresis", half_width=0.25), u)
    assert trace.u_eq[-1] == pytest.approx(0.25, abs=5e-3)  # less the valve's undershoot


def test_supply_pressure_lowers_the_charged_pressure():
    u = np.full(6000, 2.86)
    coef = np.array(FLOW_COEFFICIENTS)
    root = optimize.brentq(lambda p: flow_polynomial(coef, 2.86, p), 1, 10)
    nominal = simulate(LOCKED, u).p1[-1]
    low = simulate(LOCKED.with_effect("supply_pressure", pressure=7e5), u).p1[-1]
    assert nominal / 1e5 == pytest.approx(root, abs=0.01)
    assert low / 1e5 == pytest.approx(1 + (root - 1) * 6 / 9, abs=0.01)


def test_cross_leak_pulls_chamber_pressures_together():
    u = np.full(6000, 1.73)
    tight = simulate(LOCKED, u)
    leaky = simulate(LOCKED.with_effect("leakage", cross_coefficient=2e-9), u)
    assert leaky.p1[-1] - leaky.p2[-1] < 0.9 * (tight.p1[-1] - tight.p2[-1])


def test_polytropic_index_speeds_up_charging():
    u = np.full(200, 1.15)
    iso = simulate(LOCKED, u)
    poly = simulate(LOCKED.with_effect("thermal", polytropic_index=1.4), u)
    rise_iso = iso.p1[50] - iso.p1[0]
    assert (poly.p1[50] - poly.p1[0]) / rise_iso == pytest.approx(1.4, rel=0.03)


def test_heavier_mass_slows_the_breakaway_acceleration():
    u = np.full(60, 2.0)
    light = simulate(P, u)
    heavy = simulate(P.with_effect("moving_mass", mass=5.0), u)
    assert light.y[-1] > heavy.y[-1] > 0


def test_sensor_dynamics_lag_bias_and_drift():
    u = np.full(2000, 1.15)
    params = LOCKED.with_effect("sensor_dynamics", time_constant=0.01, bias=2000.0, drift=100.0)
    trace = simulate(params, u)
    assert np.allclose(trace.y_meas, trace.y)
    late = trace.p1_meas[-1] - trace.p1[-1]
    assert late == pytest.approx(2000 + 100 * trace.t[-1], abs=20)
    assert trace.p1_meas[30] < trace.p1[30] + 2000  # lags the rising pressure


def test_lugre_presliding_holds_below_breakaway_and_slides_above():
    lugre = P.with_effect("friction_dynamics", bristle_stiffness=1e5)
    held = simulate(lugre, np.zeros(500), f_load=-10.0)  # below the 18 N exit breakaway
    assert abs(held.y[-1]) < 1e-3
    assert abs(held.v[-1]) < 1e-4
    pushed = simulate(lugre, np.zeros(500), f_load=-400.0)
    assert pushed.y[-1] > 5e-3


def test_locked_equilibrium_matches_flow_map_roots_with_thermal_on():
    """Steady states do not depend on the polytropic index."""
    trace = simulate(LOCKED.with_effect("thermal", polytropic_index=1.3), np.full(8000, 1.15))
    coef = np.array(FLOW_COEFFICIENTS)
    root = optimize.brentq(lambda p: flow_polynomial(coef, 1.15, p), 1, 10)
    assert trace.p1[-1] / 1e5 == pytest.approx(root, abs=0.005)
