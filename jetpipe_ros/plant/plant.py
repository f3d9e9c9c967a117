"""The plant as an actuator: the interface of :class:`jetpipe_ros.model.Actuator`, its own loop.

:class:`Plant` can stand wherever the campaign runner or a test uses a model ``Actuator``:
``params``, ``constants.dt``, ``constants.u_limit``, ``outputs()``, ``step(u, f_load)``,
``run(u, f_load)`` (rows in the model's output layout, ``jetpipe_ros.model.kernel.OUT_*``),
``reset()``, ``time`` and ``reconfigure(changes)`` for the rig's switches.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jetpipe_ros.model import ModelParams, Trace
from jetpipe_ros.model.actuator import REGULATOR_KEYS, replay_command
from jetpipe_ros.model.kernel import N_OUT
from jetpipe_ros.plant import constants as s
from jetpipe_ros.plant.air import GAMMA_AIR
from jetpipe_ros.plant.chambers import volumes
from jetpipe_ros.plant.constants import PlantConstants, build_constants
from jetpipe_ros.plant.loop import advance
from jetpipe_ros.plant.passages import N_SEGMENTS
from jetpipe_ros.plant.sensors import measure
from jetpipe_ros.plant.spec import PlantSpec


class Plant:
    """One simulated stand-in for real hardware: a :class:`PlantSpec`, its state and noise.

    Args:
        spec: the plant; default the nominal model's parameters and no real effect.
    """

    def __init__(self, spec: PlantSpec | None = None) -> None:
        self.spec = spec if spec is not None else PlantSpec()
        self.constants: PlantConstants = build_constants(self.spec)
        self._rng = np.random.default_rng(self.params["sensors.seed"])
        self._one_u = np.zeros(1)
        self._one_f = np.zeros(1)
        self._one_out = np.zeros((1, N_OUT))
        self._zero_noise = np.zeros((1, 3))
        self.reset()

    @property
    def params(self) -> ModelParams:
        """The model parameters of the plant (rig switches included)."""
        return self.spec.params

    def reset(self) -> None:
        """Return to the initial state: at rest, valve at rest, pressures as configured."""
        c = self.constants
        p = self.params
        x = np.zeros(s.SIZE)
        x[s.Y] = min(max(p["mechanics.initial_position"], -c.y_max), c.y_max)
        x[s.STUCK] = 1.0
        # The seal relaxed: one reversal point, here, without friction.
        x[s.SEAL_N], x[s.SEAL_D], x[s.SEAL] = 1.0, 1.0, x[s.Y]
        x[s.SUPPLY] = x[s.REGULATOR] = c.supply_set
        self.state = x
        self._set_pressures(p["chamber.initial_pressure_1"], p["chamber.initial_pressure_2"],
                            c.t_wall, c.t_wall)
        x[s.SENSOR1] = x[s.P1]
        x[s.SENSOR2] = x[s.P2]
        x[s.POSITION] = x[s.Y]
        x[s.LOAD] = x[s.Y]
        self.ring = np.zeros(c.delay_whole + 2)

    def _set_pressures(self, p1: float, p2: float, t1: float, t2: float) -> None:
        """Fill the chambers to ``p1``, ``p2`` [Pa] at temperatures ``t1``, ``t2`` [K], their
        ports and lines to the same pressures, at rest."""
        c = self.constants
        x = self.state
        vols = volumes(x[s.Y], c.area, c.v01, c.v02)
        for m, e, p, pi, t, vol in ((s.M1, s.E1, p1, s.P1, t1, vols[0]),
                                    (s.M2, s.E2, p2, s.P2, t2, vols[1])):
            x[pi] = p
            x[m] = p * vol / (c.r_gas * t)
            x[e] = p * vol / (GAMMA_AIR - 1.0)
        for i, p in enumerate((p1, p2)):
            x[s.PORT + i] = p
            line = s.LINE + i * s.LINE_SIZE
            x[line:line + N_SEGMENTS] = p
            x[line + N_SEGMENTS:line + s.LINE_SIZE] = 0.0

    @property
    def temperatures(self) -> tuple[float, float]:
        """Gas temperatures of chambers 1 and 2 [K]."""
        c = self.constants
        x = self.state
        if not c.thermal:
            return c.t_wall, c.t_wall
        return x[s.E1] / (x[s.M1] * c.cv), x[s.E2] / (x[s.M2] * c.cv)

    @property
    def masses(self) -> tuple[float, float]:
        """Gas masses in chambers 1 and 2 [kg]."""
        return self.state[s.M1], self.state[s.M2]

    @property
    def supply_pressure(self) -> float:
        """Supply pressure at the valve [Pa, absolute]."""
        return float(self.state[s.SUPPLY])

    @property
    def time(self) -> float:
        """Simulated time since the last reset [s]."""
        return self.state[s.STEP] * self.constants.dt

    def reconfigure(self, changes: Mapping[str, Any]) -> None:
        """Apply model-parameter ``changes`` in place, keeping the state, as a test rig's switch
        does (the contract of :meth:`jetpipe_ros.model.Actuator.reconfigure`): position, velocity,
        gas, temperatures, friction, sensors, sample count and noise sequence carry over; a
        change of the valve delay restarts the valve chain at rest. With the regulators on after
        the change and one of ``REGULATOR_KEYS`` changed, the chambers are set to the
        regulators' pressures [Pa] at their temperatures and the piston is placed at rest at
        ``mechanics.initial_position`` [m]. Raises on a bad value, leaving the plant unchanged.
        """
        spec = self.spec.with_values(changes)
        constants = build_constants(spec)
        state, ring = self.state, self.ring
        if constants.delay != self.constants.delay:
            state = state.copy()
            state[s.VALVE:] = 0.0
            state[s.HEAD] = 0.0
            ring = np.zeros(constants.delay_whole + 2)
        temperatures = self.temperatures
        self.spec, self.constants, self.state, self.ring = spec, constants, state, ring
        p = spec.params
        if p["chamber.regulated"] and any(key in changes for key in REGULATOR_KEYS):
            self.state = state = state.copy()
            state[s.Y] = min(max(p["mechanics.initial_position"], -constants.y_max),
                             constants.y_max)
            state[s.V] = 0.0
            state[s.STUCK] = 1.0
            state[s.SEAL_N], state[s.SEAL], state[s.SEAL + 1] = 1.0, state[s.Y], 0.0
            state[s.LOAD], state[s.LOAD + 1] = state[s.Y], 0.0
            self._set_pressures(p["chamber.initial_pressure_1"], p["chamber.initial_pressure_2"],
                                *temperatures)

    def _noise(self, n: int) -> np.ndarray:
        if self.constants.sigma_p == 0.0 and self.constants.sigma_y == 0.0:
            return self._zero_noise if n == 1 else np.zeros((n, 3))
        return self._rng.standard_normal((n, 3))

    def outputs(self) -> np.ndarray:
        """Outputs (N_OUT,) of the current state, with fresh sensor noise."""
        out = np.zeros(N_OUT)
        measure(self.constants, self.state, self._noise(1)[0], out)
        return out

    def step(self, u: float, f_load: float = 0.0) -> np.ndarray:
        """Advance one sample with command ``u`` [V] and load ``f_load`` [N]; return outputs.

        The returned array (N_OUT,) is reused by the next call; copy it to keep it.
        """
        self._one_u[0] = u
        self._one_f[0] = f_load
        advance(self.constants, self.state, self.ring, self._one_u, self._one_f,
                self._noise(1), self._one_out)
        return self._one_out[0]

    def run(self, u: np.ndarray, f_load: np.ndarray | float = 0.0) -> np.ndarray:
        """Advance ``len(u)`` samples; return the (n, N_OUT) outputs at the end of each."""
        u = np.array(u, dtype=float)  # copies: writable and contiguous, one compiled signature
        if not np.all(np.isfinite(u)):
            raise ValueError("valve command contains NaN or infinite values")
        fl = np.array(np.broadcast_to(f_load, u.shape), dtype=float)
        out = np.empty((u.shape[0], N_OUT))
        advance(self.constants, self.state, self.ring, u, fl, self._noise(len(u)), out)
        return out


def simulate(spec: PlantSpec, u: np.ndarray, f_load: np.ndarray | float = 0.0) -> Trace:
    """Replay a command sequence through a fresh plant, as :func:`jetpipe_ros.model.simulate`
    does through the model: row k is the state at t_k = k dt, before ``u[k]`` acts."""
    return replay_command(Plant(spec), u, f_load)
