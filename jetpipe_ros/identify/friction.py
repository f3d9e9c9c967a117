"""Pressure-dependent static friction (Sec. 4.2, Eq. 18-27) from regulator-held sliding tests.

Each friction test holds the chamber pressures with regulators (Fig. 15; ``regulated: true`` in
``dataset.yaml``) and lets the piston slide from one end stop towards the other while the load
that held it (the hydraulic cylinder, measured by the force sensor: column ``f_load``, or the
entry's constant ``load_force``) is released. Newton's law (Eq. 19) gives the friction force at
each sample,

    F_f = S (p1 - p2) - F_L - M a,

with velocity and acceleration from the zero-phase differentiator (:mod:`.differentiate`), the
pressures smoothed over the same window and M the moving mass of the starting parameters. The
paper reads F_S at the breakaway instant, v_s where the Stribeck dip ends, and F_v, F_C from a
line through the data outside the Stribeck zone (Sec. 4.2.3). Here those readings only start a
joint nonlinear least-squares fit of Eq. 18 (the model's own
:func:`~jetpipe_ros.model.friction.sliding_friction`, scipy.optimize.least_squares) to every
sliding sample, which uses the whole record instead of three points.

That fit reads the velocity from the differentiated position, whose noise (about 1.3 mm/s at
1 kHz with the paper's 15 um sensor, 2.8 mm/s at 200 Hz, where the window holds five samples)
is a fifth of the Stribeck velocity: errors in the regressor bias the Stribeck part (breakaway
and Stribeck velocity 10-25 % off at 200 Hz, up to 30 % on single tests at 1 kHz). Its values
therefore only start an output-error fit (:func:`refine`): the test is replayed on the
regulated rig through the model itself, with those four values, and they are fitted to the
measured position up to the far end stop, where the only noise is the position sensor's. That
leaves each test at the sensor's noise and the planes within a few % at 200 Hz as at 1 kHz.

Entry phase (p2 > p1, v < 0) and exit phase (p1 > p2, v > 0) are fitted apart, each parameter is
fitted over the test pressures, each test weighed by its values' standard errors, with a plane c0 +
c1 p1 + c2 p2 (p in bar, Eq. 20-27; regressors from the model's
:func:`~jetpipe_ros.model.friction.plane_basis`), and the planes' largest relative error over the
tests is reported (the paper: under 5 %).

A test gives parameters only if it slides over a wide enough velocity range to separate the
Stribeck, Coulomb and viscous parts (released progressively, not in one jump); a phase needs
three tests for its planes (at pressures on a line, e.g. one side at atmosphere, the planes'
slope is along the mean pressure only: :func:`fit_planes`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize, signal

from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.identify.differentiate import clear_of_gaps, derivative, window_samples
from jetpipe_ros.identify.experiments import Recording
from jetpipe_ros.model import ModelParams, simulate
from jetpipe_ros.model.friction import plane_basis, sliding_friction
from jetpipe_ros.model.params import FRICTION_PLANES

QUANTITIES = ("breakaway", "stribeck_velocity", "viscous", "coulomb")
PHASES = ("entry", "exit")
#: Differentiation window for velocity and acceleration [s].
WINDOW = 0.021
#: Sliding samples: speed above this [m/s], before reaching within END_MARGIN of the far
#: end stop [m].
MIN_SPEED = 2e-3
END_MARGIN = 1e-3
#: A test must slide over this ratio of highest to lowest speed, with this many samples.
MIN_SPEED_RATIO = 5.0
MIN_SAMPLES = 30
#: The piston's start is read over this span [s]: 20 samples at 1 kHz, four at 200 Hz (a test
#: may break away within 40 ms: 20 samples at 200 Hz had it moving).
START_SPAN = 0.02
#: Stribeck velocities [m/s] the output-error fit also starts from (besides the Newton fit's):
#: its cost has local minima in v_s where the few samples of a slow record's Stribeck zone
#: leave the Newton fit far off; they span the paper's planes (0.004-0.03 m/s).
STRIBECK_STARTS = (0.005, 0.01, 0.02, 0.04)
#: A test determines a quantity when its standard error is within this fraction of its value:
#: the paper's 5 % tolerance on the planes, which a less certain test could not show.
DETERMINED = 0.05


@dataclass
class FrictionTest:
    """The four Eq. 18 parameters of one test (signed as the model uses them: negative forces
    and Stribeck velocity in the entry phase)."""

    name: str
    phase: str  #: entry | exit
    p1_bar: float  #: regulated chamber 1 pressure [bar]
    p2_bar: float  #: regulated chamber 2 pressure [bar]
    values: dict[str, float]  #: quantity -> value [N, m/s, N s/m, N]
    v: np.ndarray  #: sliding velocities [m/s]
    force: np.ndarray  #: friction force of Eq. 19 at those samples [N]
    rms_error: float  #: RMS of Eq. 18 with ``values`` - Eq. 19 force [N]
    rms_position: float  #: RMS of the rig's replay with ``values`` - measured position [m]
    #: quantity -> standard error of its value (the output-error fit's covariance), its unit
    errors: dict[str, float] = field(default_factory=dict)


@dataclass
class FrictionResult:
    """Planes per phase (those with enough tests) and the tests behind them."""

    planes: dict[str, dict[str, list[float]]]  #: phase -> quantity -> [c0, c1, c2]
    tests: list[FrictionTest]
    max_relative_error: dict[str, dict[str, float]]  #: phase -> quantity -> plane error [-]
    skipped: list[str] = field(default_factory=list)  #: tests or phases left out, and why


def friction_force(rec: Recording, params: Mapping[str, Any]
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(velocity [m/s], Eq. 19 friction force [N], sliding mask) of one friction test; the
    mask leaves out the samples whose derivative window reaches over a logger's gap."""
    exp = rec.experiment
    dt = exp.dt
    n = window_samples(WINDOW, dt)
    v = derivative(exp.y, dt, WINDOW)
    a = derivative(exp.y, dt, WINDOW, order=2)
    p1 = signal.savgol_filter(exp.p1, n, 3, mode="interp")
    p2 = signal.savgol_filter(exp.p2, n, 3, mode="interp")
    if exp.f_load is not None:  # an input like u: f_load[k] acts over [t_k, t_k+1), so the
        # load about t_k, where the derivatives are centred, is the mean of the two held there
        load = 0.5 * (exp.f_load + np.r_[exp.f_load[:1], exp.f_load[:-1]])
    else:
        load = np.full(exp.t.size, rec.entry.load_force)
    force = params["chamber.piston_area"] * (p1 - p2) - load - params["mechanics.mass"] * a
    # Up to the first arrival at the far end stop, less half a window of smeared impact.
    direction = sliding_direction(rec)
    stop = arrival(rec, params)
    stop = stop - n // 2 if stop < exp.t.size else stop
    moving = direction * v[:stop] > MIN_SPEED
    # The piston slides without stopping from breakaway on (the released load only grows), so
    # the sliding samples are the last unbroken run; earlier runs are noise on a stuck piston.
    still = np.flatnonzero(~moving)
    start = still[-1] + 1 if still.size else 0
    sliding = np.zeros(exp.t.size, dtype=bool)
    sliding[start:stop] = True
    return v, force, sliding & clear_of_gaps(exp.measured, dt, WINDOW)


