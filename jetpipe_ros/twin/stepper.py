"""The model stepped along measured samples, restarted from the measurements every horizon.

This is the live counterpart of the diagnosis' short-horizon predictions
(:func:`jetpipe_ros.diagnosis.prediction.predict`), with the same model object
(:class:`~jetpipe_ros.model.Actuator`) and the same restart: during the first ``warmup`` seconds
of every ``horizon`` the valve sees the measured command while the piston and the chambers are
held on the measurements (the kernel's ``drive``), then the model runs free until the next
horizon. Offline, the diagnosis smooths the measurements that set the state with a zero-phase
filter; live, the future is unknown, so a restart takes the end point and the slope of a
least-squares line through the last :data:`FIT` seconds of the warm-up's measurements (position,
velocity and pressures at the latest sample, with a fraction of the noise of one sample and no
look-ahead). A pressure read through the model's own sensor model (the ``sensor_dynamics``
effect) is first passed back through its inverse, as offline.

Samples are given as a row each: the stamp t [s], the valve command u [V] and the external load
[N] *applied over the sample that ends at t* (what ``actuator_sim`` publishes on
``voltage_applied``), and the measurements y [m], p1, p2 [Pa] taken at t (NaN: not measured,
that part of the state is simulated).
"""

from __future__ import annotations

import numpy as np

from jetpipe_ros.diagnosis.prediction import HORIZON, WARMUP, sensor_inverse
from jetpipe_ros.model import Actuator, ModelParams
from jetpipe_ros.model import kernel

#: Length of the line fitted through the warm-up's measurements to restart the state [s]: the
#: diagnosis' velocity window (:func:`jetpipe_ros.diagnosis.data.velocity`).
FIT = 0.021
#: Kernel output columns of the predicted measurements y, p1, p2.
OUT_COLUMNS = [kernel.OUT_Y_MEAS, kernel.OUT_P1_MEAS, kernel.OUT_P2_MEAS]


