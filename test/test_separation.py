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
    nominal = ModelParams()
    spec = presliding_experiment(nominal, DT)
    bristles = _run(nominal.with_effect("friction_dynamics", bristle_stiffness=1e5,
                                        bristle_damping=0.0), spec)
    # Deflection ~ force / stiffness: about 20 N / 1e5 N/m = 0.2 mm, ten times the position
    # sensor's noise (15 um).
    assert 1e-4 < np.ptp(bristles.y) < 5e-4
    force = AREA * (bristles.p1 - bristles.p2)
    assert np.ptp(bristles.y) == pytest.approx(np.ptp(force) / 1e5, rel=0.05)


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


def test_an_effect_that_explains_what_the_recalibration_leaves_is_the_answer():
    """The data prefer pre-sliding in place of a breakaway lowered by 40 %: the answer is the
    effect on the recalibration with those knobs back at nominal, judged as decide() judges."""
    from jetpipe_ros.diagnosis.calibration import CALIBRATION, NAME
    from jetpipe_ros.diagnosis.separation import StandIn, adopt
    from jetpipe_ros.diagnosis.verdict import rank

    knobs = {k.name: 1.0 for k in CALIBRATION.knobs}
    rng = np.random.default_rng(0)
    recal = _fit((NAME,), {NAME: {**knobs, "friction_entry": 0.6}}, 0.48,
                 1.0 + 0.1 * rng.random(20))
    bristles = {"bristle_stiffness": 3e4, "bristle_damping": 20.0}
    swap = _fit((NAME, "friction_dynamics"), {NAME: knobs, "friction_dynamics": bristles}, 0.23,
                recal.holdout_windows - 0.5)
    (ranked,) = rank([swap], recal.holdout, recal.holdout_windows, 1e-3)
    assert ranked.explains
    row = {"effect": "friction_dynamics", "candidate": "friction_dynamics",
           "knob_words": ["entry-phase breakaway and Coulomb friction"], "holdout_gap": 0.23,
           "recalibrated_gap": 0.48, "t_recalibration": -5.0, "shrinkage": ranked.shrinkage,
           "preferred": "effect", "separating_experiment": None}
    settled = adopt(StandIn(row, swap, ranked))
    assert settled.final is swap and settled.calibrated and not settled.unlisted
    assert settled.verdict.winner.fit.effect == "friction_dynamics"
    # shrinkage 1 - 0.23/0.48 = 52 %, margin ln(0.48/0.23)/ln(4) = 0.53
    assert settled.verdict.confidence == pytest.approx(
        (1 - 0.23 / 0.48) * np.log(0.48 / 0.23) / np.log(4.0), rel=1e-6)
    assert "the data prefer the effect, which removes 52%" in settled.reason
