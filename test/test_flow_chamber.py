"""Flow map (Eq. 8) equilibria, the vent floor, supply scaling and chamber volumes (Eq. 13)."""

import numpy as np
import pytest
from scipy import optimize

from jetpipe_ros.model.chamber import chamber_volumes, pressure_rates
from jetpipe_ros.model.flow import (FlowLaw, chamber_inflow, flow_matrix, flow_polynomial,
                                    mass_flow)
from jetpipe_ros.model.params import FLOW_COEFFICIENTS

COEF = np.array(FLOW_COEFFICIENTS)


@pytest.mark.parametrize(("u", "p_bar"), [(0.0, 4.165), (3.4, 8.70), (-3.4, 1.07)])
def test_flow_map_equilibrium_pressures(u, p_bar):
    root = optimize.brentq(lambda p: flow_polynomial(COEF, u, p), 1.0, 10.0)
    assert root == pytest.approx(p_bar, abs=0.01)


def test_array_and_kernel_paths_of_eq8_agree():
    """The least-squares regressors (flow_matrix, arrays) and the kernel's flow_polynomial
    (compiled, scalars) evaluate the same monomials; a unit coefficient picks out one term."""
    rng = np.random.default_rng(0)
    u, p = rng.uniform(-3.4, 3.4, 200), rng.uniform(1.0, 10.0, 200)
    scalar = np.array([flow_polynomial(COEF, a, b) for a, b in zip(u, p)])
    np.testing.assert_allclose(mass_flow(COEF, u, p), scalar, rtol=1e-12, atol=1e-15)
    unit = np.zeros(21)
    unit[17] = 1.0  # the paper's 18th term: u^3 p^2
    assert flow_polynomial(unit, 2.0, 3.0) == pytest.approx(1e-3 * 2.0 ** 3 * 3.0 ** 2)
    assert flow_matrix(2.0, 3.0)[0, 17] == 2.0 ** 3 * 3.0 ** 2


def test_no_outflow_at_or_below_atmosphere():
    assert flow_polynomial(COEF, -3.0, 1.0) < 0  # the fit's flaw at its edge
    assert chamber_inflow(COEF, -3.0, 1.0e5, 1.0e6) == 0.0
    assert chamber_inflow(COEF, -3.0, 0.8e5, 1.0e6) == 0.0
    assert chamber_inflow(COEF, -3.0, 3.0e5, 1.0e6) < 0


def test_pressure_clamped_to_identified_range():
    assert chamber_inflow(COEF, 1.0, 12e5, 1e6) == pytest.approx(flow_polynomial(COEF, 1.0, 10))
    assert chamber_inflow(COEF, 1.0, 0.5e5, 1e6) == pytest.approx(flow_polynomial(COEF, 1.0, 1))


def test_supply_pressure_scales_the_null_pressure():
    """At 10 bar supply the map is Eq. 8; at 7 bar the null moves to 1 + 3.165 * 6/9 bar."""
    assert chamber_inflow(COEF, 0.5, 5e5, 1e6) == flow_polynomial(COEF, 0.5, 5.0)
    root = optimize.brentq(lambda p: chamber_inflow(COEF, 0.0, p, 7e5), 1.1e5, 6.9e5)
    assert root / 1e5 == pytest.approx(1 + 3.1648 * 6 / 9, abs=0.01)


def test_chamber_volumes_eq13():
    assert chamber_volumes(0.0, 0.005433, 1.533e-4, 1.915e-4) == pytest.approx((1.533e-4,
                                                                               1.915e-4))
    v1, v2 = chamber_volumes(0.025, 0.005433, 1.533e-4, 1.915e-4)
    assert v1 == pytest.approx(0.005433 * 0.025 + 1.533e-4)
    assert v2 == pytest.approx(-0.005433 * 0.025 + 1.915e-4)
    assert min(chamber_volumes(-0.025, 0.005433, 1.533e-4, 1.915e-4)) > 0


def test_pressure_rates_eq11_eq12():
    rt = 287.0 * 298.15
    dp1, dp2 = pressure_rates(1e-3, 0.0, 4e5, 4e5, 0.0, 1.5e-4, 1.9e-4, 0.005433, rt, 1.0)
    assert dp1 == pytest.approx(rt * 1e-3 / 1.5e-4)
    assert dp2 == 0.0
    # Moving in +y compresses chamber 2 and expands chamber 1.
    dp1, dp2 = pressure_rates(0.0, 0.0, 4e5, 4e5, 0.1, 1.5e-4, 1.9e-4, 0.005433, rt, 1.0)
    assert dp1 == pytest.approx(-0.005433 * 4e5 * 0.1 / 1.5e-4)
    assert dp2 == pytest.approx(0.005433 * 4e5 * 0.1 / 1.9e-4)


