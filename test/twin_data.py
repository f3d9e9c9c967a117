"""Closed-loop "hardware" records for the twin's tests: the model with sensor noise (optionally
an effect, or one switched on mid-run) tracking random position steps through the PID."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jetpipe_ros.control import Pid, PidConfig
from jetpipe_ros.model import Actuator, ModelParams
from jetpipe_ros.model import kernel as k

DT = 0.001


def hardware(params: ModelParams, seconds: float, seed: int = 1,
             switch: tuple[float, Mapping[str, Any]] | None = None) -> np.ndarray:
    """Rows (t [s], u [V] and load [N] applied over the sample ending at t, y [m], p1, p2 [Pa])
    of a closed-loop run on random setpoints in +-18 mm held 0.2-0.6 s; ``switch``: at that time
    [s] the parameter changes are applied while it runs."""
    act = Actuator(params.with_values({"sensors.noise": True, "sensors.seed": seed}))
    pid = Pid(PidConfig(), DT)
    rng = np.random.default_rng(seed)
    hold_ends = np.cumsum(rng.uniform(0.2, 0.6, int(seconds / 0.2) + 2))
    levels = rng.uniform(-0.018, 0.018, hold_ends.size + 1)
    n = int(round(seconds / DT))
    rows = np.empty((n, 6))
    out = act.outputs().copy()
    u_prev = 0.0
    for i in range(n):
        t = i * DT
        if switch is not None and i == int(round(switch[0] / DT)):
            act.reconfigure(switch[1])
        rows[i] = (t, u_prev, 0.0, out[k.OUT_Y_MEAS], out[k.OUT_P1_MEAS], out[k.OUT_P2_MEAS])
        u_prev = pid.update(levels[np.searchsorted(hold_ends, t)], out[k.OUT_Y_MEAS])
        out = act.step(u_prev, 0.0).copy()
    return rows
