"""jetpipe selfcheck, small: withheld truths are found, `none` is answered, nothing leaks."""

import pytest
import yaml

from jetpipe_ros.diagnosis import selfcheck
from test_diagnosis import make_dataset


def test_cases_cycle_through_every_kind_with_realistic_sizes():
    cases = selfcheck.make_cases(len(selfcheck.KINDS), seed=1)
    assert [c.kind for c in cases] == list(selfcheck.KINDS)
    lag = next(c for c in cases if c.kind == "valve_lag")
    assert 10.0 <= lag.effects["valve_lag"]["corner_frequency"] <= 60.0
    orifice = next(c for c in cases if c.kind == "orifice_leak")
    assert orifice.truth == "leakage" and orifice.effects["leakage"]["form"] == "orifice"
    assert next(c for c in cases if "+" in c.kind).truth.count("+") == 1


def test_small_selfcheck_scores_the_diagnosis(tmp_path, monkeypatch):
    written = []

    def build(params, root, seed):
        make_dataset(root, params, seed=seed % 1000)
        written.append(yaml.safe_load((root / "dataset.yaml").read_text()))

    kinds = ("none", "valve_lag", "heat_transfer_thermal")
    monkeypatch.setattr(selfcheck, "KINDS", kinds)
    lines = []
    summary = selfcheck.run_selfcheck(3, seed=2, make_dataset=build, out_dir=tmp_path,
                                      progress=lines.append)
    # The heat-transfer truth has no candidate of its form: the polytropic one stands in.
    assert [r["verdict"] for r in summary["results"]] == ["none", "valve_lag", "thermal"]
    assert summary["top1_accuracy"] == 1.0 and summary["none_correct"]
    assert summary["variant_accuracy"] == 1.0
    lag, thermal = summary["results"][1:]
    assert lag["shrinkage"] >= 0.9 and thermal["shrinkage"] >= 0.3
    (rec,) = summary["recovery"]
    assert rec["param"] == "corner_frequency" and rec["rel_error"] < 0.1
    assert summary["confusion"]["valve_lag"]["valve_lag"] == 1
    assert len(lines) == 3 and "valve_lag" in lines[1]
    assert (tmp_path / "selfcheck.md").read_text().startswith("# jetpipe selfcheck: 3 cases")
    # The diagnosis saw only measurements: the dataset index carries no truth.
    for index in written:
        assert set(index) == {"experiments"}
        assert all(set(e) <= {"file", "piston", "load_force", "role"}
                   for e in index["experiments"])


@pytest.mark.parametrize("kind", ["moving_mass"])
def test_an_invisible_truth_accepts_none(kind):
    case = selfcheck.Case(0, kind, {"moving_mass": {"mass": 1.05}}, seed=1, visible=False,
                          verdict="none")
    assert case.correct
    case.visible = True
    assert not case.correct


def test_selfcheck_datasets_are_the_default_campaign(tmp_path):
    from jetpipe_ros.campaign import default_campaign
    from jetpipe_ros.dataset import read_dataset
    from jetpipe_ros.diagnosis.cli import campaign_dataset
    from jetpipe_ros.diagnosis.data import prepare
    from jetpipe_ros.model import ModelParams

    campaign_dataset(ModelParams().with_values({"sensors.noise": True}), tmp_path / "d", seed=7)
    prep = prepare(read_dataset(tmp_path / "d"))
    assert [r.name for r in prep.records] == [e.name for e in default_campaign().experiments]
    assert prep.seconds("holdout") >= 10.0 and prep.seconds("train") >= 60.0
    assert prep.noise["p1"] == pytest.approx(500.0, rel=0.1)
