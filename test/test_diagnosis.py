"""jetpipe diagnose: data preparation, the verdict on data with a known effect, outputs, bad input."""

import json
import shutil
from importlib.resources import files
import sys
import tempfile
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from scipy.signal import chirp

from jetpipe_ros.cli import main
from jetpipe_ros.dataset import DatasetError, Entry, read_dataset, write_dataset
from jetpipe_ros.workflows import diagnose
from jetpipe_ros.workflows.cli import summary_lines
from jetpipe_ros.diagnosis.calibration import CALIBRATION, group
from jetpipe_ros.diagnosis.candidates import CANDIDATES
from jetpipe_ros.diagnosis.data import noise_level, prepare
from jetpipe_ros.diagnosis.fit import fit, switched_off
from jetpipe_ros.diagnosis.score import predict_all, score
from jetpipe_ros.model import ModelParams, load_params, simulate

DT = 1e-3


def _experiments():
    t = lambda d: np.arange(int(d / DT)) * DT  # noqa: E731
    return [
        ("charge", np.concatenate([np.full(2500, 2.0), np.full(1500, -2.0)]), True, "train"),
        ("square_small", 0.6 * np.sign(np.sin(2 * np.pi * 0.25 * t(4)) + 1e-9), False, "train"),
        ("sweep", 0.3 * chirp(t(4), 1.6, 4, 60, method="logarithmic"), False, "train"),
        ("square_mid", 1.5 * np.sign(np.sin(2 * np.pi * 0.6 * t(3)) + 1e-9), False, "train"),
        ("square_large", 2.0 * np.sign(np.sin(2 * np.pi * 0.9 * t(3)) + 1e-9), False, "holdout"),
        ("sweep_large", 1.2 * chirp(t(3), 1.6, 3, 60, method="logarithmic"), False, "holdout"),
    ]


#: The small campaign's experiments that tests of the plumbing around a diagnosis (a cluster, a
#: fleet) keep: two thirds of its length, one of each kind, one held out.
PLUMBING = ("charge", "sweep", "square_mid", "square_large")


def make_dataset(root, params, seed=0, roles=True, names=None):
    """Simulate the small campaign above (its experiments ``names``, default all) with sensor
    noise and write it as a dataset."""
    out = []
    for k, (name, u, locked, role) in enumerate(_experiments()):
        if names is not None and name not in names:
            continue
        p = params.with_values({"mechanics.locked": locked, "sensors.noise": True,
                                "sensors.seed": seed * 10 + k})
        tr = simulate(p, u)
        out.append((Entry(f"{name}.csv", piston="locked" if locked else "free",
                          role=role if roles else None),
                    {"t": tr.t, "u": tr.u, "y": tr.y_meas, "p1": tr.p1_meas, "p2": tr.p2_meas}))
    return write_dataset(root, out)


