"""Run a campaign offline through the model (no ROS) and write it as a dataset.

The runner follows :meth:`Campaign.schedule` exactly as the ``id_recorder`` node does through
the topics: one actuator for the whole campaign, its state carried from phase to phase, the
piston clamped and released and the chambers' regulators switched between phases
(:meth:`~jetpipe_ros.campaign.Phase.rig_changes`,
:meth:`~jetpipe_ros.model.Actuator.reconfigure`),
closed-loop phases through the same :class:`~jetpipe_ros.control.Pid` as the ``controller``
node (one controller for the campaign, its state carried from one closed-loop phase to the
next, as the node's). Row k of an experiment's CSV holds what the sensors read at t_k = k dt and
the command applied over [t_k, t_k+1), the convention of :func:`jetpipe_ros.model.simulate`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from jetpipe_ros.campaign.plan import Campaign, Phase, default_campaign
from jetpipe_ros.control import Pid, PidConfig
from jetpipe_ros.dataset import Entry, write_dataset
from jetpipe_ros.model import Actuator, ModelParams
from jetpipe_ros.model import kernel as k

#: Kernel outputs kept per sample while running a phase.
_COLUMNS = {"y": k.OUT_Y_MEAS, "p1": k.OUT_P1_MEAS, "p2": k.OUT_P2_MEAS, "v": k.OUT_V}


def _run_phase(act: Actuator, pid: Pid, phase: Phase, out: np.ndarray) -> dict[str, np.ndarray]:
    """Run one phase from the latest outputs ``out`` (updated in place); the recorded columns:
    the sensor readings at the start of each sample and the command applied over it."""
    cmd = phase.command
    n = phase.samples
    if cmd.closed_loop:
        assert cmd.setpoint is not None and cmd.excitation is not None
        rows = np.empty((n, k.N_OUT))
        u = np.empty(n)
        for i in range(n):
            rows[i] = out
            u[i] = pid.update(float(cmd.setpoint[i]), out[k.OUT_Y_MEAS],
                              float(cmd.excitation[i]))
            out[:] = act.step(u[i], phase.load_force)
    else:
        assert cmd.voltage is not None
        u = np.asarray(cmd.voltage, dtype=float)
        load = cmd.load if cmd.load is not None else phase.load_force
        after = act.run(u, load)
        rows = np.vstack([out[None, :], after[:-1]])
        out[:] = after[-1]
    limit = act.constants.u_limit
    cols = {"t": np.arange(n) * act.constants.dt, "u": np.clip(u, -limit, limit)}
    cols.update({name: rows[:, i] for name, i in _COLUMNS.items()})
    cols["f_load"] = (np.array(cmd.load, dtype=float) if cmd.load is not None
                      else np.full(n, phase.load_force))
    if cmd.closed_loop:
        cols["setpoint"] = np.clip(cmd.setpoint, pid.config.setpoint_min,
                                   pid.config.setpoint_max)
    return cols


def run_campaign_offline(params: ModelParams, campaign: Campaign, out_dir: str | Path,
                         seed: int | None = None, controller: PidConfig | None = None,
                         overwrite: bool = False,
                         actuator: Callable[[ModelParams], Any] = Actuator) -> Path:
    """Simulate every experiment of ``campaign`` and write a docs/data.md dataset.

    Args:
        params: the model that stands in for the hardware (effects, noise as configured;
            ``sensors.noise`` decides whether the CSVs are noisy). ``mechanics.locked`` is set
            per phase by the plan, and ``integration.sample_time`` by the campaign (with
            sub-steps no longer than the parameters' own: ``ModelParams.at_sample_time``).
        campaign: the plan, e.g. :func:`~jetpipe_ros.campaign.default_campaign`.
        out_dir: dataset directory to create (written atomically).
        seed: if given, replaces ``sensors.seed``; the same seed gives the same dataset.
        controller: gains of the closed-loop phases; default :class:`PidConfig` (the values of
            ``config/controller.yaml``).
        overwrite: replace an existing non-empty ``out_dir``.
        actuator: builds what stands for the hardware from ``params`` (as changed here): the
            model's :class:`Actuator` by default, or another with its interface and its own
            ``reconfigure(changes)`` for the rig (e.g. :class:`jetpipe_ros.plant.Plant`).

    Returns:
        The dataset directory. Each CSV has ``t,u,y,p1,p2`` (sensor readings), ``v`` (true
        velocity), ``f_load`` [N] and, for closed-loop experiments, ``setpoint`` [m];
        ``dataset.yaml`` gives piston, load_force, role, kind (open_loop | closed_loop) and
        ``regulated: true`` for the regulated friction tests (what ``jetpipe identify`` reads).
    """
    # At the campaign's sample time with sub-steps no longer than the parameters' own: a
    # campaign logged at 200 Hz is the same physics sampled less often (with 4 sub-steps of
    # 1.25 ms the model's own 200 Hz record missed its 1 kHz one by 82 um and 1.3 kPa).
    changes: dict[str, object] = {"mechanics.locked": False}
    if seed is not None:
        changes["sensors.seed"] = int(seed)
    act = actuator(params.at_sample_time(campaign.sample_time).with_values(changes))
    pid = Pid(controller or PidConfig(), campaign.sample_time)
    out = act.outputs()
    experiments = []
    for phase in campaign.schedule():
        changes = phase.rig_changes(act.params)
        if changes:  # row 0 of the phase is the reading before the switch, as in the node
            act.reconfigure(changes)
        cols = _run_phase(act, pid, phase, out)
        exp = phase.experiment
        if exp is not None:
            extra: dict[str, object] = {"kind": exp.kind}
            if exp.regulated is not None:
                extra["regulated"] = True
            entry = Entry(f"{exp.name}.csv", piston="locked" if exp.locked else "free",
                          load_force=exp.load_force, role=exp.role, extra=extra)
            experiments.append((entry, cols))
    return write_dataset(out_dir, experiments, overwrite=overwrite)


def campaign_dataset(params: ModelParams, root: str | Path, seed: int,
                     sample_time: float | None = None,
                     actuator: Callable[[ModelParams], Any] = Actuator) -> Path:
    """The default campaign (``config/campaign.yaml``) recorded offline on ``params`` (or on
    what ``actuator`` builds from them, e.g. the plant) into the dataset directory ``root``:
    sensor noise as ``params`` say, seeded with ``seed % 100000``, at the plan's sample time or
    ``sample_time`` [s]."""
    plan = default_campaign()
    if sample_time is not None:
        plan = dataclasses.replace(plan, sample_time=sample_time)
    return run_campaign_offline(params, plan, root, seed=seed % 100000, actuator=actuator)
