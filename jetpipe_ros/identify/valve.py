"""Servo-valve dynamics (Sec. 2.1, 2.4) from a constant-volume sine sweep.

The paper relates the command to the mass flow obtained as in Sec. 2.3 and tunes the third-order
torque-motor model (Eq. 4): K_b to place the resonance, K_f to match the peak; then it adds the
delay (about 2 ms) and the lead-lag of Eq. 9 that its measurements showed. Here, with the piston
locked, each chamber's flow q = V/(r T) dp/dt (zero-phase derivative, :mod:`.differentiate`) is
turned back into the equivalent voltage u_eq that produced it by inverting the flow map at the
measured pressure (:func:`.flow_map.invert`; chamber 2 sees -u_eq), so the chamber's dynamics and
the map's nonlinearity drop out and what remains is the valve chain alone, unit gain at DC:

    H(jw) = G_lag(jw) G_jp(jw) / G_jp(0) exp(-j w tau)            (Eq. 4, 9, 10)

Its parameters are fitted by output error: the chain's response to the recorded command (computed
through the FFT, exact for a fractional delay, with the command's zero-order hold) is matched to
u_eq(t) by nonlinear least squares (scipy.optimize.least_squares), as the flows the two chambers
show: the model's flow, computed on a grid of at most 1 ms, is integrated to the sample instants and
differentiated with the record's window (:func:`seen_flow`), so neither the window's loss nor the
samples' aliasing is read as valve dynamics (at 200 Hz they had cut the delay from 2.1 to 1.2 ms). A
time-domain fit is used rather than a fit to a spectral estimate because a sweep record usually ends
before the valve's response to its last cycles has died out, which corrupts the spectral ratio near
the top of the sweep (several % in gain) but not the time-domain residual.

K_b and K_f enter Eq. 4 almost only through R K_f + K_b K_t (the s coefficient; K_f/J is 0.07 %
of the s^2 coefficient R/L): the response fixes that damping sum, not the split. The procedure
therefore tunes K_b, which carries 95 % of the sum, and holds K_f at its starting value (Table 1);
with R, L, J, K_s fixed (measured, as in the paper) this sets the resonance frequency and peak.
The delay and the lead-lag zero and pole take the remaining phase and high-frequency gain.
The measured response (1 Hz bands of the record's FFT) is kept for the report's Bode plot.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import fft, integrate, optimize, signal

from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.identify.differentiate import clear_of_gaps, derivative, derivative_gain
from jetpipe_ros.identify.experiments import Recording
from jetpipe_ros.identify.flow_map import chamber_capacities, invert
from jetpipe_ros.model.flow import mass_flow
from jetpipe_ros.model.params import ModelParams
from jetpipe_ros.model.valve import U_EQ_MAX, U_EQ_MIN, valve_tf

#: Fitted parameters, in the order of the optimiser's vector.
FITTED = ("valve.back_emf_constant", "valve.delay", "valve.lag_zero", "valve.lag_pole")
#: Derivative window [s]: 7 ms passes 70 Hz with < 1 % gain loss (see derivative_loss).
WINDOW = 0.007
#: Samples at the start of a sweep left out of the fit while the differentiator settles [s].
LEAD_IN = 0.05
#: Samples after a logger's gap left out of the fit [s]: the commands lost in the gap (held
#: over it) still move the valve until its chain has settled, 25.5 ms to 5 % from a command,
#: its 2 ms delay included (the nominal chain's step response).
AFTER_GAP = 0.03
#: The valve chain is computed on a grid of at most this step [s] (finer than a slow record's,
#: whose samples alias what the valve passes above half their rate).
FINE = 1e-3
#: Width of the frequency bands of the measured response [Hz].
BAND = 1.0
#: The sweep must reach this frequency [Hz] (the resonance near 50 Hz must be inside it):
#: the highest band holding at least TOP_ENERGY of the strongest band's command energy.
MIN_TOP_FREQUENCY = 60.0
TOP_ENERGY = 1e-3


@dataclass
class ValveResult:
    """Identified valve parameters and the frequency responses behind them."""

    values: dict[str, float]  #: FITTED parameter -> identified value (SI)
    frequency: np.ndarray  #: band centres of the measured response [Hz]
    measured: np.ndarray  #: measured u -> u_eq response per band (complex, V/V)
    #: the identified chain's response as the record shows it in the same bands (the flows it
    #: gives differentiated and sampled as the measured ones): what ``measured`` is fitted to
    seen: np.ndarray
    experiments: list[str]  #: sweeps used
    rms_error: float  #: RMS of the fit's residual, as chamber pressure [Pa] (noise: ~sensor)
    top_frequency: float  #: highest frequency the sweeps reached [Hz]
    sample_time: float  #: command sample time [s] (its zero-order hold is in the fit)


def response(params: Mapping[str, Any], frequency: np.ndarray, hold: float = 0.0
             ) -> np.ndarray:
    """Model valve chain u -> u_eq at ``frequency`` [Hz], delay included (complex, V/V).

    ``hold`` [s] > 0 adds the zero-order hold of a command sampled at that period, as seen
    between the command samples and the response samples: exp(-j w T/2) sinc(f T).
    """
    num, den = valve_tf(params)
    f = np.asarray(frequency, dtype=float)
    w = 2.0 * np.pi * f
    _, h = signal.freqs(num, den, worN=w)
    return h * np.exp(-1j * w * (params["valve.delay"] + hold / 2.0)) * np.sinc(f * hold)


def peak(params: Mapping[str, Any], low: float = 5.0, high: float = 150.0
         ) -> tuple[float, float]:
    """Resonance of the model valve chain: (frequency [Hz], gain [V/V]) of the gain peak."""
    f = np.linspace(low, high, 2901)
    g = np.abs(response(params, f))
    i = int(np.argmax(g))
    return float(f[i]), float(g[i])


def chain_output(params: Mapping[str, Any], u: np.ndarray, dt: float) -> np.ndarray:
    """u_eq [V] of the linear valve chain driven from rest by command samples ``u`` [V] held
    over ``dt`` [s] each, at the sample instants (FFT with enough zero padding to be linear)."""
    n = u.size
    size = fft.next_fast_len(n + round(0.5 / dt))
    f = fft.rfftfreq(size, dt)
    return fft.irfft(fft.rfft(u, size) * response(params, f, dt), size)[:n]


def equivalent_voltage(rec: Recording, params: Mapping[str, Any],
                       coefficients: Sequence[float],
                       flows: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """u_eq(t) [V] of a locked test: the flow map inverted at each chamber's flow, averaged
    over the two chambers. ``flows`` [kg/s] (chamber 1's, chamber 2's): the measured ones
    (Eq. 7 on the differentiated pressures) by default."""
    exp = rec.experiment
    if flows is None:
        c1, c2 = chamber_capacities(params, float(np.mean(exp.y)))
        flows = (c1 * derivative(exp.p1, exp.dt, WINDOW), c2 * derivative(exp.p2, exp.dt, WINDOW))
    u1 = invert(coefficients, flows[0], exp.p1 * 1e-5, exp.u)
    u2 = -invert(coefficients, flows[1], exp.p2 * 1e-5, -exp.u)
    return 0.5 * (u1 + u2)


def noise_whitening(coefficients: Sequence[float], capacity: float, u: np.ndarray,
                    p: np.ndarray, dt: float) -> np.ndarray:
    """Weights over the rfft bins of a chamber's flow residual [kg/s] that turn it into the
    chamber-pressure residual it stems from [Pa / sqrt(n)], in which sensor noise is white.

    Linearised about the mean command ``u`` [V] and pressure ``p`` [Pa], C dp/dt = a u + b p
    with C = ``capacity`` [kg/Pa]; a pressure error E(f) shows in the measured flow as
    (C D(f) - b) E, with D the differentiator's response (j w in its pass band). Weighting by
    the inverse makes least squares efficient: bins where differentiation amplifies noise count
    less.
    """
    p_bar = float(np.mean(p)) * 1e-5
    u0 = float(np.mean(u))
    b = (mass_flow(coefficients, u0, p_bar + 0.01) - mass_flow(coefficients, u0, p_bar - 0.01)
         )[0] / 2e3
    f = fft.rfftfreq(u.size, dt)
    d = 2.0 * np.pi * f * derivative_gain(f, dt, WINDOW)
    return 1.0 / np.abs(capacity * 1j * d - b) / np.sqrt(u.size)


def seen_flow(flow: np.ndarray, fine: int, dt: float) -> np.ndarray:
    """A chamber's model mass flow [kg/s] on a grid ``fine`` times finer than the record's
    sample time ``dt`` [s], as the procedure sees the measured one [kg/s]: integrated into the
    charge the chamber holds at each sample instant, then differentiated as the pressures are.

    The record's derivative is not the flow at the sample instants: its window smooths (at 1 kHz
    it passes 70 Hz within 1 %; at 200 Hz, five samples, it keeps 85 % of 50 Hz) and the
    samples alias what the valve passes above half the rate. Seen the same way, the model's flow
    is compared like for like, so neither is read as valve dynamics.
    """
    charge = integrate.cumulative_trapezoid(flow, dx=dt / fine, initial=0.0)[::fine]
    return derivative(charge, dt, WINDOW)


def after_gaps(measured: np.ndarray, rows: int) -> np.ndarray:
    """True at the rows filled over a logger's gap (``measured`` False) and at the ``rows``
    rows after each."""
    return np.convolve((~measured).astype(float), np.ones(rows + 1), "full")[:measured.size] > 0


def bridged(measured: np.ndarray) -> np.ndarray:
    """``measured`` with each single lost row between two measured ones counted as measured.

    Its line between its neighbours misses a sine of frequency f by (2 pi f dt)^2 / 8 of its
    amplitude, 2.4 % at 70 Hz (the sweep's top) and 1 kHz: under the pressure sensors' noise
    for the locked sweep's pressure swings, and the valve's response to the one command held a
    row is smaller still. The fit's residual is weighted over frequency (the pressure noise
    whitened), so every row it leaves out also spreads the residual's spectrum: leaving out
    the 1 % of single rows a non-real-time logger drops, with their windows, had moved the
    delay by 0.27 ms (its scatter over seeds: 0.08 ms)."""
    lone = ~measured & np.r_[False, measured[:-1]] & np.r_[measured[1:], False]
    return measured | lone


def band_response(u: np.ndarray, u_eq: np.ndarray, dt: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(band centre [Hz], response, command energy) per BAND-wide band of the records' FFTs:
    sum(Y U*) / sum(|U|^2) over the band, centred on its energy."""
    big_u, big_y = fft.rfft(u), fft.rfft(u_eq)
    f = fft.rfftfreq(u.size, dt)
    band = np.floor(f / BAND).astype(int)
    n = band.max() + 1
    energy = np.bincount(band, np.abs(big_u) ** 2, n)
    cross = (np.bincount(band, (big_y * big_u.conj()).real, n)
             + 1j * np.bincount(band, (big_y * big_u.conj()).imag, n))
    centre = np.bincount(band, f * np.abs(big_u) ** 2, n)
    ok = energy > 0.0
    ok[0] = False
    return centre[ok] / energy[ok], cross[ok] / energy[ok], energy[ok]


