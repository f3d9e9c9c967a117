"""The integration kernel: valve pass and physics pass by blocks, the same bits in any pieces."""

import numpy as np
import pytest

from jetpipe_ros.model import Actuator, ModelParams, kernel
from jetpipe_ros.model.valve import U_EQ_MAX, U_EQ_MIN, discretise_valve

P = ModelParams()
EFFECTS = {
    "nominal": {},
    "valve chain and LuGre, noisy": {"effects.friction_dynamics.enabled": True,
                                     "effects.valve_lag.enabled": True,
                                     "effects.valve_delay.enabled": True,
                                     "effects.valve_hysteresis.enabled": True,
                                     "sensors.noise": True},
    "heat transfer, orifice leaks, sensor lag": {"effects.thermal.enabled": True,
                                                  "effects.thermal.form": "heat_transfer",
                                                  "effects.leakage.enabled": True,
                                                  "effects.leakage.form": "orifice",
                                                  "effects.sensor_dynamics.enabled": True},
    "three sub-steps": {"integration.substeps": 3},
    "supply line, power-law leaks": {"effects.supply_pressure.enabled": True,
                                     "effects.supply_pressure.form": "line",
                                     "effects.leakage.enabled": True,
                                     "effects.leakage.form": "power",
                                     "effects.leakage.atmosphere_flow": 2e-5},
    "hose, flow lag, heat transfer, supply line": {"effects.valve_delay.enabled": True,
                                                   "effects.valve_delay.form": "hose",
                                                   "effects.valve_lag.enabled": True,
                                                   "effects.valve_lag.form": "flow",
                                                   "effects.thermal.enabled": True,
                                                   "effects.thermal.form": "heat_transfer",
                                                   "effects.supply_pressure.enabled": True,
                                                   "effects.supply_pressure.form": "line"},
    "short hose": {"effects.valve_delay.enabled": True, "effects.valve_delay.form": "hose",
                   "effects.valve_delay.length": 0.05},
    "port, command delay, heat transfer, supply line": {
        "effects.valve_lag.enabled": True, "effects.valve_lag.form": "port",
        "effects.valve_delay.enabled": True, "effects.thermal.enabled": True,
        "effects.thermal.form": "heat_transfer", "effects.supply_pressure.enabled": True,
        "effects.supply_pressure.form": "line"},
}


def command(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A rich command [V], a load [N] and a drive holding both subsystems now and then."""
    rng = np.random.default_rng(11)
    t = np.arange(n) * 1e-3
    u = 0.8 * np.sign(np.sin(2 * np.pi * 0.7 * t)) + 0.3 * np.sin(2 * np.pi * 9 * t) \
        + np.repeat(rng.uniform(-1.5, 1.5, n // 100 + 1), 100)[:n]
    f_load = np.repeat(rng.uniform(-150, 150, n // 250 + 1), 250)[:n]
    drive = np.full((n, kernel.N_DRIVE), np.nan)
    held = (np.arange(n) % 700) < 40
    drive[held, kernel.DRIVE_Y] = 0.004
    drive[held, kernel.DRIVE_V] = 0.0
    drive[held, kernel.DRIVE_P1] = 3.0e5
    drive[held, kernel.DRIVE_P2] = 5.0e5
    return u, f_load, drive


@pytest.mark.parametrize("changes", EFFECTS.values(), ids=EFFECTS.keys())
def test_any_split_into_calls_gives_the_same_bits(changes):
    """Blocks of kernel.BLOCK samples and calls of any length (the node steps one sample at a
    time, the diagnosis runs whole experiments) carry the valve, delay line, hysteresis and
    physics state across the same way."""
    u, f_load, drive = command(1500)
    whole = Actuator(ModelParams(changes)).run(u, f_load, drive)
    act = Actuator(ModelParams(changes))
    pieces, k = [], 0
    for size in [1, kernel.BLOCK - 1, kernel.BLOCK, kernel.BLOCK + 1, 2, 300, 7] * 10:
        if k < u.size:
            pieces.append(act.run(u[k:k + size], f_load[k:k + size], drive[k:k + size]))
            k += size
    np.testing.assert_array_equal(np.concatenate(pieces), whole)


def test_valve_chain_with_every_effect_fits_the_kernel():
    """Eq. 4 (third order), Eq. 9 (lead-lag) and the valve_lag effect (second order at most):
    the padded chain's size."""
    lag = {"effects.valve_lag.enabled": True}
    c = Actuator(P.with_values(lag | {"effects.valve_lag.form": "second_order"})).constants
    assert c.valve_a.shape[0] == kernel.VALVE_ORDER
    assert Actuator(P.with_values(lag)).constants.valve_a.shape[0] == kernel.VALVE_ORDER - 1
    assert Actuator(P).constants.valve_a.shape[0] == kernel.VALVE_ORDER - 2


@pytest.mark.parametrize("substeps, delay", [(4, 0.0), (4, 0.002), (3, 0.00237), (4, 0.0001),
                                             (8, 0.0031)])
def test_valve_pass_by_samples_is_the_sub_step_recursion(substeps, delay):
    """The valve pass advances the chain a sample at a time (the lifted system); here against
    the sub-step recursion x <- A x + B u_d, u_f = C x + D u_d of the discretised chain, with
    its own delay line over sub-steps interpolated linearly (whole and fractional delays, delays
    shorter than a sample, 3, 4 and 8 sub-steps)."""
    params = P.with_values({"integration.substeps": substeps, "valve.delay": delay,
                            "effects.valve_lag.enabled": True,
                            "effects.valve_lag.form": "second_order"})
    u = np.clip(command(300)[0], -3.4, 3.4)
    act = Actuator(params)
    u_eq = np.empty(u.size * substeps)
    kernel._valve_pass(act.constants, act.state, act.ring, u, u_eq)

    h = params["integration.sample_time"] / substeps
    lag = params["effects.valve_lag.corner_frequency"]
    chain = discretise_valve(params, h, extra_lag_hz=lag,
                             extra_lag_damping=params["effects.valve_lag.damping_ratio"])
    per_sub_step = np.concatenate([np.zeros(chain.delay_steps + 1), np.repeat(u, substeps)])
    x = np.zeros(chain.b.shape[0])
    expected = []
    for j in range(u.size * substeps):
        now, before = per_sub_step[j + 1], per_sub_step[j]  # delay_steps back, and one more
        u_d = (1.0 - chain.delay_fraction) * now + chain.delay_fraction * before
        expected.append(chain.c @ x + chain.d * u_d)
        x = chain.a @ x + chain.b * u_d
    expected = np.clip(params["valve.gain"] * np.array(expected), U_EQ_MIN, U_EQ_MAX)
    np.testing.assert_allclose(u_eq, expected, rtol=0, atol=1e-12)
