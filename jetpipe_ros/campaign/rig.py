"""The test rig's switches on a running model: change parameters, keep the state.

A real rig clamps the piston (constant-volume tests) or puts regulators on the chambers between
experiments without resetting anything else; :func:`reconfigure` does the same to an
:class:`~jetpipe_ros.model.Actuator`: new parameters, the integration state carried over.

The regulated rig (the friction tests of the paper's Fig. 15) also acts on the state: switching
the regulators on (``chamber.regulated``), or changing their pressures
(``chamber.initial_pressure_1``, ``_2``: the pressures the model holds) or the piston's place
(``mechanics.initial_position``) while they are on, sets the chamber pressures to the
regulators' and places the piston there at rest, as the rig's hydraulic cylinder does.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jetpipe_ros.model import Actuator, build_constants
from jetpipe_ros.model import kernel as k

#: Parameters whose change, with the regulators on, re-imposes pressures and piston place.
REGULATOR_KEYS = ("chamber.regulated", "chamber.initial_pressure_1",
                  "chamber.initial_pressure_2", "mechanics.initial_position")


def reconfigure(actuator: Actuator, changes: Mapping[str, Any]) -> None:
    """Apply parameter ``changes`` to ``actuator`` in place, keeping its state.

    Position, velocity, pressures, temperatures, friction state, sample count and the sensor
    noise sequence carry over. If the change alters the valve chain's order or delay (e.g.
    enabling ``valve_lag`` or changing ``valve.delay``), the valve chain restarts at rest.
    With the regulators on after the change and one of :data:`REGULATOR_KEYS` changed, the
    pressures [Pa] and the piston's position [m] are set as the module docstring says.
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
    if params["chamber.regulated"] and any(key in changes for key in REGULATOR_KEYS):
        state = state.copy()
        state[k.P1] = params["chamber.initial_pressure_1"]
        state[k.P2] = params["chamber.initial_pressure_2"]
        state[k.Y] = min(max(params["mechanics.initial_position"], -constants.y_max),
                         constants.y_max)
        state[k.V] = 0.0
        state[k.STUCK] = 1.0
    actuator.params, actuator.constants = params, constants
    actuator.state, actuator.ring = state, ring
