"""The plant's real effects as a withheld truth: subsystem, the listed effect each would be
named by (docs/effects.md) or ``unlisted``, and a sampler of realistic sizes.

Sizes are the typical sizes of docs/effects.md read through each form (e.g. a transducer whose
equivalent lag 2 zeta / w_n falls in 1-13 ms and whose nonlinearity is 0.25-1 % of its 10 bar
span, a line 0.3-1.7 m long and 4-6 mm in bore (0.9-4.9 ms one way at 346 m/s, quarter-wave
51-288 Hz), a port volume of 30-60 cm^3 behind a filter with a time constant of 2.5-10 ms at
rest (the range of the second-order flow lag of earlier versions), a load of 1-4 kg on a
coupling at
30-120 Hz, a leak of a few % of the valve's rated flow, a
supply that sags 0.4-1.4 bar at 3 g/s through its regulator and hose), and
for the effects on no list, sizes that matter on a real bench (a null offset of 0.05-0.2 V, a
cushion of 2-4 mm, a load spring of 3-20 kN/m, a position transducer lagging 2-8 ms).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from jetpipe_ros.plant.chambers import gap_flow
from jetpipe_ros.plant.valve import jet_flow


class RealEffect(NamedTuple):
    """What a real effect is to the diagnosis, and how large it is drawn."""

    subsystem: str  #: valve | chamber | mechanics | sensors
    listed: str  #: the effect that names it (docs/effects.md), or "unlisted"
    sample: Callable[[np.random.Generator], dict[str, float]]  #: parameters at a realistic size


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(math.exp(rng.uniform(math.log(low), math.log(high))))


def _signed(rng: np.random.Generator, low: float, high: float) -> float:
    return float(rng.choice([-1.0, 1.0]) * rng.uniform(low, high))


def _plays(rng: np.random.Generator) -> dict[str, float]:
    """Three plays, unequal weights and thresholds, weighted half-width 0.1-0.4 V."""
    weights = rng.dirichlet([2.0, 2.0, 2.0])
    shape = np.array([rng.uniform(0.2, 0.6), rng.uniform(0.8, 1.2), rng.uniform(1.5, 2.2)])
    thresholds = shape * rng.uniform(0.1, 0.4) / float(weights @ shape)
    out = {}
    for i in range(3):
        out[f"threshold_{i + 1}"] = float(thresholds[i])
        out[f"weight_{i + 1}"] = float(weights[i])
    return out


#: The seal-gap leak's size is drawn as its flow at 7 bar against 2 bar, gas at 25 degC.
_GAP_UP, _GAP_DOWN, _GAP_RT = 7e5, 2e5, 287.0 * 298.15


def _seal_gap(rng: np.random.Generator) -> dict[str, float]:
    """A gap 15-25 um high and 0.5-1.5 mm long, loss 1.2-2 dynamic heads, as wide as gives a
    leak of 0.5-1.5e-4 kg/s at 7 against 2 bar (a few % of the valve's rated 3-7 g/s; the
    flow is proportional to the width)."""
    gap = {"height": float(rng.uniform(15e-6, 25e-6)), "length": float(rng.uniform(5e-4, 1.5e-3)),
           "loss_coefficient": float(rng.uniform(1.2, 2.0))}
    per_width = gap_flow(1.0, gap["height"], gap["length"], gap["loss_coefficient"], _GAP_UP,
                         _GAP_DOWN, _GAP_RT)
    return {"width": float(rng.uniform(0.5e-4, 1.5e-4)) / per_width, **gap}


#: The port's time constant is drawn at rest at Eq. 8's null at 0 V (4.1648 bar) [Pa], the
#: gas at 25 degC (r T [J/kg]).
_PORT_P, _PORT_RT = 4.1648e5, 287.0 * 298.15


def port_conductance(volume: float, tau: float) -> float:
    """The filter conductance K [m^3/(s Pa)] that gives a port of ``volume`` [m^3] the time
    constant ``tau`` [s] at rest at 4.1648 bar: tau = V_p / (K p + r T K_v) (passages
    docstring), K_v = -dq/dp of Eq. 8 there at 0 V."""
    slope = (jet_flow(0.0, _PORT_P * 1e-5 - 1e-4) - jet_flow(0.0, _PORT_P * 1e-5 + 1e-4)) \
        / 2e-4 * 1e-5
    return (volume / tau - _PORT_RT * slope) / _PORT_P


def _port(rng: np.random.Generator) -> dict[str, float]:
    """A port of 30-60 cm^3 (log) behind a filter, time constant 2.5-10 ms (log) at rest: at
    3 g/s the filter drops 0.1-1.1 bar."""
    volume = _log_uniform(rng, 3e-5, 6e-5)
    return {"port_volume": volume,
            "filter_conductance": port_conductance(volume, _log_uniform(rng, 2.5e-3, 1e-2))}


def _bristles(rng: np.random.Generator) -> dict[str, float]:
    """Stiffness 1e4-1e6 N/m, damping 0.1-0.7 of critical, 2 sqrt(sigma_0 M), on the nominal
    1 kg."""
    sigma0 = _log_uniform(rng, 1e4, 1e6)
    return {"bristle_stiffness": sigma0,
            "bristle_damping": 2.0 * rng.uniform(0.1, 0.7) * math.sqrt(sigma0 * 1.0),
            "damping_velocity": _log_uniform(rng, 5e-4, 5e-3),
            "breakaway_fraction": float(rng.uniform(0.5, 0.9))}


def _seal(rng: np.random.Generator) -> dict[str, float]:
    """A real seal as twelve friction-rig records show it (docs/selfcheck.md): u_90 0.22-0.83 mm
    (log; the range of the records' medians over their reversals), u_50 / u_90 0.12-0.29 (ten of
    the twelve records)."""
    return {"presliding_displacement": _log_uniform(rng, 2.2e-4, 8.3e-4),
            "half_fraction": float(rng.uniform(0.12, 0.29))}


def flow_map_shape(rng: np.random.Generator) -> dict[str, float]:
    """A bench's flow map departing from Eq. 8 within the fit's error (valve docstring):
    amplitude 0.2-0.5 g/s of either sign, any phase. A property of the bench like the
    parameter deviations (``jetpipe selfcheck --flow-map-shape``), not a case's truth."""
    return {"amplitude": _signed(rng, 2e-4, 5e-4), "phase": float(rng.uniform(-math.pi, math.pi))}


