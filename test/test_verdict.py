"""The decision rules of the diagnosis on constructed rankings (no fitting): effects, pairs,
and which of calibration and effect the data need."""

from types import SimpleNamespace

import numpy as np
import pytest

from jetpipe_ros.diagnosis.calibration import CALIBRATION
from jetpipe_ros.diagnosis.candidates import CANDIDATES
from jetpipe_ros.diagnosis.fit import Fit
from jetpipe_ros.diagnosis.score import Score
from jetpipe_ros.diagnosis.verdict import decide, left_out, paired_t, rank, settle
from jetpipe_ros.model import ModelParams

FLOOR = 1e-4


def score(gap_pct):
    """A one-signal score whose gap is ``gap_pct`` above a noise floor of 1e-4."""
    return Score(mse={"p1": FLOOR + (gap_pct / 100) ** 2}, noise={"p1": FLOOR},
                 count={"p1": 20000})


def fit(name, gap_pct, windows, **values):
    """A fit of the candidates in ``name`` at their typical sizes (``values``: others, by
    candidate)."""
    groups = tuple(name.split("+"))
    values = {g: {k.name: CANDIDATES[g].typical.get(k.name, k.off) for k in CANDIDATES[g].knobs}
              | values.get(g, {}) for g in groups if g != "calibration"}
    if "calibration" in groups:
        values["calibration"] = (CALIBRATION.values(CALIBRATION.start())
                                 | {"flow_gain_charge": 0.9, "friction_exit": 1.3})
    return Fit(groups=groups, values=values, z=np.zeros(len(groups)), params=ModelParams(),
               train=score(gap_pct), holdout=score(gap_pct),
               holdout_windows=np.asarray(windows, dtype=float), evaluations=1, seconds=0.0)


def windows(level, rng, n=20, jitter=1e-5):
    return level + jitter * rng.standard_normal(n)


@pytest.fixture
def rng():
    return np.random.default_rng(0)


def test_paired_t_sees_a_consistent_improvement(rng):
    before = windows(2e-3, rng)
    assert paired_t(before, before - 1e-3) > 1e6
    assert paired_t(before, windows(1e-3, rng)) > 10
    assert abs(paired_t(before, before + 1e-6 * rng.standard_normal(20))) < 3


