"""Seal friction from friction-rig records: the model's friction forms fitted and judged.

A friction rig drives the rod along x(t) with one chamber at pressure p and the other at
atmosphere (:mod:`jetpipe_ros.dataset.friction_rig`). Each form of the model's friction is
evaluated along that motion by the model's own
:func:`~jetpipe_ros.model.friction.prescribed_friction` (velocity from the zero-phase
Savitzky-Golay derivative of x, the dynamic forms' state integrated from it), with planes built
from a few physically bounded parameters per direction of motion (exit: v > 0, entry: v < 0):

- the sliding level |F_C| = a + b (p1 + p2 - 2 p_atm) [N] (p in bar): one chamber pressure
  fixes only the sum c1 + c2 of a plane, split equally, so the level grows with the mean
  pressure on the seal; b is held at 0 when the records of a seal share one pressure;
- the breakaway F_S = r F_C with 0.2 <= r <= 2 (r < 1: no Stribeck dip, friction rising with
  speed), a Stribeck velocity v_s and a viscous F_v, constant over pressure;
- ``lugre``: a bristle stiffness sigma_0 (no damping); ``maxwell_slip``: the pre-sliding
  displacement delta and the spread of three elements;
- a bore profile (:func:`fit_profile`): factors on each direction's level at knots
  :data:`KNOT_SPACING` apart along the travelled positions, for the forms whose friction along a
  prescribed motion is linear in the level (:data:`PROFILE_FORMS`), fitted by ridge least
  squares between two fits of the other parameters.

The actuator's own friction tests (a dataset's free-piston tests with the chamber pressures held
by regulators and the piston released progressively, Sec. 4.2, both pressures measured) are
records too (:func:`prepare_test`): their friction is Newton's law, Eq. 19, as
``jetpipe identify`` computes it (:func:`~jetpipe_ros.identify.friction.friction_force`), over
the slide from breakaway to the far end stop, whose first ``split`` is fitted and the rest
judged. Such a test moves one way; the other direction's parameters come from the other tests.

``coulomb_viscous`` (r = 1) and ``static`` (Eq. 18) have no state. Records of one seal (field
``seal``) are fitted each on its first part (``split``), as the paper fits each test, and
combined over pressure into the seal's planes (:func:`combine`, then refined by a joint fit of
the seal's records); a ``role: holdout`` record is
not fitted and is predicted by the seal's planes. Every record is judged on its held-out part,
on moving samples (speed above :data:`MIN_SPEED`, the velocity's window clear of the logger's
gaps). The form selected is the one with the lowest median held-out NRMSE, among the static
forms unless records reverse in their fitted and judged parts (:func:`select`). What the fit
could not use is said (:meth:`SealResult.warnings`): a record with no moving sample in its
fitted part, a direction in which no fitted sample moves. How far the seal's planes carry to a
record they did not see (a pressure not recorded, a repeat) is judged too: each training
record's held-out part by the selected form's seal fit made without it (:func:`unseen_fit`,
:meth:`SealResult.judge_unseen`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize, signal

from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.dataset.friction_rig import RigRecord
from jetpipe_ros.identify.differentiate import clear_of_gaps, derivative, window_samples
from jetpipe_ros.identify.experiments import Recording
from jetpipe_ros.identify.friction import WINDOW as TEST_WINDOW
from jetpipe_ros.identify.friction import friction_force
from jetpipe_ros.model.flow import P_ATM
from jetpipe_ros.model.friction import (BREAKAWAY, COULOMB, LEVEL_FLOOR, LUGRE, MAXWELL_SLIP,
                                        STATIC, STRIBECK, VISCOUS, element_slips,
                                        prescribed_friction, presliding_displacement)
from jetpipe_ros.model.params import MAX_KNOTS, PROFILE_HIGH, PROFILE_LOW, ModelParams

FORMS = ("coulomb_viscous", "static", "lugre", "maxwell_slip")
STATIC_FORMS = FORMS[:2]
#: Least travel the velocity's zero-phase derivative spans [m], at the record's median moving
#: speed: what :data:`WINDOW` covers at the twelve public records' median speed (8 mm/s). A
#: slow rig's velocity is small against the same position noise, so it is averaged longer:
#: copies of three public records at half the speed were missed by a median 4.1 % with 0.1 s
#: against 2.6 % as recorded (held-out NRMSE, the shipped fit), with this travel 2.6 %.
WINDOW_TRAVEL = 8e-4
#: Shortest window of the velocity [s] (chosen on the twelve public records: docs/friction.md),
#: and the one the record's speed is first measured with.
WINDOW = 0.1
#: Fewest samples of the window: a cubic Savitzky-Golay derivative over 5 samples passes the
#: position's noise to the velocity with twice the gain of the 0.1 s window at 100 Hz (47.5
#: against 24.6 per second at 50 Hz), over 7 with the same (25.6): 50 Hz copies of three public
#: records (Maxwell-slip, held-out NRMSE) were missed by 2.9-4.1 % with 5 against 1.9-3.3 % at
#: 100 Hz, by 1.9-3.1 % with 7.
MIN_WINDOW_SAMPLES = 7
#: Moving samples: speed above this [m/s].
MIN_SPEED = 1e-3
#: Maxwell-slip elements fitted.
ELEMENTS = 3
#: Records of one seal whose mean pressures span less than this [bar] share one pressure.
MIN_PRESSURE_SPAN = 0.5
DIRECTIONS = ("exit", "entry")
#: Least swing of the friction across a reversal counted as one [N] (the measured pre-sliding),
#: for levels above it; for a seal whose levels are below it, the larger level: alone, 1 N had
#: skipped every reversal of a copy of the public PK records with its friction divided by 20.
MIN_SWING = 1.0
#: Evaluations of the joint fit of a seal's records that refines their combined fits.
SEAL_NFEV = 40
#: Forms fitted with a bore profile: along a prescribed motion their friction is linear in the
#: levels (the Maxwell-slip elements' deflections do not depend on them; LuGre's bristle does).
PROFILE_FORMS = ("coulomb_viscous", "static", "maxwell_slip")
#: Spacing of the bore profile's knots [m] (chosen by leave-one-seal-out: docs/friction.md).
KNOT_SPACING = 1e-3
#: Ridge prior of the profile: a knot's factor is pulled to 1 as if by this many samples at
#: the level, so a knot few samples reach stays near 1 (leave-one-seal-out: docs/friction.md).
PROFILE_PRIOR = 3.0
#: The profile is fitted on samples at least this far [m] past the last reversal (where the
#: records' friction has reached its level, as :func:`measured_presliding` takes it), so it does
#: not absorb the pre-sliding build-up at the stroke's ends, where a rig always reverses.
SETTLED = 3e-3
#: A profile needs the training samples to pass the same positions this many times in each
#: direction: along a single pass the position is confounded with the speed and the time (an
#: actuator's friction test slides once), so the factors would take the Stribeck curve's shape.
MIN_PASSES = 2
#: Fewest held-out moving samples [rows] a record is judged on.
MIN_JUDGED = 10
#: Evaluations of the refit of the other parameters with the profile held.
PROFILE_NFEV = 60

#: Per direction: level a [N], slope b [N/bar], ratio r = F_S/F_C, v_s [m/s], F_v [N s/m].
_PER_DIRECTION = (("level", -1e3, 1e4), ("slope", -1e3, 1e3), ("ratio", 0.2, 2.0),
                  ("stribeck_velocity", 1e-4, 0.05), ("viscous", 0.0, 1e4))
#: Dynamic parameters, fitted as log10: sigma_0 [N/m]; delta [m], spread [-].
_DYNAMIC = {"lugre": (("bristle_stiffness", 2.0, 8.0),),
            "maxwell_slip": (("presliding_displacement", -5.0, math.log10(5e-3)),
                             ("presliding_spread", -2.0, 0.0))}


@dataclass
class ActuatorTest:
    """A friction test of the actuator's own dataset, described as a rig record is."""

    name: str  #: experiment name
    file: str  #: CSV file name
    seal: str  #: the actuator (records of one seal are fitted together)
    role: str | None  #: train | holdout | None, from dataset.yaml
    t: np.ndarray  #: time [s]
    x: np.ndarray  #: piston position [m]
    valid: np.ndarray  #: bool: a measured row (False where the logger lost it)

    @property
    def dt(self) -> float:
        """Sample time [s]."""
        return float(self.t[1] - self.t[0])