def sliding_direction(rec: Recording) -> float:
    """+1 when friction test ``rec`` slides towards +y (chamber 1 the higher pressure on
    average: the exit phase), else -1."""
    exp = rec.experiment
    return 1.0 if np.mean(exp.p1) > np.mean(exp.p2) else -1.0


def arrival(rec: Recording, params: Mapping[str, Any]) -> int:
    """Index of the first sample of a friction test within END_MARGIN of the end stop it
    slides towards (the record's length if it never gets there)."""
    exp = rec.experiment
    direction = sliding_direction(rec)
    arrived = np.flatnonzero(direction * exp.y > 0.5 * params["mechanics.stroke"] - END_MARGIN)
    return int(arrived[0]) if arrived.size else exp.t.size


def rig(rec: Recording, params: ModelParams) -> ModelParams:
    """``params`` as the regulated rig of friction test ``rec`` (the paper's Fig. 15): the
    chamber pressures held at their measured means, the piston at its measured start (the
    median over the record's first START_SPAN), at the record's sample time."""
    exp = rec.experiment
    start = exp.y[:max(1, round(START_SPAN / exp.dt))]
    return params.at_sample_time(exp.dt).with_values({
        "chamber.regulated": True,
        "chamber.initial_pressure_1": float(np.mean(exp.p1)),
        "chamber.initial_pressure_2": float(np.mean(exp.p2)),
        "mechanics.initial_position": float(np.median(start))})


