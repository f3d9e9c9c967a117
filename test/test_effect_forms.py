"""Alternative effect forms (the self-check's "real" variants), regulators and driven replay."""

import math

import numpy as np
import pytest

from jetpipe_ros.model import Actuator, ModelParams, simulate
from jetpipe_ros.model.chamber import pressure_temperature_rates
from jetpipe_ros.model.flow import orifice_flow
from jetpipe_ros.model.friction import friction_parameters

P = ModelParams()
LOCKED = P.with_values({"mechanics.locked": True})
RT = 287.0 * 298.15


def test_orifice_flow_is_choked_below_the_critical_ratio():
    # ISO 6358 choked flow: A p_up / sqrt(r T) * 0.6847 for gamma = 1.4.
    assert orifice_flow(1e-7, 5e5, 1e5, RT) == pytest.approx(1e-7 * 5e5 / math.sqrt(RT) * 0.6847,
                                                             rel=1e-3)
    assert orifice_flow(1e-7, 1e5, 5e5, RT) == -orifice_flow(1e-7, 5e5, 1e5, RT)
    subsonic = orifice_flow(1e-7, 5e5, 4e5, RT)
    assert 0 < subsonic < orifice_flow(1e-7, 5e5, 2.6e5, RT)
    assert orifice_flow(1e-7, 5e5, 5e5, RT) == 0.0


def test_energy_balance_rates_are_adiabatic_without_heat_exchange():
    p, temp, vol, dvol = 4e5, 298.15, 1.5e-4, -1e-3
    dp, dtemp = pressure_temperature_rates(0.0, p, temp, dvol, vol, 287.0, 298.15, 1.4, 0.0)
    assert dp == pytest.approx(-1.4 * p * dvol / vol)  # p V^gamma constant
    assert dtemp / temp == pytest.approx(-0.4 * dvol / vol)  # T V^(gamma-1) constant
    # Charging at the wall temperature: gamma times the isothermal rate.
    dp, _ = pressure_temperature_rates(1e-3, p, temp, 0.0, vol, 287.0, 298.15, 1.4, 0.0)
    assert dp == pytest.approx(1.4 * RT * 1e-3 / vol)


def test_heat_transfer_thermal_spans_adiabatic_to_isothermal():
    u = np.full(300, 3.0)
    iso = simulate(LOCKED, u).p1
    rise = iso[5:60] - iso[4:59]

    def ratio(conductance):
        p = simulate(LOCKED.with_effect("thermal", form="heat_transfer",
                                        heat_transfer=conductance), u).p1
        return float(np.median((p[5:60] - p[4:59]) / rise))

    assert ratio(1e-3) == pytest.approx(1.4, rel=0.03)  # adiabatic charging
    assert ratio(100.0) == pytest.approx(1.0, abs=0.05)  # walls keep it isothermal


def test_multi_element_hysteresis_keeps_the_width_but_rounds_the_corner():
    """Prandtl-Ishlinskii loop: thresholds evenly in w (1 +- spread)."""
    u = np.concatenate([np.linspace(-2, 2, 2000), np.linspace(2, -2, 2000)])
    w = 0.25

    def loop(elements):
        return simulate(LOCKED.with_effect("valve_hysteresis", half_width=w,
                                           elements=elements), u).u_eq

    plain = simulate(LOCKED, u).u_eq
    lag_width = plain[3000] - plain[1000]  # the valve chain's own lag at 2 V/s
    for elements in (1, 4):
        up, down = loop(elements)[1000], loop(elements)[3000]  # both at u = 0
        assert down - up - lag_width == pytest.approx(2 * w, abs=0.005)
    # After the reversal at u = 2 V, input down by 0.4 V < 2 w: one play is still flat, of four
    # (thresholds w/4, 3w/4, 5w/4, 7w/4) the smallest two follow: mean drop (0.275 + 0.025) / 4.
    single, multi = loop(1), loop(4)
    k = 2000 + 200 + 10
    assert single[k] == pytest.approx(single[1990:2030].max(), abs=0.005)
    assert multi[1990:2030].max() - multi[k] == pytest.approx(0.075, abs=0.01)
    # spread 0.5: thresholds 5w/8, 7w/8, 9w/8, 11w/8; a play follows once the input has fallen
    # twice its threshold: only the smallest, by 0.4 - 0.3125 V, mean 0.021875 V; spread 0 is
    # the single loop.
    half = simulate(LOCKED.with_effect("valve_hysteresis", half_width=w, elements=4,
                                       spread=0.5), u).u_eq
    assert half[1990:2030].max() - half[k] == pytest.approx(0.021875, abs=0.005)
    sharp = simulate(LOCKED.with_effect("valve_hysteresis", half_width=w, elements=4,
                                        spread=0.0), u).u_eq
    np.testing.assert_allclose(sharp, single, atol=1e-12)


def test_regulated_pressures_give_the_viscous_steady_velocity_of_eq19():
    p1, p2 = 5e5, 3e5
    params = P.with_values({"chamber.regulated": True, "chamber.initial_pressure_1": p1,
                            "chamber.initial_pressure_2": p2,
                            "mechanics.initial_position": -0.02})
    trace = simulate(params, np.zeros(200))
    assert np.all(trace.p1 == p1) and np.all(trace.p2 == p2)
    f_s, v_s, f_v, f_c = friction_parameters(
        np.array([[P[f"friction.{ph}.{q}"] for q in ("breakaway", "stribeck_velocity",
                                                     "viscous", "coulomb")]
                  for ph in ("entry", "exit")]), 1.0, p1, p2)
    v_ss = (0.005433 * (p1 - p2) - f_c) / f_v  # Eq. 19 at steady state, Stribeck term gone
    moving = trace.v[(trace.y > -0.015) & (trace.y < 0.015)]
    assert moving.size > 5
    np.testing.assert_allclose(moving, v_ss, rtol=0.01)


def test_driven_replay_reproduces_the_free_simulation():
    t = np.arange(0, 2, 1e-3)
    u = 0.8 * np.sign(np.sin(2 * np.pi * 1.3 * t)) + 0.2 * np.sin(2 * np.pi * 7 * t)
    free = simulate(P, u)
    n = u.size - 1
    # Chambers driven by the recorded motion: the pressures come back.
    drive = np.full((n, 4), np.nan)
    drive[:, 0] = free.y[:-1]
    drive[:, 1] = (free.y[1:] - free.y[:-1]) / 1e-3
    out = Actuator(P).run(u[:-1], drive=drive)
    assert np.abs(out[:, 4] - free.p1[1:]).max() < 3e3
    assert np.abs(out[:, 5] - free.p2[1:]).max() < 3e3
    # Mechanics driven by the recorded pressures: the motion comes back.
    drive = np.full((n, 4), np.nan)
    drive[:, 2] = free.p1[:-1]
    drive[:, 3] = free.p2[:-1]
    out = Actuator(P).run(u[:-1], drive=drive)
    assert np.abs(out[:, 2] - free.y[1:]).max() < 3e-4
    assert np.ptp(free.y) > 0.01


def test_drive_shape_is_checked():
    with pytest.raises(ValueError, match="drive must have shape"):
        Actuator(P).run(np.zeros(5), drive=np.zeros((4, 4)))
