"""Each unmodelled effect of docs/effects.md switches on from parameters and acts as named,
checked against independent solutions (root finders, scipy.signal, solve_ivp)."""

import numpy as np
import pytest
from scipy import optimize, signal
from scipy.integrate import solve_ivp

from jetpipe_ros.model import EFFECTS, ModelParams, simulate
from jetpipe_ros.model.flow import flow_polynomial, orifice_flow
from jetpipe_ros.model.params import FLOW_COEFFICIENTS
from newton import AREA, paper_friction, slide

P = ModelParams()
LOCKED = P.with_values({"mechanics.locked": True})
T = np.arange(0, 3, 1e-3)
RICH = 0.8 * np.sign(np.sin(2 * np.pi * 0.7 * T)) + 0.3 * np.sin(2 * np.pi * 9 * T)
COEF = np.array(FLOW_COEFFICIENTS)


def null_pressure(u: float) -> float:
    """Pressure [Pa] where q(u, p) = 0: a locked chamber's equilibrium without leaks."""
    return 1e5 * optimize.brentq(lambda p: flow_polynomial(COEF, u, p), 1.0, 10.0)


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


def test_second_order_valve_lag_resonates_by_one_over_two_zeta():
    """At its natural frequency a second-order lag has gain 1 / (2 zeta): 1.43 at zeta 0.35,
    where a first-order lag at that corner would give 0.71."""
    u = 0.3 * np.sin(2 * np.pi * 30 * T[:1000])
    base = simulate(LOCKED, u).u_eq[500:]
    lagged = simulate(LOCKED.with_effect("valve_lag", form="second_order", corner_frequency=30.0,
                                         damping_ratio=0.35), u).u_eq[500:]
    assert np.ptp(lagged) / np.ptp(base) == pytest.approx(1 / 0.7, rel=0.03)


def test_hysteresis_offsets_the_flow_by_half_width_after_a_reversal():
    u = np.concatenate([np.linspace(0, 2, 400), np.linspace(2, 0, 400), np.zeros(200)])
    trace = simulate(LOCKED.with_effect("valve_hysteresis", half_width=0.25), u)
    assert trace.u_eq[-1] == pytest.approx(0.25, abs=5e-3)  # less the valve's undershoot


def test_supply_pressure_lowers_the_charged_pressure():
    u = np.full(6000, 2.86)
    root = null_pressure(2.86) / 1e5
    nominal = simulate(LOCKED, u).p1[-1]
    low = simulate(LOCKED.with_effect("supply_pressure", pressure=7e5), u).p1[-1]
    assert nominal / 1e5 == pytest.approx(root, abs=0.01)
    assert low / 1e5 == pytest.approx(1 + (root - 1) * 6 / 9, abs=0.01)


def q(u: float, p: float) -> float:
    """Eq. 8 [kg/s] at ``u`` [V] and ``p`` [Pa] (inside [1, 10] bar)."""
    return flow_polynomial(COEF, u, p / 1e5)


def psi(ratio: float) -> float:
    """Saint-Venant flow function of an orifice (ISO 6358 form, air): A p_up psi / sqrt(r T)."""
    g = 1.4
    critical = (2 / (g + 1)) ** (g / (g - 1))
    r = max(ratio, critical)
    return np.sqrt(2 * g / (g - 1) * (r ** (2 / g) - r ** ((g + 1) / g)))


def test_laminar_cross_leak_locked_equilibrium():
    """Locked at 1.73 V with a 2e-9 kg/(s Pa) leak across the piston: q(u, p1) = c (p1 - p2) =
    -q(-u, p2). Eliminating p2 leaves one equation in p1 for brentq; the leak pulls the
    pressures 1.7 bar closer together (7.36 / 1.53 bar without it)."""
    c, u = 2e-9, 1.73
    trace = simulate(LOCKED.with_effect("leakage", cross_coefficient=c), np.full(8000, u))

    def p2_of(p1: float) -> float:
        return p1 - q(u, p1) / c

    p1 = optimize.brentq(lambda p: q(u, p) + q(-u, p2_of(p)), 4.2e5, 9e5)
    assert trace.p1[-1] == pytest.approx(p1, abs=100.0)  # 6.57 bar
    assert trace.p2[-1] == pytest.approx(p2_of(p1), abs=100.0)  # 2.42 bar
    tight = simulate(LOCKED, np.full(8000, u))
    assert (tight.p1[-1] - tight.p2[-1]) - (p1 - p2_of(p1)) > 1.5e5