@dataclass
class Prepared:
    """A record with what the fit needs: velocity, pressures, train and test masks."""

    record: RigRecord | ActuatorTest
    v: np.ndarray  #: velocity [m/s]
    p1: np.ndarray  #: chamber 1 pressure, or the rig's chamber [Pa]
    p2: np.ndarray  #: chamber 2 pressure, or the rig's other side: atmosphere [Pa]
    friction: np.ndarray  #: measured friction [N]
    train: np.ndarray  #: bool: fitted samples
    test: np.ndarray  #: bool: judged samples (held out, moving)

    @property
    def pressure(self) -> float:
        """The pressure the seal's level follows [Pa absolute]: the mean of p1 + p2 - p_atm
        over the fitted samples (the rig's chamber pressure when the other side is at
        atmosphere), over all samples if none is fitted."""
        m = self.train if self.train.any() else np.ones(self.p1.size, dtype=bool)
        return float(np.mean(self.p1[m] + self.p2[m])) - P_ATM

    def describe_pressure(self) -> str:
        """The record's pressures in words: the rig's chamber in bar gauge, or both of an
        actuator's chambers in bar absolute."""
        if isinstance(self.record, RigRecord):
            return f"{(self.pressure - P_ATM) * 1e-5:.1f} bar gauge"
        return f"p1 {np.mean(self.p1) * 1e-5:.2f}, p2 {np.mean(self.p2) * 1e-5:.2f} bar"

    def moves(self, direction: str) -> bool:
        """True when the fitted samples move in ``direction`` (exit: v > 0, entry: v < 0)."""
        sign = 1.0 if direction == "exit" else -1.0
        return bool(np.any(self.train & (sign * self.v > 0)))


def no_profile() -> np.ndarray:
    """The empty bore profile (3, 0): every factor 1."""
    return np.zeros((3, 0))


@dataclass
class FormFit:
    """One form fitted to one seal's records."""

    form: str
    values: dict[str, float]  #: named parameters (per direction: ``exit.level`` ...)
    planes: np.ndarray  #: (2, 4, 3) friction planes, the model's layout
    sigma0: float  #: LuGre stiffness [N/m] (form lugre)
    slips: np.ndarray  #: Maxwell-slip slip displacements [m] (form maxwell_slip)
    #: bore profile (3, K): knots [m, the records' position], exit and entry factors
    profile: np.ndarray = field(default_factory=no_profile)

    def predict(self, prep: Prepared, profile: np.ndarray | None = None) -> np.ndarray:
        """Modelled friction [N] along a prepared record (with ``profile`` instead of the
        fit's own if given)."""
        return prescribed_friction(_KERNEL_FORM[self.form], self.planes,
                                   self.profile if profile is None else profile, prep.v,
                                   prep.record.x, prep.p1, prep.p2, prep.record.dt,
                                   self.sigma0, 0.0, self.slips, LEVEL_FLOOR)

    def params(self, base: ModelParams, centre: float = 0.0, scale: float = 1.0,
               keep: tuple[str, ...] = ()) -> ModelParams:
        """``base`` with this fit's planes (held at the rig's floor, :data:`LEVEL_FLOOR`, not
        the paper's), its bore profile (knots shifted by ``-centre`` [m]: the records' position
        that becomes the model's y = 0) and, for a dynamic form, its friction_dynamics. Its
        forces (breakaway, viscous and Coulomb planes, LuGre's stiffness) are multiplied by
        ``scale``: a seal's friction grows with its circumference, its lengths (v_s, the
        pre-sliding displacements) do not. The phases in ``keep`` (``entry``, ``exit``) keep
        ``base``'s planes: a direction the records never fitted."""
        planes = self.planes.copy()
        planes[:, [BREAKAWAY, VISCOUS, COULOMB]] *= scale
        changes: dict[str, Any] = {"friction.floor": LEVEL_FLOOR}
        if self.profile.shape[1]:
            changes["friction.profile.position"] = [float(k - centre) for k in self.profile[0]]
            changes["friction.profile.exit"] = [float(f) for f in self.profile[1]]
            changes["friction.profile.entry"] = [float(f) for f in self.profile[2]]
        for phase, i in (("entry", 0), ("exit", 1)):
            if phase in keep:
                continue
            for q, row in (("breakaway", BREAKAWAY), ("stribeck_velocity", STRIBECK),
                           ("viscous", VISCOUS), ("coulomb", COULOMB)):
                changes[f"friction.{phase}.{q}"] = [float(c) for c in planes[i, row]]
        params = base.with_values(changes)
        if self.form == "lugre":
            params = params.with_effect("friction_dynamics", form="lugre",
                                        bristle_stiffness=scale * self.sigma0,
                                        bristle_damping=0.0)
        elif self.form == "maxwell_slip":
            params = params.with_effect(
                "friction_dynamics", form="maxwell_slip",
                presliding_displacement=self.values["presliding_displacement"],
                presliding_spread=self.values["presliding_spread"], elements=ELEMENTS)
        return params

    @property
    def presliding(self) -> float:
        """Displacement after a reversal [m] to 90 % of the swing between the sliding levels
        (Maxwell-slip: :func:`presliding_displacement`; LuGre: 3 g / sigma_0 at the mean
        level; NaN for the static forms)."""
        if self.form == "maxwell_slip":
            return presliding_displacement(self.slips)
        if self.form == "lugre":
            level = np.mean([abs(self.planes[i, 3, 0] + 2 * self.planes[i, 3, 1])
                             for i in (0, 1)])
            return float(math.log(20.0) * level / self.sigma0)
        return math.nan