def assert_schema(path):
    """The diagnosis.json at ``path`` is valid under the JSON Schema the package ships."""
    schema = json.loads(files("jetpipe_ros.diagnosis").joinpath("diagnosis.schema.json")
                        .read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    doc = json.loads(Path(path).read_text())
    errors = [f"{'/'.join(map(str, e.absolute_path))}: {e.message}"
              for e in jsonschema.Draft202012Validator(schema).iter_errors(doc)]
    assert not errors, errors
    return doc


# Where the diagnosis runs: the verdict and the numbers do not depend on it (the same functions
# run in a worker as here), so the tests about what it finds run in this process (workers=1,
# --jobs 1): on a 2-core machine a local Dask cluster only adds its start and slower evaluations
# (README, Scaling out), up to 2.5 x the time of one of these diagnoses on a busy machine; the
# refusals of bad input come before any fit, where a cluster would only be started to be
# closed. This fixture keeps 2 local workers: a local cluster started, the fits spread over it,
# the cluster closed, stay tested.
#: The module fixtures below are costly: every test of this module runs on one test worker
#: (``scripts/test.sh`` distributes with ``--dist loadgroup``), so they are built once.
pytestmark = pytest.mark.xdist_group("test_diagnosis")


@pytest.fixture(scope="module")
def lag_result(tmp_path_factory):
    root = tmp_path_factory.mktemp("lag")
    make_dataset(root / "data", ModelParams().with_effect("valve_lag", corner_frequency=20.0))
    result = diagnose(root / "data", root / "out", workers=2, quiet=True)  # a local cluster
    return root, result


def test_noise_level_recovers_the_sensor_sigma():
    rng = np.random.default_rng(3)
    t = np.arange(20000) * DT
    x = 4e5 + 2e5 * np.sin(2 * np.pi * 0.5 * t) + 500.0 * rng.standard_normal(t.size)
    assert noise_level(x) == pytest.approx(500.0, rel=0.05)


def test_verdict_names_the_withheld_effect_and_recovers_it(lag_result):
    root, result = lag_result
    v = result["verdict"]
    assert v["effect"] == "valve_lag" and v["subsystem"] == "valve"
    assert v["params"]["corner_frequency"] == pytest.approx(20.0, rel=0.15)
    assert v["confidence"] > 0.5
    assert result["gap"]["shrinkage"] >= 0.7
    assert result["gap"]["augmented"] < result["gap"]["nominal"]
    assert result["ranking"][0]["effect"] == "valve_lag"
    assert {r["effect"] for r in result["ranking"]} >= {"valve_delay", "leakage", "thermal"}


def test_outputs_follow_the_contract(lag_result):
    root, result = lag_result
    out = root / "out"
    doc = assert_schema(out / "diagnosis.json")
    assert doc["schema"] == "jetpipe.diagnosis/2"
    assert doc["verdict"]["model_fits"] is True and doc["data"]["cannot_judge"] == {}
    assert doc["data"]["sensors"] == ["y", "p1", "p2"] and doc["data"]["corrections"] == []
    assert set(doc) >= {"verdict", "calibration", "gap", "localization", "ranking"}
    assert set(doc["calibration"]) >= {"knobs", "gap_before", "gap_after", "significant"}
    assert set(doc["localization"]) >= {"signals", "subsystems", "regimes", "frequency"}
    assert doc["gap"]["metric"] == "excess_nrmse_pct"
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64") >= 4 and "valve_lag" in html
    aug = load_params(out / "augmented.yaml")
    assert aug.enabled_effects() == ["valve_lag"]
    assert aug["effects.valve_lag.corner_frequency"] == pytest.approx(
        result["verdict"]["params"]["corner_frequency"], rel=1e-6)
    assert not [p for p in root.iterdir() if p.name.startswith(".")]


def off_params(flow=0.9, friction=1.3):
    """A bench whose flow map is ``flow`` x and friction forces ``friction`` x nominal, set on
    the raw parameters (not through the calibration knobs)."""
    nominal = ModelParams()
    changes = {"flow.gain_charge": flow, "flow.gain_discharge": flow}
    for ph in ("entry", "exit"):
        for q in ("breakaway", "coulomb", "viscous"):
            changes[f"friction.{ph}.{q}"] = [friction * c for c in nominal[f"friction.{ph}.{q}"]]
    return nominal.with_values(changes)


def test_parameters_that_are_off_are_recalibrated_not_blamed_on_an_effect(tmp_path):
    # The bench: flow map 10 % weaker, friction 30 % higher, nothing else.
    make_dataset(tmp_path / "data", off_params(), seed=5)
    result = diagnose(tmp_path / "data", tmp_path / "out", workers=1, quiet=True)  # see lag_result
    v, cal = result["verdict"], result["calibration"]
    assert v["effect"] == "none" and cal["significant"]
    assert assert_schema(tmp_path / "out" / "diagnosis.json")["calibration"]["stand_ins"]
    assert cal["knobs"]["flow_gain_charge"] == pytest.approx(0.9, abs=0.02)
    assert cal["knobs"]["friction_exit"] == pytest.approx(1.3, abs=0.1)
    assert cal["gap_after"] <= 0.2 * cal["gap_before"]
    assert result["gap"]["augmented"] == pytest.approx(cal["gap_after"])
    assert "no unmodelled effect" in v["reason"] and "10% weaker" in v["reason"]
    # A lower supply could stand in for a weaker charging flow map, not for the discharging
    # one the bench also has: fitted in the knob's place it leaves more, significantly.
    rows = {r["effect"]: r for r in cal["stand_ins"]}
    assert rows["supply_pressure"]["preferred"] == "recalibration"
    assert rows["supply_pressure"]["holdout_gap"] > 0.5 > cal["gap_after"]
    aug = load_params(tmp_path / "out" / "augmented.yaml")
    assert aug.enabled_effects() == []
    assert aug["flow.gain_charge"] == pytest.approx(cal["knobs"]["flow_gain_charge"])


def test_an_effect_masked_by_parameters_that_are_off_is_found(tmp_path):
    # The same bench with a 30 Hz valve lag: plain in the sweeps once recalibrated.
    make_dataset(tmp_path / "data", off_params().with_effect("valve_lag",
                                                             corner_frequency=30.0), seed=6)
    result = diagnose(tmp_path / "data", tmp_path / "out", workers=1, quiet=True)  # see lag_result
    v, cal = result["verdict"], result["calibration"]
    assert v["effect"] == "valve_lag" and cal["significant"]
    assert v["params"]["corner_frequency"] == pytest.approx(30.0, rel=0.15)
    assert cal["knobs"]["flow_gain_discharge"] == pytest.approx(0.9, abs=0.03)
    assert result["gap"]["shrinkage"] >= 0.85
    aug = load_params(tmp_path / "out" / "augmented.yaml")
    assert aug.enabled_effects() == ["valve_lag"]
    assert aug["flow.gain_discharge"] == pytest.approx(cal["knobs"]["flow_gain_discharge"])


def test_nominal_data_gives_none(tmp_path):
    make_dataset(tmp_path / "data", ModelParams(), seed=4)
    result = diagnose(tmp_path / "data", tmp_path / "out", workers=1, quiet=True)  # in-process
    assert result["verdict"]["effect"] == "none"
    assert result["gap"]["nominal"] < 0.5
    assert not result["calibration"]["significant"]
    # Nothing beyond noise in the model's equations either.
    assert result["localization"]["equations"]["missing"] is None
    # How small an effect these records would show: a valve delay (both pressures logged, each
    # answering the command late) from under its typical 3 ms; every candidate judged said.
    limits = result["visibility"]["smallest_shown"]
    assert set(limits) == set(result["visibility"]["at_typical_size_gap_pct"])
    assert 0.05 < limits["valve_delay"]["times_typical"] < 1.0
    assert limits["valve_delay"]["values"]["delay"] < 0.003
    lines = summary_lines(result, "out")
    assert any(line.startswith("smallest size shown, times the typical") and "valve_delay 0."
               in line for line in lines)
    report = (tmp_path / "out" / "report.html").read_text()
    assert "smallest size shown [x typical]" in report


def test_the_localisation_points_at_the_valve_for_a_valve_lag(lag_result):
    _, result = lag_result
    loc = result["localization"]
    # Command to chamber pressure: the nominal model misses the lag's gain above 20 Hz, the
    # augmented model does not (the paper's metrics, per band).
    high = loc["frequency"]["bands"]["20-70 Hz"]
    assert high["nominal"]["gain_error_pct"] > 20.0
    assert high["augmented"]["gain_error_pct"] < 0.3 * high["nominal"]["gain_error_pct"]
    sig = loc["signals"]
    assert sig["augmented"]["gap"] < 0.3 * sig["nominal"]["gap"]
    # The valve and chambers replayed with the measured motion hold the gap, not the mechanics.
    sub = loc["subsystems"]
    assert sub["valve_and_chambers"]["gap"] > sub["mechanics"]["gap"]
    assert result["visibility"]["at_typical_size_gap_pct"]["valve_lag:first_order"] > 1.0
    assert "valve_lag:first_order" not in result["visibility"]["too_small_to_see"]
    assert "smallest_shown" not in result["visibility"]  # an effect is named: no limits


def test_a_nominal_model_with_the_effect_on_has_nothing_left(tmp_path):
    """--params with an effect switched on: that effect is no candidate, the gap is noise."""
    truth = ModelParams().with_effect("valve_lag", corner_frequency=20.0)
    make_dataset(tmp_path / "data", truth, seed=3)
    params = tmp_path / "nominal.yaml"
    params.write_text(truth.to_ros_yaml(only_changed=True))
    assert main(["diagnose", str(tmp_path / "data"), "--out", str(tmp_path / "out"),
                 "--params", str(params), "--quiet", "--jobs", "1"]) == 0
    result = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert result["nominal_effects"] == ["valve_lag"]
    assert "valve_lag" not in {r["effect"] for r in result["ranking"]}
    assert result["verdict"]["effect"] == "none" and result["gap"]["nominal"] < 0.5


def test_a_member_switched_off_leaves_the_model_without_it(tmp_path):
    """A pair's fit with one member switched off (the rest as fitted, nothing refitted)
    predicts as the model without that member: on records of a 20 Hz valve lag, the lag
    beside a leak at its typical size, the leak switched off, scores as the model with the lag
    alone built another way; with the leak on, the pair misses far more."""
    lagging = ModelParams().with_effect("valve_lag", corner_frequency=20.0)
    make_dataset(tmp_path / "data", lagging)
    prepared = prepare(read_dataset(tmp_path / "data"))
    names = ("calibration", "valve_lag:first_order", "leakage:laminar")
    groups = [group(g) for g in names]
    leak = CANDIDATES["leakage:laminar"].typical
    z = np.concatenate([CALIBRATION.start(), groups[1].to_unit({"corner_frequency": 20.0}),
                        groups[2].to_unit(leak)])
    pair = fit(prepared, ModelParams(), groups, z, budget=1)  # scored where it starts
    off = switched_off(prepared, ModelParams(), pair, "leakage:laminar")
    alone = score(prepared, predict_all(lagging, prepared, "holdout"), "holdout")
    assert off.holdout.gap == pytest.approx(alone.gap, rel=1e-9)
    assert off.values["leakage:laminar"] == {k: 0.0 for k in leak}
    assert off.values["valve_lag:first_order"] == pair.values["valve_lag:first_order"]
    assert pair.holdout.gap > off.holdout.gap + 0.5


def test_the_separating_experiment_is_where_two_models_differ_most():
    from jetpipe_ros.diagnosis.separation import separating_experiment

    root = Path(tempfile.mkdtemp())
    try:
        make_dataset(root / "data", ModelParams())
        prepared = prepare(read_dataset(root / "data"))
        a = ModelParams().with_effect("valve_lag", corner_frequency=40.0)
        b = ModelParams().with_effect("valve_delay", delay=0.004)
        sep = separating_experiment(a, b, prepared)
        # A lag and a delay differ most where the command is fast: a sweep to 60-70 Hz.
        assert "sweep" in sep["experiment"] and sep["difference_over_noise"] > 3.0
        assert "with_sensors" not in sep  # every sensor logged
        same = separating_experiment(a, a, prepared)
        assert same["difference_over_noise"] == 0.0
    finally:
        shutil.rmtree(root)


def test_a_separating_experiment_is_judged_on_the_sensors_the_bench_has(tmp_path):
    """A bench without a chamber-2 sensor: the experiments it could record are compared on the
    position and p1 only (a missing sensor has no noise to divide by: 1e13 x the noise)."""
    from jetpipe_ros.diagnosis.separation import separating_experiment
    from jetpipe_ros.plant.logger import log

    make_dataset(tmp_path / "data", ModelParams())
    log("one_pressure", tmp_path / "data", 1)
    prepared = prepare(read_dataset(tmp_path / "data"))
    assert prepared.sensors == ("y", "p1")
    a = ModelParams().with_effect("valve_lag", corner_frequency=40.0)
    b = ModelParams().with_effect("valve_delay", delay=0.004)
    sep = separating_experiment(a, b, prepared)
    # A 40 Hz lag against a 4 ms delay: a few to a few hundred times the noise, no more.
    assert all(0.0 <= m["difference_over_noise"] < 1e3 for m in sep["menu"])
    assert sep["difference_over_noise"] > 3.0
    # Logging chamber 2's pressure would tell them on these very experiments: their predictions
    # of it differ by more than a 500 Pa sensor's noise, RMS over thousands of samples (2.75 x);
    # identical models, 0.
    assert set(sep["with_sensors"]) == {"p2"} and 1.0 < sep["with_sensors"]["p2"] < 1e3
    assert separating_experiment(a, a, prepared)["with_sensors"] == {"p2": 0.0}


def test_split_fallbacks_are_stated(tmp_path):
    make_dataset(tmp_path / "data", ModelParams(), roles=False)
    prep = prepare(read_dataset(tmp_path / "data"))
    assert "every third" in prep.split_note
    assert [r.holdout.all() for r in prep.records] == [False, False, True, False, False, True]
    single = tmp_path / "single"
    ds = read_dataset(tmp_path / "data")
    write_dataset(single, [(Entry("a.csv"), ds.experiments[1].columns()),
                           (Entry("b.csv"), ds.experiments[2].columns())])
    prep = prepare(read_dataset(single))
    assert "last 30 %" in prep.split_note
    assert prep.records[0].holdout.mean() == pytest.approx(0.3, abs=0.01)


def test_bad_datasets_get_clear_errors_and_leave_no_output(tmp_path, capsys, monkeypatch):
    make_dataset(tmp_path / "data", ModelParams())
    csv = tmp_path / "data" / "sweep.csv"
    lines = csv.read_text().splitlines()
    lines[100] = lines[100].replace(lines[100].split(",")[3], "inf", 1)  # nan: a lost reading
    csv.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"

    def no_cluster(*args):
        raise AssertionError("the cluster started before the dataset was read")

    # The default --jobs: the dataset's error comes before any worker is started.
    monkeypatch.setattr(sys.modules["jetpipe_ros.workflows.diagnose"], "Cluster", no_cluster)
    assert main(["diagnose", str(tmp_path / "data"), "--out", str(out), "--quiet"]) == 2
    assert "sweep.csv: line 101, column 'p1'" in capsys.readouterr().err
    assert not out.exists()
    # Everything held out: no training data.
    make_dataset(tmp_path / "all_held", ModelParams())
    index = tmp_path / "all_held" / "dataset.yaml"
    index.write_text(index.read_text().replace("role: train", "role: holdout"))
    with pytest.raises(DatasetError, match="every experiment is marked holdout"):
        prepare(read_dataset(tmp_path / "all_held"))


def test_too_little_data_is_refused(tmp_path):
    cols = {"t": np.arange(500) * DT, "u": np.zeros(500), "y": np.zeros(500),
            "p1": np.full(500, 4.1648e5), "p2": np.full(500, 4.1648e5)}
    write_dataset(tmp_path / "d", [(Entry("a.csv"), cols), (Entry("b.csv"), cols)])
    with pytest.raises(DatasetError, match="s of train data; the diagnosis needs at least"):
        prepare(read_dataset(tmp_path / "d"))


IDENT_SUBSET = ("charge_0p57V", "charge_1p73V", "charge_2p86V", "valve_sweep_1V",
                "friction_1_9p92bar", "friction_4p15_9p92bar", "friction_1_6p93bar",
                "friction_4p96_1bar", "friction_8p98_1bar", "friction_10p115_8p89bar",
                "square_0p6V_0p1122Hz")


def test_identify_then_diagnose_with_the_identified_parameters(tmp_path, capsys):
    """The user's path on a bench that is off: `jetpipe identify` on the identification
    experiments, then `jetpipe diagnose --params` with what it identified."""
    from pathlib import Path

    from jetpipe_ros.campaign import load_campaign, run_campaign_offline

    config = Path(__file__).parents[1] / "config" / "campaign_identification.yaml"
    plan = load_campaign(config).select(IDENT_SUBSET)
    truth = off_params(flow=0.92, friction=1.25).with_effect("valve_lag",
                                                             corner_frequency=30.0)
    data = run_campaign_offline(truth.with_values({"sensors.noise": True}), plan,
                                tmp_path / "data", seed=11)
    params = tmp_path / "identified.yaml"
    assert main(["identify", str(data), "--out", str(params)]) == 0
    out = tmp_path / "out"
    assert main(["diagnose", str(data), "--out", str(out), "--params", str(params),
                 "--quiet", "--jobs", "1"]) == 0  # in this process: see lag_result
    result = json.loads((out / "diagnosis.json").read_text())
    # The paper's procedures take up the bench's flow map and friction, and the valve sweep the
    # lag (in the lead-lag of Eq. 9): what is left is within noise.
    assert result["gap"]["nominal"] < 0.5
    assert result["verdict"]["effect"] == "none"
    aug = load_params(out / "augmented.yaml")
    assert aug["valve.lag_pole"] == pytest.approx(load_params(params)["valve.lag_pole"])
    assert "verdict: none" in capsys.readouterr().out


def test_a_real_loggers_record_is_diagnosed_and_its_output_follows_the_schema(tmp_path):
    # What another logger writes: one pressure sensor only, in bar gauge, time in ms, every
    # second row of a 1 kHz loop (500 Hz), and three rows lost in every experiment. The reader
    # converts and fills, the diagnosis leaves out what a pressure alone cannot judge, says
    # that the commands between the rows are not in the record, and diagnosis.json says so
    # under its schema.
    out = []
    for k, (name, u, locked, role) in enumerate(_experiments()):
        p = ModelParams().with_effect("valve_lag", corner_frequency=20.0).with_values(
            {"mechanics.locked": locked, "sensors.noise": True, "sensors.seed": 70 + k})
        tr = simulate(p, u)
        keep = np.arange(tr.t.size) % 2 == 0
        keep[1500:1506] = False
        out.append((Entry(f"{name}.csv", piston="locked" if locked else "free", role=role,
                          units={"t": "ms", "p1": "bar gauge"}),
                    {"t": tr.t[keep] * 1e3, "u": tr.u[keep],
                     "p1": (tr.p1_meas[keep] - 1e5) / 1e5}))
    write_dataset(tmp_path / "data", out)
    result = diagnose(tmp_path / "data", tmp_path / "out", workers=1, quiet=True)
    doc = assert_schema(tmp_path / "out" / "diagnosis.json")
    assert doc["data"]["sensors"] == ["p1"]
    assert set(doc["data"]["cannot_judge"]) == {"friction_dynamics", "moving_mass"}
    assert not {"friction_dynamics", "moving_mass"} & {r["effect"] for r in doc["ranking"]}
    assert doc["data"]["rows_not_compared"] >= 3 * len(out)
    assert doc["verdict"]["effect"] == result["verdict"]["effect"] == "valve_lag"
    # Gauge without its reference: the model's 1 bar assumed and said so, in the corrections
    # and beside the effect named (this logger did subtract 1 bar, but nothing says so).
    assert any("+ 100000 Pa" in c and "assumed, not declared (gauge_reference)" in c
               for c in doc["data"]["corrections"])
    assert "declared gauge without the ambient pressure" in doc["verdict"]["reason"]
    # Slower than 1 kHz, with commands that change at every row (the sweeps), what a faster
    # controller gave between the rows is not in the record: said in the notes and beside the
    # effect named.
    assert any("logged at 500 Hz" in n for n in doc["data"]["notes"])
    assert "the records are logged at 500 Hz" in doc["verdict"]["reason"]


def test_corrections_said_of_many_files_are_printed_once():
    """A unit converted in every file is one line with the files named, not one per file;
    notes that differ stay apart, in the order first said."""
    from jetpipe_ros.dataset import grouped_notes as grouped
    notes = [f"{f}.csv: y: mm -> m (x 0.001)" for f in "abcde"] + [
        "a.csv: 3 rows missing", "holdout as marked", "b.csv: 3 rows missing"]
    assert grouped(notes) == ["5 files (a.csv, b.csv, c.csv, ...): y: mm -> m (x 0.001)",
                              "2 files (a.csv, b.csv): 3 rows missing", "holdout as marked"]
    # Alike but for their numbers: one line, each number that differs as its range (a name's
    # digit, p1 against p2, is not a number).
    notes = ["a.csv: jitter (RMS 0.171 ms, max 0.3 ms): snapped",
             "b.csv: jitter (RMS 0.176 ms, max 0.3 ms): snapped",
             "c.csv: jitter (RMS 0.168 ms, max 0.3 ms): snapped",
             "a.csv: p1 offset -2 kPa", "b.csv: p2 offset 3 kPa"]
    assert grouped(notes) == ["3 files (a.csv, b.csv, c.csv): jitter (RMS 0.168-0.176 ms, "
                              "max 0.3 ms): snapped", "a.csv: p1 offset -2 kPa",
                              "b.csv: p2 offset 3 kPa"]
