"""Calibration knobs: what each one changes in the model, checked against independent numbers,
and their recovery from data whose nominal parameters are off (no unmodelled effect)."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import signal

from jetpipe_ros.diagnosis.calibration import CALIBRATION, at_bound, describe
from jetpipe_ros.diagnosis.data import prepare
from jetpipe_ros.diagnosis.fit import fit, uncertainty
from jetpipe_ros.diagnosis.noise_floor import calibrate
from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.model import ModelParams, ParameterError
from jetpipe_ros.model.params import end_stop_volumes
from jetpipe_ros.model.valve import valve_tf
from test_diagnosis import make_dataset

NOMINAL = ModelParams()


def _peak_hz(params):
    num, den = valve_tf(params)
    w = 2 * np.pi * np.linspace(5.0, 200.0, 40000)
    _, h = signal.freqs(num, den, w)
    return w[np.argmax(np.abs(h))] / (2 * np.pi)


def test_neutral_knobs_change_nothing():
    p = CALIBRATION.apply(NOMINAL, CALIBRATION.values(CALIBRATION.start()))
    assert {k: v for k, v in p.items() if v != NOMINAL[k]} == {}


def test_each_knob_moves_its_own_physics():
    p = CALIBRATION.apply(NOMINAL, {"flow_gain_charge": 0.9, "flow_gain_discharge": 1.2,
                                    "valve_gain": 1.05, "friction_entry": 1.3,
                                    "viscous_exit": 0.8})
    assert p["flow.gain_charge"] == pytest.approx(0.9)
    assert p["flow.gain_discharge"] == pytest.approx(1.2)
    assert p["valve.gain"] == pytest.approx(1.05)
    for q in ("breakaway", "coulomb"):
        assert p[f"friction.entry.{q}"] == pytest.approx([1.3 * c for c in
                                                          NOMINAL[f"friction.entry.{q}"]])
        assert p[f"friction.exit.{q}"] == NOMINAL[f"friction.exit.{q}"]
    assert p["friction.exit.viscous"] == pytest.approx([0.8 * c for c in
                                                        NOMINAL["friction.exit.viscous"]])
    assert p["friction.entry.viscous"] == NOMINAL["friction.entry.viscous"]
    assert p["friction.entry.stribeck_velocity"] == NOMINAL["friction.entry.stribeck_velocity"]


def test_valve_frequency_scales_the_resonance():
    # The nominal chain peaks at 49.7 Hz (docs/model.md); a factor f moves the torque motor's
    # natural frequency by f, and with it the peak (the lead-lag shifts it by a little).
    for f in (0.9, 1.1):
        p = CALIBRATION.apply(NOMINAL, {"valve_frequency": f})
        assert _peak_hz(p) / _peak_hz(NOMINAL) == pytest.approx(f, rel=0.03)


def test_dead_volume_knob_scales_the_volume_left_at_the_end_stop():
    # Eq. 13: V1 = S y + V01; at y = -stroke/2 chamber 1 keeps V01 - S stroke/2 = 17.5 cm^3.
    s = NOMINAL["chamber.piston_area"]
    assert end_stop_volumes(NOMINAL) == pytest.approx((1.533e-4 - s * 0.025,
                                                      1.915e-4 - s * 0.025))
    p = CALIBRATION.apply(NOMINAL, {"dead_volume_1": 0.5, "dead_volume_2": 2.0})
    stop1, stop2 = end_stop_volumes(p)
    assert stop1 == pytest.approx(0.5 * (1.533e-4 - s * 0.025))
    assert stop2 == pytest.approx(2.0 * (1.915e-4 - s * 0.025))
    # At its lowest factor the chamber still keeps a volume (the model refuses none).
    low = CALIBRATION.apply(NOMINAL, {"dead_volume_1": CALIBRATION.knobs[4].low})
    assert end_stop_volumes(low)[0] > 0


def test_a_chamber_that_would_vanish_is_refused():
    with pytest.raises(ParameterError, match="chamber.dead_volume_1 .* would vanish"):
        ModelParams({"chamber.dead_volume_1": 1.2e-4})


def test_words_and_bounds():
    values = {"flow_gain_charge": 0.91, "friction_exit": 1.28, "dead_volume_2": 1.01,
              "valve_gain": 1.25}
    words = describe(values)
    assert "flow map when charging 9% weaker" in words
    assert "exit-phase breakaway and Coulomb friction 28% higher" in words
    assert not any("chamber 2" in w for w in words)  # 1 %: below the 2 % reported
    full = {k.name: 1.0 for k in CALIBRATION.knobs} | values
    assert at_bound(full) == ["valve_gain"]


#: The module fixtures below are costly: every test of this module runs on one test worker
#: (``scripts/test.sh`` distributes with ``--dist loadgroup``), so they are built once.
pytestmark = pytest.mark.xdist_group("test_calibration")


@pytest.fixture(scope="module")
def off_bench(tmp_path_factory):
    """The small campaign on a bench whose flow map is 10 % weaker (both directions) and whose
    friction forces are 30 % higher than nominal, set on the raw parameters."""
    root = tmp_path_factory.mktemp("off")
    changes = {"flow.gain_charge": 0.9, "flow.gain_discharge": 0.9}
    for ph in ("entry", "exit"):
        for q in ("breakaway", "coulomb", "viscous"):
            changes[f"friction.{ph}.{q}"] = [1.3 * c for c in NOMINAL[f"friction.{ph}.{q}"]]
    make_dataset(root / "data", NOMINAL.with_values(changes), seed=4)
    return root


def test_recalibration_recovers_the_factors_from_a_neutral_start(off_bench):
    prepared = prepare(read_dataset(off_bench / "data"))
    prepared.floor, prepared.floor_windows = calibrate(prepared, NOMINAL)
    f = fit(prepared, NOMINAL, [CALIBRATION], CALIBRATION.start(), budget=150)
    got = f.values["calibration"]
    assert got["flow_gain_charge"] == pytest.approx(0.9, abs=0.01)
    assert got["flow_gain_discharge"] == pytest.approx(0.9, abs=0.01)
    for k in ("viscous_entry", "viscous_exit"):
        assert got[k] == pytest.approx(1.3, abs=0.06), k
    for k in ("valve_gain", "valve_frequency"):
        assert got[k] == pytest.approx(1.0, abs=0.02), k
    # The breakaway and Coulomb planes are what these records pin least (standard errors
    # about 0.1): held to the hardware's spread (sd 0.4 in ln) they land within one standard
    # error of the truth, on its side of nominal by most of the way.
    errors = uncertainty(prepared, NOMINAL, f)["calibration"]
    for k in ("friction_entry", "friction_exit"):
        assert abs(got[k] - 1.3) < errors[k] < 0.15, k
        assert got[k] > 1.15, k
    assert f.holdout.gap < 0.1


def test_the_position_alone_sends_no_knob_to_its_bound_to_imitate_a_hysteresis(tmp_path):
    """The self-check's weighted-play hysteresis (seed 7103, case 4: the plant's three plays of
    0.12-0.55 V on a bench whose parameters are off too) seen by the position alone. Fitted
    without the hardware's spread as a prior, the recalibration took eight of the ten knobs to
    their bounds (both dead volumes halved, the entry friction 2.5 times nominal, ...) to
    imitate the loop, and the hysteresis on top then explained 40 % of what was left: answered
    `unlisted`. Held to the spread, the posterior mode, every knob stays inside its range."""
    from jetpipe_ros.plant.logger import log
    from jetpipe_ros.workflows.selfcheck import make_cases, record

    case = make_cases(20, 7103)[4]
    assert case.kind == "weighted_play_hysteresis"
    record(case.truth_model().with_values({"sensors.noise": True,
                                           "sensors.seed": case.seed % 100000}),
           tmp_path, case.seed)
    log("position_only", tmp_path, case.seed + 1)
    prepared = prepare(read_dataset(tmp_path))
    assert prepared.sensors == ("y",)
    prepared.floor, prepared.floor_windows = calibrate(prepared, NOMINAL)
    f = fit(prepared, NOMINAL, [CALIBRATION], CALIBRATION.start(), budget=150)
    assert at_bound(f.values["calibration"]) == []


def test_a_joint_fit_grids_the_effect_from_a_given_base(off_bench):
    """The restart used when a knob ends at its bound (diagnose.fit_effects): the effect's first
    knob searched on a grid with the calibration knobs held at a given base. With a budget of
    just the grid, the fit ends on a grid point whose knobs are the base's, and from the
    bench's own factors that grid fits better than from nominal."""
    from jetpipe_ros.diagnosis.calibration import group
    from jetpipe_ros.diagnosis.fit import GRID

    prepared = prepare(read_dataset(off_bench / "data"))
    truth = {k.name: 1.0 for k in CALIBRATION.knobs} | {
        "flow_gain_charge": 0.9, "flow_gain_discharge": 0.9, "friction_entry": 1.3,
        "friction_exit": 1.3, "viscous_entry": 1.3, "viscous_exit": 1.3}
    lag = group("valve_lag:first_order")
    base = np.concatenate([CALIBRATION.to_unit(truth), lag.start()])
    from_base = fit(prepared, NOMINAL, [CALIBRATION, lag], None, GRID, grid_base=base)
    assert from_base.evaluations == GRID
    assert from_base.z[:len(CALIBRATION.knobs)] == pytest.approx(base[:len(CALIBRATION.knobs)])
    from_nominal = fit(prepared, NOMINAL, [CALIBRATION, lag], None, GRID)
    assert from_nominal.values["calibration"]["flow_gain_charge"] == pytest.approx(1.0)
    assert from_base.train.total < 0.5 * from_nominal.train.total