_KERNEL_FORM = {"coulomb_viscous": STATIC, "static": STATIC, "lugre": LUGRE,
                "maxwell_slip": MAXWELL_SLIP}


def velocity_window(record: RigRecord) -> float:
    """The velocity's window [s]: :data:`WINDOW_TRAVEL` at the record's median moving speed
    (measured over :data:`WINDOW`), :data:`WINDOW` and :data:`MIN_WINDOW_SAMPLES` samples at
    least; no longer than that for a record too short or too still to measure a speed on."""
    shortest = MIN_WINDOW_SAMPLES * record.dt
    first = max(WINDOW, shortest)
    if record.t.size < 4 * window_samples(first, record.dt):
        return first
    v = np.abs(derivative(record.x, record.dt, first))
    moving = record.valid & (v > MIN_SPEED)
    if not moving.any():
        return first
    return max(WINDOW_TRAVEL / float(np.median(v[moving])), first)


def prepare(record: RigRecord, split: float = 0.5) -> Prepared:
    """Velocity and masks of one record: train = the first ``split`` of a non-holdout record,
    test = the rest (all of a holdout record); both moving samples with a clean window."""
    window = velocity_window(record)
    n = window_samples(window, record.dt)
    if record.t.size < 4 * n:
        raise DatasetError(f"{record.file}: {record.t.size} samples, need at least {4 * n} "
                           f"(four {window:g} s velocity windows)")
    v = derivative(record.x, record.dt, window)
    clean = clear_of_gaps(record.valid, record.dt, window)
    clean[:n] = clean[-n:] = False
    moving = clean & (np.abs(v) > MIN_SPEED)
    check_dissipates(record, v, moving)
    check_pressure_side(record)
    cut = int(split * record.t.size) if record.role != "holdout" else 0
    first = np.arange(record.t.size) < cut
    return Prepared(record=record, v=v, p1=record.p, p2=np.full(record.t.size, P_ATM),
                    friction=record.friction, train=moving & first, test=moving & ~first)


def check_dissipates(record: RigRecord, v: np.ndarray, moving: np.ndarray) -> None:
    """Refuse a record whose friction gives the rod power instead of taking it: a seal only
    dissipates, so in the contract's convention (F - (p - p_atm) A, positive in the direction
    of motion) the mean of friction times velocity [W] over the moving samples is positive.
    Negative, the position, the force or the side the pressure acts on was logged with the
    other sign. On the twelve public records the friction is along the motion on 99 % of the
    moving samples and the mean power +0.03-0.10 W; with the position's sign flipped, 0.5 %
    and -0.05 W, and every form's fit missed by half the friction's range. DatasetError
    naming the file."""
    if not moving.any():
        return
    power = float(np.mean(record.friction[moving] * v[moving]))
    if power <= 0.0:
        along = float(np.mean(np.sign(record.friction[moving]) == np.sign(v[moving])))
        raise DatasetError(
            f"{record.file}: the friction F - (p - p_atm) A gives the rod power instead of "
            f"taking it (mean friction x velocity {power:+.3g} W over {int(moving.sum())} "
            f"moving samples; along the motion on {along:.0%} of them): a seal only "
            f"dissipates, so x, F or the side the pressure acts on is logged with the other "
            f"sign than the contract's (friction = F - (p - p_atm) A, positive in the direction "
            f"of motion; docs/friction.md)")


#: Least mean gauge pressure [Pa] at which the pressure's force is large enough to tell which
#: way the force counts (0.1 bar: 4.9 N on the public records' 25 mm bore).
MIN_GAUGE = 1e4


def check_pressure_side(record: RigRecord) -> None:
    """Refuse a record whose friction outweighs the pressure's force on average: the load cell
    reads the pressure's force and the seal's, F = (p - p_atm) A + friction, and a seal's
    friction averaged over its strokes is a few per cent of that force (2-3 % on the twelve
    public records, 1-7 bar gauge). With the position and the force both logged with the other
    sign (a rig whose positive direction is the other way) the power check passes (both signs
    turn round), but F - (p - p_atm) A is then -(2 (p - p_atm) A + friction): its mean -2
    times the pressure's force, and every form's fit missed by eight times the friction's
    range. So the mean friction beyond the pressure's force itself is a sign, not a seal.
    Records near atmospheric pressure (under :data:`MIN_GAUGE`) cannot tell. DatasetError
    naming the file."""
    push = (record.p[record.valid] - P_ATM) * record.area
    if float(np.mean(push)) < MIN_GAUGE * record.area:
        return
    ratio = float(np.mean(record.friction[record.valid])) / float(np.mean(push))
    if abs(ratio) > 1.0:
        raise DatasetError(
            f"{record.file}: the friction F - (p - p_atm) A averages {ratio:+.2f} times the "
            f"pressure's force (p - p_atm) A, where a seal's is a few per cent of it: F (and x "
            f"with it, or the power check would have refused it) is logged with the other sign "
            f"than the contract's, or the pressure acts on the other side of the piston "
            f"(friction = F - (p - p_atm) A, positive in the direction of motion; "
            f"docs/friction.md)")


