"""Units declared in dataset.yaml (jetpipe_ros.dataset.units): gauge pressures and the ambient
pressure they are relative to, read back against the record the plant wrote in SI."""

import shutil

import numpy as np
import pytest
import yaml

from jetpipe_ros.campaign import default_campaign, run_campaign_offline
from jetpipe_ros.dataset import DatasetError, read_dataset
from jetpipe_ros.model import ModelParams
from jetpipe_ros.plant.logger import P_ATM_LOGGER, log


#: The module fixtures below are costly: every test of this module runs on one test worker
#: (``scripts/test.sh`` distributes with ``--dist loadgroup``), so they are built once.
pytestmark = pytest.mark.xdist_group("test_dataset_units")


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """One experiment of the default campaign, recorded with sensor noise, in SI."""
    root = tmp_path_factory.mktemp("units") / "clean"
    run_campaign_offline(ModelParams().with_values({"sensors.noise": True}),
                         default_campaign().select(("sweep_1p5V",)), root, seed=2)
    return root


def _relogged(clean, tmp_path, reference: str | None):
    """The clean record as the gauge_mm logger writes it (bar relative to 101325 Pa, mm), its
    reference declared as ``reference`` or left out (None)."""
    root = tmp_path / "gauge"
    shutil.copytree(clean, root)
    log("gauge_mm", root, seed=0)
    doc = yaml.safe_load((root / "dataset.yaml").read_text())
    assert doc["units"]["gauge_reference"] == "101325 Pa"  # what the logger declares
    if reference is None:
        del doc["units"]["gauge_reference"]
    else:
        doc["units"]["gauge_reference"] = reference
    (root / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return read_dataset(root).experiments[0]


@pytest.mark.parametrize("reference", ["101325 Pa", "1013.25 hPa", "1.01325 bar"])
def test_a_declared_gauge_reference_gives_the_absolute_pressures_back(clean, tmp_path,
                                                                      reference):
    truth = read_dataset(clean).experiments[0]
    gauge = _relogged(clean, tmp_path, reference)
    for p in ("p1", "p2"):
        assert np.max(np.abs(getattr(gauge, p) - getattr(truth, p))) < 1e-6  # [Pa]
    assert np.max(np.abs(gauge.y - truth.y)) < 1e-12  # [m]
    assert any("+ 101325 Pa" in n and "assumed" not in n for n in gauge.notes)


def test_an_undeclared_reference_is_the_models_atmosphere_and_the_notes_say_so(clean,
                                                                              tmp_path):
    """Without the logger's 101325 Pa the reader adds the model's 1 bar: both pressures read
    1325 Pa low, a common bias (what a barometer's reading would have set right)."""
    truth = read_dataset(clean).experiments[0]
    gauge = _relogged(clean, tmp_path, None)
    for p in ("p1", "p2"):
        bias = getattr(gauge, p) - getattr(truth, p)
        assert bias == pytest.approx(np.full_like(bias, 1e5 - P_ATM_LOGGER), abs=1e-6)
    assert any("assumed, not declared (gauge_reference)" in n for n in gauge.notes)


@pytest.mark.parametrize("reference, words", [
    ("1013", "expected an absolute pressure and its unit"),
    ("100 kPag", "expected an absolute pressure and its unit"),
    ("5 bar", "outside the 30000-120000 Pa"),
])
def test_a_bad_gauge_reference_is_refused_naming_it(clean, tmp_path, reference, words):
    with pytest.raises(DatasetError, match=f"dataset.yaml: units: gauge_reference: .*{words}"):
        _relogged(clean, tmp_path, reference)
