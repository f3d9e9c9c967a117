"""Fitting knob groups (candidate effects, the calibration) on the training experiments and
scoring them on the held-out ones.

One knob: a coarse grid over the whole range (the landscape of a delay, quantised to sub-steps,
is flat in places and may have several minima), then a bounded Brent search around the best grid
point. Several knobs: a grid over the first knob of the first effect from the neutral point of
the others (and from each value a form-selecting knob lists in ``tries``), or a given start,
then bounded least squares on the residual vector (trust-region reflective, each knob scaled by
its column of the Jacobian: calibration knobs and an effect trade off along narrow valleys that
an unscaled step crawls along). Every fit has a budget of model evaluations and keeps the best
point it has seen.

Every fit that holds the calibration knobs holds them to the hardware's typical spread
(:data:`calibration.SPREAD`) as a prior: its residuals carry one row per knob, scaled so that
the least squares find the posterior mode (:meth:`_Objective._prior`). The records pin a knob
far more tightly than that where they can; where they cannot (the dead volumes and frictions
with the position alone) the knob no longer runs to its bound to imitate an effect.

A fit of the calibration knobs then fits, on all records (training and held-out alike), the
directions of them that the training records leave free but the held-out predictions depend on
(:mod:`nuisance`, :attr:`data.Prepared.nuisance`; at most a few), the rest held: nuisance
parameters, fitted alike for every model compared, so that no model wins or loses on the
held-out data by where the training left them.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from jetpipe_ros.diagnosis.calibration import CALIBRATION as CALIBRATION_GROUP
from jetpipe_ros.diagnosis.calibration import NAME as CALIBRATION
from jetpipe_ros.diagnosis.calibration import group
from jetpipe_ros.diagnosis.candidates import CANDIDATES, KnobGroup, effect_of
from jetpipe_ros.diagnosis.data import Prepared
from jetpipe_ros.diagnosis.score import (Score, effective_samples, predict_all,
                                         residual_vector, score, window_errors)
from jetpipe_ros.model import ModelParams

GRID = 9
BUDGET = 40
#: Model evaluations of the nuisance directions' fit on all records (a few knobs, started
#: where the training left them).
NUISANCE_BUDGET = 8


@dataclass
class Fit:
    """Fitted knob groups (an effect or a pair, with or without the calibration) with their
    train and held-out scores."""

    groups: tuple[str, ...]  #: the fitted groups' names, in fitting order
    values: dict[str, dict[str, float]]  #: fitted parameters per group
    z: np.ndarray  #: the fitted knobs, unit-scaled, concatenated in group order
    params: ModelParams  #: the augmented model
    train: Score
    holdout: Score
    holdout_windows: np.ndarray  #: held-out error per prediction window (see window_errors)
    evaluations: int
    seconds: float
    #: independent pieces of evidence in the training records (:func:`score.effective_samples`)
    evidence: float = 1.0
    #: the calibration knobs' squared distance from nominal in the hardware's spreads
    #: (:meth:`_Objective._prior`; 0 when the fit holds none)
    prior: float = 0.0

    @property
    def cost(self) -> float:
        """What the fit minimised, as a negative log posterior up to a constant: N log C + P,
        C the training error over N pieces of evidence, P the calibration knobs' prior term
        (:meth:`_Objective._prior`). Two fits of the same knob groups from different starts are
        compared on it, as the descent compared its steps: on the training error alone a fit
        whose recalibration ran a knob to its bound to stand in for the effect wins by a
        hair's breadth of noise (seed 9437's port lag with the position alone: dead volumes
        twice nominal and the port at a sixth of its size, 2.7 % less training error than the
        fit from nominal dead volumes, which found the port's size within 8 % and left 0.84 %
        held out where the other left 3.09 %)."""
        return self.evidence * math.log(max(self.train.total, 1e-300)) + self.prior

    @property
    def effects(self) -> tuple[str, ...]:
        """The candidates (unmodelled effects, ``effect`` or ``effect:form``) among the
        groups."""
        return tuple(g for g in self.groups if g != CALIBRATION)

    @property
    def effect_names(self) -> tuple[str, ...]:
        """The effects' names (docs/effects.md), without their forms."""
        return tuple(effect_of(g) for g in self.effects)

    @property
    def forms(self) -> dict[str, str]:
        """The form of each effect that has several."""
        return {effect_of(g): CANDIDATES[g].form for g in self.effects
                if CANDIDATES[g].form is not None}

    def knobs_by_group(self) -> dict[str, np.ndarray]:
        """The unit-scaled knobs of each group."""
        sizes = np.cumsum([len(self.values[g]) for g in self.groups])[:-1]
        return dict(zip(self.groups, np.split(self.z, sizes)))

    def effect_values(self) -> dict[str, dict[str, float]]:
        """The fitted parameters by effect name (calibration knobs left out)."""
        return {effect_of(g): self.values[g] for g in self.effects}

    @property
    def calibrated(self) -> bool:
        """True when the calibration knobs were fitted too."""
        return CALIBRATION in self.groups

    @property
    def name(self) -> str:
        """The candidates joined with '+' (``calibration`` when there is none)."""
        return "+".join(self.effects) or CALIBRATION

    @property
    def effect(self) -> str:
        """The effects' names joined with '+' (``none`` when there is none): the verdict's
        vocabulary."""
        return "+".join(self.effect_names) or "none"