class _StubFitter:
    """Runs no model: each job's fit gets the training error its start's basin is given, so
    the search's bookkeeping is checked alone (the jobs it asks for, the fit it keeps)."""

    #: records measuring all three signals: every knob judged
    prepared = SimpleNamespace(sensors=("y", "p1", "p2"))

    def __init__(self, recalibration_basin, own_basin):
        self.errors = {"recalibration": recalibration_basin, "own": own_basin}
        self.jobs = []

    def run(self, jobs, labels=None):
        self.jobs += jobs
        return [_stub_fit(j.groups, 5e-4 if CALIBRATION.name not in j.groups else
                          self.errors["own" if np.ndim(j.start) == 2 else "recalibration"])
                for j in jobs]


def _stub_fit(groups, mse, noise=1e-4):
    from jetpipe_ros.diagnosis.calibration import group
    from jetpipe_ros.diagnosis.fit import Fit
    from jetpipe_ros.diagnosis.score import Score

    s = Score({"y": mse}, {"y": noise}, {"y": 1000})
    return Fit(groups=tuple(groups), values={g: {k.name: 1.0 for k in group(g).knobs}
                                             for g in groups},
               z=np.concatenate([group(g).start() for g in groups]), params=NOMINAL, train=s,
               holdout=s, holdout_windows=np.zeros(1), evaluations=1, seconds=0.0)


