"""Mass flow map of the valve (Sec. 2.3, Eq. 7-8) from constant-volume charge/discharge tests.

With the piston locked each chamber holds a constant volume, so Eq. 7 gives the mass flow into it
from its pressure alone: q = V / (r T) dp/dt. The derivative is the zero-phase Savitzky-Golay
estimate of :mod:`.differentiate`. While a command level is held (after the valve has settled)
chamber 1 receives q(u_eq, p1) and, by the valve's symmetry (Remark 2), chamber 2 receives q(-u_eq,
p2), so both chambers give samples of the same map. In steady state the equivalent voltage is the
command clipped to the jet-pipe's travel, u_eq = clip(u, -2.8, 3.0) V (docs/model.md): the map is
fitted against u_eq, so a command beyond the travel (e.g. 3.4 V) adds samples at the travel's end.
The fit is Eq. 8's fifth-order polynomial in (u [V], p [bar]) by linear least squares, in g/s as the
paper writes its coefficients, on the regressors of the model's own Eq. 8
(:func:`jetpipe_ros.model.flow.flow_matrix`), so the fitted coefficients mean exactly what the
simulator does with them.

Samples at or below 1.05 bar are left out: a chamber vented down to atmosphere has no outflow
whatever the polynomial says (the model's vent floor), which is not the valve's map.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.identify.differentiate import clear_of_gaps, derivative
from jetpipe_ros.identify.experiments import Recording
from jetpipe_ros.model.chamber import chamber_volumes
from jetpipe_ros.model.flow import (KG_PER_G, TABLE_P, TABLE_SIZE, TABLE_U, flow_matrix,
                                   mass_flow, table_matrix)
from jetpipe_ros.model.valve import U_EQ_MAX, U_EQ_MIN

#: Derivative window [s]: 21 ms keeps the curvature bias of a 3.4 V charge below 1e-5 kg/s.
WINDOW = 0.021
#: Time after a command change before the valve counts as settled [s] (5 % settling 25.5 ms).
SETTLE = 0.05
#: Lowest pressure used [bar]: below it the vent floor, not the map, sets the flow.
P_FLOOR_BAR = 1.05
#: Fewest distinct equivalent voltages for a fifth-order polynomial in u.
MIN_LEVELS = 6
#: Voltage step of the central difference giving the map's slope dq/du in :func:`invert` [V]
#: (relative error ~1e-8 on a fifth-order polynomial).
SLOPE_STEP = 1e-4


@dataclass
class FlowSamples:
    """Flow samples of held command levels: equivalent voltage, pressure and mass flow."""

    u: np.ndarray  #: equivalent voltage u_eq [V]
    p_bar: np.ndarray  #: chamber pressure [bar, absolute]
    q: np.ndarray  #: mass flow into the chamber [kg/s]
    chamber: np.ndarray  #: the chamber each sample is of (1 or 2)


@dataclass
class FlowMapResult:
    """The identified map and how well it fits its own samples."""

    coefficients: list[float]  #: Eq. 8 coefficients (paper order, u in V, p in bar, g/s)
    samples: FlowSamples  #: the samples fitted
    experiments: list[str]  #: names of the charge/discharge tests used
    max_error: float  #: largest |fit - sample| [kg/s]
    rms_error: float  #: RMS of fit - sample [kg/s]
    levels: list[float]  #: distinct equivalent voltages held [V]

    def u_range(self) -> tuple[float, float]:
        """Identified voltage range [V]."""
        return float(self.samples.u.min()), float(self.samples.u.max())

    def p_range(self) -> tuple[float, float]:
        """Identified pressure range [bar]."""
        return float(self.samples.p_bar.min()), float(self.samples.p_bar.max())


def chamber_capacities(params: Mapping[str, Any], y: float) -> tuple[float, float]:
    """V / (r T) of chambers 1 and 2 at piston position ``y`` [m] (Eq. 7, volumes of Eq. 13)
    [kg/Pa]."""
    rt = params["chamber.gas_constant"] * params["chamber.temperature"]
    vol1, vol2 = chamber_volumes(y, params["chamber.piston_area"],
                                 params["chamber.dead_volume_1"], params["chamber.dead_volume_2"])
    return vol1 / rt, vol2 / rt


def held_mask(u: np.ndarray, dt: float, settle: float, tail: float) -> np.ndarray:
    """Samples at least ``settle`` [s] after and ``tail`` [s] before a command change; the
    record's start counts as a change (the valve may not be settled there)."""
    change = np.flatnonzero(np.abs(np.diff(u)) > 1e-9) + 1
    edges = np.concatenate([[0], change, [u.size]])
    mask = np.zeros(u.size, dtype=bool)
    first = round(settle / dt)
    last = round(tail / dt)
    for a, b in zip(edges[:-1], edges[1:]):
        mask[a + first:max(a, b - last)] = True
    return mask


