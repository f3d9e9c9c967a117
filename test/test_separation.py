"""Telling explanations apart: the pre-sliding test, which knobs may stand in for which effect,
and the stand-in rows' words."""

import numpy as np
import pytest

from jetpipe_ros.campaign import signals
from jetpipe_ros.diagnosis.separation import (PRESLIDING_MARGIN, moved_knobs,
                                              presliding_experiment, suspects, words)
from jetpipe_ros.model import ModelParams, simulate
from jetpipe_ros.model.actuator import build_constants
from jetpipe_ros.model.friction import friction_parameters

DT = 1e-3
AREA = 0.005433  # piston area S [m^2], docs/model.md


def _run(params, spec):
    quiet = params.with_values({"sensors.noise": False})
    return simulate(quiet, spec.command(DT).voltage)


def test_the_presliding_test_stays_just_below_breakaway():
    nominal = ModelParams()
    spec = presliding_experiment(nominal, DT)
    assert spec is not None and spec.kind == "open_loop" and not spec.locked
    amplitude = spec.voltage.args["amplitude"]
    trace = _run(nominal, spec)
    assert np.ptp(trace.y) == 0.0  # stuck
    # The largest amplitude that keeps it stuck is MARGIN below: a little above it slides.
    critical = amplitude / PRESLIDING_MARGIN
    quiet = nominal.with_values({"sensors.noise": False})
    triangle = lambda a: simulate(quiet, signals.triangle(  # noqa: E731
        DT, spec.duration, a, spec.voltage.args["frequency"]))
    assert np.ptp(triangle(1.05 * critical).y) > 1e-6
    # Independently: at the critical amplitude the pneumatic force peaks at the breakaway force
    # of Eq. 15 at those pressures (the friction planes, docs/model.md).
    stuck = triangle(critical)
    force = AREA * (stuck.p1 - stuck.p2)
    k = int(np.argmax(np.abs(force)))
    f_s = friction_parameters(build_constants(nominal).planes, np.sign(force[k]),
                              stuck.p1[k], stuck.p2[k])[0]
    assert abs(force[k]) == pytest.approx(abs(f_s), rel=0.05)


def test_the_presliding_test_shows_bristles_a_lower_breakaway_does_not():
    # The two explanations the test separates: a recalibration that lowered the breakaway and
    # Coulomb friction by 30 %, and the nominal friction with pre-sliding bristles. Designed
    # below the lowered breakaway, the test leaves the first stuck and deflects the second.
    nominal = ModelParams()
    lower = nominal.with_values({f"friction.{ph}.{q}": [0.7 * c for c in nominal[
        f"friction.{ph}.{q}"]] for ph in ("entry", "exit") for q in ("breakaway", "coulomb")})
    spec = presliding_experiment(lower, DT)
    assert spec.voltage.args["amplitude"] < presliding_experiment(nominal, DT).voltage.args[
        "amplitude"]
    assert np.ptp(_run(lower, spec).y) == 0.0
    bristles = _run(nominal.with_effect("friction_dynamics", bristle_stiffness=1e5,
                                        bristle_damping=0.0), spec)
    # Deflection ~ force / stiffness (no creep below breakaway): about 0.1 mm, several times
    # the position sensor's noise (15 um).
    assert np.ptp(bristles.y) > 5e-5
    force = AREA * (bristles.p1 - bristles.p2)
    assert np.ptp(bristles.y) == pytest.approx(np.ptp(force) / 1e5, rel=0.05)


def test_the_presliding_test_shows_a_real_seals_maxwell_slip_at_its_typical_size():
    """The friction_dynamics:maxwell_slip candidate at its typical size (delta 0.56 mm, the
    records' median) moves the piston in the designed pre-sliding test by 0.1-0.2 mm, over
    six times the position sensor's noise (15 um), where the nominal model stays put; where
    the candidate vanishes (delta 2 um) it moves by under a fifth of that noise."""
    from jetpipe_ros.diagnosis.candidates import CANDIDATES

    nominal = ModelParams()
    spec = presliding_experiment(nominal, DT)
    seal = CANDIDATES["friction_dynamics:maxwell_slip"]
    assert np.ptp(_run(nominal, spec).y) == 0.0
    assert 1e-4 < np.ptp(_run(seal.apply(nominal, seal.typical), spec).y) < 2e-4
    assert np.ptp(_run(seal.apply(nominal, seal.values(seal.start())), spec).y) < 3e-6


def test_stand_ins_follow_the_direction_of_the_move():
    se = {k: 0.01 for k in ("friction_entry", "friction_exit", "flow_gain_charge",
                             "dead_volume_1", "valve_gain")}
    moved = moved_knobs({"friction_entry": 0.66, "friction_exit": 1.3,
                         "flow_gain_charge": 0.9, "dead_volume_1": 1.2, "valve_gain": 1.015},
                        se)
    assert "valve_gain" not in moved  # 1.5 %: below what the report names
    found = suspects(moved, already=[])
    assert found == {"friction_dynamics": ["friction_entry"],
                     "valve_hysteresis": ["friction_exit"],
                     "supply_pressure": ["flow_gain_charge"]}  # a larger volume: no thermal
    # A move within three standard errors is no move; an effect already modelled no suspect.
    assert moved_knobs({"friction_entry": 0.8}, {"friction_entry": 0.1}) == {}
    assert suspects({"friction_entry": 0.66}, already=["friction_dynamics"]) == {}


