"""The assembled actuator: steady states, the paper's square wave, stick-slip, sub-steps."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import optimize

from jetpipe_ros.model import Actuator, ModelParams, kernel, simulate
from jetpipe_ros.model.flow import P_ATM, P_SUPPLY_NOMINAL, flow_polynomial, mass_flow
from jetpipe_ros.model.friction import friction_parameters
from jetpipe_ros.model.params import FLOW_COEFFICIENTS

P = ModelParams()
COEF = np.array(FLOW_COEFFICIENTS)
STROKE_HALF = 0.025


def null_pressure(u):
    """Pressure [Pa] where q(u, p) = 0."""
    return 1e5 * optimize.brentq(lambda p: flow_polynomial(COEF, u, p), 1.0, 10.0)


@pytest.mark.parametrize("u", [0.29, 1.15, 1.73])
def test_locked_chambers_settle_where_flow_vanishes(u):
    trace = simulate(P.with_values({"mechanics.locked": True}), np.full(8000, u))
    assert trace.p1[-1] == pytest.approx(null_pressure(u), abs=500)
    assert trace.p2[-1] == pytest.approx(null_pressure(-u), abs=500)
    assert np.all(trace.y == 0.0)


def test_discharging_chamber_stops_at_atmosphere():
    """At -2.86 V Eq. 8 is negative down to 1 bar; the vent floor stops the chamber there."""
    trace = simulate(P.with_values({"mechanics.locked": True}), np.full(4000, 2.86))
    assert trace.p2.min() >= 1e5 - 50.0  # one explicit sub-step may overshoot slightly
    assert trace.p2[-1] == pytest.approx(1e5, abs=300)


def test_free_piston_at_zero_command_stays_at_rest():
    """Both chambers at the null of q(0, p) (docs/model.md: 4.1648 bar): no flow, no force."""
    trace = simulate(P, np.zeros(5000))
    assert np.all(trace.y == 0.0) and np.all(trace.v == 0.0)
    assert trace.p1[-1] == pytest.approx(null_pressure(0.0), abs=50)
    assert trace.p2[-1] == pytest.approx(null_pressure(0.0), abs=50)


def test_square_wave_0p6V_drives_piston_between_end_stops():
    """Paper Fig. 32: 0.6 V peak at 0.1122 Hz moves the piston from stop to stop."""
    t = np.arange(0, 2 / 0.1122, 1e-3)
    u = np.where(np.sin(2 * np.pi * 0.1122 * t) >= 0, 0.6, -0.6)
    trace = simulate(P, u)
    half = int(round(1 / 0.1122 / 2 / 1e-3))
    for k in range(1, 4):
        seg = trace.y[(k - 1) * half:k * half]
        target = STROKE_HALF if k % 2 == 1 else -STROKE_HALF
        assert seg[-1] == pytest.approx(target, abs=1e-9)
    assert np.all(np.abs(trace.y) <= STROKE_HALF)
    assert trace.v.max() > 0.02 and trace.v.min() < -0.02


def test_positive_command_moves_positive_and_friction_opposes_motion():
    trace = simulate(P, np.full(1500, 1.0))
    moving = np.abs(trace.v) > 1e-3
    assert trace.y[-1] > 0.0
    assert np.all(np.sign(trace.friction[moving]) == np.sign(trace.v[moving]))


def test_breakaway_when_applied_force_exceeds_breakaway_force():
    """Eq. 15: a slowly charging command holds the piston until |S dp| reaches |F_S|."""
    trace = simulate(P, np.full(3000, 0.05))
    first = int(np.argmax(trace.v != 0.0))
    assert first > 0
    area = P["chamber.piston_area"]
    for k, stuck in ((first - 1, True), (first, False)):
        f_a = area * (trace.p1[k] - trace.p2[k])
        f_s = friction_parameters(Actuator(P).constants.planes, 1.0, trace.p1[k],
                                  trace.p2[k])[0]
        assert (abs(f_a) <= abs(f_s)) == stuck or abs(abs(f_a) - abs(f_s)) < 2.0
    assert trace.y[first - 1] == 0.0


def test_stick_slip_does_not_chatter():
    """Slow small motion sticks and slips; velocity never flips sign sample to sample and each
    stuck phase lasts longer than a couple of samples."""
    t = np.arange(0, 6, 1e-3)
    trace = simulate(P, 0.25 * np.sin(2 * np.pi * 0.5 * t))
    v = trace.v
    assert np.count_nonzero(v[:-1] * v[1:] < 0) == 0
    stuck = (v == 0.0).astype(int)
    edges = np.flatnonzero(np.diff(stuck))
    runs = np.diff(edges)[1::2] if stuck[edges[0] + 1] else np.diff(edges)[::2]
    assert len(edges) >= 4  # it does stick and slip
    assert runs.min() >= 3


def test_results_do_not_depend_on_substeps():
    """Halving the sub-step changes position by < 20 um and pressures by < 1000 Pa over 10 s
    of a rich command (square wave + sine + steps)."""
    t = np.arange(0, 10, 1e-3)
    rng = np.random.default_rng(3)
    u = (0.6 * np.sign(np.sin(2 * np.pi * 0.3 * t)) + 0.4 * np.sin(2 * np.pi * 3 * t)
         + np.repeat(rng.uniform(-1, 1, 100), 100))
    coarse = simulate(P, u)
    fine = simulate(P.with_values({"integration.substeps": 2 * P["integration.substeps"]}), u)
    assert np.max(np.abs(coarse.y - fine.y)) < 20e-6
    assert max(np.max(np.abs(coarse.p1 - fine.p1)), np.max(np.abs(coarse.p2 - fine.p2))) < 1000


def test_step_by_step_equals_batch():
    """The node's per-sample stepping and the batch simulator are the same computation."""
    u = np.sin(np.linspace(0, 20, 500)) * 1.5
    batch = Actuator(P).run(u)
    act = Actuator(P)
    stepped = np.array([act.step(x).copy() for x in u])
    np.testing.assert_array_equal(batch, stepped)