def flow_samples(rec: Recording, params: Mapping[str, Any]) -> FlowSamples:
    """Eq. 7 samples of both chambers of one locked charge/discharge test (none where the
    derivative's window reaches over a logger's gap)."""
    exp = rec.experiment
    dt = exp.dt
    c1, c2 = chamber_capacities(params, float(np.mean(exp.y)))
    keep = held_mask(exp.u, dt, SETTLE, WINDOW / 2 + 2 * dt) \
        & clear_of_gaps(exp.measured, dt, WINDOW)
    us, ps, qs, chambers = [], [], [], []
    for chamber, sign, p, cap in ((1, 1.0, exp.p1, c1), (2, -1.0, exp.p2, c2)):
        q = cap * derivative(p, dt, WINDOW)
        ok = keep & (p * 1e-5 > P_FLOOR_BAR)
        us.append(np.clip(sign * exp.u[ok], U_EQ_MIN, U_EQ_MAX))
        ps.append(p[ok] * 1e-5)
        qs.append(q[ok])
        chambers.append(np.full(int(ok.sum()), chamber))
    return FlowSamples(*(np.concatenate(x) for x in (us, ps, qs, chambers)))


def pooled(parts: Sequence[FlowSamples]) -> FlowSamples:
    """The samples of several tests as one set."""
    return FlowSamples(*(np.concatenate([getattr(x, f) for x in parts])
                         for f in ("u", "p_bar", "q", "chamber")))


def identify_flow_map(recs: list[Recording], params: Mapping[str, Any]) -> FlowMapResult:
    """Fit Eq. 8 to the charge/discharge tests ``recs`` (chamber geometry from ``params``).

    Raises DatasetError when the tests hold fewer than :data:`MIN_LEVELS` distinct equivalent
    voltages (both chambers counted), too few for a fifth-order polynomial in u.
    """
    if not recs:
        raise DatasetError("flow map: no constant-volume charge/discharge test (piston: locked, "
                           "piecewise-constant command) in the dataset")
    parts = [flow_samples(r, params) for r in recs]
    s = pooled(parts)
    levels = sorted({round(float(v), 3) for v in s.u})
    if len(levels) < MIN_LEVELS:
        raise DatasetError(
            f"flow map: the charge/discharge tests ({', '.join(r.name for r in recs)}) hold "
            f"{len(levels)} distinct voltage(s) {levels} in both chambers; Eq. 8 needs at least "
            f"{MIN_LEVELS} (the paper: |u| = 0, 0.29, 0.57, 1.15, 1.73, 2.29, 2.86, 3.4 V)")
    basis = flow_matrix(s.u, s.p_bar)
    scale = np.linalg.norm(basis, axis=0)
    sol, *_ = np.linalg.lstsq(basis / scale, s.q / KG_PER_G, rcond=None)
    coef = sol / scale
    resid = basis @ coef * KG_PER_G - s.q
    return FlowMapResult(coefficients=[float(c) for c in coef], samples=s,
                         experiments=[r.name for r in recs],
                         max_error=float(np.max(np.abs(resid))),
                         rms_error=float(np.sqrt(np.mean(resid ** 2))), levels=levels)


def invert(coefficients: Sequence[float], q: np.ndarray, p_bar: np.ndarray,
           start: np.ndarray, iterations: int = 20) -> np.ndarray:
    """Equivalent voltage u [V] with Eq. 8 q(u, p) = ``q`` [kg/s] at ``p_bar`` [bar].

    Newton's method from ``start`` [V] on the model's map (:func:`~jetpipe_ros.model.flow.
    mass_flow`, slope by a central difference over :data:`SLOPE_STEP`), kept within the
    jet-pipe's travel [-2.8, 3.0] V, where the map rises with u; where no voltage in the travel
    gives ``q`` the end of the travel is returned.
    """
    coef = np.asarray(coefficients, dtype=float)
    p = np.asarray(p_bar, dtype=float)
    u = np.clip(np.asarray(start, dtype=float), U_EQ_MIN, U_EQ_MAX)
    for _ in range(iterations):
        value = mass_flow(coef, u, p) - q
        slope = (mass_flow(coef, u + SLOPE_STEP, p) - mass_flow(coef, u - SLOPE_STEP, p)) \
            / (2.0 * SLOPE_STEP)
        step = value / np.where(slope > 1e-6, slope, 1e-6)
        u = np.clip(u - step, U_EQ_MIN, U_EQ_MAX)
    return u