def stacked(below: Fit, above: Fit) -> Fit:
    """``above`` (fitted on ``below``'s model, with ``below``'s knobs held) as one fit of all
    their groups: same model and scores, values, knobs and prior of both."""
    return dataclasses.replace(above, groups=below.groups + above.groups,
                               values={**below.values, **above.values},
                               z=np.concatenate([below.z, above.z]),
                               prior=below.prior + above.prior)


class _BudgetSpent(Exception):
    pass


class _Objective:
    """Training residuals as a function of the unit-scaled knobs of one or more groups."""

    def __init__(self, prepared: Prepared, nominal: ModelParams,
                 candidates: Sequence[KnobGroup], budget: int) -> None:
        self.prepared = prepared
        self.nominal = nominal
        self.candidates = tuple(candidates)
        self.sizes = [len(c.knobs) for c in self.candidates]
        self.budget = budget
        self.calls = 0
        self.best_cost = np.inf
        self.best_z: np.ndarray | None = None
        offsets = np.cumsum([0] + self.sizes)
        #: the calibration knobs' group and where they lie in the knob vector (None, None: not
        #: fitted here)
        self.calibration_group, self.calibration = next(
            ((c, slice(int(o), int(o) + len(c.knobs)))
             for c, o in zip(self.candidates, offsets) if c.name == CALIBRATION), (None, None))
        #: independent pieces of evidence in the training records (set at the first call)
        self.evidence: float | None = None

    def params(self, z: np.ndarray) -> ModelParams:
        p = self.nominal
        for cand, zc in zip(self.candidates, np.split(z, np.cumsum(self.sizes)[:-1])):
            p = cand.apply(p, cand.values(zc))
        return p

    def values(self, z: np.ndarray) -> dict[str, dict[str, float]]:
        return {c.name: c.values(zc) for c, zc in
                zip(self.candidates, np.split(z, np.cumsum(self.sizes)[:-1]))}

    def residuals(self, z: np.ndarray) -> np.ndarray:
        if self.calls >= self.budget:
            raise _BudgetSpent
        self.calls += 1
        z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
        preds = predict_all(self.params(z), self.prepared, "train")
        r = residual_vector(self.prepared, preds, "train")
        if self.calibration is not None:
            r = np.concatenate([r, self._prior(r, preds, z)])
        cost = float(r @ r)
        if cost < self.best_cost:
            self.best_cost = cost
            self.best_z = z.copy()
        return r

    def _prior(self, r: np.ndarray, preds: Sequence, z: np.ndarray) -> np.ndarray:
        """Residuals that hold the calibration knobs to the hardware's spread: with the data's
        training error C = r.r over N pieces of evidence, rows sqrt(C / N) ln(f) / sigma, so
        that the sum of squares is C (1 + P / N), P the knobs' squared distance from nominal in
        spreads. Minimising it minimises N log C + P to first order: the posterior mode of the
        knobs under the prior of :data:`calibration.SPREAD`, the residuals' variance unknown
        (estimated by C, as :func:`uncertainty` does)."""
        if self.evidence is None:
            self.evidence = effective_samples(score(self.prepared, preds, "train"),
                                              self.prepared.dt)
        knobs = self.calibration_group.prior_residuals(z[self.calibration])
        return float(np.sqrt(float(r @ r) / self.evidence)) * knobs

    def cost(self, z: np.ndarray) -> float:
        r = self.residuals(z)
        return float(r @ r)


