"""jetpipe trend: diagnoses of one actuator over time, and the drifts among them."""

from __future__ import annotations

import json
from datetime import date, timedelta

import numpy as np
import pytest

from jetpipe_ros.cli import main
from jetpipe_ros.diagnosis.verdict import MIN_T
from jetpipe_ros.twin import cli as trend_cli

KNOBS = ("flow_gain_charge", "flow_gain_discharge", "valve_gain", "valve_frequency",
         "dead_volume_1", "dead_volume_2", "friction_entry", "friction_exit", "viscous_entry",
         "viscous_exit")
WEEKS = 6
STEP = 0.08  # friction factor gained per week
SCATTER = 0.02  # scatter of a recalibrated knob between diagnoses (one sigma)


def _diagnoses(root, leak_from_week: int = 3):
    """Weekly diagnoses of a plant whose seals wear: both friction knobs grow by STEP a week;
    from ``leak_from_week`` on the verdict is a leak whose coefficient grows too."""
    rng = np.random.default_rng(3)
    start = date(2026, 1, 5)
    for week in range(WEEKS):
        knobs = {k: 1.0 + SCATTER * rng.standard_normal() for k in KNOBS}
        for k in ("friction_entry", "friction_exit"):
            knobs[k] += STEP * week
        leaking = week >= leak_from_week
        verdict = {"effect": "leakage" if leaking else "none", "subsystem": "chamber",
                   "params": {"cross_coefficient": 1e-9 * (week - 2)} if leaking else {}}
        folder = root / f"axis1_{start + timedelta(weeks=week):%Y-%m-%d}" / "diagnosis"
        folder.mkdir(parents=True)
        (folder / "diagnosis.json").write_text(json.dumps(
            {"schema": "jetpipe.diagnosis/1", "verdict": verdict,
             "calibration": {"knobs": knobs}}))


def test_friction_growing_week_by_week_is_a_drift_of_the_right_rate(tmp_path, capsys):
    _diagnoses(tmp_path / "history")
    assert main(["trend", str(tmp_path / "history"), "--out", str(tmp_path / "out")]) == 0
    doc = json.loads((tmp_path / "out" / "trend.json").read_text())
    assert [d["date_from"] for d in doc["diagnoses"]] == ["name"] * WEEKS
    series = {s["name"]: s for s in doc["series"]}
    for k in ("friction_entry", "friction_exit"):
        s = series[k]
        assert s["drift"] and s["t"] >= MIN_T
        true_rate = STEP / 7.0
        assert s["rate_per_day"] > 0.0
        assert abs(s["rate_per_day"] - true_rate) <= 2.0 * s["rate_stderr_per_day"]
        assert s["rate_stderr_per_day"] < 0.25 * true_rate
    for k in set(KNOBS) - {"friction_entry", "friction_exit"}:
        assert not series[k]["drift"], series[k]
    leak = series["leakage.cross_coefficient"]
    assert leak["points"] == WEEKS - 3 and leak["drift"]
    assert leak["rate_per_day"] == pytest.approx(1e-9 / 7.0, rel=1e-6)
    assert sorted(doc["drifts"]) == ["friction_entry", "friction_exit",
                                     "leakage.cross_coefficient"]
    png = (tmp_path / "out" / "trend.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    out = capsys.readouterr().out
    assert "friction_entry" in out and "DRIFT" in out


def test_a_date_field_wins_over_the_folder_name(tmp_path):
    _diagnoses(tmp_path / "h")
    first = sorted((tmp_path / "h").rglob("diagnosis.json"))[0]
    doc = json.loads(first.read_text())
    doc["date"] = "2025-12-01T08:00:00Z"
    first.write_text(json.dumps(doc))
    assert main(["trend", str(tmp_path / "h"), "--out", str(tmp_path / "o")]) == 0
    dated = json.loads((tmp_path / "o" / "trend.json").read_text())["diagnoses"][0]
    assert (dated["date"], dated["date_from"]) == ("2025-12-01T08:00:00+00:00", "field")


def test_a_folder_without_diagnoses_is_named(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["trend", str(tmp_path / "empty"), "--out", str(tmp_path / "o")]) == 2
    assert f"{tmp_path / 'empty'}: no diagnosis.json" in capsys.readouterr().err
    assert not (tmp_path / "o" / "trend.json").exists()


def test_the_command_states_the_diagnosis_significance_bar():
    assert trend_cli.MIN_T == MIN_T