@pytest.mark.parametrize("left, descends_again", [(3e-4, True), (1.1e-4, False)])
def test_a_joint_fit_also_descends_from_the_effects_own_size(left, descends_again):
    """diagnose.fit_effects: with the calibration, an effect is refitted from the recalibration
    (effect on top) and, while that leaves a training gap of NOISE_GAP or more (here
    100 sqrt(3e-4 - 1e-4) = 1.41 %, against 0.32 % for 1.1e-4), also from the size it took
    alone; the fit kept is the one of lower training error (their priors alike). The
    recalibration's start fits best by construction, and a single descent from there stalled
    with a seal-gap leak at nothing (2.27 % left held out against 0.42 %)."""
    from jetpipe_ros.diagnosis.diagnose import fit_effects
    from jetpipe_ros.diagnosis.verdict import NOISE_GAP

    cand = "leakage:orifice"
    fitter = _StubFitter(recalibration_basin=left, own_basin=1.1e-4)
    cal = _stub_fit((CALIBRATION.name,), 4e-4)
    nom_train = _stub_fit((CALIBRATION.name,), 1e-3).train
    alone, joint = fit_effects(fitter, NOMINAL, nom_train, cal, [cand], lambda m: None)
    starts = [j.start for j in fitter.jobs if CALIBRATION.name in j.groups]
    assert (_stub_fit((cand,), left).train.gap >= NOISE_GAP) == descends_again
    assert [np.ndim(s) for s in starts] == ([1, 2] if descends_again else [1])
    assert joint[0].train.total == pytest.approx(1.1e-4 if descends_again else left)
    if descends_again:  # from the alone fit's knobs, with the nominal knobs or the recalibration
        size = alone[cand].z
        assert starts[1][:, -size.size:] == pytest.approx(np.stack([size, size]))
        assert starts[1][0, :-size.size] == pytest.approx(CALIBRATION.start())
        assert starts[1][1, :-size.size] == pytest.approx(cal.z)


