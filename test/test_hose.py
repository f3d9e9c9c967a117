"""The valve_delay effect's ``hose`` form (model/hose.py): a lumped hose before each chamber,
checked against the physics of a tube (the quarter wave, Darcy's drop, the added volume) and
against the model without it."""

import math

import numpy as np
import pytest
from locked_step import chamber_time_constant

from jetpipe_ros.diagnosis.candidates import CANDIDATES
from jetpipe_ros.model import Actuator, ModelParams, build_constants, kernel, simulate
from jetpipe_ros.model.flow import GAMMA_AIR
from jetpipe_ros.model.hose import HOSE_STATES, SEGMENTS

P = ModelParams()
RT = 287.0 * 298.15
C = math.sqrt(GAMMA_AIR * RT)  # 346 m/s
MU = 1.84e-5  # air at 25 degC [Pa s]


def hose(params, length, bore):
    return params.with_effect("valve_delay", form="hose", length=length, bore=bore)


def chamber_1_hose(act):
    """Chamber 1's hose in the state: nodes' pressures [Pa] from the valve, segments' flows."""
    first = act.state.shape[0] - 2 * HOSE_STATES
    x = act.state[first:first + HOSE_STATES]
    return x[:SEGMENTS], x[SEGMENTS:]


def held_run(params, u, p_held, record=None):
    """Run ``params`` sample by sample on command ``u`` [V] with both chambers' pressures held
    at ``p_held`` [Pa] (driven, as a measured pressure); ``record`` picks from chamber 1's hose
    after each sample."""
    act = Actuator(params)
    drive = np.full((1, 4), np.nan)
    drive[0, 2:] = p_held
    out = []
    for k in range(u.size):
        act.run(u[k:k + 1], 0.0, drive)
        if record is not None:
            out.append(record(*chamber_1_hose(act)))
    return act, np.array(out)


def test_a_hose_of_length_zero_is_the_model_without_it():
    """Length 0 switches the hose off: every output equals the nominal model's, bit for bit."""
    u = np.concatenate([np.zeros(50), np.full(300, 1.2), np.full(300, -2.0), np.zeros(200)])
    a = simulate(P, u)
    b = simulate(hose(P, 0.0, 0.005), u)
    for field in ("y", "v", "p1", "p2", "friction"):
        assert np.array_equal(getattr(a, field), getattr(b, field))


@pytest.mark.parametrize("length", [1.0, 2.0])
def test_the_hose_rings_at_its_quarter_wave(length):
    """Chamber pressures held (an open end), a command step: the pressure at the hose's valve
    end rings at the quarter wave c / (4 L) of a tube closed at the valve, 86.5 Hz at 1 m and
    43.3 Hz at 2 m (c = 346 m/s), within 1 % (the lumped chain's inertance is set for it; the
    valve's flow slope and the wall friction damp it), counted from 30 ms after the step (the
    valve settled) to 140 ms (the ring still over 100 Pa; measured 0.1 % and 0.03 % off)."""
    params = hose(P.with_values({"integration.sample_time": 1e-4, "integration.substeps": 1}),
                  length, 0.006)
    u = np.concatenate([np.zeros(100), np.full(3900, 0.5)])
    _, p0 = held_run(params, u, P["chamber.initial_pressure_1"], lambda p, w: p[0])
    ring = p0[400:1500] - p0[-1]
    crossings = np.flatnonzero(np.diff(np.sign(ring)) != 0)
    frequency = (crossings.size - 1) / 2.0 / ((crossings[-1] - crossings[0]) * 1e-4)
    assert frequency == pytest.approx(C / (4.0 * length), rel=0.01)