def identify_valve(recs: list[Recording], params: ModelParams,
                   coefficients: Sequence[float]) -> ValveResult:
    """Fit K_b, the delay and the Eq. 9 lead-lag to the sweeps ``recs``.

    ``params`` gives the chamber geometry and the starting values (K_f, R, L, J, K_s, K_t are
    kept); ``coefficients`` the flow map (Eq. 8) used to recover u_eq. Each sweep must start
    with the valve at rest. Raises DatasetError when the sweeps stop short of
    :data:`MIN_TOP_FREQUENCY`.
    """
    if not recs:
        raise DatasetError("valve dynamics: no constant-volume sine sweep (piston: locked, "
                           "oscillating command, e.g. 1 V, 1-70 Hz) in the dataset")
    dt = recs[0].experiment.dt
    traces = [(r.experiment.u, equivalent_voltage(r, params, coefficients)) for r in recs]
    bands = [band_response(u, ueq, dt) for u, ueq in traces]
    f_all = np.concatenate([b[0] for b in bands])
    energy = np.concatenate([b[2] for b in bands])
    top = float(f_all[energy >= TOP_ENERGY * energy.max()].max())
    if top < MIN_TOP_FREQUENCY:
        raise DatasetError(
            f"valve dynamics: the sweep(s) {', '.join(r.name for r in recs)} reach {top:.0f} Hz; "
            f"need {MIN_TOP_FREQUENCY:.0f} Hz to see the resonance near 50 Hz (sweep 1-70 Hz, "
            f"about 1 V, several seconds)")
    skip = round(LEAD_IN / dt)
    fine = int(np.ceil(dt / FINE - 1e-9))
    # Per chamber: command, sign, pressure [bar] on the fine grid, measured flow [kg/s], weights,
    # and the samples compared: after the lead-in, the derivative's window clear of a
    # logger's gaps (a flow differentiated across the line drawn over a gap is not measured),
    # and AFTER_GAP past each gap of two rows or more.
    chambers = []
    for r in recs:
        exp = r.experiment
        on_fine = np.arange(exp.u.size * fine) / fine
        measured = bridged(exp.measured)
        compared = clear_of_gaps(measured, dt, WINDOW) & ~after_gaps(measured,
                                                                   round(AFTER_GAP / dt))
        compared[:skip] = False
        for sign, p, cap in zip((1.0, -1.0), (exp.p1, exp.p2),
                                chamber_capacities(params, float(np.mean(exp.y)))):
            chambers.append((np.repeat(exp.u, fine), sign,
                             np.interp(on_fine, np.arange(p.size), p * 1e-5),
                             cap * derivative(p, dt, WINDOW),
                             noise_whitening(coefficients, cap, sign * exp.u, p, dt), compared))

    def model(theta: np.ndarray) -> ModelParams:
        kb, tau, wz, wp = theta
        return params.with_values(dict(zip(FITTED, (np.exp(kb), tau, np.exp(wz), np.exp(wp)))))

    def seen_flows(q: ModelParams) -> list[np.ndarray]:
        """Each chamber's flow [kg/s] with the valve chain of ``q``, as the record shows it."""
        return [seen_flow(mass_flow(coefficients, np.clip(sign * chain_output(q, u, dt / fine),
                                                          U_EQ_MIN, U_EQ_MAX), p_bar), fine, dt)
                for u, sign, p_bar, *_ in chambers]

    def residual(theta: np.ndarray) -> np.ndarray:
        out = []
        for (*_, flow, w, compared), model_flow in zip(chambers, seen_flows(model(theta))):
            err = np.where(compared, model_flow - flow, 0.0)
            spec = fft.rfft(err) * w
            out += [spec.real, spec.imag]
        return np.concatenate(out)

    start = np.array([np.log(params[FITTED[0]]), params[FITTED[1]], np.log(params[FITTED[2]]),
                      np.log(params[FITTED[3]])])
    lower = [np.log(1e-3), 0.0, np.log(10.0), np.log(10.0)]
    upper = [np.log(5.0), 0.02, np.log(1e4), np.log(1e4)]
    fit = optimize.least_squares(residual, start, bounds=(lower, upper), x_scale="jac")
    best = model(fit.x)
    flows = seen_flows(best)
    seen = np.concatenate([band_response(r.experiment.u, equivalent_voltage(
        r, params, coefficients, flows[2 * i:2 * i + 2]), dt)[1] for i, r in enumerate(recs)])
    keep = f_all <= top
    order = np.argsort(f_all[keep])
    return ValveResult(
        values={k: float(best[k]) for k in FITTED},
        frequency=f_all[keep][order], measured=np.concatenate([b[1] for b in bands])[keep][order],
        seen=seen[keep][order],
        experiments=[r.name for r in recs],
        rms_error=float(np.sqrt(2.0 * np.mean(fit.fun ** 2))),
        top_frequency=top,
        sample_time=dt)