def fit(prepared: Prepared, nominal: ModelParams, candidates: Sequence[KnobGroup],
        start: np.ndarray | None = None, budget: int = BUDGET,
        grid_base: np.ndarray | None = None) -> Fit:
    """Fit the knob groups ``candidates`` jointly on the training data, applied in order to
    ``nominal``; score on the holdout. Without ``start`` the first knob of the first effect is
    searched on a grid, the others at ``grid_base`` (unit-scaled; default: where each group
    changes nothing; from a given ``grid_base`` the grid leaves the first knob's neutral value
    out, :func:`_grid_first_knob`); with several starts (rows of a 2-D ``start``) the fit goes
    on from the best."""
    began = time.perf_counter()
    obj = _Objective(prepared, nominal, candidates, budget)
    try:
        if start is None:
            start = _grid_first_knob(obj, grid_base)
        elif start.ndim == 2:
            start = min(start, key=obj.cost)
        if start.size == 1:
            _brent(obj, start)
        else:
            optimize.least_squares(obj.residuals, np.clip(start, 1e-6, 1 - 1e-6),
                                   bounds=(0.0, 1.0), diff_step=0.03, x_scale="jac",
                                   xtol=1e-3, ftol=1e-4, max_nfev=budget)
    except _BudgetSpent:
        pass
    z = obj.best_z if obj.best_z is not None else np.clip(start, 0.0, 1.0)
    return _scored(obj, _nuisance_fitted(obj, z), began)


def with_nuisance(prepared: Prepared, nominal: ModelParams, fitted: Fit) -> Fit:
    """``fitted`` (which holds the calibration knobs) with the nuisance directions of
    ``prepared`` fitted on all records, and scored again."""
    began = time.perf_counter() - fitted.seconds
    obj = _Objective(prepared, nominal, [group(g, prepared.sensors) for g in fitted.groups],
                     budget=0)
    obj.calls = fitted.evaluations
    return _scored(obj, _nuisance_fitted(obj, fitted.z), began)


def switched_off(prepared: Prepared, nominal: ModelParams, fitted: Fit, name: str) -> Fit:
    """``fitted`` (its groups applied to ``nominal``) with the group ``name`` back where it
    changes nothing and every other knob as fitted, nothing refitted, scored again: what the
    rest of the fit predicts without that group."""
    began = time.perf_counter()
    groups = [group(g, prepared.sensors) for g in fitted.groups]
    obj = _Objective(prepared, nominal, groups, budget=0)
    z = fitted.knobs_by_group()
    z[name] = group(name, prepared.sensors).rest(fitted.values[name])
    return _scored(obj, np.concatenate([z[g] for g in fitted.groups]), began)


def _scored(obj: _Objective, z: np.ndarray, began: float) -> Fit:
    """The fit at the unit-scaled knobs ``z``, scored on the training and held-out data."""
    prepared = obj.prepared
    params = obj.params(z)
    train = score(prepared, predict_all(params, prepared, "train"), "train")
    held = predict_all(params, prepared, "holdout")
    prior = (0.0 if obj.calibration is None else
             float(np.sum(obj.calibration_group.prior_residuals(z[obj.calibration]) ** 2)))
    return Fit(groups=tuple(c.name for c in obj.candidates), values=obj.values(z), z=z,
               params=params, train=train, holdout=score(prepared, held, "holdout"),
               holdout_windows=window_errors(prepared, held, "holdout"), evaluations=obj.calls,
               seconds=time.perf_counter() - began,
               evidence=effective_samples(train, prepared.dt), prior=prior)


def _nuisance_fitted(obj: _Objective, z: np.ndarray) -> np.ndarray:
    """``z`` with the calibration knobs moved along the nuisance directions
    (:attr:`data.Prepared.nuisance`) to fit all records, training and held-out, every other
    knob held (``z`` itself when there are none or the calibration is not fitted here)."""
    directions = obj.prepared.nuisance
    if directions is None or obj.calibration is None:
        return z
    prepared, knobs = obj.prepared, obj.calibration

    def at(a: np.ndarray) -> np.ndarray:
        moved = z.copy()
        moved[knobs] = CALIBRATION_GROUP.moved(z[knobs], directions @ a)
        return moved

    def residuals(a: np.ndarray) -> np.ndarray:
        obj.calls += 1
        return residual_vector(prepared, predict_all(obj.params(at(a)), prepared, None), None)

    # Each direction is one standard deviation of what the records and the hardware's spread
    # leave of it (nuisance.directions): unit scale, steps of a twentieth of it.
    found = optimize.least_squares(residuals, np.zeros(directions.shape[1]), diff_step=0.05,
                                   xtol=1e-3, ftol=1e-4, max_nfev=NUISANCE_BUDGET)
    return at(found.x)


