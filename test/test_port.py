"""The valve_lag effect's ``port`` form (model/port.py): a port volume before each chamber behind
an ISO 6358 restriction (Darcy's law at its porous end), checked against the physics of a volume
behind a restriction (the steady drop, the time constant, the added volume) and against the model
without it."""

import math

import numpy as np
import pytest
from locked_step import chamber_time_constant

from jetpipe_ros.diagnosis.candidates import CANDIDATES, combinable
from jetpipe_ros.model import Actuator, ModelParams, ParameterError, build_constants, kernel
from jetpipe_ros.model import simulate
from jetpipe_ros.model.actuator import port_time_constant
from jetpipe_ros.model.flow import GAMMA_AIR, chamber_inflow
from jetpipe_ros.model.params import FLOW_COEFFICIENTS

P = ModelParams()
RT = 287.0 * 298.15
COEF = np.array(FLOW_COEFFICIENTS)
RHO_0, T_0 = 1.185, 293.15  # ISO 8778's reference atmosphere


def port(params, volume, conductance, index=0.5):
    return params.with_effect("valve_lag", form="port", port_volume=volume,
                              port_conductance=conductance, port_index=index)


def held(params, u, p_held, port_start=None):
    """Run ``params`` on command ``u`` [V] with both chambers held at ``p_held`` [Pa] (driven,
    as measured pressures), chamber 1's port starting at ``port_start`` [Pa] if given; returns
    the actuator and chamber 1's port pressure after each sample."""
    act = Actuator(params)
    if port_start is not None:
        act.state[kernel.PORT1] = port_start
    drive = np.full((u.size, 4), np.nan)
    drive[:, 2:] = p_held
    ports = []
    for k in range(u.size):
        act.run(u[k:k + 1], 0.0, drive[k:k + 1])
        ports.append(act.state[kernel.PORT1])
    return act, np.array(ports)


def test_a_port_of_volume_zero_is_the_model_without_it():
    """Volume 0 switches the port off: every output equals the nominal model's, bit for bit."""
    u = np.concatenate([np.zeros(50), np.full(300, 1.2), np.full(300, -2.0), np.zeros(200)])
    a = simulate(P, u)
    b = simulate(port(P, 0.0, 3e-9), u)
    for field in ("y", "v", "p1", "p2", "friction"):
        assert np.array_equal(getattr(a, field), getattr(b, field))


@pytest.mark.parametrize("u, conductance, index", [(1.0, 3e-9, 0.5), (2.0, 3e-9, 0.5),
                                                   (1.0, 1e-9, 0.5), (1.0, 5e-9, 1.0),
                                                   (2.0, 5e-9, 1.0)])
def test_the_steady_drop_across_the_restriction_follows_iso_6358(u, conductance, index):
    """A steady flow from the valve through the port into chamber 1 held at 4 bar: the flow the
    map gives at the port's pressure p_p and the drop to the chamber satisfy ISO 6358-1:2013
    by hand, q = C rho_0 p_p sqrt(T_0 / T) (1 - ((r - b) / (1 - b))^2)^m, r = p_c / p_p, with
    b = 0.528 (the model's nozzle function has that critical ratio; ISO's ellipse and the
    nozzle's (Psi / Psi*)^2 differ by under 1 % in between), times Darcy's pressure factor
    (p_mean / 4.1648 bar)^(2 m - 1): the drop predicted from the flow within 2 % (measured
    0.4-0.6 % at m = 0.5, 0.56-1.9 g/s and 0.56-1.8 bar; at m = 1 see the parameters), and at
    m = 1 (a porous element) the drop nearly proportional to the flow."""
    b = 0.528
    params = port(P, 4e-5, conductance, index)
    act, ports = held(params, np.full(800, u), 4e5)
    p_p = ports[-1]
    assert ports[-1] == pytest.approx(ports[-50], rel=1e-6)  # steady
    flow = chamber_inflow(COEF, act.outputs()[kernel.OUT_UEQ], p_p, 1e6)
    choked = conductance * RHO_0 * p_p * math.sqrt(T_0 / P["chamber.temperature"]) \
        * (0.5 * (p_p + 4e5) / 4.1648e5) ** (2.0 * index - 1.0)
    ratio = b + (1.0 - b) * math.sqrt(1.0 - (flow / choked) ** (1.0 / index))
    assert flow > 5e-4
    assert p_p - 4e5 == pytest.approx(p_p * (1.0 - ratio), rel=0.02)


def test_a_porous_restriction_drops_in_proportion_to_the_flow():
    """Chamber 1 held at 4 bar, the command doubled from 1 to 2 V: behind m = 1 (a porous
    element) the drop grows as the flow (drop ratio over flow ratio 1.17 measured, under 1.25:
    the law leaves its linear range as it nears choking), behind m = 0.5 (an orifice) as its
    square (drop ratio over the flow ratio squared within 10 % of 1; 1.03 measured)."""
    def drop_and_flow(index, u):
        act, ports = held(port(P, 4e-5, 5e-9, index), np.full(800, u), 4e5)
        return ports[-1] - 4e5, chamber_inflow(COEF, act.outputs()[kernel.OUT_UEQ], ports[-1],
                                               1e6)

    for index, power, low, high in ((1.0, 1.0, 1.0, 1.25), (0.5, 2.0, 0.9, 1.1)):
        (d1, q1), (d2, q2) = drop_and_flow(index, 1.0), drop_and_flow(index, 2.0)
        assert q2 / q1 > 1.7
        assert low < (d2 / d1) / (q2 / q1) ** power < high


