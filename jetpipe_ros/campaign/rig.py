"""The test rig's switches on a running model: change parameters, keep the state.

A real rig clamps the piston (constant-volume tests) or puts regulators on the chambers between
experiments without resetting anything else; :func:`reconfigure` does the same to an
:class:`~jetpipe_ros.model.Actuator`: new parameters, the integration state carried over.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jetpipe_ros.model import Actuator, build_constants
from jetpipe_ros.model import kernel as k


def reconfigure(actuator: Actuator, changes: Mapping[str, Any]) -> None:
    """Apply parameter ``changes`` to ``actuator`` in place, keeping its state.

    Position, velocity, pressures, temperatures, friction state, sample count and the sensor
    noise sequence carry over. If the change alters the valve chain's order or delay (e.g.
    enabling ``valve_lag`` or changing ``valve.delay``), the valve chain restarts at rest.
    Raises :class:`~jetpipe_ros.model.ParameterError` on a bad value, leaving ``actuator``
    unchanged.
    """
    params = actuator.params.with_values(changes)
    constants = build_constants(params)
    state, ring = actuator.state, actuator.ring
    size = k.VALVE + constants.valve_b.shape[0]
    if state.shape[0] != size or ring.shape[0] != constants.delay_steps + 1:
        kept = state[:k.VALVE].copy()
        state = np.zeros(size)
        state[:k.VALVE] = kept
        state[k.PLAY:k.VALVE] = 0.0
        state[k.HEAD] = 0.0
        ring = np.zeros(constants.delay_steps + 1)
    actuator.params, actuator.constants = params, constants
    actuator.state, actuator.ring = state, ring
