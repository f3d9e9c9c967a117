"""The paper's identification experiments as a campaign plan, run offline through the model:
what a bench would record.

Used by the tests, the benchmark and anyone who wants to see ``jetpipe identify`` work before
recording a real actuator. Each function below gives one experiment as a campaign-plan entry
(the YAML mapping of :mod:`jetpipe_ros.campaign.plan`: its signals come from
:mod:`jetpipe_ros.campaign.signals`), and :func:`record` runs a list of them through
:func:`~jetpipe_ros.campaign.run_campaign_offline`: one actuator with the given parameters
(effects and sensor noise as configured), settle phases between the experiments, the rig of the
friction tests switched by :meth:`~jetpipe_ros.model.Actuator.reconfigure`. Nothing here
simulates: the same plan runs through ROS with ``id_recorder``.

The friction test is the rig of the paper's Fig. 15 as this package reads it (the campaign
plan's ``regulated`` experiment): regulators hold p1 and p2, the piston starts at the end stop it
leaves, and the hydraulic cylinder, which held it there against S (p1 - p2), releases it
progressively: its force (recorded by the force sensor, column ``f_load``) ramps from
S (p1 - p2) to 0 at ``ramp_rate`` N/s. The net applied force S (p1 - p2) - F_L then grows from
zero, the piston breaks away when it reaches the breakaway force (Eq. 15) and slides at the
velocity where friction balances it, sweeping the Stribeck and viscous parts of Eq. 18.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from jetpipe_ros.campaign import Campaign, parse_campaign, run_campaign_offline
from jetpipe_ros.dataset import COMPLETE, Dataset, read_dataset
from jetpipe_ros.model import ModelParams

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

Experiment = dict[str, Any]  #: one entry of a campaign plan's ``experiments:`` list


def charge_discharge(voltage: float, charge: float = 4.4, discharge: float = 1.8,
                     name: str | None = None) -> Experiment:
    """Sec. 2.3 at constant volume: ``voltage`` [V] for ``charge`` [s], then minus it for
    ``discharge`` [s]."""
    return {"name": name or f"charge_{voltage:g}V".replace(".", "p"), "kind": "open_loop",
            "locked": True, "role": "train", "duration": charge + discharge,
            "voltage": {"signal": "steps", "levels": [voltage, -voltage],
                        "durations": [charge, discharge]}}


def valve_sweep(amplitude: float = 1.0, f0: float = 1.0, f1: float = 70.0,
                duration: float = 6.0, name: str = "valve_sweep") -> Experiment:
    """Sec. 2.4 at constant volume: a logarithmic sine sweep ``f0``-``f1`` [Hz] of
    ``amplitude`` [V] over ``duration`` [s], starting with the valve at rest."""
    return {"name": name, "kind": "open_loop", "locked": True, "role": "train",
            "duration": duration,
            "voltage": {"signal": "sine_sweep", "amplitude": amplitude, "f0": f0, "f1": f1}}


def slow_ramps(amplitude: float = 3.4, frequency: float = 0.1, periods: float = 1.25,
               name: str = "slow_ramps") -> Experiment:
    """Sec. 2.2 at constant volume: a triangle wave of ``amplitude`` [V] at ``frequency`` [Hz],
    starting at 0 V rising, over ``periods`` periods."""
    return {"name": name, "kind": "open_loop", "locked": True, "role": "train",
            "duration": periods / frequency,
            "voltage": {"signal": "triangle", "amplitude": amplitude, "frequency": frequency}}


def friction_test(p1_bar: float, p2_bar: float, ramp_rate: float = 1000.0,
                  duration: float = 1.5, name: str | None = None) -> Experiment:
    """Sec. 4.2 on the Fig. 15 rig (module docstring): regulated ``p1_bar``, ``p2_bar`` [bar];
    entry phase when p2 > p1 (starts at the outer end stop), exit phase otherwise; the load
    released at ``ramp_rate`` [N/s] over ``duration`` [s]."""
    return {"name": name or f"friction_{p1_bar:g}_{p2_bar:g}bar".replace(".", "p"),
            "kind": "open_loop", "role": "train", "duration": duration,
            "regulated": {"p1": p1_bar * 1e5, "p2": p2_bar * 1e5},
            "load": {"signal": "release", "rate": ramp_rate}}


def validation_square(amplitude: float = 0.6, frequency: float = 0.1122, duration: float = 9.0,
                      name: str = "square_0p6V") -> Experiment:
    """Sec. 6's validation input, held out: a square wave of ``amplitude`` [V] at
    ``frequency`` [Hz] on the free piston."""
    return {"name": name, "kind": "open_loop", "locked": False, "role": "holdout",
            "duration": duration,
            "voltage": {"signal": "square", "amplitude": amplitude, "frequency": frequency}}


def paper_campaign(voltages: Sequence[float] = PAPER_VOLTAGES,
                   entry: Sequence[tuple[float, float]] = PAPER_ENTRY,
                   exit_: Sequence[tuple[float, float]] = PAPER_EXIT,
                   validation: bool = True, **lengths: Any) -> Campaign:
    """The paper's identification campaign as a plan.

    Charge/discharge at each of ``voltages``, the valve sweep, the slow ramps, a friction test
    at each (p1, p2) of ``entry`` and ``exit_`` [bar], and (``validation``) the 0.6 V /
    0.1122 Hz square wave of Sec. 6 held out. ``lengths`` may shorten the tests: ``charge``,
    ``discharge``, ``sweep``, ``ramp_frequency`` (see the functions above).
    """
    plan = [charge_discharge(v, lengths.get("charge", 4.4), lengths.get("discharge", 1.8))
            for v in voltages]
    plan.append(valve_sweep(duration=lengths.get("sweep", 6.0)))
    plan.append(slow_ramps(frequency=lengths.get("ramp_frequency", 0.1)))
    plan += [friction_test(p1, p2) for p1, p2 in (*entry, *exit_)]
    if validation:
        plan.append(validation_square())
    return parse_campaign({"experiments": plan}, "synthetic.paper_campaign")


def paper_dataset(root: str | Path, params: ModelParams,
                  voltages: Sequence[float] = PAPER_VOLTAGES,
                  entry: Sequence[tuple[float, float]] = PAPER_ENTRY,
                  exit_: Sequence[tuple[float, float]] = PAPER_EXIT,
                  validation: bool = True, overwrite: bool = False,
                  **lengths: Any) -> Path:
    """Write the dataset of :func:`paper_campaign` run offline with ``params`` (the stand-in
    for the bench: effects, ``sensors.noise``, ``sensors.seed``) to ``root``."""
    plan = paper_campaign(voltages, entry, exit_, validation, **lengths)
    return run_campaign_offline(params, plan, root, overwrite=overwrite)


def record(params: ModelParams, experiments: Sequence[Experiment], root: str | Path,
           sample_time: float = 0.001) -> Dataset:
    """Run ``experiments`` (plan entries, e.g. from the functions above) offline with
    ``params``, logged every ``sample_time`` [s], and read back the dataset written to
    ``root``."""
    plan = parse_campaign({"sample_time": sample_time, "experiments": list(experiments)},
                          "synthetic.record")
    return read_dataset(run_campaign_offline(params, plan, root), required=COMPLETE)
