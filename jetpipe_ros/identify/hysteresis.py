"""Valve hysteresis (Sec. 2.2) from slow voltage ramps at constant volume.

The paper ramps the command slowly up and down to the jet-pipe's travel limits, reads the major
loop of jet-pipe position against voltage, and keeps its midpoint lines (Eq. 5); half the
separation of the loop's two halves (0.25 V on its valve) is the hysteresis left out. This
package's sensors do not see the jet pipe, but its equivalent voltage u_eq (the voltage the
midpoint lines assign to its position) shows in the chambers: with the piston locked, each
chamber's flow q = V/(r T) dp/dt is the map q(u_eq, p) at the measured pressure, so inverting the
map (:func:`.flow_map.invert`, derivative over :data:`WINDOW`) gives u_eq(t), and the loop is
u_eq against the command u, read on the rising and the falling ramps.

At equal u_eq the rising half lies at u = u_eq + w and the falling half at u = u_eq - w for a
play of half-width w (the model's ``valve_hysteresis`` effect), so w is half the horizontal
separation, taken as the median over the u_eq range both halves cover (leaving out the flat
turns at the ends, where u moves while u_eq waits). The midpoint line is the mean of the halves;
the model's reading of Eq. 5 (docs/model.md) makes it u = u_eq, and its fitted slope and offset
say how well the valve follows that. Chamber 1 resolves u_eq where its pressure stays above the
vent floor (u_eq above about -2.2 V), chamber 2 (which sees -u_eq) below about +2.2 V; both are
used.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.identify.differentiate import clear_of_gaps, derivative
from jetpipe_ros.identify.experiments import Recording
from jetpipe_ros.identify.flow_map import P_FLOOR_BAR, chamber_capacities, invert
from jetpipe_ros.model.valve import U_EQ_MAX, U_EQ_MIN

#: Derivative window [s]: ramps are slow, so a long window keeps the noise down.
WINDOW = 0.051
#: u_eq bins for reading the two halves [V], and samples needed per bin and half.
BIN = 0.05
MIN_PER_BIN = 5
#: Margin left out at the ends of the u_eq range covered (the loop's flat turns) [V].
END_MARGIN = 0.15
#: Fewest bins both halves must cover for a loop.
MIN_BINS = 10
#: Half-widths below this are not distinguished from none [V] (about 3 bins' noise).
RESOLUTION = 0.02


@dataclass
class HysteresisResult:
    """The loop read from the ramps and what it gives the model."""

    half_width: float  #: median half separation of the loop's halves [V]
    max_half_width: float  #: largest half separation over the bins [V] (the paper's 0.25 V)
    midline_slope: float  #: slope of the midpoint line u(u_eq) [V/V] (model: 1)
    midline_offset: float  #: offset of the midpoint line at u_eq = 0 [V] (model: 0)
    u: np.ndarray  #: command of the loop samples [V]
    u_eq: np.ndarray  #: equivalent voltage of the loop samples [V]
    rising: np.ndarray  #: True where the command rises
    levels: np.ndarray  #: u_eq bin centres [V]
    u_rise: np.ndarray  #: rising half u per bin [V]
    u_fall: np.ndarray  #: falling half u per bin [V]
    experiments: list[str]

    @property
    def significant(self) -> bool:
        """True when the loop is wider than the procedure resolves."""
        return self.half_width >= RESOLUTION


def loop_samples(rec: Recording, params: Mapping[str, Any], coefficients: Sequence[float]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, u_eq, rising) of one ramp test, at the samples where a chamber resolves u_eq (and
    the derivative's window holds no row filled over a logger's gap)."""
    exp = rec.experiment
    caps = chamber_capacities(params, float(np.mean(exp.y)))
    du = np.gradient(exp.u)
    clear = clear_of_gaps(exp.measured, exp.dt, WINDOW)
    us, ueqs, rising = [], [], []
    for sign, p, cap in zip((1.0, -1.0), (exp.p1, exp.p2), caps):
        q = cap * derivative(p, exp.dt, WINDOW)
        u_eq = sign * invert(coefficients, q, p * 1e-5, sign * exp.u)
        ok = (clear & (p * 1e-5 > P_FLOOR_BAR + 0.05) & (np.abs(du) > 1e-9)
              & (u_eq > U_EQ_MIN + 0.05) & (u_eq < U_EQ_MAX - 0.05))
        us.append(exp.u[ok])
        ueqs.append(u_eq[ok])
        rising.append(du[ok] > 0)
    return np.concatenate(us), np.concatenate(ueqs), np.concatenate(rising)


def _half_medians(u: np.ndarray, u_eq: np.ndarray, mask: np.ndarray, edges: np.ndarray
                  ) -> np.ndarray:
    idx = np.digitize(u_eq[mask], edges) - 1
    out = np.full(edges.size - 1, np.nan)
    for k in range(edges.size - 1):
        sel = u[mask][idx == k]
        if sel.size >= MIN_PER_BIN:
            out[k] = np.median(sel)
    return out


def identify_hysteresis(recs: list[Recording], params: Mapping[str, Any],
                        coefficients: Sequence[float]) -> HysteresisResult:
    """Read the loop of the ramp tests ``recs`` with the flow map ``coefficients``.

    Raises DatasetError when there are no ramps or their two halves overlap on fewer than
    :data:`MIN_BINS` bins of u_eq (ramps too short, too fast, or one-way).
    """
    if not recs:
        raise DatasetError("hysteresis: no slow ramp test (piston: locked, command ramped up "
                           "and down slowly, e.g. a triangle over +-3.4 V at 0.1 Hz) in the "
                           "dataset")
    parts = [loop_samples(r, params, coefficients) for r in recs]
    u, u_eq, rising = (np.concatenate([p[i] for p in parts]) for i in range(3))
    names = ", ".join(r.name for r in recs)
    if u.size == 0 or rising.all() or not rising.any():
        raise DatasetError(f"hysteresis: the ramp test(s) {names} do not ramp both up and down "
                           f"where the chamber pressures resolve the valve")
    low = max(u_eq[rising].min(), u_eq[~rising].min()) + END_MARGIN
    high = min(u_eq[rising].max(), u_eq[~rising].max()) - END_MARGIN
    edges = np.arange(low, high + BIN, BIN) if high > low else np.array([low])
    u_rise = _half_medians(u, u_eq, rising, edges)
    u_fall = _half_medians(u, u_eq, ~rising, edges)
    both = np.isfinite(u_rise) & np.isfinite(u_fall)
    if np.count_nonzero(both) < MIN_BINS:
        raise DatasetError(
            f"hysteresis: the rising and falling ramps of {names} overlap on "
            f"{np.count_nonzero(both)} bin(s) of {BIN} V; need {MIN_BINS}: ramp slowly "
            f"(<= 2 V/s) over the whole travel, up and down")
    levels = 0.5 * (edges[:-1] + edges[1:])[both]
    u_rise, u_fall = u_rise[both], u_fall[both]
    half = 0.5 * (u_rise - u_fall)
    slope, offset = np.polyfit(levels, 0.5 * (u_rise + u_fall), 1)
    return HysteresisResult(
        half_width=float(max(np.median(half), 0.0)), max_half_width=float(np.max(half)),
        midline_slope=float(slope), midline_offset=float(offset), u=u, u_eq=u_eq,
        rising=rising, levels=levels, u_rise=u_rise, u_fall=u_fall,
        experiments=[r.name for r in recs])