def _grid_first_knob(obj: _Objective, base: np.ndarray | None = None) -> np.ndarray:
    """Start of a fit: every knob at ``base`` (default: its neutral point) but the first knob of
    the first effect, which is searched on a grid (and from each value a form-selecting knob
    lists in ``tries``). Calibration knobs are not gridded: they start at 1, or at ``base``.

    From a given ``base`` (the refits that look for an effect's basin away from the
    recalibration's, :func:`diagnose.fit_effects`) the grid leaves out the first knob's neutral
    value: the effect at nothing has been fitted already there, and a descent that starts with
    the effect doing nothing can stay there, its other knobs without a gradient (a 0.32 m line
    whose hose started at length 0, the best grid point before the dead volumes moved: 1.0 %
    of the training gap left, where from the next grid point, 0.31 m, it converged at 0.29 m
    and 0.04 %)."""
    acting = base is not None
    if base is None:
        base = np.concatenate([c.start() for c in obj.candidates])
    knobs = [k for c in obj.candidates for k in c.knobs]
    offsets = np.cumsum([0] + obj.sizes)
    first = next((int(o) for c, o in zip(obj.candidates, offsets) if c.name != CALIBRATION),
                 None)
    if first is None:
        return base
    bases = [base]
    for i, k in enumerate(knobs[first + 1:], first + 1):
        for value in k.tries:
            b = base.copy()
            b[i] = k.to_unit(value)
            bases.append(b)
    grid = np.linspace(0.0, 1.0, GRID)
    if acting:
        grid = grid[~np.isclose(grid, knobs[first].to_unit(knobs[first].off))]
    best, best_cost = base, np.inf
    for b in bases:
        for g in grid:
            z = b.copy()
            z[first] = g
            c = obj.cost(z)
            if c < best_cost:
                best, best_cost = z, c
    return best


def _brent(obj: _Objective, start: np.ndarray) -> None:
    step = 1.0 / (GRID - 1)
    lo, hi = max(start[0] - step, 0.0), min(start[0] + step, 1.0)
    optimize.minimize_scalar(lambda g: obj.cost(np.array([g])), bounds=(lo, hi),
                             method="bounded", options={"xatol": 2e-3, "maxiter": 14})


def jacobian(residuals: Callable[[np.ndarray], np.ndarray], z: np.ndarray,
             step: float) -> np.ndarray:
    """d ``residuals`` / d ``z`` at the unit-scaled knobs ``z``: central differences of
    ``step``, one-sided where a knob is within ``step`` of the unit box's edge."""
    columns = []
    for i in range(z.size):
        lo, hi = z.copy(), z.copy()
        lo[i] = max(lo[i] - step, 0.0)
        hi[i] = min(hi[i] + step, 1.0)
        columns.append((residuals(hi) - residuals(lo)) / (hi[i] - lo[i]))
    return np.column_stack(columns)


def uncertainty(prepared: Prepared, nominal: ModelParams, fitted: Fit,
                groups: Sequence[KnobGroup] | None = None,
                step: float = 0.01) -> dict[str, dict[str, float | None]]:
    """Standard errors of every fitted parameter (effects and calibration knobs), from the
    curvature of the training error at the fit, each marginal over the others: what a
    parameter trades off against widens its error.

    With N independent pieces of evidence (one per signal and prediction window: the residuals
    of a window are correlated, :func:`score.effective_samples`) the log-likelihood is about
    -N/2 log(C) for the training error C = r.r, so the covariance of the knobs is
    C / N (J^T J)^-1, J the Jacobian of the residuals over all the fit's knobs (central
    differences, ``step`` in the unit-scaled knobs); the calibration knobs' prior rows
    (:meth:`_Objective._prior`) are among the residuals, so theirs is the posterior's
    curvature, which the hardware's spread bounds. A knob the error does not depend on there
    (a delay between two sub-steps) has no standard error (None). ``groups`` are the fit's
    knob groups when they are not candidates or the calibration (looked up by name).
    """
    groups = (list(groups) if groups is not None else
              [group(g, prepared.sensors) for g in fitted.groups])
    obj = _Objective(prepared, nominal, groups, budget=10**9)
    r0 = obj.residuals(fitted.z)
    jac = jacobian(obj.residuals, fitted.z, step)
    info = jac.T @ jac
    cov = float(r0 @ r0) / fitted.evidence * np.linalg.pinv(info)
    out: dict[str, dict[str, float | None]] = {}
    knobs = [(g.name, k) for g in groups for k in g.knobs]
    for i, (name, k) in enumerate(knobs):
        z = float(fitted.z[i])
        se = None
        if info[i, i] > 0 and cov[i, i] > 0:  # to the parameter's scale through its map
            lo, hi = max(z - step, 0.0), min(z + step, 1.0)
            se = abs(k.to_value(hi) - k.to_value(lo)) / (hi - lo) * float(np.sqrt(cov[i, i]))
        out.setdefault(name, {})[k.name] = se
    return out
