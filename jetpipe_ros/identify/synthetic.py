"""The paper's identification experiments run on the simulator: what a bench would record.

Used by the tests, the benchmark and anyone who wants to see ``jetpipe identify`` work before
recording a real actuator. Every experiment is simulated from the model's initial state with the
given parameters (effects and sensor noise as configured) and returned as dataset columns
(DESIGN.md s.5: ``t,u,y,p1,p2`` as the sensors read them, plus ``f_load``).

The friction test emulates the rig of the paper's Fig. 15 as this package reads it: regulators
hold p1 and p2 (``chamber.regulated``), the piston starts at the end stop it leaves, and the
hydraulic cylinder, which held it there against S (p1 - p2), releases it progressively: its
force (recorded by the force sensor, column ``f_load``) ramps from S (p1 - p2) to 0 at
``ramp_rate`` N/s. The net applied force S (p1 - p2) - F_L then grows from zero, the piston
breaks away when it reaches the breakaway force (Eq. 15) and slides at the velocity where
friction balances it, sweeping the Stribeck and viscous parts of Eq. 18 on the way.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal

from jetpipe_ros.dataset import Entry, write_dataset
from jetpipe_ros.model import ModelParams, simulate

#: The paper's charge/discharge voltages (Sec. 2.3) [V].
PAPER_VOLTAGES = (0.29, 0.57, 1.15, 1.73, 2.29, 2.86, 3.4)
#: Entry-phase (p1, p2) of Sec. 4.2.2 [bar] (the paper's 26) and exit-phase set O [bar].
PAPER_ENTRY = ((1, 9.92), (2.22, 9.9), (4.15, 9.92), (7.18, 9.9), (1, 9.15), (1, 6.93),
               (1, 5.04), (1, 3.96), (1, 1.65), (2.2, 8.87), (4.23, 8.89), (6.15, 8.88),
               (8.01, 8.94), (3.21, 7.89), (5.16, 7.85), (7.02, 7.9), (2.22, 6.87), (4.17, 6.88),
               (5.98, 7.05), (3.02, 5.89), (4.98, 6.04), (2.01, 5.07), (4.07, 5.07), (2.99, 4.2),
               (1.98, 3.2), (8.54, 10.08))
PAPER_EXIT = ((1.78, 1), (4.015, 1), (4.96, 1), (6.89, 1), (7.97, 1), (8.98, 1), (10.0075, 1),
              (10.115, 8.89), (10.225, 6.955), (10.205, 4.195), (10.15, 2.105))

Columns = dict[str, np.ndarray]


def _columns(params: ModelParams, u: np.ndarray, f_load: np.ndarray | float = 0.0) -> Columns:
    trace = simulate(params, u, f_load)
    return {"t": trace.t, "u": trace.u, "y": trace.y_meas, "p1": trace.p1_meas,
            "p2": trace.p2_meas, "f_load": np.broadcast_to(f_load, u.shape).astype(float)}


def charge_discharge(params: ModelParams, voltage: float, charge: float = 4.4,
                     discharge: float = 1.8) -> Columns:
    """Sec. 2.3 at constant volume: ``voltage`` [V] for ``charge`` [s], then minus it for
    ``discharge`` [s]."""
    dt = params["integration.sample_time"]
    u = np.repeat([voltage, -voltage], [round(charge / dt), round(discharge / dt)])
    return _columns(params.with_values({"mechanics.locked": True}), u)


def valve_sweep(params: ModelParams, amplitude: float = 1.0, f0: float = 1.0, f1: float = 70.0,
                duration: float = 6.0) -> Columns:
    """Sec. 2.4 at constant volume: a logarithmic sine sweep ``f0``-``f1`` [Hz] of
    ``amplitude`` [V] (scipy.signal.chirp)."""
    dt = params["integration.sample_time"]
    t = np.arange(round(duration / dt)) * dt
    u = amplitude * signal.chirp(t, f0, t[-1], f1, method="logarithmic", phi=-90.0)
    return _columns(params.with_values({"mechanics.locked": True}), u)


def slow_ramps(params: ModelParams, amplitude: float = 3.4, frequency: float = 0.1,
               periods: float = 1.25) -> Columns:
    """Sec. 2.2 at constant volume: a triangle wave of ``amplitude`` [V] at ``frequency`` [Hz],
    starting at 0 V rising, over ``periods`` periods."""
    dt = params["integration.sample_time"]
    t = np.arange(round(periods / frequency / dt)) * dt
    u = amplitude * signal.sawtooth(2.0 * np.pi * frequency * t + np.pi / 2.0, width=0.5)
    return _columns(params.with_values({"mechanics.locked": True}), u)


def friction_test(params: ModelParams, p1_bar: float, p2_bar: float, ramp_rate: float = 1000.0,
                  duration: float = 1.5) -> Columns:
    """Sec. 4.2 on the Fig. 15 rig (module docstring): regulated ``p1_bar``, ``p2_bar`` [bar];
    entry phase when p2 > p1 (starts at the outer end stop), exit phase otherwise."""
    dt = params["integration.sample_time"]
    sign = 1.0 if p1_bar > p2_bar else -1.0
    force = params["chamber.piston_area"] * (p1_bar - p2_bar) * 1e5
    t = np.arange(round(duration / dt)) * dt
    f_load = force - sign * np.minimum(ramp_rate * t, abs(force))
    rig = params.with_values({"chamber.regulated": True, "chamber.initial_pressure_1": p1_bar * 1e5,
                              "chamber.initial_pressure_2": p2_bar * 1e5,
                              "mechanics.initial_position": -sign * params["mechanics.stroke"] / 2})
    return _columns(rig, np.zeros(t.size), f_load)


def paper_dataset(root: str | Path, params: ModelParams, voltages: Sequence[float] = PAPER_VOLTAGES,
                  entry: Sequence[tuple[float, float]] = PAPER_ENTRY,
                  exit_: Sequence[tuple[float, float]] = PAPER_EXIT,
                  validation: bool = True, overwrite: bool = False,
                  **lengths: Any) -> Path:
    """Write a dataset of the paper's identification campaign simulated with ``params``.

    Charge/discharge at each of ``voltages``, the valve sweep, the slow ramps, a friction test
    at each (p1, p2) of ``entry`` and ``exit_`` [bar], and (``validation``) the 0.6 V / 0.1122 Hz
    square wave of Sec. 6 as a held-out free-piston run. ``lengths`` may shorten the tests:
    ``charge``, ``discharge``, ``sweep``, ``ramp_frequency`` (see the functions above).
    """
    noise_seed = params["sensors.seed"]
    runs: list[tuple[Entry, Columns]] = []

    def seeded(i: int) -> ModelParams:
        return params.with_values({"sensors.seed": noise_seed + i})

    for v in voltages:
        name = f"charge_{v:g}V".replace(".", "p")
        runs.append((Entry(f"{name}.csv", piston="locked", role="train"),
                     charge_discharge(seeded(len(runs)), v, lengths.get("charge", 4.4),
                                      lengths.get("discharge", 1.8))))
    runs.append((Entry("valve_sweep.csv", piston="locked", role="train"),
                 valve_sweep(seeded(len(runs)), duration=lengths.get("sweep", 6.0))))
    runs.append((Entry("slow_ramps.csv", piston="locked", role="train"),
                 slow_ramps(seeded(len(runs)), frequency=lengths.get("ramp_frequency", 0.1))))
    for p1, p2 in (*entry, *exit_):
        name = f"friction_{p1:g}_{p2:g}bar".replace(".", "p")
        runs.append((Entry(f"{name}.csv", piston="free", role="train",
                           extra={"regulated": True}),
                     friction_test(seeded(len(runs)), p1, p2)))
    if validation:
        dt = params["integration.sample_time"]
        t = np.arange(round(9.0 / dt)) * dt
        u = 0.6 * signal.square(2.0 * np.pi * 0.1122 * t)
        runs.append((Entry("square_0p6V.csv", piston="free", role="holdout"),
                     _columns(seeded(len(runs)), u)))
    return write_dataset(root, runs, overwrite=overwrite)