def prepare_test(rec: Recording, params: ModelParams, split: float = 0.5) -> Prepared:
    """A friction test of the actuator's own dataset as a record: friction from Eq. 19
    (:func:`~jetpipe_ros.identify.friction.friction_force`, with the piston area and moving
    mass of ``params``), pressures smoothed over the same window; train = the first ``split``
    of the slide (none for a ``role: holdout`` test), test = the rest. DatasetError naming the
    experiment when it does not slide."""
    exp = rec.experiment
    v, force, sliding = friction_force(rec, params)
    slide = np.flatnonzero(sliding & (np.abs(v) > MIN_SPEED))
    if slide.size < 20:
        raise DatasetError(f"{rec.entry.file}: the piston slides for {slide.size} samples "
                           f"faster than {MIN_SPEED * 1e3:g} mm/s; a friction test needs 20")
    n = window_samples(TEST_WINDOW, exp.dt)
    p1, p2 = (signal.savgol_filter(x, n, 3, mode="interp") for x in (exp.p1, exp.p2))
    cut = slide[0] + int(split * slide.size) if rec.entry.role != "holdout" else 0
    first = np.arange(exp.t.size) < cut
    moving = np.zeros(exp.t.size, dtype=bool)
    moving[slide] = True
    record = ActuatorTest(name=rec.name, file=rec.entry.file, seal="", role=rec.entry.role,
                          t=exp.t, x=exp.y, valid=np.ones(exp.t.size, dtype=bool))
    return Prepared(record=record, v=v, p1=p1, p2=p2, friction=force,
                    train=moving & first, test=moving & ~first)


def _names(form: str) -> list[str]:
    return [f"{d}.{q}" for d in DIRECTIONS for q, _, _ in _PER_DIRECTION] + \
        [q for q, _, _ in _DYNAMIC.get(form, ())]


def parameter_bounds(form: str) -> dict[str, tuple[float, float, bool]]:
    """The range each parameter of ``form`` is fitted in, by name, in the units of
    :attr:`FormFit.values`, and whether it is fitted as its log10 (the dynamic ones)."""
    lo, hi = _bounds(form)
    dynamic = {q for q, _, _ in _DYNAMIC.get(form, ())}
    return {name: (10.0 ** a, 10.0 ** b, True) if name in dynamic else (float(a), float(b), False)
            for name, a, b in zip(_names(form), lo, hi)}


def _bounds(form: str) -> tuple[np.ndarray, np.ndarray]:
    spans = [(lo, hi) for _ in DIRECTIONS for _, lo, hi in _PER_DIRECTION] + \
        [(lo, hi) for _, lo, hi in _DYNAMIC.get(form, ())]
    return np.array([s[0] for s in spans]), np.array([s[1] for s in spans])


def planes_of(values: dict[str, float]) -> np.ndarray:
    """The model's (2, 4, 3) planes [entry, exit] x [F_S, v_s, F_v, F_C] x [c0, c1, c2] of
    named parameters: |F_C| = level + slope (p1 + p2 - 2 bar), F_S = ratio F_C."""
    planes = np.zeros((2, 4, 3))
    for i, direction, sign in ((1, "exit", 1.0), (0, "entry", -1.0)):
        a, b = values[f"{direction}.level"], values[f"{direction}.slope"]
        coulomb = sign * np.array([a - 2.0 * b, b, b])
        planes[i, 3] = coulomb
        planes[i, 0] = values[f"{direction}.ratio"] * coulomb
        planes[i, 1, 0] = sign * values[f"{direction}.stribeck_velocity"]
        planes[i, 2, 0] = values[f"{direction}.viscous"]
    return planes


def _build(form: str, theta: np.ndarray, profile: np.ndarray | None = None) -> FormFit:
    """The fit of parameter vector ``theta`` (dynamic parameters as log10) and ``profile``."""
    values = dict(zip(_names(form), (float(x) for x in theta)))
    for name, _, _ in _DYNAMIC.get(form, ()):
        values[name] = 10.0 ** values[name]
    return _from_values(form, values, profile)


def _from_values(form: str, values: dict[str, float],
                 profile: np.ndarray | None = None) -> FormFit:
    """The fit of named parameters (SI units) and a bore profile (none if None)."""
    if form == "coulomb_viscous":
        values["exit.ratio"] = values["entry.ratio"] = 1.0
    slips = np.zeros(0)
    if form == "maxwell_slip":
        slips = element_slips(values["presliding_displacement"], values["presliding_spread"],
                              ELEMENTS)
    return FormFit(form=form, values=values, planes=planes_of(values),
                   sigma0=values.get("bristle_stiffness", 0.0), slips=slips,
                   profile=no_profile() if profile is None else profile)


def _start(form: str, preps: list[Prepared], attempt: int) -> np.ndarray:
    """A generic start from the data's levels (medians of the training friction per
    direction), never from a fitted answer; later attempts move the dynamic part."""
    theta = []
    for sign in (1.0, -1.0):
        level = [np.median(sign * p.friction[p.train & (sign * p.v > 0)]) for p in preps
                 if np.any(p.train & (sign * p.v > 0))]
        theta += [float(np.median(level)) if level else 1.0, 0.0, 1.0, 5e-3, 0.0]
    dynamic = {"bristle_stiffness": [4.5, 3.5, 6.0][attempt % 3],
               "presliding_displacement": [-3.3, -3.8, -2.8][attempt % 3],
               "presliding_spread": [-1.0, -0.5, -1.5][attempt % 3]}
    theta += [dynamic[q] for q, _, _ in _DYNAMIC.get(form, ())]
    return np.array(theta)