@dataclass
class FlowTableResult:
    """The flow map's correction table (``flow.table``) and the cross-validation that chose it."""

    table: list[float]  #: correction [g/s] on the nodes of TABLE_U x TABLE_P (flow module)
    #: the table predicts the tests left out better than Eq. 8 with the bench's own scales
    kept: bool
    smoothing: float  #: the roughness weight chosen by cross-validation [-]
    rms_before: float  #: RMS of Eq. 8's error on the samples left out, over all folds [kg/s]
    rms_after: float  #: the same with the table fitted without them [kg/s]
    #: the same with the bench's scales (:func:`scale_regressors`) fitted without them, and
    #: with those scales and the table beside them [kg/s]: what decides :attr:`kept`
    rms_scales: float
    rms_scales_table: float
    samples: FlowSamples  #: the samples fitted
    experiments: list[str]  #: the charge/discharge tests used


#: Roughness weights tried, relative to the data's weight per node [-]: from a table that
#: follows every node's samples to one as flat as a plane.
SMOOTHING = np.logspace(-3.0, 3.0, 13)
#: Relative weight of the pull toward zero on nodes no sample reaches [-]: small enough not to
#: bias a node with data, large enough that the least-squares problem has one solution.
RIDGE = 1e-6
#: Least reduction of the left-out tests' mean square error for the table to be kept: a table
#: fitted to noise cannot lower a left-out test's error, and the best of SMOOTHING's weights
#: gains 0.6-0.8 % on the plant's records of a valve Eq. 8 holds (seeds 0-12), a tenth of this;
#: the smallest departure the self-check draws (0.2 g/s) gains 41 % (docs/identification.md).
MIN_GAIN = 0.10
#: Number of the bench's own scales the table is judged beside (:func:`scale_regressors`).
N_SCALES = 5


def scale_regressors(s: FlowSamples, coefficients: np.ndarray) -> np.ndarray:
    """(n, :data:`N_SCALES`) regressors [g/s] of what an individual bench does to the samples
    of Eq. 8 (``coefficients``) without its map departing: each chamber's flow scaled apart
    where it fills and where it empties (Eq. 7 reads the flow through the chamber's dead
    volume, which belongs to the bench, and the valve's gain differs per direction: four
    products, three of them independent), and the jet pipe's deflection per volt (the
    equivalent voltage scaled: u dq/du)."""
    q8 = mass_flow(coefficients, s.u, s.p_bar) / KG_PER_G
    slope = (mass_flow(coefficients, s.u + SLOPE_STEP, s.p_bar)
             - mass_flow(coefficients, s.u - SLOPE_STEP, s.p_bar)) / (2.0 * SLOPE_STEP * KG_PER_G)
    return np.column_stack([q8 * (s.chamber == c) * fills for c in (1, 2)
                            for fills in (q8 > 0.0, q8 < 0.0)] + [s.u * slope])


def _roughness() -> np.ndarray:
    """Second differences of the table along voltage and along pressure, one row each."""
    nu, npp = TABLE_U.size, TABLE_P.size
    rows = []
    for i in range(nu):
        for j in range(npp):
            for di, dj in ((1, 0), (0, 1)):
                if 0 <= i - di and i + di < nu and 0 <= j - dj and j + dj < npp:
                    r = np.zeros(TABLE_SIZE)
                    r[(i - di) * npp + j - dj] = 1.0
                    r[i * npp + j] = -2.0
                    r[(i + di) * npp + j + dj] = 1.0
                    rows.append(r)
    return np.array(rows)


def _solve(gram: np.ndarray, rhs: np.ndarray, penalty: np.ndarray, weight: float) -> np.ndarray:
    """The penalised least squares of the table's entries, then of any free unknowns after
    them (the bench's scales: not penalised, their ridge as small as the entries')."""
    n = gram.shape[0]
    scale = np.trace(gram[:TABLE_SIZE, :TABLE_SIZE]) / TABLE_SIZE
    pen = np.zeros((n, n))
    pen[:TABLE_SIZE, :TABLE_SIZE] = weight * penalty
    return np.linalg.solve(gram + scale * (pen + RIDGE * np.eye(n)), rhs)


@dataclass(frozen=True)
class _Normal:
    """Each test's design and errors with their normal equations, formed once for every
    roughness weight tried."""

    designs: list[np.ndarray]
    errors: Sequence[np.ndarray]
    grams: list[np.ndarray]
    rhs: list[np.ndarray]

    @classmethod
    def of(cls, designs: list[np.ndarray], errors: Sequence[np.ndarray]) -> _Normal:
        return cls(designs, errors, [a.T @ a for a in designs],
                   [a.T @ e for a, e in zip(designs, errors)])