def test_a_porous_restriction_conducts_in_proportion_to_its_mean_pressure():
    """Darcy's law for a gas through a porous element, w = K (p_up^2 - p_down^2) / (2 r T):
    near equal pressures its conductance w / dp is K p_mean / (r T). A drop of 0.2 % at 2, 4.1648
    and 8 bar behind C = 5e-9: at m = 1 the conductance in proportion to the mean pressure
    (within 0.1 %), at 4.1648 bar the ISO law's small-drop conductance (A_e Psi_1(0.995) /
    (0.005 sqrt(r T)), Psi_1 = Psi* (Psi / Psi*)^2, by hand: 5.0 C); at m = 0.5 (the orifice,
    linear there by its own rule) the same conductance at every pressure. (ISO's law at m = 1
    alone keeps it the same too: a factor 4 short at 8 bar against 2.)"""
    from jetpipe_ros.model.port import restriction_flow
    area = 5e-9 * RHO_0 * math.sqrt(287.0 * T_0) / 0.68473
    psi_995 = math.sqrt(2.0 * GAMMA_AIR / (GAMMA_AIR - 1.0)
                        * (0.995 ** (2.0 / GAMMA_AIR) - 0.995 ** ((GAMMA_AIR + 1.0) / GAMMA_AIR)))
    g_0 = area * 0.68473 * (psi_995 / 0.68473) ** 2 / (0.005 * math.sqrt(RT))
    assert g_0 / 5e-9 == pytest.approx(5.0, abs=0.05)

    def conductance(p, index):  # a drop of 0.2 %: r = 0.998, in the linear range (r > 0.995)
        return restriction_flow(area, p / 0.998, p, RT, index) / (p / 0.998 - p)

    means = {p: 0.5 * (p / 0.998 + p) for p in (2e5, 4.1648e5, 8e5)}
    for p, mean in means.items():
        assert conductance(p, 1.0) == pytest.approx(g_0 * mean / 4.1648e5, rel=1e-3)
    assert conductance(8e5, 1.0) / conductance(2e5, 1.0) == pytest.approx(
        means[8e5] / means[2e5], rel=1e-3)
    assert conductance(8e5, 0.5) == pytest.approx(conductance(2e5, 0.5), rel=1e-9)


def test_the_port_relaxes_with_its_small_signal_time_constant():
    """Chamber 1 held at the valve's null pressure, the command at 0, the port 1 kPa above
    (within the restriction's linear range, 0.5 % of the pressure): the port's pressure decays
    with tau = V_p / (gamma r T (G_0 + K_v)), G_0 the restriction's small-drop conductance
    (34.2 C: Psi(0.995) / 0.005 A_e / sqrt(r T), A_e = C rho_0 sqrt(r T_0) / 0.685) and K_v the
    map's slope -dq/dp there (by hand: 7.8e-9 kg/(s Pa)), for 40 cm^3 behind C = 3e-9
    (3.0 ms) and behind C = 1e-9 (7.9 ms), within 1 % (the trapezoid's error at these steps is
    under 0.1 %)."""
    p0 = P["chamber.initial_pressure_1"]
    k_v = -(chamber_inflow(COEF, 0.0, p0 + 100.0, 1e6) - chamber_inflow(COEF, 0.0, p0, 1e6)) \
        / 100.0
    psi_995 = math.sqrt(2.0 * GAMMA_AIR / (GAMMA_AIR - 1.0)
                        * (0.995 ** (2.0 / GAMMA_AIR) - 0.995 ** ((GAMMA_AIR + 1.0) / GAMMA_AIR)))
    for conductance in (3e-9, 1e-9):
        area = conductance * RHO_0 * math.sqrt(287.0 * T_0) / 0.68473
        g_0 = area * psi_995 / (0.005 * math.sqrt(RT))
        tau = 4e-5 / (GAMMA_AIR * RT * (g_0 + k_v))
        _, ports = held(port(P, 4e-5, conductance), np.zeros(200), p0, port_start=p0 + 1e3)
        excess = ports[:60] - ports[-1]
        t = np.arange(1, 61) * 1e-3
        use = excess > 20.0  # well above the round-off of the settled value
        slope = np.polyfit(t[use], np.log(excess[use]), 1)[0]
        assert -1.0 / slope == pytest.approx(tau, rel=0.01)
        # What the report says of a named port: the same time constant from its parameters.
        assert port_time_constant(port(P, 4e-5, conductance)) == pytest.approx(tau, rel=1e-3)
    assert port_time_constant(P) is None