def fit_form(form: str, preps: list[Prepared], what: str, attempts: int = 3,
             start: FormFit | None = None, max_nfev: int = 200,
             profile: bool = True) -> FormFit:
    """Fit ``form`` to the training samples of one seal's prepared records (least squares on
    the friction [N]); a start outside the bounds is clipped into them, and a failed or
    non-finite fit retried from another start. The first attempt starts from ``start`` if
    given (the seal's records' fits combined), the others from the data's levels. With
    ``profile``, a form of :data:`PROFILE_FORMS` then gets a bore profile
    (:func:`fit_profile`), its other parameters are refitted with the profile held, and the
    profile is fitted again. DatasetError naming the seal's records if no attempt succeeds
    (``what`` names them: the record or the seal)."""
    lo, hi = _bounds(form)
    free = np.ones(lo.size, dtype=bool)
    pressures = [p.pressure * 1e-5 for p in preps if p.train.any()]
    if not pressures:
        raise DatasetError(f"{what}: no moving training samples (role: holdout, or the rod "
                           f"never moves faster than {MIN_SPEED * 1e3:g} mm/s)")
    names = _names(form)
    trained = [p for p in preps if p.train.any()]
    for i, name in enumerate(names):
        fixed_slope = name.endswith(".slope") and \
            max(pressures) - min(pressures) < MIN_PRESSURE_SPAN
        # A direction no training sample moves in (an actuator's test slides one way) has
        # nothing to fit: its parameters keep their start.
        unseen = any(name.startswith(f"{d}.") and not any(p.moves(d) for p in trained)
                     for d in DIRECTIONS)
        if fixed_slope or unseen or (form == "coulomb_viscous" and name.endswith(
                (".ratio", ".stribeck_velocity"))):
            free[i] = False
    error = "no attempt"
    for attempt in range(attempts):
        if start is not None and attempt == 0:
            dynamic = {q for q, _, _ in _DYNAMIC.get(form, ())}
            held = np.array([math.log10(start.values[n]) if n in dynamic else start.values[n]
                             for n in names])
        else:
            held = _start(form, trained, attempt)
        held = np.clip(held, lo, hi)
        theta, error = _least_squares(form, trained, held, free, lo, hi, max_nfev)
        if theta is None:
            continue
        fit = _build(form, theta)
        if not profile or form not in PROFILE_FORMS:
            return fit
        shape = fit_profile(fit, trained)
        refit, _ = _least_squares(form, trained, theta, free, lo, hi, PROFILE_NFEV, shape)
        fit = _build(form, theta if refit is None else refit, shape)
        return _normalised(_build(form, theta if refit is None else refit,
                                  fit_profile(fit, trained)))
    raise DatasetError(f"{what}: the {form} friction fit failed: {error}")