@pytest.mark.parametrize("joint_prior, joint_kept", [(10.4, True), (20.2, False)])
def test_of_two_fits_of_one_candidate_the_one_of_higher_posterior_is_kept(joint_prior,
                                                                           joint_kept):
    """diagnose.fit_effects keeps, of a candidate's fit on top of the recalibration and its joint
    fit with the calibration, the one of lower cost N log C + P (fit.Fit.cost), which the joint
    descent minimised. Seed 9437's port lag with the position alone: on top of a recalibration
    with the dead volumes at twice nominal and the valve's frequency at 0.8 (P = 20.2 in the
    hardware's spreads: (ln 2 / 0.30)^2 = 5.3 for each volume, (ln 0.8 / 0.10)^2 = 5.0),
    C = 1.070e-5; jointly, the dead volumes 1.33 and 1.26, P = 10.4, C = 1.099e-5, 2.7 % more
    over N = 13 pieces of evidence: 13 ln(1.099 / 1.070) = 0.35, against 9.8 less prior. The
    joint fit is kept (it found the port within 8 % and left 0.84 % held out, the other
    3.09 %); on the training error alone it was not. With the priors alike the lower error
    is kept."""
    from jetpipe_ros.diagnosis.diagnose import fit_effects

    cand = "leakage:orifice"

    class Fitter(_StubFitter):
        def run(self, jobs, labels=None):
            self.jobs += jobs
            fits = []
            for j in jobs:
                joint = CALIBRATION.name in j.groups
                f = _stub_fit(j.groups, 1.099e-5 if joint else 1.070e-5)
                fits.append(dataclasses.replace(f, evidence=13.0,
                                                prior=joint_prior if joint else 0.0))
            return fits

    cal = dataclasses.replace(_stub_fit((CALIBRATION.name,), 4e-4), evidence=13.0, prior=20.2)
    nom_train = _stub_fit((CALIBRATION.name,), 1e-3).train
    _, (kept,) = fit_effects(Fitter(None, None), NOMINAL, nom_train, cal, [cand],
                             lambda m: None)
    assert kept.groups == (CALIBRATION.name, cand)
    assert kept.train.total == pytest.approx(1.099e-5 if joint_kept else 1.070e-5)
    assert kept.prior == pytest.approx(joint_prior if joint_kept else 20.2)
    assert kept.cost == pytest.approx(13.0 * np.log(kept.train.total) + kept.prior)