#: Real effect name -> (subsystem, listed effect or "unlisted", sampler).
REAL_EFFECTS: dict[str, RealEffect] = {
    "wall_heat_exchange": RealEffect("chamber", "thermal", lambda r: {
        "heat_transfer_coefficient": _log_uniform(r, 10.0, 100.0),
        "supply_temperature_offset": float(r.uniform(-3.0, 3.0))}),
    "iso6358_leak": RealEffect("chamber", "leakage", lambda r: {
        "cross_conductance": float(r.uniform(1e-10, 3e-10)),
        "atmosphere_conductance": float(r.choice([0.0, r.uniform(0.5e-10, 1.5e-10)])),
        "critical_ratio": float(r.uniform(0.3, 0.45))}),
    "weighted_play_hysteresis": RealEffect("valve", "valve_hysteresis", _plays),
    "elastoplastic_friction": RealEffect("mechanics", "friction_dynamics", _bristles),
    "measured_seal": RealEffect("mechanics", "friction_dynamics", _seal),
    "sensor_second_order": RealEffect("sensors", "sensor_dynamics", lambda r: {
        "natural_frequency": _log_uniform(r, 25.0, 100.0),
        "damping_ratio": float(r.uniform(0.6, 1.0)),
        "nonlinearity": _signed(r, 2.5e3, 1e4),
        "offset_1": _signed(r, 1e3, 1e4), "offset_2": _signed(r, 1e3, 1e4)}),
    "transport_delay": RealEffect("valve", "valve_delay", lambda r: {
        "length": float(r.uniform(0.3, 1.7)), "bore": float(r.uniform(4e-3, 6e-3))}),
    "flow_lag": RealEffect("valve", "valve_lag", _port),
    "supply_droop": RealEffect("valve", "supply_pressure", lambda r: {
        "set_pressure": float(r.uniform(6.5e5, 9e5)), "droop": float(r.uniform(0.5e7, 1.5e7)),
        "droop_quadratic": float(r.uniform(2e9, 7e9)),
        "time_constant": float(r.uniform(5e-3, 2e-2)),
        "hose_conductance": float(r.uniform(1e-7, 3e-7)),
        "hose_volume": _log_uniform(r, 5e-5, 2.5e-4)}),
    "seal_gap_leak": RealEffect("chamber", "leakage", _seal_gap),
    "extra_mass": RealEffect("mechanics", "moving_mass", lambda r: {
        "mass": float(r.uniform(1.0, 4.0)), "frequency": _log_uniform(r, 30.0, 120.0),
        "damping_ratio": float(r.uniform(0.05, 0.3))}),
    "null_offset": RealEffect("valve", "unlisted", lambda r: {
        "offset": _signed(r, 0.05, 0.2)}),
    "pressure_dependent_gain": RealEffect("valve", "unlisted", lambda r: {
        "slope": _signed(r, 0.2, 0.5)}),
    "load_spring": RealEffect("mechanics", "unlisted", lambda r: {
        "stiffness": _log_uniform(r, 3e3, 2e4), "free_position": float(r.uniform(-0.01, 0.01))}),
    "position_filter": RealEffect("sensors", "unlisted", lambda r: {
        "time_constant": 0.5 * float(r.uniform(2e-3, 8e-3))}),
    "end_stop_cushion": RealEffect("mechanics", "unlisted", lambda r: {
        "length": float(r.uniform(2e-3, 4e-3)), "stiffness": _log_uniform(r, 2e5, 1e6),
        "damping": float(r.uniform(2e3, 8e3))}),
}