class _Levels:
    """The fit's coordinates of each direction's level line |F_C| = a + b g (g = p1 + p2 -
    2 p_atm [bar]): with the slope free, the levels at the lowest and highest g the training
    samples reach, each held at :data:`LEVEL_FLOOR` or more, so the line stays on its physical
    side over the records' pressures. The kernel holds a level under the floor at the floor,
    where the friction no longer depends on it: a fit that crossed it would stop there (a
    Coulomb level at 0 and its friction left to the viscous term), and its numbers would read
    as a negative friction. With the slope held, the level's lower bound keeps the line above
    the floor at both ends. The other parameters are the fit's own."""

    def __init__(self, form: str, trained: list[Prepared], free: np.ndarray) -> None:
        gauge = np.concatenate([(p.p1 + p.p2 - 2 * P_ATM)[p.train] for p in trained]) * 1e-5
        self.ends = (float(np.min(gauge)), float(np.max(gauge)))
        names = _names(form)
        pairs = [(names.index(f"{d}.level"), names.index(f"{d}.slope")) for d in DIRECTIONS]
        self.lines = [(i, j) for i, j in pairs if free[i] and free[j]
                      and self.ends[1] - self.ends[0] >= MIN_PRESSURE_SPAN]
        self.held = [(i, j) for i, j in pairs if free[i] and not free[j]]

    def to_fit(self, theta: np.ndarray) -> np.ndarray:
        """Parameter vector -> the fit's coordinates."""
        x = theta.copy()
        for i, j in self.lines:
            x[i], x[j] = theta[i] + theta[j] * self.ends[0], theta[i] + theta[j] * self.ends[1]
        return x

    def from_fit(self, x: np.ndarray) -> np.ndarray:
        """The fit's coordinates -> parameter vector."""
        theta = x.copy()
        for i, j in self.lines:
            theta[j] = (x[j] - x[i]) / (self.ends[1] - self.ends[0])
            theta[i] = x[i] - theta[j] * self.ends[0]
        return theta

    def bounds(self, theta: np.ndarray, lo: np.ndarray, hi: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """The fit's bounds: ``lo``/``hi`` with each level line's ends, or a held slope's
        level, kept at the floor or more (``theta`` gives the held slopes)."""
        lo, hi = lo.copy(), hi.copy()
        for i, j in self.lines:
            lo[i] = lo[j] = LEVEL_FLOOR
            hi[j] = hi[i]
        for i, j in self.held:
            lo[i] = max(lo[i], LEVEL_FLOOR - min(theta[j] * g for g in self.ends))
        return lo, hi


def _least_squares(form: str, trained: list[Prepared], held: np.ndarray, free: np.ndarray,
                   lo: np.ndarray, hi: np.ndarray, max_nfev: int,
                   profile: np.ndarray | None = None) -> tuple[np.ndarray | None, str]:
    """The parameter vector fitted from ``held`` (its ``free`` entries within ``lo``-``hi``,
    each level line above the floor over the training pressures: :class:`_Levels`, the others
    held) with the bore ``profile`` held, or None and why it failed."""
    levels = _Levels(form, trained, free)
    lo, hi = levels.bounds(held, lo, hi)
    start = levels.to_fit(held)

    def residual(x: np.ndarray) -> np.ndarray:
        coords = start.copy()
        coords[free] = x
        fit = _build(form, levels.from_fit(coords), profile)
        return np.concatenate([(fit.predict(p) - p.friction)[p.train] for p in trained])

    try:
        sol = optimize.least_squares(residual, np.clip(start[free], lo[free], hi[free]),
                                     bounds=(lo[free], hi[free]), x_scale="jac",
                                     max_nfev=max_nfev)
    except (ValueError, FloatingPointError) as exc:
        return None, str(exc)
    # Status 0 (evaluations used up) keeps the best point reached: still a fit.
    if sol.status >= 0 and np.all(np.isfinite(sol.fun)):
        coords = start.copy()
        coords[free] = sol.x
        return levels.from_fit(coords), ""
    return None, sol.message if sol.status < 0 else "non-finite residuals"


def passes(preps: list[Prepared]) -> tuple[int, int]:
    """Passes (exit, entry) of the training samples of ``preps``: runs of moving samples in
    one direction, a run ending where the direction changes."""
    counts = [0, 0]
    for p in preps:
        sign = np.sign(p.v[p.train])
        if sign.size:
            starts = np.concatenate([[0], np.flatnonzero(sign[1:] != sign[:-1]) + 1])
            counts[0] += int(np.sum(sign[starts] > 0))
            counts[1] += int(np.sum(sign[starts] < 0))
    return counts[0], counts[1]


def _normalised(fit: FormFit) -> FormFit:
    """``fit`` with each direction's profile factors divided by their mean over the knots and
    its level (a and b) multiplied by it: the same friction, the level the mean over the
    positions travelled and the profile a ripple about 1."""
    if not fit.profile.shape[1]:
        return fit
    values, profile = dict(fit.values), fit.profile.copy()
    for row, direction in ((1, "exit"), (2, "entry")):
        mean = float(np.mean(profile[row]))
        profile[row] = np.clip(profile[row] / mean, PROFILE_LOW, PROFILE_HIGH)
        values[f"{direction}.level"] *= mean
        values[f"{direction}.slope"] *= mean
    return _from_values(fit.form, values, profile)


def _hat(x: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """(x.size, K) weights of linear interpolation between ``knots`` at ``x`` (held beyond
    the ends), as :func:`~jetpipe_ros.model.friction.level_factors` interpolates."""
    xc = np.clip(x, knots[0], knots[-1])
    j = np.clip(np.searchsorted(knots, xc) - 1, 0, knots.size - 2)
    w = (xc - knots[j]) / (knots[j + 1] - knots[j])
    out = np.zeros((x.size, knots.size))
    out[np.arange(x.size), j] = 1.0 - w
    out[np.arange(x.size), j + 1] = w
    return out


def fit_profile(fit: FormFit, preps: list[Prepared], spacing: float = KNOT_SPACING,
                prior: float = PROFILE_PRIOR, settled: float = SETTLED) -> np.ndarray:
    """The bore profile (3, K) of ``fit``'s form over the training samples of ``preps`` at
    least ``settled`` [m] past the last reversal (or before the first), the other parameters
    held: knots about ``spacing`` [m] apart over the positions travelled
    (at most :data:`~jetpipe_ros.model.params.MAX_KNOTS`), each direction's factors by least
    squares on the friction [N] with a ridge of ``prior`` samples at the direction's level
    pulling each factor to 1, clipped to the parameters' range. Along a prescribed motion the
    form's friction is F = f_exit(x) E + f_entry(x) N + R (``fit``'s prediction with one
    direction's level only, and with neither), so the factors are linear. No profile (3, 0)
    when the records travel less than two knot spacings, or pass fewer than
    :data:`MIN_PASSES` times each way."""
    if min(passes(preps)) < MIN_PASSES:
        return no_profile()
    masks = [p.train & ~(np.abs(since_reversal(p.record.x, p.v)) < settled) for p in preps]
    xs = np.concatenate([p.record.x[m] for p, m in zip(preps, masks)])
    if xs.size < 2 or np.ptp(xs) < 2.0 * spacing:
        return no_profile()
    knots = np.linspace(xs.min(), xs.max(),
                        min(MAX_KNOTS, int(round(np.ptp(xs) / spacing)) + 1))
    one = np.array([[xs.min()], [1.0], [0.0]])
    rows, rhs = [], []
    levels = np.zeros(2)
    for p, m in zip(preps, masks):
        exit_only, entry_only, neither = (fit.predict(p, one), fit.predict(p, one[[0, 2, 1]]),
                                          fit.predict(p, one[[0, 2, 2]]))
        basis = _hat(p.record.x[m], knots)
        e, n, r = (exit_only - neither)[m], (entry_only - neither)[m], neither[m]
        rows.append(np.hstack([e[:, None] * basis, n[:, None] * basis]))
        rhs.append(p.friction[m] - e - n - r)
        levels += [np.sum(np.abs(e)), np.sum(np.abs(n))]
    levels /= xs.size
    k = knots.size
    ridge = math.sqrt(prior) * np.diag(np.repeat(np.maximum(levels, 1e-9), k))
    delta = np.linalg.lstsq(np.vstack([*rows, ridge]),
                            np.concatenate([*rhs, np.zeros(2 * k)]), rcond=None)[0]
    factors = np.clip(1.0 + delta, PROFILE_LOW, PROFILE_HIGH)
    return np.vstack([knots, factors[:k], factors[k:]])


def judge(prep: Prepared, fit: FormFit) -> dict[str, float]:
    """:func:`scores` of ``fit`` on the record's held-out moving samples."""
    return scores(prep.friction[prep.test], fit.predict(prep)[prep.test], prep.v[prep.test])


def scores(measured: np.ndarray, model: np.ndarray, v: np.ndarray) -> dict[str, float]:
    """NRMSE (RMS error over the measured range), R^2, R^2 within each direction of motion
    (what the sign flip between directions does not explain) and pooled over both, and the
    sample count, of friction [N] ``model`` against ``measured`` at velocities ``v``."""
    err = model - measured
    out = {"samples": float(measured.size),
           "nrmse": float(np.sqrt(np.mean(err ** 2)) / np.ptp(measured)),
           "r2": float(1.0 - np.sum(err ** 2) / np.sum((measured - measured.mean()) ** 2))}
    sse = sst = 0.0
    for direction, sign in zip(DIRECTIONS, (1.0, -1.0)):
        m = sign * v > 0
        if m.sum() < 3:
            out[f"r2_{direction}"] = math.nan
            continue
        e, s = np.sum(err[m] ** 2), np.sum((measured[m] - measured[m].mean()) ** 2)
        out[f"r2_{direction}"] = float(1.0 - e / s)
        sse, sst = sse + e, sst + s
    out["r2_within"] = float(1.0 - sse / sst) if sst > 0 else math.nan
    return out


def measured_presliding(prep: Prepared, fraction: float = 0.9) -> np.ndarray:
    """Displacement [m] after each reversal of a record at which the measured friction has
    covered ``fraction`` of its swing from the level before the reversal (median over the last
    2 mm before it) to the level after (median over 3-5 mm after it); reversals whose
    transition lies in a logger's gap, or whose friction swings by less than
    :data:`MIN_SWING` or, for a seal whose levels are below it, the larger of the two levels
    (a true reversal swings by about their sum), are skipped."""
    x, f, v, ok = prep.record.x, prep.friction, prep.v, prep.record.valid
    out = []
    turns = reversals(v)
    for k, end in zip(turns, [*turns[1:], x.size]):
        sign = 1.0 if v[k] > 0 else -1.0
        u = sign * (x - x[k])
        before = np.arange(max(0, k - 400), k)
        before = before[u[before] > -2e-3]
        after = np.arange(k, end)
        level_after = after[(u[after] > 3e-3) & (u[after] < 5e-3)]
        if before.size < 3 or level_after.size < 3:
            continue
        f0, f1 = np.median(f[before]), np.median(f[level_after])
        if sign * (f1 - f0) < min(MIN_SWING, max(abs(f0), abs(f1))):
            continue
        reached = after[sign * (f[after] - f0) >= fraction * sign * (f1 - f0)]
        if reached.size and ok[max(0, k - 3):reached[0] + 2].all():
            out.append(float(u[reached[0]]))
    return np.array(out)


def combine(form: str, fits: list[FormFit], preps: list[Prepared]) -> FormFit:
    """One seal's fit over pressure from its records' fits (``fits[i]`` of ``preps[i]``, at
    its :attr:`Prepared.pressure`: the paper's route from tests to planes, Sec. 4.2.3): per
    direction a line of the level over the pressure (its slope 0 when the pressures span less
    than :data:`MIN_PRESSURE_SPAN`) through the records that move that way, the other
    parameters' medians over them; the bore profile of a single record's fit."""
    values = {}
    for name in fits[0].values:
        direction = name.split(".")[0]
        judged = [f for f, p in zip(fits, preps) if direction not in DIRECTIONS
                  or p.moves(direction)] or fits
        values[name] = float(np.median([f.values[name] for f in judged]))
    for direction in DIRECTIONS:
        moving = [(f, p) for f, p in zip(fits, preps) if p.moves(direction)] or \
            list(zip(fits, preps))
        gauge = np.array([(p.pressure - P_ATM) * 1e-5 for _, p in moving])
        levels = np.array([f.values[f"{direction}.level"] for f, _ in moving])
        if np.ptp(gauge) >= MIN_PRESSURE_SPAN:
            slope, level = np.polyfit(gauge, levels, 1)
        else:
            slope, level = 0.0, float(np.mean(levels))
        values[f"{direction}.level"], values[f"{direction}.slope"] = float(level), float(slope)
    # One record: its profile; several: the joint fit that refines this one fits theirs.
    return _from_values(form, values, fits[0].profile if len(fits) == 1 else None)


@dataclass
class SealResult:
    """Every form fitted to one seal's records, judged, and the one selected."""

    seal: str
    preps: list[Prepared]
    per_record: dict[str, dict[str, FormFit]]  #: form -> record name -> its own fit
    seal_fits: dict[str, FormFit]  #: form -> the seal's fit over pressure
    scores: dict[str, dict[str, dict[str, float]]]  #: form -> record name -> metrics
    selected: str
    #: training records (not ``role: holdout``) with no moving sample in their fitted part,
    #: left out of the fit and judged with the seal's fit, by file
    left_out: tuple[str, ...] = ()
    #: directions in which no fitted sample moves: their planes are not fitted (the starting
    #: parameters' are written, :func:`jetpipe_ros.identify.seal_report.params_yaml`)
    unfitted: tuple[str, ...] = ()
    #: the selected form's fit of the seal made without each training record
    #: (:func:`unseen_fit`), by record name; empty with one training record
    unseen_fits: dict[str, FormFit] = field(default_factory=dict)
    #: each of those records' held-out scores with it (:meth:`judge_unseen`), by record name
    unseen: dict[str, dict[str, float]] = field(default_factory=dict)

    def judge_unseen(self, fits: dict[str, FormFit]) -> None:
        """Keep the selected form's fits made without each training record ``fits`` (record
        name -> :func:`unseen_fit`) and score each record's held-out samples with its own
        (:func:`scores`): the samples its own fit is judged on, so the two scores compare how
        far the seal's fit carries to a record it did not see (another pressure, a repeat)."""
        self.unseen_fits = dict(fits)
        self.unseen = {p.record.name: judge(p, fits[p.record.name]) for p in self.preps
                       if p.record.name in fits and p.test.sum() >= MIN_JUDGED}

    def unseen_from_one_pressure(self) -> list[str]:
        """The records judged by a fit made without them whose other training records all sit
        at one pressure (within :data:`MIN_PRESSURE_SPAN`), another than theirs: that fit holds
        the level of that pressure (slope 0, :func:`combine`), a guess at theirs."""
        trained = {p.record.name: (p.pressure - P_ATM) * 1e-5 for p in self.preps
                   if p.record.name in self.per_record[self.selected]}
        out = []
        for name in self.unseen:
            others = [g for n, g in trained.items() if n != name]
            if (others and np.ptp(others) < MIN_PRESSURE_SPAN
                    and abs(trained[name] - others[0]) >= MIN_PRESSURE_SPAN):
                out.append(name)
        return out

    def model_of(self, form: str, prep: Prepared) -> FormFit:
        """The fit that predicts a record: its own, or the seal's for a held-out record."""
        return self.per_record[form].get(prep.record.name, self.seal_fits[form])

    def warnings(self, split: float) -> list[str]:
        """What the fit could not use, in words: records left out, directions not fitted."""
        out = [f"{file}: no moving sample in its first {split:g} (the rod still, or in a "
               f"logger's gap there): left out of the fit, judged with the seal's fit"
               for file in self.left_out]
        out += [f"{direction} direction ({'v > 0' if direction == 'exit' else 'v < 0'}): no "
                f"fitted sample moves that way, so its planes are not fitted; the starting "
                f"parameters' are written" for direction in self.unfitted]
        parts = without_reversal(self.preps)
        if parts:
            out.append(f"no record reverses its motion in "
                       f"{' nor in '.join(f'its {part} part' for part in parts)}: the dynamic "
                       f"forms ({', '.join(f for f in FORMS if f not in STATIC_FORMS)}), "
                       f"whose pre-sliding shows after a reversal, are not selectable")
        return out


def training(seal: str, preps: list[Prepared], split: float = 0.5) -> list[Prepared]:
    """The records of one seal that have moving training samples; DatasetError naming the seal
    and its files if none has, or if no record has :data:`MIN_JUDGED` held-out moving samples
    (nothing to judge the forms on)."""
    trained = [p for p in preps if p.train.any()]
    files = ", ".join(p.record.file for p in preps)
    if not trained:
        raise DatasetError(f"{f'seal {seal}: ' if seal else ''}no moving training samples in "
                           f"{files} (all role: holdout, or the rod never moves faster than "
                           f"{MIN_SPEED * 1e3:g} mm/s; split {split:g})")
    if not any(p.test.sum() >= MIN_JUDGED for p in preps):
        raise DatasetError(f"{f'seal {seal}: ' if seal else ''}no held-out moving samples in "
                           f"{files} (split {split:g})")
    return trained


def fit_seal_form(seal: str, form: str, trained: list[Prepared]
                  ) -> tuple[dict[str, FormFit], FormFit]:
    """``form`` fitted to each of one seal's training records alone (record name -> fit), and
    the seal's fit over pressure: the records' fits combined (:func:`combine`) and, with
    several records, refined by one fit of them all. One task of :func:`identify_seal`, which
    the command runs in parallel."""
    own = {p.record.name: fit_form(form, [p], p.record.file) for p in trained}
    return own, over_pressure(seal, form, trained, own)


def over_pressure(seal: str, form: str, trained: list[Prepared], own: dict[str, FormFit]
                  ) -> FormFit:
    """The seal's fit of ``form`` over pressure from its training records ``trained`` and
    their own fits ``own`` (record name -> fit): combined (:func:`combine`) and, with several
    records, refined by one fit of them all."""
    fit = combine(form, [own[p.record.name] for p in trained], trained)
    if len(trained) > 1:
        # One set of planes for all the seal's pressures, refined from the combination.
        fit = fit_form(form, trained, seal or "seal", start=fit, max_nfev=SEAL_NFEV)
    return fit


def unseen_fit(seal: str, form: str, trained: list[Prepared], own: dict[str, FormFit],
               name: str) -> FormFit:
    """The seal's fit of ``form`` over pressure made without the record ``name`` (the other
    training records and their own fits ``own``): what predicts a record at a pressure, or in
    a repeat, the fit never saw. At least two training records."""
    return over_pressure(seal, form, [p for p in trained if p.record.name != name], own)


def identify_seal(seal: str, preps: list[Prepared], split: float = 0.5,
                  fitted: dict[str, tuple[dict[str, FormFit], FormFit]] | None = None
                  ) -> SealResult:
    """Fit every form to each training record of one seal (prepared with its first ``split``
    fitted), combine them over pressure (:func:`fit_seal_form`; ``fitted`` gives those fits,
    form -> its result, when they were made elsewhere), judge each record's held-out samples
    with its own fit (a ``role: holdout`` record with the seal's), and select a form
    (:func:`select`)."""
    trained = training(seal, preps, split)
    if fitted is None:
        fitted = {form: fit_seal_form(seal, form, trained) for form in FORMS}
    per_record = {form: fitted[form][0] for form in FORMS}
    seal_fits = {form: fitted[form][1] for form in FORMS}
    judged: dict[str, dict[str, dict[str, float]]] = {}
    for form in FORMS:
        judged[form] = {}
        for p in preps:
            if p.test.sum() >= MIN_JUDGED:
                judged[form][p.record.name] = judge(
                    p, per_record[form].get(p.record.name, seal_fits[form]))
    left_out = tuple(p.record.file for p in preps
                     if p.record.role != "holdout" and p not in trained)
    unfitted = tuple(d for d in DIRECTIONS if not any(p.moves(d) for p in trained))
    return SealResult(seal=seal, preps=preps, per_record=per_record, seal_fits=seal_fits,
                      scores=judged, selected=select(judged, preps), left_out=left_out,
                      unfitted=unfitted)


def select(judged: dict[str, dict[str, dict[str, float]]], preps: list[Prepared]) -> str:
    """The form with the lowest median held-out NRMSE over the records; only the static forms
    unless a record reverses its motion in its fitted part and one in its judged part
    (:func:`reverses`): pre-sliding and frictional memory show after a reversal, so without
    one fitted the dynamic forms' parameters are not identified, and without one judged their
    scores measure nothing they add (two records cut to their first 5 s, one stroke each
    fitted: LuGre had been selected at 71 % held-out NRMSE)."""
    forms = FORMS if not without_reversal(preps) else STATIC_FORMS
    return min(forms, key=lambda form: float(np.median(
        [s["nrmse"] for s in judged[form].values()])))


def without_reversal(preps: list[Prepared]) -> list[str]:
    """The parts (``fitted``, ``judged``) in which no record of a seal reverses its motion."""
    return [part for part, mask in (("fitted", "train"), ("judged", "test"))
            if not any(reverses(p, getattr(p, mask)) for p in preps)]


def reverses(prep: Prepared, samples: np.ndarray | None = None) -> bool:
    """True when the record's moving samples (those of ``samples``, a mask: default fitted
    and judged) go both ways (a reversal the dynamic forms' pre-sliding shows after)."""
    moving = prep.train | prep.test if samples is None else samples
    return bool(np.any(prep.v[moving] > 0) and np.any(prep.v[moving] < 0))


def reversals(v: np.ndarray) -> np.ndarray:
    """Indices where the velocity ``v`` changes sign (each the first sample after it)."""
    return np.flatnonzero(np.sign(v[1:]) != np.sign(v[:-1])) + 1


def since_reversal(x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Displacement since the last reversal [m], signed as the motion: x minus x where the
    velocity ``v`` last changed sign (NaN before the first reversal)."""
    out = np.full(x.size, math.nan)
    turns = reversals(v)
    for k, end in zip(turns, [*turns[1:], x.size]):
        out[k:end] = x[k:end] - x[k]
    return out
