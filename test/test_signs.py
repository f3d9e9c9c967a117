"""Which way the signals count (jetpipe_ros.diagnosis.signs): records rewritten here, apart from
the code that reads them, as a rig with a sensor mounted the other way, a valve wired the other
way or the pressures on each other's channels would log them, read back by the contract."""

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from jetpipe_ros.campaign import default_campaign, run_campaign_offline
from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.diagnosis.data import prepare
from jetpipe_ros.diagnosis.signs import measure
from jetpipe_ros.model import ModelParams, load_params
from foreign_hardware import write_foreign_dataset, write_foreign_params

#: A short campaign with locked, open-loop and closed-loop experiments, three held out.
EXPERIMENTS = ("charge_2p86V", "valve_sweep_1V", "sweep_1p5V", "prbs_multilevel", "stick_slip",
               "square_3V_0p97Hz", "sweep_0p8V", "stick_slip_holdout")

pytestmark = pytest.mark.xdist_group("test_signs")


def record(root: Path, params: ModelParams) -> Path:
    """The short campaign recorded on ``params`` with the paper's sensor noise, no velocity."""
    run_campaign_offline(params.with_values({"sensors.noise": True}),
                         default_campaign().select(EXPERIMENTS), root, seed=4)
    rewire(root, drop=("v",))
    return root


def rewire(root: Path, negate: tuple[str, ...] = (), cross: bool = False,
           drop: tuple[str, ...] = ()) -> None:
    """Rewrite every CSV of ``root``: the columns ``negate`` with the opposite sign, the columns
    ``drop`` not logged, then the pressure columns' names exchanged (``cross``)."""
    doc = yaml.safe_load((root / "dataset.yaml").read_text())
    for entry in doc["experiments"]:
        path = root / entry["file"]
        header = path.read_text().splitlines()[0].split(",")
        data = np.loadtxt(path, delimiter=",", skiprows=1)
        for c in negate:
            if c in header:
                data[:, header.index(c)] *= -1.0
        keep = [i for i, c in enumerate(header) if c not in drop]
        names = [{"p1": "p2", "p2": "p1"}.get(header[i], header[i]) if cross else header[i]
                 for i in keep]
        np.savetxt(path, data[:, keep], delimiter=",", header=",".join(names), comments="",
                   fmt="%.17g")


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """An actuator with its parameters off as the self-check moves them (seed 11)."""
    from jetpipe_ros.workflows.selfcheck import deviations

    changes, _ = deviations(np.random.default_rng(11), ModelParams())
    return record(tmp_path_factory.mktemp("signs") / "clean", ModelParams().with_values(changes))


def test_a_record_logged_by_the_contract_is_read_as_logged(clean):
    """Every signal's changes follow the nominal model's (parameters off and all): nothing
    else is tried."""
    found = measure(read_dataset(clean), prepare(read_dataset(clean)), ModelParams())
    assert found.changes == () and found.also_fit == ()
    assert set(found.taken.correlation) == {"y", "p1", "p2"}
    assert min(found.taken.correlation.values()) > 0.9


@pytest.mark.parametrize("negate, cross, drop, changes", [
    (("y",), False, (), ("y",)),  # a position sensor mounted the other way
    (("u",), False, (), ("u",)),  # a valve wired the other way
    ((), True, (), ("p",)),  # the pressure sensors on each other's channels
    (("y",), False, ("p1", "p2"), ("y",)),  # the position alone, counted the other way
    (("u",), False, ("p1", "p2"), ("u",)),  # the position alone, the valve wired the other way
    ((), True, ("p2",), ("p",)),  # chamber 1's sensor alone, logged as p2
])
def test_a_signal_counted_the_other_way_is_found_and_read_by_the_contract(clean, tmp_path,
                                                                          negate, cross, drop,
                                                                          changes):
    """The rewritten signals move against the nominal model's prediction (a correlation below
    -0.3; the contract's reading gives above 0.9), and read back the one way that makes every
    signal follow it, each correlation then within 0.02 of the record logged by the contract
    with the same sensors."""
    reference = Path(shutil.copytree(clean, tmp_path / "reference"))
    rewire(reference, drop=drop)
    root = Path(shutil.copytree(clean, tmp_path / "rewired"))
    rewire(root, negate=negate, cross=cross, drop=drop)
    found = measure(read_dataset(root), prepare(read_dataset(root)), ModelParams())
    assert found.changes == changes
    assert min(found.as_logged.correlation.values()) < -0.3
    truth = measure(read_dataset(reference), prepare(read_dataset(reference)), ModelParams())
    assert truth.changes == ()
    assert found.taken.correlation == pytest.approx(truth.taken.correlation, abs=0.02)
    assert "and are read so; declare" in found.words


def test_hardware_outside_the_model_class_is_read_as_logged(tmp_path):
    """The on/off-valve cylinder the model does not describe: its signals follow the model
    weakly (the position 0.44) but not against it, so nothing is turned round."""
    root = write_foreign_dataset(tmp_path / "data")
    params = load_params(write_foreign_params(tmp_path / "params.yaml"))
    found = measure(read_dataset(root), prepare(read_dataset(root)), params)
    assert found.changes == ()
    assert 0.2 < found.taken.correlation["y"] < 0.7

