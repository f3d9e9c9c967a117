"""Zero-phase robust derivatives of sampled signals, for off-line identification.

The paper differentiates its noisy pressure and position records off-line with an adaptive
super-twisting (sliding-mode) differentiator run so that no phase lag remains (Sec. 2.3,
Remark 3). Off-line, the same job is done here by a Savitzky-Golay filter
(:func:`scipy.signal.savgol_filter`): in a window centred on each sample it fits a polynomial by
least squares and returns that polynomial's derivative. The filter is a symmetric FIR, so it has
exactly zero phase; for white sensor noise it is the minimum-variance unbiased estimate of the
derivative of any signal that is a polynomial of that order over the window; and its one tuning
knob, the window length, trades noise against the bias on curvature, as the super-twisting
differentiator's Lipschitz gain does. Unlike the sliding-mode differentiator it needs no
convergence time at the start of a record and it is linear, so its frequency response is known
(:func:`derivative_gain`).
"""

from __future__ import annotations

import numpy as np
from scipy import signal

#: Polynomial order of the local fits: cubic, exact for constant jerk over the window.
POLYORDER = 3


def window_samples(window: float, dt: float) -> int:
    """Odd number of samples covering about ``window`` [s] at sample time ``dt`` [s], >= 5."""
    n = max(POLYORDER + 2, int(round(window / dt)))
    return n + 1 - n % 2


def derivative(x: np.ndarray, dt: float, window: float, order: int = 1) -> np.ndarray:
    """Zero-phase derivative of order ``order`` of ``x`` sampled every ``dt`` [s].

    ``window`` [s] is the length of the centred least-squares window (rounded to an odd number
    of samples). The result has the units of ``x`` per second^order and the length of ``x``;
    near the ends the polynomial fitted to the first (last) window is used.
    """
    n = window_samples(window, dt)
    if x.size < n:
        raise ValueError(f"need at least {n} samples for a {window * 1e3:.0f} ms window, "
                         f"got {x.size}")
    return signal.savgol_filter(np.asarray(x, dtype=float), n, POLYORDER, deriv=order,
                                delta=dt, mode="interp")


def clear_of_gaps(measured: np.ndarray, dt: float, window: float) -> np.ndarray:
    """True at the rows whose :func:`derivative` window (``window`` [s] at ``dt`` [s],
    centred) holds no row filled over a logger's gap: ``measured`` marks the measured rows. A
    derivative whose window reaches over a gap differentiates the line drawn across it (a kink
    at each end: a 30 ms gap in a locked charge gives a flow that steps), not the
    measurement."""
    n = window_samples(window, dt)
    return np.convolve((~measured).astype(float), np.ones(n), "same") == 0.0


def derivative_gain(frequency: np.ndarray, dt: float, window: float) -> np.ndarray:
    """Response of :func:`derivative` (order 1) relative to an ideal differentiator at
    ``frequency`` [Hz], for a signal sampled every ``dt`` [s]: 1 in the pass band, falling where
    the window smooths, negative where its response turns over (real: the filter has zero
    phase). The derivative of a record holding a component at f is this times the true one,
    which a fit can apply to its model instead of reading the loss as physics."""
    f = np.asarray(frequency, dtype=float)
    n = window_samples(window, dt)
    taps = signal.savgol_coeffs(n, POLYORDER, deriv=1, delta=dt, use="conv")
    omega = 2.0 * np.pi * f
    _, h = signal.freqz(taps, worN=omega * dt)
    # Centre the antisymmetric FIR (zero phase): what remains is j omega times a real gain.
    centred = h * np.exp(1j * omega * dt * (n - 1) / 2)
    return np.where(omega > 0.0, (centred / (1j * np.where(omega > 0.0, omega, 1.0))).real,
                    1.0)  # exact on polynomials: unit gain at DC