@pytest.mark.parametrize("suspect", [False, True])
def test_a_carriers_refit_runs_beside_the_others_unless_a_bound_knob_turns_suspect(suspect):
    """diagnose.fit_effects: a candidate that carries calibration knobs (a hose's volume is dead
    volume) is refitted from the recalibration with those knobs at nominal. That refit waits on
    nothing unless a knob at a bound turns out suspect (the others' joint fits leave a training
    gap of NOISE_GAP or more: here 1.41 %, against 0.32 %), so it runs in the same batch as the
    others' joint fits and is kept; when the knob does turn suspect it is made again with that
    knob at nominal too, and that refit is the one kept: the same fits as one after the other."""
    from jetpipe_ros.diagnosis.diagnose import fit_effects

    hose, leak = "valve_delay:hose", "leakage:orifice"
    knobs = [k.name for k in CALIBRATION.knobs]

    class Batches(_StubFitter):
        def run(self, jobs, labels=None):
            self.batches = [*getattr(self, "batches", []), list(jobs)]
            fits = super().run(jobs, labels)
            # tag each fit with its batch; a carrier's joint fit fits best of all
            return [dataclasses.replace(f, seconds=float(len(self.batches)),
                                        train=_stub_fit(f.groups, 1.05e-4).train)
                    if hose in f.groups and CALIBRATION.name in f.groups else
                    dataclasses.replace(f, seconds=float(len(self.batches))) for f in fits]

    fitter = Batches(recalibration_basin=3e-4 if suspect else 1.1e-4, own_basin=2e-4)
    cal = _stub_fit((CALIBRATION.name,), 4e-4)
    cal = dataclasses.replace(cal, z=np.full(len(knobs), 0.3), values={CALIBRATION.name: {
        **cal.values[CALIBRATION.name], "valve_gain": 0.8}})  # at its lower bound
    nom_train = _stub_fit((CALIBRATION.name,), 1e-3).train
    _, joint = fit_effects(fitter, NOMINAL, nom_train, cal, [hose, leak], lambda m: None)

    def reset(job):  # the calibration knobs a job starts at nominal, not at the recalibration's
        return {name for name, z in zip(knobs, job.grid_base) if z != pytest.approx(0.3)}

    hose_jobs = [(i, j) for i, batch in enumerate(fitter.batches[1:], 2) for j in batch
                 if hose in j.groups and CALIBRATION.name in j.groups]
    assert hose_jobs[0][0] == 2  # the batch of the joint fits, beside the leak's
    assert any(leak in j.groups for j in fitter.batches[1])
    assert reset(hose_jobs[0][1]) == {"dead_volume_1", "dead_volume_2"}
    kept = {f.groups[-1]: f for f in joint}[hose]
    if suspect:
        (last, again), = hose_jobs[1:]
        assert last == len(fitter.batches)
        assert reset(again) == {"dead_volume_1", "dead_volume_2", "valve_gain"}
        assert kept.seconds == last
    else:
        assert len(hose_jobs) == 1
        assert kept.seconds == 2


@pytest.mark.parametrize("onto", [None, 2.4])
def test_a_joint_fit_left_at_the_neutral_edge_starts_from_the_typical_size(onto):
    """diagnose.fit_effects: the joint fit with the calibration starts where the effect's fit
    on top of the recalibration ended, unless that is where the effect changes nothing (a wall
    heat's h A = 100 W/K, where the recalibration's dead volumes stood in for it with the
    position alone: the descent stayed there, 1.17 % held out, against 0.17 % from 0.5 W/K):
    then from the candidate's typical size, 0.5 W/K, beside the recalibration's knobs."""
    from jetpipe_ros.diagnosis.calibration import group
    from jetpipe_ros.diagnosis.diagnose import fit_effects

    cand = "thermal:heat_transfer"
    heat = group(cand)

    class Fitter(_StubFitter):
        def run(self, jobs, labels=None):
            fits = super().run(jobs, labels)
            if onto is not None:  # the fit on the recalibration ends at 2.4 W/K
                fits = [dataclasses.replace(f, z=heat.to_unit({"heat_transfer": onto}))
                        if f.groups == (cand,) and j.base is not NOMINAL else f
                        for f, j in zip(fits, jobs)]
            return fits

    fitter = Fitter(recalibration_basin=1.1e-4, own_basin=1.1e-4)
    cal = _stub_fit((CALIBRATION.name,), 4e-4)
    cal = dataclasses.replace(cal, z=np.full(len(CALIBRATION.knobs), 0.3),
                              params=NOMINAL.with_values({}))  # another model than NOMINAL
    nom_train = _stub_fit((CALIBRATION.name,), 1e-3).train
    fit_effects(fitter, NOMINAL, nom_train, cal, [cand], lambda m: None)
    (start,) = [j.start for j in fitter.jobs if CALIBRATION.name in j.groups]
    assert start[:-1] == pytest.approx(cal.z)
    expected = 0.5 if onto is None else onto
    assert heat.knobs[0].to_value(start[-1]) == pytest.approx(expected)