def test_laminar_leak_to_atmosphere_locked_equilibrium():
    """Each chamber leaks c (p - p_atm) to atmosphere: q(+-u, p) = c (p - p_atm) (brentq)."""
    c, u = 5e-10, 1.73
    trace = simulate(LOCKED.with_effect("leakage", cross_coefficient=0.0,
                                        atmosphere_coefficient=c), np.full(8000, u))
    for p, sign in ((trace.p1, 1.0), (trace.p2, -1.0)):
        want = optimize.brentq(lambda x: q(sign * u, x) - c * (x - 1e5), 1.01e5, 10e5)
        assert p[-1] == pytest.approx(want, abs=100.0)
        assert abs(want - null_pressure(sign * u)) > 2e3  # the leak shows


def test_orifice_law_matches_the_textbook():
    """Choked air flow through 1 mm^2 at 6 bar, 298.15 K: 0.0404 A p / sqrt(T) (SI) =
    1.404 g/s; subsonic: the Saint-Venant function typed here; reversed flow is negative."""
    rt = 287.0 * 298.15
    assert orifice_flow(1e-6, 6e5, 1e5, rt) == pytest.approx(0.0404e-6 * 6e5 / np.sqrt(298.15),
                                                             rel=1e-3)
    for ratio in (0.6, 0.8, 0.95):
        assert orifice_flow(1e-6, 5e5, ratio * 5e5, rt) == pytest.approx(
            1e-6 * 5e5 / np.sqrt(rt) * psi(ratio), rel=1e-9)
    assert orifice_flow(1e-6, 1e5, 5e5, rt) == -orifice_flow(1e-6, 5e5, 1e5, rt)


def test_orifice_leaks_locked_equilibria():
    """Locked at 1.73 V: to atmosphere through 0.2 mm^2 each chamber settles where
    q(+-u, p) = A p psi(p_atm / p) / sqrt(r T) (brentq; choked); across the piston through
    0.2 mm^2 where q(u, p1) = A p1 psi(p2 / p1) / sqrt(r T) = -q(-u, p2) (scipy.optimize.root)."""
    rt, u, area = 287.0 * 298.15, 1.73, 2e-7

    def orifice(p_up: float, p_down: float) -> float:
        return area * p_up / np.sqrt(rt) * psi(p_down / p_up)

    trace = simulate(LOCKED.with_effect("leakage", form="orifice", atmosphere_area=area),
                     np.full(8000, u))
    for p, sign in ((trace.p1, 1.0), (trace.p2, -1.0)):
        want = optimize.brentq(lambda x: q(sign * u, x) - orifice(x, 1e5), 1.01e5, 10e5)
        assert p[-1] == pytest.approx(want, abs=100.0)
    trace = simulate(LOCKED.with_effect("leakage", form="orifice", cross_area=area),
                     np.full(8000, u))
    sol = optimize.root(lambda x: [q(u, x[0]) - orifice(x[0], x[1]),
                                   q(-u, x[1]) + orifice(x[0], x[1])],
                        [null_pressure(u), null_pressure(-u)])
    assert sol.success
    assert trace.p1[-1] == pytest.approx(sol.x[0], abs=100.0)
    assert trace.p2[-1] == pytest.approx(sol.x[1], abs=100.0)
    assert null_pressure(u) - sol.x[0] > 1e4  # the leak shows


def test_polytropic_index_speeds_up_charging():
    u = np.full(200, 1.15)
    iso = simulate(LOCKED, u)
    poly = simulate(LOCKED.with_effect("thermal", polytropic_index=1.4), u)
    rise_iso = iso.p1[50] - iso.p1[0]
    assert (poly.p1[50] - poly.p1[0]) / rise_iso == pytest.approx(1.4, rel=0.03)


def test_moving_mass_follows_newtons_law():
    """The regulated rig (1, 6.93) bar, the load that held the piston at its stop released in
    one sample: the 5 kg piston follows Eq. 14 with Eq. 18 (solve_ivp, test/newton.py) within
    50 um, where the nominal 1 kg would be 1 mm ahead."""
    p1, p2, mass = 1.0e5, 6.93e5, 5.0
    f_load = np.zeros(80)
    f_load[0] = AREA * (p1 - p2)
    rig = P.with_values({"chamber.regulated": True, "chamber.initial_pressure_1": p1,
                         "chamber.initial_pressure_2": p2, "mechanics.initial_position": 0.025})
    trace = simulate(rig.with_effect("moving_mass", mass=mass), np.zeros(f_load.size), f_load)
    y, v, k0, n = slide(p1, p2, f_load, 0.025, mass=mass)
    assert k0 == 1 and n > 50  # breaks away as released, reaches the stop after 50 ms
    assert np.max(np.abs(trace.y[:n] - y[:n])) < 5e-5
    assert np.max(np.abs(trace.v[:n] - v[:n])) < 0.03  # [m/s]; 0.9 m/s at the end
    light, _, _, m = slide(p1, p2, f_load, 0.025, mass=1.0)
    assert np.max(np.abs(light[:min(n, m)] - y[:min(n, m)])) > 1e-3