def _left_out(normal: _Normal, solve: Any) -> float:
    """Sum of squares of each test's errors predicted by ``solve(gram, rhs)`` fitted on the
    other tests (leave-one-test-out)."""
    gram_all, rhs_all = sum(normal.grams), sum(normal.rhs)
    return sum(float(np.sum((e - a @ solve(gram_all - g, rhs_all - r)) ** 2))
               for a, e, g, r in zip(normal.designs, normal.errors, normal.grams, normal.rhs))


def identify_flow_table(recs: list[Recording], params: Mapping[str, Any],
                        coefficients: Sequence[float]) -> FlowTableResult:
    """Fit the flow map's correction table to what Eq. 8 (``coefficients``) leaves of the
    charge/discharge tests ``recs``, as smooth as leave-one-test-out cross-validation asks.

    The table is fitted to the Eq. 7 samples' error of Eq. 8, through the model's own
    interpolation (:func:`~jetpipe_ros.model.flow.table_matrix`), penalised by its second
    differences along voltage and pressure; each roughness weight of :data:`SMOOTHING` is
    scored on every test left out in turn, and the best one fitted on all. The table is kept
    when, beside the bench's own scales (:func:`scale_regressors`: each chamber's flow per
    direction, the jet pipe's gain), it lowers the left-out tests' mean square error those
    scales leave by :data:`MIN_GAIN` or more, else it is zero: a valve whose map Eq. 8 holds
    gets no table fitted to its noise, nor to its bench's dead volumes and gains (judged
    against Eq. 8 alone, a table that took in an actuator's 25 % larger dead volume and 3 %
    lower jet-pipe gain was kept, up to 1.03 g/s, and the recalibrated model missed its
    held-out experiments by 0.80 % for 0.105 % without it: docs/identification.md). The table
    written is fitted alone, the gains per direction as ``params`` give them: fitted together
    with a table they trade against it (seen: a discharging gain of 0.79 beside a table of
    5 g/s, on a valve whose gains are 1.08 and 1.06), so what scales the whole map is the
    table's too, where it was measured, and the diagnosis recalibrates the bench around it.

    Raises DatasetError with fewer than two tests (nothing to leave out).
    """
    if len(recs) < 2:
        raise DatasetError(f"flow table: {len(recs)} constant-volume charge/discharge test(s) "
                           f"in the dataset; leaving one out to choose the table's smoothness "
                           f"needs at least 2")
    parts = [flow_samples(r, params) for r in recs]
    coef = np.asarray(coefficients, dtype=float)
    designs, scales, errors = [], [], []
    for s in parts:
        designs.append(table_matrix(s.u, s.p_bar))
        scales.append(scale_regressors(s, coef))
        eq8 = mass_flow(coef, s.u, s.p_bar)
        gain = np.where(eq8 > 0.0, params["flow.gain_charge"], params["flow.gain_discharge"])
        errors.append((s.q / gain - eq8) / KG_PER_G)  # the table sits inside the gains
    penalty = _roughness()
    penalty = penalty.T @ penalty
    table_only = _Normal.of(designs, errors)
    both = _Normal.of([np.column_stack([a, b]) for a, b in zip(designs, scales)], errors)
    before = sum(float(e @ e) for e in errors)
    scored = [(_left_out(table_only, lambda g, r, w=w: _solve(g, r, penalty, w)),
               _left_out(both, lambda g, r, w=w: _solve(g, r, penalty, w)), w)
              for w in SMOOTHING]
    alone, _, weight = min(scored)
    beside = min(x[1] for x in scored)
    scaled = _left_out(_Normal.of(scales, errors), lambda g, r: np.linalg.solve(g, r))
    n = sum(e.size for e in errors)
    kept = beside <= (1.0 - MIN_GAIN) * scaled
    table = (_solve(sum(table_only.grams), sum(table_only.rhs), penalty, weight) if kept
             else np.zeros(TABLE_SIZE))
    return FlowTableResult(
        table=[float(v) for v in table], kept=bool(kept), smoothing=float(weight),
        rms_before=math.sqrt(before / n) * KG_PER_G,
        rms_after=math.sqrt(alone / n) * KG_PER_G,
        rms_scales=math.sqrt(scaled / n) * KG_PER_G,
        rms_scales_table=math.sqrt(beside / n) * KG_PER_G,
        samples=pooled(parts),
        experiments=[r.name for r in recs])