def test_the_port_volume_adds_to_the_chamber_at_low_frequency():
    """Piston locked, a small command step: chamber 1 settles as a first-order lag whose time
    constant is its capacitance over the valve's flow slope. A port of 60 cm^3 (adiabatic:
    capacitance V_p / (gamma r T)) behind a wide restriction stretches it by
    V_p / (gamma V_1) = 28.0 % of chamber 1's 153.3 cm^3 (isothermal), within 3 % of that (an
    isothermal port would give 39.1 %). Each time constant is the area over the normalised step
    response less the valve's own mean delay (the same area over its u_eq)."""
    nominal = chamber_time_constant(P)
    with_port = chamber_time_constant(port(P, 6e-5, 3e-8))
    expected = 6e-5 / (GAMMA_AIR * P["chamber.dead_volume_1"])
    assert with_port / nominal - 1.0 == pytest.approx(expected, rel=0.03)


def test_a_tiny_port_behind_a_wide_restriction_neither_rings_nor_blows_up():
    """0.1 cm^3 behind C = 1e-5 (a port a thousand times faster than the sub-step): the
    integration stays stable and the port relaxes to the chamber, the model within 100 Pa of
    the one without a port (under the sensor's 500 Pa noise)."""
    u = np.concatenate([np.zeros(50), np.full(300, 1.2), np.full(300, -2.0), np.zeros(200)])
    a = simulate(P, u)
    b = simulate(port(P, 1e-7, 1e-5), u)
    assert np.abs(b.p1 - a.p1).max() < 100.0
    assert np.abs(b.p2 - a.p2).max() < 100.0


def test_the_diagnosis_equation_errors_see_the_port():
    """The chambers' equation errors (kernel.chamber_rates, what the diagnosis regresses) of a
    record with 40 cm^3 behind C = 3e-9: with the port in the constants the measured pressure
    rate of chamber 1 is matched within twice the nominal model's own error on its record, and
    over five times closer than by the constants without the port."""
    t = np.arange(3000) * 1e-3
    u = 0.8 * np.sign(np.sin(2 * np.pi * 1.3 * t)) + 0.4 * np.sin(2 * np.pi * 7 * t)

    def rms_error(truth, model):
        run = simulate(truth, u)
        rates = kernel.chamber_rates(build_constants(model), run.y, run.v, run.p1, run.p2,
                                     run.u_eq)
        return float(np.sqrt(np.mean((np.gradient(run.p1, 1e-3) - rates[0])[100:] ** 2)))

    with_port = port(P, 4e-5, 3e-9)
    own = rms_error(P, P)
    assert rms_error(with_port, with_port) < 2.0 * own
    assert rms_error(with_port, P) > 5.0 * rms_error(with_port, with_port)


def test_a_port_beside_a_line_or_a_hose_is_refused_and_never_fitted():
    """One passage between valve and chamber: the port with the line's or the hose's delay is
    a parameter error naming both, and the diagnosis never pairs those candidates."""
    for form in ("line", "hose"):
        with pytest.raises(ParameterError, match="valve_lag.form = port.*valve_delay.form"):
            port(P, 4e-5, 3e-9).with_effect("valve_delay", form=form)
        assert not combinable("valve_lag:port", f"valve_delay:{form}")
    assert combinable("valve_lag:port", "valve_delay")
    port(P, 0.0, 3e-9).with_effect("valve_delay", form="hose")  # no port: no passage


def test_the_port_candidate_vanishes_with_its_volume_and_reads_c_as_an_extent():
    """valve_lag:port: at volume 0 it changes nothing whatever C and m; a volume at the 100 cm^3
    edge is pinned (the truth may lie beyond), C or m at either edge is not; it carries the dead
    volumes, whose signature its volume has."""
    candidate = CANDIDATES["valve_lag:port"]
    assert candidate.vanishes({"port_volume": 0.0, "port_conductance": 1e-9, "port_index": 1.0})
    assert not candidate.vanishes({"port_volume": 1e-5, "port_conductance": 1e-7,
                                   "port_index": 0.5})
    assert candidate.pinned({"port_volume": 1e-4, "port_conductance": 1e-9,
                             "port_index": 1.0}) == ["port_volume"]
    assert candidate.pinned({"port_volume": 4e-5, "port_conductance": 1e-7,
                             "port_index": 0.5}) == []
    assert set(candidate.carries) == {"dead_volume_1", "dead_volume_2"}


def test_a_nominal_model_with_a_hose_is_not_offered_a_port():
    """The diagnosis does not fit a port to a nominal model whose valve delay is a hose (the
    model holds one passage before each chamber and refuses both): it would stop the diagnosis
    with a ParameterError. The other valve lag forms stay candidates."""
    from jetpipe_ros.diagnosis.diagnose import candidates_for

    plain = {c.name for c in candidates_for(ModelParams(), {})}
    assert {"valve_lag:port", "valve_delay:hose"} <= plain
    hosed = {c.name for c in candidates_for(
        ModelParams().with_effect("valve_delay", form="hose", length=1.0), {})}
    assert "valve_lag:port" not in hosed and "valve_lag:flow" in hosed
    assert not any(n.startswith("valve_delay") for n in hosed)