def line_end(t: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """Value at the last stamp and slope [unit/s] of the least-squares line through the finite
    samples of ``x`` at times ``t`` [s]; with fewer than three, the last finite value and slope
    0; NaN and 0 without any."""
    ok = np.isfinite(x)
    if not ok.any():
        return np.nan, 0.0
    if ok.sum() < 3:
        return float(x[ok][-1]), 0.0
    tt, xx = t[ok] - t[-1], x[ok]
    tm, xm = tt.mean(), xx.mean()
    den = float(((tt - tm) ** 2).sum())
    slope = float(((tt - tm) * (xx - xm)).sum()) / den if den > 0.0 else 0.0
    return xm - slope * tm, slope


class Stepper:
    """One model instance following measured samples, with the diagnosis' restarts.

    Args:
        params: model parameters (sensor noise is switched off: the model predicts, it does not
            measure).
        dt: sample time [s].
        horizon: time between restarts [s].
        warmup: held part of each horizon [s].
    """

    def __init__(self, params: ModelParams, dt: float, horizon: float = HORIZON,
                 warmup: float = WARMUP) -> None:
        self.params = params.at_sample_time(dt).with_values({"sensors.noise": False})
        self.act = Actuator(self.params)
        self.dt = dt
        self.period = max(int(round(horizon / dt)), 2)
        self.lead = min(max(int(round(warmup / dt)), 1), self.period - 1)
        self.n_fit = max(int(round(FIT / dt)), 3)
        self._warm = np.full((self.lead, 4), np.nan)  # t, y, p1, p2 of this horizon's warm-up
        self.index = -1  # sample index of the latest sample in the segment, -1: none yet
        self._inverse = bool(self.params["effects.sensor_dynamics.enabled"])

    def restart(self) -> None:
        """Begin a new segment: the next sample starts a horizon and nothing steps into it."""
        self.index = -1

    def align(self) -> None:
        """Continue the segment with the next sample starting a horizon (for a copy that replays
        one horizon of another stepper from its state)."""
        self.index = self.period - 1

    def snapshot(self) -> tuple[np.ndarray, np.ndarray]:
        """The model's state and delay line, copied."""
        return self.act.state.copy(), self.act.ring.copy()

    def load(self, snap: tuple[np.ndarray, np.ndarray]) -> None:
        """Set the model's state and delay line from :meth:`snapshot`."""
        self.act.state, self.act.ring = snap[0].copy(), snap[1].copy()

    def next_starts_horizon(self) -> bool:
        """True when the next sample is the first of a horizon (or of a segment)."""
        return self.index < 0 or (self.index + 1) % self.period == 0

    def _restart_drive(self, i: int) -> np.ndarray:
        """Drive row [y, v, p1, p2] for the step out of warm-up sample ``i``: the fitted line's
        end through the warm-up's samples up to ``i``."""
        w = self._warm[max(0, i - self.n_fit + 1):i + 1]
        t = w[:, 0]
        y, v = line_end(t, w[:, 1])
        row = np.array([y, v if np.isfinite(y) else np.nan, np.nan, np.nan])
        for chamber in (1, 2):
            p = w[:, 1 + chamber]
            if self._inverse and np.isfinite(p).all() and p.size > 2:
                p = sensor_inverse(self.params, p, t, chamber)
            row[1 + chamber] = line_end(t, p)[0]
        return row

    def step_one(self, t: float, u: float, f_load: float,
                 meas: np.ndarray) -> tuple[np.ndarray, bool]:
        """:meth:`feed` for one sample (``meas``: y, p1, p2 (3,)); the prediction (3,) and
        whether it is free. Outside the warm-up the model steps alone (the kernel gives the same
        bits one sample at a time as in a block)."""
        i = self.index
        if i >= 0 and (i % self.period) >= self.lead and (i + 1) % self.period >= self.lead:
            out = self.act.step(u, f_load)
            self.index = i + 1
            return out[OUT_COLUMNS], True
        pred, free = self.feed(np.array([t]), np.array([u]), np.array([f_load]),
                               meas[None, :])
        return pred[0], bool(free[0])

    def feed(self, t: np.ndarray, u: np.ndarray, f_load: np.ndarray,
             meas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Step through samples that all belong to one horizon (the first may start it).

        Args:
            t: stamps [s], (n,).
            u: command [V] applied over the sample ending at each stamp, (n,).
            f_load: external load [N] applied over the same samples, (n,).
            meas: measured y [m], p1, p2 [Pa] at each stamp, (n, 3); NaN where not measured.

        Returns:
            The predicted measurements (n, 3) (NaN for a segment's first sample, which nothing
            steps into) and the bool mask (n,) of samples predicted free (not held on the
            measurements), the ones a score compares.
        """
        n = t.size
        pred = np.full((n, 3), np.nan)
        free = np.zeros(n, dtype=bool)
        first = 0
        if self.index < 0:
            self.index = 0
            self._warm[:] = np.nan
            self._warm[0] = (t[0], *meas[0])
            first = 1
        if first == n:
            return pred, free
        idx = self.index + 1 + np.arange(n - first)
        phase = idx % self.period
        if phase[0] == 0:
            self._warm[:] = np.nan
        if phase[-1] < phase[0]:
            raise ValueError("feed() takes the samples of one horizon at a time")
        for j in np.flatnonzero(phase < self.lead):
            self._warm[phase[j]] = (t[first + j], *meas[first + j])
        drive = np.full((n - first, kernel.N_DRIVE), np.nan)
        for j in np.flatnonzero((phase - 1) % self.period < self.lead):
            drive[j] = self._restart_drive(int((phase[j] - 1) % self.period))
        out = self.act.run(u[first:], f_load[first:], drive)
        pred[first:] = out[:, OUT_COLUMNS]
        free[first:] = phase >= self.lead
        self.index = int(idx[-1])
        return pred, free