def test_sensor_dynamics_lag_bias_and_drift():
    """The measured pressure is the true one through a first-order lag (scipy.signal.lfilter
    of the lag discretised with a first-order hold) plus bias plus drift t; position is not
    affected. The 7.5 kPa lag of a charging chamber is matched within 150 Pa."""
    u = np.full(2000, 1.15)
    tau, bias, drift = 0.01, 2000.0, 100.0
    params = LOCKED.with_effect("sensor_dynamics", time_constant=tau, bias=bias, drift=drift)
    trace = simulate(params, u)
    assert np.allclose(trace.y_meas, trace.y)
    b, a, _ = signal.cont2discrete(([1.0], [tau, 1.0]), 1e-3, method="foh")
    for true, measured in ((trace.p1, trace.p1_meas), (trace.p2, trace.p2_meas)):
        lagged = signal.lfilter(np.ravel(b), a, true - true[0]) + true[0]
        assert np.max(np.abs(true - lagged)) > 5e3  # the lag is there to see
        assert np.max(np.abs(measured - (lagged + bias + drift * trace.t))) < 150.0


def test_sensor_gain_error_and_per_chamber_bias():
    """Without lag the sensors read (1 + gain) p + bias, chamber 2 plus bias_difference."""
    u = np.full(1500, -1.0)
    params = LOCKED.with_effect("sensor_dynamics", time_constant=0.0, bias=1500.0,
                                bias_difference=-4000.0, gain=0.02)
    trace = simulate(params, u)
    assert np.allclose(trace.p1_meas, 1.02 * trace.p1 + 1500.0, rtol=0, atol=1e-6)
    assert np.allclose(trace.p2_meas, 1.02 * trace.p2 + 1500.0 - 4000.0, rtol=0, atol=1e-6)


def test_a_delay_between_sub_steps_is_interpolated():
    """The delay is continuous: 1.1 ms (4.4 sub-steps of 0.25 ms) lies between 1 and 1.25 ms,
    in proportion, at every sample of a step response."""
    u = np.concatenate([np.zeros(20), np.full(60, 2.0)])
    runs = {d: simulate(LOCKED.with_effect("valve_delay", delay=d), u).p1
            for d in (0.001, 0.0011, 0.00125)}
    low, mid, high = runs[0.001], runs[0.0011], runs[0.00125]
    assert np.max(np.abs(high - low)) > 300.0  # a quarter of a millisecond shows
    expected = low + 0.4 * (high - low)
    assert np.max(np.abs(mid - expected)) < 0.02 * np.max(np.abs(high - low))


@pytest.mark.parametrize("force", [2.0, 25.0, 40.0])
def test_lugre_follows_its_equations(force):
    """Regulated rig at (5, 4) bar (exit planes: F_S 30.7 N), a net force ``force`` [N] from
    rest, sigma0 1e5 N/m: the kernel against the LuGre equations integrated by solve_ivp
    (dz/dt = v - sigma0 |v| z / g(v), M dv/dt = F - sigma0 z - F_v v) within 2 um. Well below
    breakaway the bristles deflect F / sigma0 (pre-sliding, 2 N: 20 um) and hold; above it the
    piston slides."""
    p1, p2, sigma0, n = 5e5, 4e5, 1e5, 300
    f_s, v_s, f_v, f_c = paper_friction(p1, p2)
    rig = P.with_values({"chamber.regulated": True, "chamber.initial_pressure_1": p1,
                         "chamber.initial_pressure_2": p2})
    trace = simulate(rig.with_effect("friction_dynamics", bristle_stiffness=sigma0),
                     np.zeros(n), f_load=AREA * (p1 - p2) - force)

    def rhs(t, x):
        y, v, z = x
        g = f_c + (f_s - f_c) * np.exp(-(v / v_s) ** 2)
        return [v, force - sigma0 * z - f_v * v, v - sigma0 * abs(v) * z / g]

    t = np.arange(n) * 1e-3
    sol = solve_ivp(rhs, (0.0, t[-1]), [0.0, 0.0, 0.0], method="LSODA", t_eval=t,
                    rtol=1e-9, atol=[1e-12, 1e-10, 1e-12])
    assert np.max(np.abs(trace.y - sol.y[0])) < 2e-6
    if force < abs(f_s):
        assert trace.friction[-1] == pytest.approx(force, rel=1e-3)  # holds
    else:
        assert trace.v[-1] > 1e-3  # slides
    if force == 2.0:
        assert trace.y[-1] == pytest.approx(force / sigma0, rel=0.05)


def test_locked_equilibrium_matches_flow_map_roots_with_thermal_on():
    """Steady states do not depend on the polytropic index."""
    trace = simulate(LOCKED.with_effect("thermal", polytropic_index=1.3), np.full(8000, 1.15))
    root = null_pressure(1.15) / 1e5
    assert trace.p1[-1] / 1e5 == pytest.approx(root, abs=0.005)