def refine(rec: Recording, phase: str, start: np.ndarray, breakaway: float,
           params: ModelParams) -> tuple[np.ndarray, np.ndarray, float]:
    """Output-error fit of one test's Eq. 18 magnitudes (F_S [N], v_s [m/s], F_v [N s/m],
    F_C [N], all positive) from ``start``: the rig replayed through the model with constant
    planes of ``phase`` set to them, fitted to the measured position (no row filled over a
    logger's gap) from the start of the record to the far end stop. The fit also starts from
    ``breakaway`` [N] (the applied force when the piston began to slide) for F_S and from each
    of STRIBECK_STARTS for v_s, and keeps the best: a start whose F_S the piston never
    reaches, or whose v_s lies in another basin, ends where the cost is flat. Returns the
    fitted magnitudes, their standard errors (the residual's variance times the inverse
    Gauss-Newton matrix: the residual is the position sensor's white noise once the fit is
    right) and the position RMS [m]."""
    exp = rec.experiment
    test_rig = rig(rec, params)
    s = 1.0 if phase == "exit" else -1.0
    load = exp.f_load if exp.f_load is not None else rec.entry.load_force
    compared = (np.arange(exp.t.size) < arrival(rec, params)) & exp.measured

    def residual(x: np.ndarray) -> np.ndarray:
        signed = (s * x[0], s * x[1], x[2], s * x[3])
        trial = test_rig.with_values({f"friction.{phase}.{q}": [v, 0.0, 0.0]
                                      for q, v in zip(QUANTITIES, signed)})
        return simulate(trial, exp.u, load).y[compared] - exp.y[compared]

    lower, upper = np.array([1.0, 1e-4, 0.0, 1.0]), np.array([1e4, 0.5, 1e5, 1e4])
    x0 = np.clip(start, lower, upper)
    fits = [optimize.least_squares(residual, np.clip(np.r_[f_s, v_s, x0[2:]], lower, upper),
                                   bounds=(lower, upper), diff_step=1e-4,
                                   x_scale=np.maximum(x0, [1.0, 1e-3, 10.0, 1.0]))
            for f_s in (x0[0], breakaway) for v_s in (x0[1], *STRIBECK_STARTS)]
    fit = min(fits, key=lambda f: f.cost)
    variance = float(np.sum(fit.fun ** 2)) / max(fit.fun.size - x0.size, 1)
    # diag((J^T J)^-1) from J's singular values; a direction the record does not see (a
    # singular value ~0) makes the parameters along it unknown, not known exactly.
    _, sv, vt = np.linalg.svd(fit.jac, full_matrices=False)
    sv = np.maximum(sv, 1e-9 * sv[0])
    se = np.sqrt(variance * np.sum((vt / sv[:, None]) ** 2, axis=0))
    return fit.x, se, float(np.sqrt(np.mean(fit.fun ** 2)))


def fit_test(rec: Recording, params: ModelParams) -> FrictionTest:
    """Fit Eq. 18 to one friction test; raise DatasetError if it cannot separate the terms."""
    exp = rec.experiment
    p1_bar, p2_bar = float(np.mean(exp.p1)) * 1e-5, float(np.mean(exp.p2)) * 1e-5
    s = sliding_direction(rec)
    phase = "exit" if s > 0 else "entry"
    v, force, sliding = friction_force(rec, params)
    speed, mag = s * v[sliding], s * force[sliding]
    if speed.size < MIN_SAMPLES or speed.max() < MIN_SPEED_RATIO * speed.min():
        span = f"{speed.min():.3g}-{speed.max():.3g} m/s" if speed.size else "none"
        raise DatasetError(
            f"friction: test {rec.name} slides over {speed.size} sample(s), speeds {span}; "
            f"need {MIN_SAMPLES} over a {MIN_SPEED_RATIO:g}x speed range to separate Stribeck, "
            f"Coulomb and viscous friction: release the piston progressively (record the "
            f"ramped load in column f_load)")
    # The paper's readings as the start: a line through the faster half, F_S at the slowest.
    fast = speed > np.median(speed)
    f_v0, f_c0 = np.polyfit(speed[fast], mag[fast], 1)
    slow = speed <= np.quantile(speed, 0.05)
    start = [max(np.median(mag[slow]), f_c0 + 1.0), 0.01, max(f_v0, 1.0), max(f_c0, 1.0)]

    def residual(x: np.ndarray) -> np.ndarray:
        return sliding_friction(speed, *x) - mag

    lower, upper = np.array([0.0, 1e-4, 0.0, 0.0]), np.array([1e4, 0.5, 1e5, 1e4])
    # A direction whose friction fits "the wrong way" (a negative line) starts out of bounds.
    fit = optimize.least_squares(residual, np.clip(start, lower, upper), bounds=(lower, upper),
                                 x_scale="jac")
    first = int(np.argmax(sliding))  # the paper's reading of F_S: the force at breakaway
    load = exp.f_load[first] if exp.f_load is not None else rec.entry.load_force
    applied = s * (params["chamber.piston_area"] * (np.mean(exp.p1) - np.mean(exp.p2)) - load)
    x, se, rms_position = refine(rec, phase, fit.x, applied, params)
    values = dict(zip(QUANTITIES, (s * x[0], s * x[1], x[2], s * x[3])))
    return FrictionTest(name=rec.name, phase=phase, p1_bar=p1_bar, p2_bar=p2_bar,
                        values={k: float(x) for k, x in values.items()}, v=v[sliding],
                        force=force[sliding],
                        rms_error=float(np.sqrt(np.mean(residual(x) ** 2))),
                        rms_position=rms_position,
                        errors={k: float(e) for k, e in zip(QUANTITIES, se)})