def test_flow_gains_scale_each_direction_and_keep_the_null():
    q_in = chamber_inflow(COEF, 1.0, 3e5, 1e6)
    q_out = chamber_inflow(COEF, -1.0, 6e5, 1e6)
    assert q_in > 0 > q_out
    gains = FlowLaw(gain_charge=0.9, gain_discharge=1.2)
    assert chamber_inflow(COEF, 1.0, 3e5, 1e6, gains) == pytest.approx(0.9 * q_in)
    assert chamber_inflow(COEF, -1.0, 6e5, 1e6, gains) == pytest.approx(1.2 * q_out)
    # The null pressure of q(0, p) (4.165 bar) does not move with the gains.
    others = FlowLaw(gain_charge=0.7, gain_discharge=1.3)
    root = optimize.brentq(lambda p: chamber_inflow(COEF, 0.0, p, 1e6, others), 2e5, 8e5)
    assert root == pytest.approx(4.165e5, rel=1e-3)


@pytest.mark.parametrize("reference, null_bar, scale", [
    (1e5, 1.0 + 3.165 * 6.0 / 9.0, 6.0 / 9.0),  # affine over [p_atm, p_s]: 3.110 bar
    (0.0, 4.165 * 0.7, 0.7),  # similarity in absolute pressure: 2.916 bar
    (0.5e5, 0.5 + 3.665 * 6.5 / 9.5, 6.5 / 9.5),
])
def test_a_lower_supply_moves_the_null_and_the_flow_by_the_laws_reference(reference, null_bar,
                                                                          scale):
    """At 7 bar the null of q(0, p) (4.165 bar at 10) lies at the reference plus the nominal
    null's excess over it times (7 bar - ref) / (10 bar - ref), and a flow read at the mapped
    pressure is scaled by the same span."""
    root = optimize.brentq(lambda p: chamber_inflow(COEF, 0.0, p, 7e5, FlowLaw(reference)),
                           1.5e5, 6e5)
    assert root == pytest.approx(null_bar * 1e5, rel=1e-3)
    # chamber 1 at the pressure that maps onto 3 bar at 10 bar: the flow is Eq. 8's there,
    # times the span
    p = reference + (3e5 - reference) * scale
    assert chamber_inflow(COEF, 2.0, p, 7e5, FlowLaw(reference)) == pytest.approx(
        scale * flow_polynomial(COEF, 2.0, 3.0), rel=1e-9)
    # at the nominal supply the reference changes nothing: Eq. 8
    assert chamber_inflow(COEF, 2.0, 3e5, 1e6, FlowLaw(reference)) == pytest.approx(
        flow_polynomial(COEF, 2.0, 3.0), rel=1e-12)


def test_valve_gain_moves_the_locked_equilibrium_to_the_null_of_the_scaled_voltage():
    from jetpipe_ros.model import ModelParams, simulate

    u, gain = 1.0, 1.1
    p = ModelParams().with_values({"mechanics.locked": True, "valve.gain": gain})
    tr = simulate(p, np.full(8000, u))
    null = optimize.brentq(lambda x: chamber_inflow(COEF, gain * u, x, 1e6), 2e5, 9.9e5)
    assert tr.p1[-1] == pytest.approx(null, rel=2e-3)
    assert tr.u_eq[-1] == pytest.approx(gain * u, rel=1e-6)


def test_flow_polynomial_is_the_papers_sum_of_terms():
    """Eq. 8 as the model evaluates it (Horner's scheme over flow.FLOW_TERMS) and the
    identification's regressors (flow_matrix) equal the 21 terms written out here in the
    paper's order."""
    rng = np.random.default_rng(2)
    for u, p in zip(rng.uniform(-3.4, 3.4, 200), rng.uniform(1.0, 10.0, 200)):
        terms = [1, u, p, u**2, u * p, p**2, u**3, u**2 * p, u * p**2, p**3, u**4, u**3 * p,
                 u**2 * p**2, u * p**3, p**4, u**5, u**4 * p, u**3 * p**2, u**2 * p**3,
                 u * p**4, p**5]
        assert flow_polynomial(COEF, u, p) == pytest.approx(1e-3 * COEF @ terms, rel=1e-12,
                                                            abs=1e-15)
        np.testing.assert_allclose(flow_matrix(u, p)[0], terms, rtol=1e-14)
