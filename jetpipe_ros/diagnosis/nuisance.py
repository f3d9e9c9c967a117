"""Calibration knobs the training records leave free where the held-out ones depend on them.

The diagnosis fits everything on the training experiments and judges it on the held-out ones.
That is fair only when the training records pin whatever the held-out predictions depend on.
Records with fewer sensors may not: without pressure sensors nothing in the default campaign's
training experiments pins the chambers' dead volumes (the locked-piston charge tests that do
are left out: they have no position to compare), while the held-out 3 V square drives the
piston into its end stops, where the dead volumes set how fast it leaves them. Fitted to the
training records alone, such a knob lands anywhere its range allows (chamber 1's dead volume
at 1.73 times nominal for a truth of 1.03 on a position-only record of an actuator with nothing
but its parameters off), and every model compared then misses the held-out data by where it
landed: a gap of 3.5 % that no effect causes, answered as an effect or `unlisted`.

Such directions are *nuisance parameters*: they must be fitted, but the question asked of the
held-out data (does an effect generalise?) is not about them. :func:`directions` finds them
after the recalibration: with the knobs' covariance from the training records (their Jacobian
at the recalibration, against the noise a model that fits them would leave, as
:func:`fit.uncertainty` has it) and the hardware's spread as a prior
(:data:`calibration.SPREAD`), the directions along which one posterior standard deviation moves
the held-out predictions by more than the sensors' noise (their normalised mean square, the
noise floor's) are the ones the training leaves the held-out data to decide. At most
:data:`MOST` of them, the largest first, are then fitted on all records, training and held-out,
in every fit of the calibration knobs (:func:`fit.fit`): alike for every model compared, so no
candidate wins or loses on them. A few knobs fitted on thousands of samples cost the held-out
judgement little; a knob left where the training put it costs it everything.

Records with both chamber pressures pin every direction on the default campaign (the largest
held-out effect of one posterior standard deviation is a tenth of the noise), and nothing changes
for them.
"""

from __future__ import annotations

import numpy as np

from jetpipe_ros.diagnosis.calibration import CALIBRATION, SPREAD
from jetpipe_ros.diagnosis.data import Prepared
from jetpipe_ros.diagnosis.fit import Fit, jacobian
from jetpipe_ros.diagnosis.score import effective_samples, predict_all, residual_vector
from jetpipe_ros.model import ModelParams

#: Most directions fitted on all records: each costs the held-out judgement one piece of its
#: evidence (one prediction window of one signal, tens of them on the default campaign).
MOST = 3
#: Step of the Jacobian's central differences, in the unit-scaled knobs.
STEP = 0.01


def directions(prepared: Prepared, nominal: ModelParams,
               recalibrated: Fit) -> tuple[np.ndarray | None, dict]:
    """The nuisance directions of the recalibration ``recalibrated`` (a fit of the calibration
    knobs alone) on ``prepared``: columns in the natural logs of the knobs' factors, each one
    posterior standard deviation long (None when there are none), and what diagnosis.json
    reports of them (``calibration.nuisance``)."""
    knobs = [k.name for k in CALIBRATION.knobs]
    z0 = recalibrated.z
    train = calibration_jacobian(prepared, nominal, z0, "train")
    held = calibration_jacobian(prepared, nominal, z0, "holdout")
    noise = max(recalibrated.train.noise_total, 1e-300)
    information = effective_samples(recalibrated.train, prepared.dt) / noise * train.T @ train
    prior = np.diag([1.0 / SPREAD[k] ** 2 for k in knobs])
    posterior = np.linalg.inv(information + prior)
    root = np.linalg.cholesky(0.5 * (posterior + posterior.T))
    moved, vectors = np.linalg.eigh(root.T @ (held.T @ held) @ root)
    order = np.argsort(moved)[::-1]
    threshold = max(recalibrated.holdout.noise_total, 1e-300)
    chosen = [j for j in order[:MOST] if moved[j] > threshold]
    columns = [root @ vectors[:, j] for j in chosen]
    report = {
        "fitted_on": "all records",
        "directions": [
            {"heldout_over_noise": float(moved[j] / threshold),
             "knobs": {k: float(v) for k, v in zip(knobs, col)
                       if abs(v) >= 0.3 * float(np.max(np.abs(col)))}}
            for j, col in zip(chosen, columns)],
        "largest_heldout_over_noise": float(moved[order[0]] / threshold),
    }
    return (np.column_stack(columns) if columns else None), report


def words(report: dict) -> str | None:
    """The nuisance directions in words (None when there are none)."""
    found = report["directions"]
    if not found:
        return None
    knobs = ", ".join(dict.fromkeys(k for d in found for k in d["knobs"]))
    return (f"the training records leave {len(found)} direction{'s' if len(found) > 1 else ''}"
            f" of the calibration knobs free (mostly {knobs}) that the held-out predictions "
            f"depend on (one standard deviation moves them by up to "
            f"{found[0]['heldout_over_noise']:.0f} times the sensors' noise): fitted on all "
            f"records, alike in every model compared")


def calibration_jacobian(prepared: Prepared, nominal: ModelParams, z: np.ndarray,
                         role: str | None) -> np.ndarray:
    """d(residuals of the ``role`` samples, all for None) / d(ln factor) of each calibration
    knob at the unit-scaled knobs ``z`` (:func:`fit.jacobian`)."""

    def residuals(at: np.ndarray) -> np.ndarray:
        params = CALIBRATION.apply(nominal, CALIBRATION.values(at))
        return residual_vector(prepared, predict_all(params, prepared, role), role)

    return jacobian(residuals, z, STEP) / CALIBRATION.log_slopes()[None, :]