def undetermined(test: FrictionTest, quantity: str) -> bool:
    """Whether ``test`` leaves ``quantity`` too uncertain to judge a plane by: a standard
    error over DETERMINED of the value (a low-pressure test whose breakaway barely exceeds
    its Coulomb level cannot place the Stribeck velocity)."""
    return test.errors.get(quantity, 0.0) > DETERMINED * abs(test.values[quantity])


def fit_planes(tests: list[FrictionTest]) -> tuple[dict[str, list[float]], dict[str, float]]:
    """Planes c0 + c1 p1 + c2 p2 of each quantity over ``tests`` and their largest relative
    error over the tests that determine it (:func:`undetermined`; NaN if none does). Each test
    weighs by the inverse of its value's standard error, where the tests give one. Tests whose
    pressures lie on a line (one side at atmosphere, say) fix only the plane's slope along the
    mean pressure (p1 + p2) / 2: it is split equally, c1 = c2; tests at one pressure give a
    constant."""
    p1 = np.array([t.p1_bar for t in tests])
    p2 = np.array([t.p2_bar for t in tests])
    basis = np.column_stack(plane_basis(p1, p2))
    rank = np.linalg.matrix_rank(basis, tol=1e-3)
    mean = 0.5 * (p1 + p2)
    reduced = basis if rank == 3 else (np.column_stack((np.ones(p1.size), mean))
                                       if np.ptp(mean) > 1e-3 else np.ones((p1.size, 1)))
    planes, errors = {}, {}
    for q in QUANTITIES:
        values = np.array([t.values[q] for t in tests])
        se = np.array([t.errors.get(q, 1.0) for t in tests])
        w = 1.0 / np.maximum(se, 1e-9 * np.abs(values) + 1e-12)
        coef, *_ = np.linalg.lstsq(reduced * w[:, None], values * w, rcond=None)
        if reduced.shape[1] == 2:
            coef = np.array([coef[0], 0.5 * coef[1], 0.5 * coef[1]])
        elif reduced.shape[1] == 1:
            coef = np.array([coef[0], 0.0, 0.0])
        planes[q] = [float(c) for c in coef]
        judged = np.array([not undetermined(t, q) for t in tests])
        errors[q] = (float(np.max(np.abs(basis @ coef - values)[judged] / np.abs(values[judged])))
                     if judged.any() else float("nan"))
    return planes, errors


def identify_friction(recs: list[Recording], params: ModelParams,
                      progress: Callable[[str], None] = lambda message: None
                      ) -> FrictionResult:
    """Friction planes of both phases from the friction tests ``recs``, each test's end said
    through ``progress`` (its output-error fit takes about half a second).

    Tests that cannot separate the terms, and phases with fewer than three usable tests, are
    listed in ``skipped``; DatasetError if no phase remains.
    """
    if not recs:
        raise DatasetError("friction: no friction test (piston: free, regulated: true, the "
                           "released load in column f_load) in the dataset")
    tests, skipped = [], []
    for i, rec in enumerate(recs, 1):
        try:
            tests.append(fit_test(rec, params))
        except DatasetError as exc:
            skipped.append(str(exc))
        progress(f"friction: test {i} of {len(recs)} ({rec.name}) fitted")
    planes, errors = {}, {}
    for phase in PHASES:
        mine = [t for t in tests if t.phase == phase]
        if len(mine) < 3:
            skipped.append(f"friction: {phase} phase planes not identified ({len(mine)} usable "
                           f"test(s), need 3 {'p2 > p1' if phase == 'entry' else 'p1 > p2'} "
                           f"tests); keeping the starting planes")
            continue
        planes[phase], errors[phase] = fit_planes(mine)
    if not planes:
        raise DatasetError("; ".join(skipped))
    return FrictionResult(planes=planes, tests=tests, max_relative_error=errors, skipped=skipped)


def paper_planes(phase: str) -> dict[str, list[float]]:
    """Eq. 20-23 (entry) or Eq. 24-27 (exit) as quantity -> [c0, c1, c2]."""
    return {q: list(FRICTION_PLANES[phase][q]) for q in QUANTITIES}