def test_stand_in_words_say_what_to_do():
    row = {"candidate": "friction_dynamics", "effect": "friction_dynamics",
           "knob_words": ["entry-phase breakaway and Coulomb friction"], "holdout_gap": 0.32,
           "recalibrated_gap": 0.32, "t_recalibration": 0.1, "preferred": "cannot tell",
           "separating_experiment": {"experiment": "stick_slip", "in_dataset": True,
                                     "designed": False, "difference_over_noise": 5.6}}
    text = words(row)
    assert "cannot tell them apart" in text and "'role: holdout'" in text
    # Already held out, the experiment is not to be marked so again: a longer run of it is.
    row["separating_experiment"] = {**row["separating_experiment"], "held_out": True}
    text = words(row)
    assert "'role: holdout'" not in text and "longer or repeated held-out run" in text
    row["separating_experiment"] = {**row["separating_experiment"], "in_dataset": False,
                                    "designed": True, "experiment": "presliding_triangle"}
    assert "recording the experiment 'presliding_triangle' (designed for this" in words(row)
    row["preferred"] = "recalibration"
    assert "the data prefer the recalibration" in words(row)


def _fit(groups, values, gap, windows):
    """A fit with held-out error ``gap`` [%] beyond noise (one signal, unit noise variance)."""
    from jetpipe_ros.diagnosis.calibration import group
    from jetpipe_ros.diagnosis.fit import Fit
    from jetpipe_ros.diagnosis.score import Score

    held = Score({"y": 1e-4 + (gap / 100.0) ** 2}, {"y": 1e-4}, {"y": 1000})
    z = np.concatenate([group(g).to_unit(values[g]) for g in groups])
    return Fit(tuple(groups), values, z, ModelParams(), held, held, np.asarray(windows), 1, 0.0)


class _Fitter:
    """Stands in for the diagnosis's Fitter: every job gets the same prepared fit."""

    def __init__(self, fit):
        self.fit, self.jobs = fit, []

    def run(self, jobs, labels=None):
        self.jobs += list(jobs)
        return [self.fit for _ in jobs]


def _stand_in(effect_gap, shift):
    """stand_ins() on a recalibration that lowered the entry-phase breakaway by 40 % (held-out
    gap 0.48 %), with pre-sliding friction in its place leaving ``effect_gap`` and per-window
    errors ``shift`` from the recalibration's (each with its own scatter)."""
    from types import SimpleNamespace

    from jetpipe_ros.diagnosis.calibration import CALIBRATION, NAME
    from jetpipe_ros.diagnosis.separation import stand_ins

    knobs = {k.name: 1.0 for k in CALIBRATION.knobs}
    rng = np.random.default_rng(0)
    windows = 1.0 + 0.1 * rng.random(20)
    recal = _fit((NAME,), {NAME: {**knobs, "friction_entry": 0.6}}, 0.48, windows)
    bristles = {"bristle_stiffness": 3e4, "bristle_damping": 20.0}
    effect = _fit(("friction_dynamics:lugre",), {"friction_dynamics:lugre": bristles}, effect_gap,
                  windows + shift + 0.05 * rng.standard_normal(windows.size))
    fitter = _Fitter(effect)
    stderr = {k: 0.01 for k in knobs}
    rows = stand_ins(fitter, SimpleNamespace(dt=DT), ModelParams(), recal, stderr,
                     lambda _: None)
    return recal, fitter, rows


def test_an_effect_that_explains_what_the_recalibration_leaves_is_the_answer():
    """stand_ins() fits pre-sliding in place of a breakaway lowered by 40 %, with that knob back
    at nominal; the data prefer it (it explains what the recalibration leaves, significantly),
    and adopt() makes it the answer with the confidence decide() would give."""
    from jetpipe_ros.diagnosis.calibration import NAME
    from jetpipe_ros.diagnosis.separation import adopt
    from jetpipe_ros.diagnosis.verdict import confidence_of

    recal, fitter, rows = _stand_in(0.23, -0.5)
    # Only the move beyond three standard errors is suspect; the effect is fitted on the
    # recalibration with that knob back at nominal, once per form of the effect.
    assert [job.groups for job in fitter.jobs] == [("friction_dynamics:lugre",),
                                                   ("friction_dynamics:maxwell_slip",)]
    assert all(job.base["friction.entry.breakaway"] == ModelParams()["friction.entry.breakaway"]
               for job in fitter.jobs)
    (swap,) = rows
    row = swap.row
    assert (row["effect"], row["knobs"], row["preferred"]) == (
        "friction_dynamics", ["friction_entry"], "effect")
    assert row["holdout_gap"] == pytest.approx(0.23) and row["recalibrated_gap"] == pytest.approx(
        0.48)
    assert row["shrinkage"] == pytest.approx(1 - 0.23 / 0.48)
    assert np.isfinite(row["t_recalibration"]) and row["t_recalibration"] < -3.0
    assert swap.fit.groups == (NAME, "friction_dynamics:lugre")
    assert swap.fit.values[NAME]["friction_entry"] == 1.0  # back at nominal
    assert row["separating_experiment"] is None
    settled = adopt(swap)
    assert settled.final is swap.fit and settled.calibrated and not settled.unlisted
    assert settled.verdict.winner.fit.effect == "friction_dynamics"
    assert settled.verdict.confidence == confidence_of(swap.ranked, swap.ranked.base_gap)
    assert 0.0 < settled.verdict.confidence < 1.0
    assert "the data prefer the effect, which removes 52%" in settled.reason


def test_a_recalibration_the_held_out_data_prefer_is_kept():
    # The same, with pre-sliding in the knob's place leaving more (0.70 % against 0.48 %):
    # the recalibration is preferred and nothing is adopted.
    _, _, rows = _stand_in(0.70, +0.5)
    (swap,) = rows
    assert swap.row["preferred"] == "recalibration" and swap.row["t_recalibration"] > 3.0
    assert not swap.ranked.explains
