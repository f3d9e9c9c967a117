"""The plant's sensors: a second-order, nonlinear pressure transducer with offsets, and noise.

- **Second-order nonlinear pressure sensor** (``sensor_second_order``): each transducer (its
  diaphragm and the gas in its port) reads the chamber pressure p through

      s'' = w_n^2 (p - s) - 2 zeta w_n s',
      p_meas,i = s_i + o_i + 4 N x_i (1 - x_i),   x_i = (s_i - p_0) / P,

  with w_n = 2 pi f_n [rad/s], zeta [-], an offset o_i [Pa] of its own per sensor and a bow
  nonlinearity N [Pa] (the terminal-point nonlinearity of a data sheet: zero at both ends of
  the span p_0 = 1 bar to p_0 + P = 11 bar absolute, 0-10 bar gauge, N at mid-span). The
  dynamics are discretised exactly at the sub-step (zero-order hold on p over the sub-step), so
  a pressure held over whole samples is read exactly as ``scipy.signal.lfilter`` of the same
  transfer function discretised at the sample time. The model's candidate is a first-order lag
  with biases, a gain linear in p and a drift; no candidate bends the reading with pressure.
- **Position transducer with a filter** (``position_filter``, on no list): the reading passes
  two equal first-order stages in series (a conditioning filter, critically damped)

      tau s_a' = y - s_a,   tau s_b' = s_a - s_b,   y_meas = s_b

  with tau [s] (its lag at low frequency is 2 tau): 1 / (tau s + 1)^2, the critically damped
  second-order lag of natural frequency 1 / tau, discretised exactly as the pressure
  transducers are, the position held over the sub-step at its mean. The model has no position sensor
  dynamics at all.
- **Noise**: as the model's, Gaussian, position sigma 15 um and pressure sigma 500 Pa by
  default (``sensors.*`` of the model parameters), from ``numpy.random.default_rng(seed)``
  drawn as the model draws it, added after the sensor dynamics.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from jetpipe_ros.model.kernel import (OUT_FORCE, OUT_FRICTION, OUT_P1, OUT_P1_MEAS, OUT_P2,
                                     OUT_P2_MEAS, OUT_T, OUT_U, OUT_UEQ, OUT_V, OUT_Y,
                                     OUT_Y_MEAS)
from jetpipe_ros.plant.constants import (FRICTION, P1, P2, POSITION, SENSOR1, SENSOR2, STEP,
                                         UCMD, UEQ, V, Y, PlantConstants)


@njit(cache=True, error_model="numpy")
def _reading(c: PlantConstants, s: float) -> float:
    """The transducer's reading [Pa] of its diaphragm's pressure ``s`` [Pa], before its offset:
    s + 4 N x (1 - x), x = (s - p_0) / P (module docstring)."""
    x = (s - c.sensor_low) / c.sensor_span
    return s + 4.0 * c.sensor_bow * x * (1.0 - x)


@njit(cache=True, error_model="numpy")
def measure(c: PlantConstants, x: np.ndarray, noise: np.ndarray, out: np.ndarray) -> None:
    """Write the outputs of state ``x`` into ``out`` (the model's layout,
    ``jetpipe_ros.model.kernel.OUT_*``); ``noise`` holds 3 standard normals (y, p1, p2)."""
    out[OUT_T] = x[STEP] * c.dt
    out[OUT_U] = x[UCMD]
    out[OUT_Y] = x[Y]
    out[OUT_V] = x[V]
    out[OUT_P1] = x[P1]
    out[OUT_P2] = x[P2]
    out[OUT_FRICTION] = x[FRICTION]
    out[OUT_FORCE] = c.area * (x[P1] - x[P2])
    out[OUT_UEQ] = x[UEQ]
    out[OUT_Y_MEAS] = (x[POSITION] if c.position_filter else x[Y]) + c.sigma_y * noise[0]
    if c.sensor:
        out[OUT_P1_MEAS] = _reading(c, x[SENSOR1]) + c.sensor_offset_1 + c.sigma_p * noise[1]
        out[OUT_P2_MEAS] = _reading(c, x[SENSOR2]) + c.sensor_offset_2 + c.sigma_p * noise[2]
    else:
        out[OUT_P1_MEAS] = x[P1] + c.sigma_p * noise[1]
        out[OUT_P2_MEAS] = x[P2] + c.sigma_p * noise[2]