def test_reconfigure_keeps_the_state():
    act = Actuator()
    act.run(np.full(200, 1.0))
    before = act.state.copy()
    act.reconfigure({"mechanics.locked": True})
    assert np.array_equal(act.state, before) and act.constants.locked
    y = act.state[0]
    act.run(np.full(200, -1.0))
    assert act.state[0] == y  # clamped where it was


def test_sensor_noise_is_seeded_and_sized():
    noisy = P.with_values({"sensors.noise": True, "sensors.seed": 7})
    a = simulate(noisy, np.zeros(4000))
    b = simulate(noisy, np.zeros(4000))
    np.testing.assert_array_equal(a.p1_meas, b.p1_meas)
    assert np.std(a.p1_meas - a.p1) == pytest.approx(500, rel=0.1)
    assert np.std(a.y_meas - a.y) == pytest.approx(1.5e-5, rel=0.1)


#: Highest chamber pressure at which Eq. 8 still fills a chamber for some equivalent voltage in
#: the jet-pipe's travel [-2.8, 3.0] V [Pa]: about 9.0 bar (near 2.97 V; at 10 bar every u_eq
#: vents). Above it only compression by the piston raises a pressure.
_U, _P = np.meshgrid(np.linspace(-2.8, 3.0, 117), np.linspace(1.0, 10.0, 1801))
P_FILL = 1e5 * float(_P[mass_flow(COEF, _U, _P).reshape(_U.shape) > 0.0].max())
F_MAX = 400.0  #: largest load drawn [N]
#: The vent floor works sub-step by sub-step: a chamber just above atmosphere venting at Eq. 8's
#: largest outflow there (0.42 g/s at -2.8 V) drops below it by up to h r T q / V in one explicit
#: sub-step (h = 0.25 ms), then stops: per chamber [Pa], with margin for n <= 1.4.
_Q_VENT = -float(mass_flow(COEF, np.linspace(-2.8, 3.0, 117), 1.0).min())
_H_RT = 1e-3 / P["integration.substeps"] * P["chamber.gas_constant"] * P["chamber.temperature"]
OVERSHOOT = tuple(1.5 * _H_RT * _Q_VENT / (-P["chamber.piston_area"] * STROKE_HALF + v0)
                  for v0 in (P["chamber.dead_volume_1"], P["chamber.dead_volume_2"]))
commands = st.lists(st.tuples(st.floats(-6, 6), st.floats(-F_MAX, F_MAX), st.integers(1, 400)),
                    min_size=1, max_size=12)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(commands, st.sampled_from([None, "friction_dynamics", "leakage", "thermal",
                                  "valve_hysteresis", "supply_pressure", "moving_mass"]))