@pytest.mark.parametrize("from_base", [False, True])
def test_the_grid_from_a_given_base_leaves_the_effect_at_nothing_out(from_base):
    """fit._grid_first_knob: from a given base (the refits that look for an effect's basin
    away from the recalibration's) the first knob's grid leaves out its neutral value (a hose
    of length 0, where a descent kept it: 1.0 % of the training gap left against 0.04 % from
    0.31 m); from the neutral point (an effect fitted alone) the grid spans the whole range."""
    from types import SimpleNamespace

    from jetpipe_ros.diagnosis.calibration import group
    from jetpipe_ros.diagnosis.fit import GRID, _grid_first_knob

    hose = group("valve_delay:hose")
    groups = (CALIBRATION, hose)
    seen = []

    def cost(z):  # lowest where the hose is nothing
        seen.append(hose.knobs[0].to_value(z[len(CALIBRATION.knobs)]))
        return seen[-1]

    obj = SimpleNamespace(candidates=groups, sizes=[len(g.knobs) for g in groups], cost=cost)
    base = np.concatenate([CALIBRATION.start(), hose.start()]) if from_base else None
    start = _grid_first_knob(obj, base)
    lengths = np.linspace(0.0, 2.5, GRID)
    assert seen == pytest.approx(list(lengths[1:] if from_base else lengths))
    assert hose.knobs[0].to_value(start[len(CALIBRATION.knobs)]) == pytest.approx(
        lengths[1] if from_base else 0.0)


@pytest.mark.parametrize("refit_error", [2e-4, 9e-4])
def test_the_effect_without_the_calibration_is_refitted_from_the_joint_fits_values(
        refit_error):
    """Whether the recalibration is needed beside the named effect is judged against the effect
    fitted without it. That fit descends from the better of the fit alone and the joint fit's
    effect values (rows of the start), with the joint budget, and the lower cost is kept: a fit
    alone stuck in another basin would make the calibration look needed."""
    from jetpipe_ros.diagnosis.diagnose import JOINT_BUDGET, effect_without_calibration

    class Refit(_StubFitter):
        def run(self, jobs, labels=None):
            self.jobs += jobs
            return [_stub_fit(j.groups, refit_error) for j in jobs]

    cal, effect = CALIBRATION.name, "valve_hysteresis"
    joint = _stub_fit((cal, effect), 1.5e-4)
    joint.z = np.arange(joint.z.size) / 20.0
    n_cal = len(CALIBRATION.knobs)
    alone = _stub_fit((effect,), 5e-4)
    fitter = Refit(None, None)
    kept = effect_without_calibration(fitter, NOMINAL, joint, alone, n_cal, lambda m: None)
    (job,) = fitter.jobs
    assert job.base is NOMINAL and job.groups == (effect,) and job.budget == JOINT_BUDGET
    np.testing.assert_array_equal(job.start, np.vstack([alone.z, joint.z[n_cal:]]))
    assert (kept is alone) == (refit_error > 5e-4)
    assert kept.train.mse["y"] == min(refit_error, 5e-4)
    # A pair (never fitted alone): from the joint fit's values only.
    fitter.jobs.clear()
    effect_without_calibration(fitter, NOMINAL, joint, None, n_cal, lambda m: None)
    np.testing.assert_array_equal(fitter.jobs[0].start, joint.z[n_cal:])