def test_clear_winner_is_named_with_high_confidence(rng):
    nom = windows(FLOOR + 4e-4, rng)
    fits = [fit("valve_lag:first_order", 0.2, windows(FLOOR + 1e-5, rng)),
            fit("valve_delay", 1.2, windows(FLOOR + 1.5e-4, rng)),
            fit("thermal:polytropic", 2.0, nom)]
    v = decide(rank(fits, score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.winner.fit.name == "valve_lag:first_order" and not v.ambiguous
    assert v.confidence > 0.85


def test_two_equal_explanations_are_ambiguous(rng):
    nom = windows(FLOOR + 4e-4, rng)
    fits = [fit("valve_lag:first_order", 0.50, windows(FLOOR + 2e-5, rng)),
            fit("valve_delay", 0.55, windows(FLOOR + 2.2e-5, rng))]
    v = decide(rank(fits, score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.ambiguous and v.runner_up.fit.name == "valve_delay"
    assert v.confidence < 0.2


def test_noise_level_gap_with_no_significant_fit_is_none(rng):
    nom = windows(FLOOR, rng, jitter=3e-5)
    fits = [fit("valve_lag:first_order", 0.05, nom + 2e-5 * rng.standard_normal(20))]
    v = decide(rank(fits, score(0.1), nom, 1e-3), score(0.1), nom, None)
    assert v.winner is None and "within what sensor noise explains" in v.reason


def test_a_small_gap_an_effect_explains_beyond_noise_is_named_and_called_small(rng):
    # A 0.3 % gap (under the 0.5 % bar), an effect removing most of it with significance: named
    # (on the nominal or a recalibrated base alike), its reason saying the gap is small.
    base = windows(FLOOR + 9e-6, rng, jitter=1e-6)
    fits = [fit("valve_delay", 0.1, windows(FLOOR + 1e-6, rng, jitter=1e-6))]
    ranking = rank(fits, score(0.3), base, 1e-3)
    assert ranking[0].explains
    v = decide(ranking, score(0.3), base, None)
    assert v.winner.fit.name == "valve_delay"
    assert "a small gap (under the 0.5 % at which it shows" in v.reason
    # The same gap, an effect whose removal is within the windows' noise: nothing named.
    noisy = windows(FLOOR + 9e-6, rng, jitter=2e-5)
    fits = [fit("valve_delay", 0.1, noisy - 8e-6 + 3e-5 * rng.standard_normal(20))]
    ranking = rank(fits, score(0.3), noisy, 1e-3)
    assert not ranking[0].explains
    v = decide(ranking, score(0.3), noisy, None)
    assert v.winner is None and "within what sensor noise explains" in v.reason
    # A gap beyond noise: named without the word.
    big = windows(FLOOR + 4e-4, rng)
    fits = [fit("valve_delay", 0.2, windows(FLOOR + 1e-5, rng))]
    v = decide(rank(fits, score(2.0), big, 1e-3), score(2.0), big, None)
    assert v.winner.fit.name == "valve_delay" and "small" not in v.reason


def test_unexplained_gap_is_none_naming_the_reason(rng):
    nom = windows(FLOOR + 4e-4, rng)
    fits = [fit("leakage:laminar", 1.8, windows(FLOOR + 3.2e-4, rng))]  # 10 % of the gap: too little
    v = decide(rank(fits, score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.winner is None and "not among the candidates" in v.reason


def test_a_pair_must_remove_clearly_more_than_its_better_member(rng):
    nom = windows(FLOOR + 4e-4, rng)
    single = fit("thermal:polytropic", 0.80, windows(FLOOR + 6.4e-5, rng))
    pair = fit("thermal:polytropic+leakage:laminar", 0.75, windows(FLOOR + 5.6e-5, rng))
    v = decide(rank([single, pair], score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.winner.fit.name == "thermal:polytropic"
    better_pair = fit("thermal:polytropic+leakage:laminar", 0.1, windows(FLOOR + 1e-6, rng))
    v = decide(rank([single, better_pair], score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.winner.fit.name == "thermal:polytropic+leakage:laminar"


def test_a_second_effect_switched_off_must_lose_what_the_pair_gains(rng):
    """One chamber pressure, a wall heat exchange (seeds 6563, 2477, 2203): the heat alone
    leaves 0.67 %; beside a supply 1.4 kPa low, 0.45 %, a third less, significantly. With the
    supply switched off and the rest as fitted, 0.41 %: the supply carries nothing held out
    (it moved the heat and the knobs in training), so the heat is named alone and the reason
    says why the pair is not. A pair that leaves 0.25 % (held-out BIC better than the heat
    alone's although the supply fits two knobs, its set pressure and its law's reference) and
    whose supply, switched off, leaves what the heat leaves or more (0.80 %) is named. A pair
    that gains too little over the heat anyway (0.60 %) is not named, and the reason does not
    blame the switched-off test. Each pair's ranking row says which rule left it out
    (:func:`left_out`), or nothing when named."""
    level = lambda g: FLOOR + (g / 100) ** 2  # noqa: E731
    nom = windows(level(5.4), rng)
    single = fit("calibration+thermal:heat_transfer", 0.67, windows(level(0.67), rng))
    heat = "thermal:heat_transfer"
    for pair_gap, off_gap, named, said, why in (
            (0.45, 0.41, heat, True, "supply_pressure switched off leaves as little"),
            (0.25, 0.80, f"{heat}+supply_pressure", False, None),
            (0.60, 0.55, heat, False, f"gains too little over {heat} alone")):
        pair = fit(f"calibration+{heat}+supply_pressure", pair_gap,
                   windows(level(pair_gap), rng))
        ranking = rank([single, pair], score(5.4), nom, 1e-3)
        (row,) = [r for r in ranking if r.fit is pair]
        assert row.explains
        row.switched_off = {"supply_pressure": fit(f"calibration+{heat}", off_gap,
                                                    windows(level(off_gap), rng))}
        v = decide(ranking, score(5.4), nom, None)
        assert v.winner.fit.name == named, (pair_gap, off_gap)
        assert ("supply_pressure does not carry the improvement" in v.reason) == said
        assert left_out(row, ranking, None) == why
        assert row.to_json(score(5.4))["switched_off_gap"] == {
            "supply_pressure": pytest.approx(off_gap)}


def test_a_single_effect_switched_off_must_lose_most_of_what_it_gains(rng):
    """Seed 9437's actuator with no effect a position sensor can see (case 7, the position
    alone, a campaign with a 2.6 V square wave trained on): the recalibration leaves 0.079 %,
    a polytropic gas fitted with it 0.045 %, significantly; switched off, the calibration as
    fitted beside it, 0.048 %: the joint fit found a better calibration, the gas carries a
    tenth of the gain, so nothing is named and the reason says why. The same fit whose gas,
    switched off, leaves 0.075 % (nine tenths of the gain carried) is named; so is one never
    scored switched off."""
    level = lambda g: FLOOR + (g / 100) ** 2  # noqa: E731
    base = windows(level(0.079), rng, jitter=1e-9)
    gas = "thermal:polytropic"
    for off_gap, named in ((0.048, None), (0.075, gas), (None, gas)):
        single = fit(f"calibration+{gas}", 0.045, windows(level(0.045), rng, jitter=1e-9))
        ranking = rank([single], score(0.079), base, 1e-3)
        (row,) = ranking
        assert row.explains
        if off_gap is not None:
            row.switched_off = {gas: fit("calibration", off_gap,
                                         windows(level(off_gap), rng, jitter=1e-9))}
        v = decide(ranking, score(0.079), base, None)
        assert (v.winner.fit.effect if v.winner else None) == ("thermal" if named else None)
        idle = off_gap == 0.048
        assert left_out(row, ranking, None) == (f"{gas} switched off leaves as little"
                                                if idle else None)
        assert ("switched off, the calibration as fitted beside it, the fit leaves 0.05 %: "
                "the improvement is that calibration's" in v.reason) == idle


def test_a_second_effect_that_takes_a_third_of_a_large_remainder_is_not_named(rng):
    """A supply that droops with the flow: the constant supply explains 88 % of the gap and
    leaves 4.0 %; a sensor lag beside it takes a third of that (2.68 % left, far beyond noise,
    significantly): at most part of the rest's cause, so the supply is named alone. Taking
    more than half of the remainder (1.8 % left), the pair is named."""
    level = lambda g: FLOOR + (g / 100) ** 2  # noqa: E731
    nom = windows(level(34.5), rng)
    single = fit("supply_pressure", 4.0, windows(level(4.0), rng))
    for gap, named in ((2.68, "supply_pressure"), (1.8, "supply_pressure+sensor_dynamics")):
        pair = fit("supply_pressure+sensor_dynamics", gap, windows(level(gap), rng))
        # 200 s held out (dt 1e-2 s counts the 20000 samples as 200 windows): the pair has
        # the better BIC, so the rule, not the ranking, decides
        ranking = rank([single, pair], score(34.5), nom, 1e-2)
        assert ranking[0].fit.name == "supply_pressure+sensor_dynamics"
        v = decide(ranking, score(34.5), nom, None)
        assert v.winner.fit.name == named, gap


def test_a_short_holdout_is_backed_by_the_cross_check(rng):
    # Removes 80 % of a small gap, but the improvement shows in a few windows only: t < 3.
    nom = windows(FLOOR, rng, jitter=3e-5)
    better = nom.copy()
    better[:3] -= 4e-5
    fits = [fit("friction_dynamics:lugre", 0.02, better)]
    ranking = rank(fits, score(0.1), nom, 1e-3)
    (r,) = ranking
    assert 0 < r.t < 3 and r.needs_cross_check and not r.explains
    assert decide(ranking, score(0.1), nom, None).winner is None
    r.t_cross = 1.0  # the other fold does not confirm it: (t + 1) / sqrt(2) < 3
    assert not r.explains and not r.needs_cross_check
    r.t_cross = 4.0  # confirmed out of sample in the other fold
    assert r.explains
    assert decide(ranking, score(0.1), nom, None).winner.fit.name == "friction_dynamics:lugre"


def _settle(rng, cal_gap, on_cal_gap, alone_gap, effect="valve_lag:first_order"):
    """Nominal gap 2 %; the recalibration leaves ``cal_gap``; the effect on top of it leaves
    ``on_cal_gap``; the effect alone (nominal parameters) leaves ``alone_gap`` [%]."""
    level = lambda g: FLOOR + (g / 100) ** 2  # noqa: E731
    nom = windows(level(2.0), rng)
    cal = fit("calibration", cal_gap, windows(level(cal_gap), rng))
    (cal_row,) = rank([cal], score(2.0), nom, 1e-3)
    w = fit(f"calibration+{effect}", on_cal_gap, windows(level(on_cal_gap), rng))
    on_cal = decide(rank([w], cal.holdout, cal.holdout_windows, 1e-3), cal.holdout,
                    cal.holdout_windows, None)
    b = fit(effect, alone_gap, windows(level(alone_gap), rng))
    alone = decide(rank([b], score(2.0), nom, 1e-3), score(2.0), nom, None)
    given = effect_alone = None
    if on_cal.winner is not None:
        (given,) = rank([w], b.holdout, b.holdout_windows, 1e-3)
        (effect_alone,) = rank([b], score(2.0), nom, 1e-3)
    return settle(cal_row, on_cal, alone, given, effect_alone, None)


def test_parameters_off_and_no_effect_is_a_calibration(rng):
    s = _settle(rng, cal_gap=0.05, on_cal_gap=0.05, alone_gap=1.9)
    assert s.verdict.winner is None and s.calibrated and s.final.name == "calibration"
    assert "no unmodelled effect" in s.reason and "charging 10% weaker" in s.reason
    assert s.alternative is None


def test_parameters_off_and_an_effect_keep_both(rng):
    s = _settle(rng, cal_gap=1.0, on_cal_gap=0.05, alone_gap=1.0)
    assert s.verdict.winner.fit.effects == ("valve_lag:first_order",) and s.calibrated
    assert s.final.calibrated and s.given.explains
    assert "were off" in s.reason


def test_an_effect_alone_drops_a_calibration_it_does_not_need(rng):
    # The recalibration stood in for part of the effect; given the effect it adds nothing.
    s = _settle(rng, cal_gap=1.0, on_cal_gap=0.05, alone_gap=0.05)
    assert s.verdict.winner.fit.name == "valve_lag:first_order" and not s.calibrated
    assert not s.final.calibrated and not s.given.explains


def test_an_effect_that_mimics_a_calibration_is_reported_as_the_alternative(rng):
    # supply_pressure alone explains the gap as well as recalibrating 8 knobs: fewer knobs win,
    # the recalibration is named as the alternative the data cannot rule out.
    s = _settle(rng, cal_gap=0.10, on_cal_gap=0.10, alone_gap=0.09, effect="supply_pressure")
    assert s.final.name == "supply_pressure" and not s.calibrated
    assert s.alternative.fit.name == "calibration" and "cannot tell" in s.reason


def test_an_effect_that_mimics_a_calibration_and_leaves_a_gap_beyond_noise_is_not_named(rng):
    # A supply restriction alone leaves 0.8 % of a 2 % gap (removes 60 %, "mostly"), the
    # recalibration 1.2 %, and nothing explains what the recalibration leaves: both readings
    # leave a cause on no list, and the effect only did what mis-set parameters do.
    s = _settle(rng, cal_gap=1.2, on_cal_gap=1.2, alone_gap=0.8, effect="supply_pressure")
    assert s.unlisted and s.verdict.winner is None and s.final.name == "calibration"
    assert "supply_pressure alone, instead of the recalibration, leaves 0.80 %" in s.reason
    # The same effect leaving a gap within noise is the alternative reading, as above.
    s = _settle(rng, cal_gap=1.2, on_cal_gap=1.2, alone_gap=0.3, effect="supply_pressure")
    assert not s.unlisted and s.final.name == "supply_pressure"


def test_nothing_to_explain_gives_the_nominal_model(rng):
    s = _settle(rng, cal_gap=1.95, on_cal_gap=1.95, alone_gap=1.95)
    assert s.final is None and not s.calibrated and s.verdict.winner is None


def test_a_candidate_explaining_a_minority_of_a_gap_beyond_noise_is_not_the_cause(rng):
    nom = windows(FLOOR + 4e-4, rng)
    part = fit("supply_pressure", 1.2, windows(FLOOR + 1.44e-4, rng))  # 40 % of the gap
    v = decide(rank([part], score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.winner is None and v.unexplained and v.partial.fit.name == "supply_pressure"
    assert "explains only" in v.reason and "not among the candidates" in v.reason
    cal = fit("calibration", 2.0, nom)
    (cal_row,) = rank([cal], score(2.0), nom, 1e-3)
    s = settle(cal_row, v, v, None, None, None)
    assert s.unlisted and s.final is None


@pytest.mark.parametrize("rival_gap, jitter, named", [
    (0.0896, 3e-7, False),  # leaves 1.06 times the winner's gap, not told apart: none
    (0.1352, 3e-7, True),   # leaves 1.6 times: the winner's part is its own
    (0.1000, 1e-9, True),   # 1.18 times, but worse in every window (paired t in the hundreds)
])
def test_a_small_gap_taken_alike_by_unrelated_effects_names_none(rng, rival_gap, jitter, named):
    # Seed 2609's parameters-only actuator with the position alone: after recalibration a hose
    # took 35 % of a 0.13 % gap (significant), an orifice leak 32 % of it.
    level = lambda g: FLOOR + (g / 100) ** 2  # noqa: E731
    base = windows(level(0.13), rng, jitter=jitter)
    hose = fit("valve_delay:hose", 0.0845, base - level(0.13) + level(0.0845))
    leak = fit("leakage:orifice", rival_gap, base - level(0.13) + level(rival_gap)
               + jitter * rng.standard_normal(20))
    ranking = rank([hose, leak], score(0.13), base, 1e-3)
    assert ranking[0].fit is hose and ranking[0].explains
    assert ranking[0].shrinkage == pytest.approx(0.35, abs=0.01)
    v = decide(ranking, score(0.13), base, None)
    if named:
        assert v.winner.fit is hose
        return
    assert v.winner is None and v.partial.fit is hose and not v.unexplained
    assert "leakage:orifice, another effect, removes about as much (31%)" in v.reason
    assert "evidence for none of them" in v.reason
    nom = windows(level(1.84), rng)
    (cal_row,) = rank([fit("calibration", 0.13, base)], score(1.84), nom, 1e-3)
    s = settle(cal_row, v, decide([], score(1.84), nom, None), None, None, None)
    assert s.final is cal_row.fit and not s.unlisted
    assert s.reason.startswith("no unmodelled effect") and "evidence for none of them" in s.reason
    # A gap beyond noise is not judged so: there a winner removing a minority of it is named
    # only when what it leaves is within noise (0.65 % -> 0.45 %), the rule it met.
    big = windows(level(0.65), rng, jitter=jitter)
    part = fit("valve_delay:hose", 0.45, big - level(0.65) + level(0.45))
    alike = fit("leakage:orifice", 0.47, big - level(0.65) + level(0.47))
    assert decide(rank([part, alike], score(0.65), big, 1e-3), score(0.65), big,
                  None).winner.fit is part


def test_a_second_effect_is_named_when_it_pays_on_held_out_data(rng):
    nom = windows(FLOOR + 4e-4, rng)
    single = fit("valve_lag:first_order", 1.0, windows(FLOOR + 1e-4, rng))
    # The second effect removes 60 % of what the first leaves: a small share of the whole gap.
    pair = fit("valve_lag:first_order+leakage:laminar", 0.4, windows(FLOOR + 1.6e-5, rng))
    v = decide(rank([single, pair], score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.winner.fit.name == "valve_lag:first_order+leakage:laminar"
    # Noise-level differences do not make a pair.
    noise_pair = fit("valve_lag:first_order+leakage:laminar", 0.99, windows(FLOOR + 1e-4, rng))
    v = decide(rank([single, noise_pair], score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.winner.fit.name == "valve_lag:first_order"


def test_a_second_effect_pinned_at_the_edge_of_its_range_is_not_named(rng):
    """A pair that pays, but with its second effect's leak to atmosphere at the far edge of its
    range (a leak several times the largest typical one, soaking up what the first effect's
    form misses): the single effect is the answer, and the reason says why the pair is not."""
    nom = windows(FLOOR + 4e-4, rng)
    single = fit("supply_pressure", 1.0, windows(FLOOR + 1e-4, rng))
    area = CANDIDATES["leakage:orifice"].knobs[1]
    pinned = fit("supply_pressure+leakage:orifice", 0.4, windows(FLOOR + 1.6e-5, rng),
                 **{"leakage:orifice": {area.name: area.high}})
    ranking = rank([single, pinned], score(2.0), nom, 1e-3)
    v = decide(ranking, score(2.0), nom, None)
    assert v.winner.fit.name == "supply_pressure"
    assert "leakage:orifice.atmosphere_area at the edge of its range" in v.reason
    assert left_out(next(r for r in ranking if r.fit is pinned),
                    ranking, None) == ("leakage:orifice.atmosphere_area at the edge of its "
                                       "search range")
    # Inside its range, or at the edge where the effect vanishes, the second effect is named.
    for value in (0.5 * area.high, area.off):
        inside = fit("supply_pressure+leakage:orifice", 0.4, windows(FLOOR + 1.6e-5, rng),
                     **{"leakage:orifice": {area.name: value}})
        v = decide(rank([single, inside], score(2.0), nom, 1e-3), score(2.0), nom, None)
        assert v.winner.fit.name == "supply_pressure+leakage:orifice"


def test_a_single_effect_pinned_at_the_edge_of_its_range_is_not_named(rng):
    """The plant's flow lag before the candidates had its form: a command delay pinned at its
    8 ms bound removing 71 % of the gap, the spool's second-order lag 42 %. The pinned delay
    measures nothing, so it is not named; the lag explains less than half, so nothing is: the
    cause lies outside the candidates, and the reason says which one stood in. Inside its range
    the delay is named; pinned but ranked above an effect that explains most of the gap, that
    effect is named with the stand-in in the reason."""
    nom = windows(FLOOR + 4e-4, rng)

    def delay(value, gap):
        return fit("valve_delay", gap, windows(FLOOR + (gap / 100) ** 2, rng),
                   valve_delay={"delay": value})

    bound = CANDIDATES["valve_delay"].knobs[0].high
    lag = fit("valve_lag:second_order", 1.16, windows(FLOOR + 1.16e-2 ** 2, rng))
    ranking = rank([delay(bound, 0.58), lag], score(2.0), nom, 1e-3)
    v = decide(ranking, score(2.0), nom, None)
    assert v.winner is None and v.unexplained
    assert "valve_delay.delay at the edge of its search range" in v.reason
    assert [left_out(r, ranking, None) for r in ranking] == [
        "valve_delay.delay at the edge of its search range", None]
    v = decide(rank([delay(0.5 * bound, 0.58), lag], score(2.0), nom, 1e-3), score(2.0), nom,
               None)
    assert v.winner.fit.name == "valve_delay"
    mostly = fit("valve_lag:second_order", 0.8, windows(FLOOR + 0.8e-2 ** 2, rng))
    v = decide(rank([delay(bound, 0.58), mostly], score(2.0), nom, 1e-3), score(2.0), nom, None)
    assert v.winner.fit.name == "valve_lag:second_order"
    assert "valve_delay.delay at the edge of its search range" in v.reason


def test_a_pair_member_back_where_it_vanishes_is_found():
    """diagnose.vanished: a joint refit that put the supply back at 10 bar (or a hose's length
    back at 0, its bore anywhere) left the leak doing the work (the pair is the leak alone,
    refitted without the supply); a member that still acts, even slightly, or a single effect,
    is not taken out."""
    from jetpipe_ros.diagnosis.diagnose import vanished

    def joint(supply_pa):
        f = fit("calibration+supply_pressure+leakage:orifice", 0.1, np.zeros(3),
                supply_pressure={"pressure": supply_pa},
                **{"leakage:orifice": {"cross_area": 6e-8, "atmosphere_area": 0.0}})
        z = [CALIBRATION.start()] + [CANDIDATES[g].to_unit(f.values[g]) for g in f.effects]
        f.z = np.concatenate(z)
        return f

    assert vanished(joint(0.9997e6)) == ["supply_pressure"]
    assert vanished(joint(0.97e6)) == []
    # a knob spanning a form's extent is never at "off": a hose of no length, whatever its bore
    hose = fit("calibration+valve_delay:hose+leakage:orifice", 0.1, np.zeros(3),
               **{"valve_delay:hose": {"length": 0.0, "bore": 0.003}})
    assert vanished(hose) == ["valve_delay:hose"]
    single = fit("leakage:orifice", 0.1, np.zeros(3), **{"leakage:orifice": {"cross_area": 0.0}})
    assert vanished(single) == []


class _SecondFold:
    """Stands in for :class:`jobs.Fitter` in :func:`diagnose.second_fold`: each job's fit on the
    holdout leaves the training data the gap given for its candidates."""

    prepared = SimpleNamespace(dt=1e-3)

    def __init__(self, gaps):
        self.gaps = gaps

    def run(self, jobs, labels=None):
        assert all(j.swapped for j in jobs)
        return [fit("+".join(j.groups), self.gaps["+".join(j.groups)], np.zeros(20))
                for j in jobs]


@pytest.mark.parametrize("hose, line, kept", [(0.71, 0.54, "line"), (0.50, 0.90, "hose")])
def test_an_ambiguous_verdict_goes_to_the_better_of_both_folds(rng, hose, line, kept):
    """A drooping supply seen by the position alone (held-out seeds 8623 and 6563): the hose
    ranks first by its one knob fewer though the supply line leaves less held out (0.344 %
    against 0.376 % of 0.55 %); the two are ambiguous. Refitted on the holdout and judged on the
    training data, the one that leaves less over both folds is kept (6563: 0.54 % against
    0.71 %); with the second fold the other way round, the ranking stands."""
    from jetpipe_ros.diagnosis.diagnose import second_fold

    nom = windows(FLOOR + 0.55e-2 ** 2, rng)
    cal = fit("calibration", 0.55, nom)
    names = {"hose": "calibration+valve_delay:hose", "line": "calibration+supply_pressure:line"}
    fits = [fit(names["hose"], 0.376, windows(FLOOR + 0.376e-2 ** 2, rng)),
            fit(names["line"], 0.344, windows(FLOOR + 0.344e-2 ** 2, rng))]
    ranking = rank(fits, cal.holdout, nom, 1e-3)
    first = decide(ranking, cal.holdout, nom, None)
    assert first.winner.fit.name == "valve_delay:hose" and first.ambiguous
    v, listed = second_fold(first, ranking,
                            _SecondFold({names["hose"]: hose, names["line"]: line}),
                            ModelParams(), (cal.holdout, nom), None, lambda message: None)
    assert v.winner.fit is fits[kept == "line"] and v.ambiguous
    assert ("two-fold" in v.reason) == (kept == "line")
    # What is listed (and drawn) first is what is named; each row holds its second fold's gap.
    assert listed[0] is v.winner and sorted(map(id, listed)) == sorted(map(id, ranking))
    assert {r.fit.name: r.second_fold for r in listed} == pytest.approx(
        {"valve_delay:hose": hose, "supply_pressure:line": line})