def test_the_steady_pressure_drop_follows_the_tube_friction_laws():
    """A steady flow through a 1.5 m, 4 mm hose into a chamber held at 4 bar drops, from the
    valve's end to the chamber, Darcy's f (L / d) w^2 / (2 rho A^2) with Blasius' factor
    0.3164 Re^-0.25 at a turbulent flow (Re above 10^4), and Hagen-Poiseuille's
    128 mu L w / (pi rho d^4) at a laminar one (Re under 400; the chamber held next to the
    valve's null pressure so the flow is small), each within 2 % (rho at the mean pressure;
    measured 0.004 % at 1.3 g/s, Re 22400, 0.109 bar; 0.1 % at 0.011 g/s, Re 197, 10 Pa)."""
    length, bore = 1.5, 0.004
    area = math.pi * bore ** 2 / 4.0
    params = hose(P, length, bore)
    for u, p_held, turbulent in ((1.0, 4e5, True), (0.0, 4.15e5, False)):
        act, _ = held_run(params, np.full(1500, u), p_held)
        p, w = chamber_1_hose(act)
        assert w[-1] == pytest.approx(w[0], rel=1e-6)  # steady: one flow all along
        flow = w[-1]
        reynolds = abs(flow) * bore / (area * MU)
        drop = p[0] - p_held
        rho = (p[0] + p_held) / (2.0 * RT)
        if turbulent:
            assert reynolds > 1e4
            law = 0.3164 * reynolds ** -0.25 * length / bore * flow * abs(flow) / (
                2.0 * rho * area ** 2)
        else:
            assert reynolds < 400.0
            law = 128.0 * MU * length * flow / (math.pi * rho * bore ** 4)
        assert drop == pytest.approx(law, rel=0.02)


def test_the_hose_volume_adds_to_the_chamber_at_low_frequency():
    """Piston locked, a small command step: chamber 1 settles as a first-order lag whose time
    constant is its capacitance over the valve's flow slope. A 2 m, 8 mm hose (100.5 cm^3 of
    gas, adiabatic in the hose: capacitance V / (gamma r T)) stretches it by
    V_hose / (gamma V_1) = 46.8 % of chamber 1's 153.3 cm^3 (isothermal), within 2 % of that
    (measured 46.4 %; an isothermal hose would give 65.6 %).
    Each time constant is the area over the normalised step response less the valve's own mean
    delay (the same area over its u_eq: 2 ms of delay and the chain's lags)."""
    nominal = chamber_time_constant(P)
    with_hose = chamber_time_constant(hose(P, 2.0, 0.008))
    v_hose = math.pi * 0.008 ** 2 / 4.0 * 2.0
    expected = v_hose / (GAMMA_AIR * P["chamber.dead_volume_1"])
    assert with_hose / nominal - 1.0 == pytest.approx(expected, rel=0.02)


def test_the_diagnosis_equation_errors_see_the_hose():
    """The chambers' equation errors (kernel.chamber_rates, what the diagnosis regresses) of a
    record with a 1.5 m, 5 mm hose: with the hose in the constants the measured pressure rate
    of chamber 1 is matched as closely as the nominal model matches its own record (RMS under
    twice that: 5.6 and 3.5 kPa/s measured, of a rate of 206 kPa/s RMS), and over ten times
    closer than by the constants without the hose (97.5 kPa/s)."""
    t = np.arange(3000) * 1e-3
    u = 0.8 * np.sign(np.sin(2 * np.pi * 1.3 * t)) + 0.4 * np.sin(2 * np.pi * 7 * t)

    def rms_error(truth, model):
        run = simulate(truth, u)
        rates = kernel.chamber_rates(build_constants(model), run.y, run.v, run.p1, run.p2,
                                     run.u_eq)
        return float(np.sqrt(np.mean((np.gradient(run.p1, 1e-3) - rates[0])[100:] ** 2)))

    with_hose = hose(P, 1.5, 0.005)
    own = rms_error(P, P)
    assert rms_error(with_hose, with_hose) < 2.0 * own
    assert rms_error(with_hose, P) > 10.0 * rms_error(with_hose, with_hose)


def test_the_hose_candidate_vanishes_with_its_length_and_reads_its_bore_as_an_extent():
    """valve_delay:hose: at length 0 it changes nothing whatever the bore (the bore spans the
    tubing's extent); a length at the 2.5 m edge of its search range is pinned (the truth may
    lie beyond), a bore at 2 or 8 mm is not; and it carries the dead volumes, whose signature
    its volume has."""
    hose_candidate = CANDIDATES["valve_delay:hose"]
    assert hose_candidate.vanishes({"length": 0.0, "bore": 0.008})
    assert not hose_candidate.vanishes({"length": 0.1, "bore": 0.005})
    assert hose_candidate.pinned({"length": 2.5, "bore": 0.008}) == ["length"]
    assert hose_candidate.pinned({"length": 1.0, "bore": 0.002}) == []
    assert set(hose_candidate.carries) == {"dead_volume_1", "dead_volume_2"}