def test_random_commands_and_loads_obey_the_flow_map_and_friction(segments, effect):
    """What physics bounds, not what the kernel clamps. (1) A chamber rises above P_FILL only
    by compression, which stops once S (p_i - p_j) balances the load: p <= P_FILL + F_MAX / S
    (+ 0.05 bar: viscous friction stops the piston within a millimetre), below the supply.
    (2) With the piston at rest (volumes constant), a chamber at or below atmosphere that is
    also the lower one never loses gas (the vent floor; leaks flow into it), and one above
    P_FILL that is also the higher never gains (but for one explicit sub-step's OVERSHOOT).
    (3) Friction dissipates: F_f v >= 0 (Eq. 18 carries the sign of v), except with LuGre
    bristles, which store energy."""
    u = np.concatenate([np.full(n, v) for v, _, n in segments])
    f_load = np.concatenate([np.full(n, f) for _, f, n in segments])
    params = P if effect is None else P.with_values({f"effects.{effect}.enabled": True})
    trace = simulate(params, u, f_load)
    for name in ("y", "v", "p1", "p2", "friction"):
        assert np.all(np.isfinite(getattr(trace, name))), name
    supply = params["effects.supply_pressure.pressure"] if effect == "supply_pressure" \
        else P_SUPPLY_NOMINAL
    fill = P_ATM + (P_FILL - P_ATM) * (supply - P_ATM) / (P_SUPPLY_NOMINAL - P_ATM)
    assert max(trace.p1.max(), trace.p2.max()) <= fill + F_MAX / P["chamber.piston_area"] + 5e3
    rest = trace.y[1:] == trace.y[:-1]
    for p, other, slack in ((trace.p1, trace.p2, OVERSHOOT[0]), (trace.p2, trace.p1,
                                                                OVERSHOOT[1])):
        before, after = p[:-1], p[1:]
        low = rest & (before <= P_ATM) & (before <= other[:-1])
        assert np.all(after[low] >= before[low] - slack)
        high = rest & (before >= fill) & (before >= other[:-1])
        assert np.all(after[high] <= before[high] + slack)
    if effect != "friction_dynamics":
        assert np.all(trace.friction * trace.v >= 0.0)


def test_a_record_at_another_rate_is_simulated_with_the_models_own_sub_step():
    """A 200 Hz (or 2 kHz) record replays through sub-steps as short as the model's own
    (0.25 ms), so its samples are those of a 1 kHz simulation of the same held command, to
    rounding; at its default 4 sub-steps of 1.25 ms a 200 Hz run is off by 82 um and 1.3 kPa."""
    p = ModelParams()
    t = np.arange(600) * 5e-3
    u200 = 1.5 * np.sign(np.sin(2 * np.pi * 1.3 * t) + 1e-9) + 0.3 * np.sin(2 * np.pi * 7 * t)
    fine = simulate(p, np.repeat(u200, 5))
    for dt, steps in ((5e-3, 20), (5e-4, 2)):
        other = p.at_sample_time(dt)
        assert other["integration.sample_time"] == dt
        assert other["integration.substeps"] == steps
    slow = simulate(p.at_sample_time(5e-3), u200)
    np.testing.assert_allclose(slow.y, fine.y[::5], rtol=0, atol=1e-9)
    np.testing.assert_allclose(slow.p1, fine.p1[::5], rtol=0, atol=1e-3)
    coarse = simulate(p.with_values({"integration.sample_time": 5e-3}), u200)
    assert np.max(np.abs(coarse.y - fine.y[::5])) > 2e-5
    assert np.max(np.abs(coarse.p1 - fine.p1[::5])) > 500.0


def test_every_run_uses_the_one_compiled_kernel():
    """A scalar load, a load per sample, read-only arrays (a broadcast load, a memory-mapped
    record) and the node's step all reach one compiled specialization of the kernel: another
    array type would compile the whole kernel again (40-50 s on a fresh install)."""
    act = Actuator(P)
    act.step(0.0)
    u = np.full(50, 0.5)
    act.run(u)
    act.run(u, np.linspace(0.0, 20.0, 50))
    frozen = np.broadcast_to(np.array([0.5]), (50,))
    drive = np.full((50, kernel.N_DRIVE), np.nan)
    drive.setflags(write=False)
    act.run(frozen, np.broadcast_to(np.array([5.0]), (50,)), drive)
    assert len(kernel.advance.signatures) == 1
    assert not any(arg.mutable is False for arg in kernel.advance.signatures[0][1:])


def test_preloaded_hysteresis_shifts_what_the_valve_sees_at_rest_by_its_half_width():
    """A single 0.3 V play preloaded from above holds the valve at +0.3 V (times the jet pipe's
    gain) under a 0 V command, from below at -0.3 V, midway at 0 V: u_eq, the voltage the flow map
    sees, says so once the valve chain has settled; a side outside [-1, 1] is refused."""
    params = ModelParams().with_values({"mechanics.locked": True}) \
        .with_effect("valve_hysteresis", half_width=0.3, elements=1)
    gain = params["valve.gain"]
    for side in (1.0, 0.0, -1.0):
        act = Actuator(params)
        act.preload_hysteresis(side)
        out = act.run(np.zeros(100))
        assert out[-1, kernel.OUT_UEQ] == pytest.approx(0.3 * side * gain, abs=1e-9)
    with pytest.raises(ValueError, match="side"):
        Actuator(params).preload_hysteresis(1.5)
