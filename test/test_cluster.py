"""The diagnosis's work on a Dask cluster: a self-check's cases spread over two local workers,
resumed after an interruption and scored; a fleet of three datasets, one of them bad."""

from __future__ import annotations

import functools
import json
import shutil

import dask
import pytest
import yaml
from distributed import LocalCluster

from jetpipe_ros.cli import main
from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.workflows import selfcheck
from jetpipe_ros.workflows.cluster import WORKER_CONFIG, close_local
from jetpipe_ros.workflows.fleet import dataset_dirs, names_of
from jetpipe_ros.model import ModelParams
from test_diagnosis import PLUMBING, make_dataset


#: The module fixtures below are costly: every test of this module runs on one test worker
#: (``scripts/test.sh`` distributes with ``--dist loadgroup``), so they are built once.
pytestmark = pytest.mark.xdist_group("test_cluster")


@pytest.fixture(scope="module")
def scheduler():
    """A running cluster of two single-threaded worker processes, reached by its address as a
    remote one would be (``--scheduler``); its workers set up as the README tells for workers
    started by hand (and as the package starts its local ones): no statistical profiler."""
    with dask.config.set(WORKER_CONFIG):  # passed on to the worker processes
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               dashboard_address=None)
    try:
        yield cluster.scheduler_address
    finally:
        close_local(cluster)


def _build(log, truth, root, seed):
    """The small campaign of test_diagnosis; logs each case it records and the dataset index it
    wrote (the workers are other processes: files tell what they did); case 0 fails while
    ``log``.stop exists (its truth is ``none``, the quickest to diagnose again on resuming)."""
    with open(log, "a") as f:
        f.write(root.name + "\n")
    if root.name == "case00" and log.with_suffix(".stop").exists():
        raise RuntimeError("interrupted")
    make_dataset(root, truth, seed=seed % 1000, names=PLUMBING)
    with open(log.with_suffix(".index"), "a") as f:
        f.write(json.dumps(yaml.safe_load((root / "dataset.yaml").read_text())) + "\n")


def test_selfcheck_cases_run_on_the_cluster_and_resume(tmp_path, monkeypatch, scheduler):
    """The self-check's machinery on a cluster: two cases (the model truths of seed 2: none and
    a valve lag) spread over the workers, the first case interrupted, the run resumed, then both
    scored (results, confusion, recovery, intervals, report). The truths
    are the candidates' own forms, so this checks the plumbing, not the detection: detection on
    truths of other forms is test_selfcheck's plant case; that the datasets carry no truth is
    test_selfcheck_datasets_are_the_default_campaign."""
    monkeypatch.setitem(selfcheck.KINDS, "model", ("none", "valve_lag"))
    log = tmp_path / "recorded.log"
    log.with_suffix(".stop").touch()
    build = functools.partial(_build, log)
    out = tmp_path / "out"
    run = functools.partial(selfcheck.run_selfcheck, 2, 2, build, out, deviate=False,
                            source="model", scheduler=scheduler)
    with pytest.raises(selfcheck.SelfcheckError, match="1 of 2 cases failed.*case 0.*"
                                                       "interrupted.*run the same command"):
        run(progress=lambda line: None)
    assert sorted(log.read_text().split()) == ["case00", "case01"]
    assert [p.parent.name for p in sorted(out.glob("cases/*/result.json"))] == ["case01"]
    assert not (out / "selfcheck.json").exists()

    log.with_suffix(".stop").unlink()
    lines = []
    summary = run(progress=lines.append)
    assert log.read_text().split()[2:] == ["case00"]  # only the first is computed
    assert len(lines) == 2 and lines[0].startswith("resuming: 1 of 2 cases already done")
    assert lines[-1].startswith("[2/2]") and "left" in lines[-1] and "none" in lines[-1]
    assert summary["resumed"] == 1 and summary["ran_on"] == f"the Dask scheduler at {scheduler}"
    assert [r["truth"] for r in summary["results"]] == ["none", "valve_lag"]
    assert [r["verdict"] for r in summary["results"]] == ["none", "valve_lag"]
    assert summary["top1_accuracy"] == 1.0 and summary["none_correct"]
    assert all(r["shrinkage"] >= 0.9 for r in summary["results"][1:])
    (lag,) = summary["recovery"]
    assert lag["param"] == "corner_frequency" and lag["rel_error"] < 0.1
    assert summary["confusion"]["valve_lag"]["valve_lag"] == 1
    by_truth = summary["accuracy_by_truth"]
    assert [by_truth[t]["cases"] for t in ("none", "valve_lag")] == [1, 1]
    for a in [*by_truth.values(), *summary["accuracy_by_kind"].values()]:
        lo, hi = a["interval"]
        assert 0.0 <= lo <= a["accuracy"] <= hi <= 1.0 and hi - lo > 0.2  # few cases: wide
    q = summary["shrinkage_quantiles"]
    assert q["cases"] >= 1 and q["min"] <= q["median"] <= q["max"]
    md = (out / "selfcheck.md").read_text()
    assert md.startswith("# jetpipe selfcheck: 2 cases") and "from the model" in md
    assert "Wilson interval" in md and selfcheck.SHRINKAGE_PNG in md
    assert (out / selfcheck.SHRINKAGE_PNG).read_bytes()[:4] == b"\x89PNG"
    assert json.loads((out / "selfcheck.json").read_text())["cases"] == 2
    assert (out / "cases" / "case01" / "diagnosis.json").exists()
    assert "valve_lag" in (out / "cases" / "case01" / "truth.yaml").read_text()
    # Each case recorded once on a worker, the interrupted one again on resuming.
    assert len(log.with_suffix(".index").read_text().splitlines()) == 2

    # Another configuration in the same OUT is refused before anything runs.
    with pytest.raises(selfcheck.SelfcheckError, match="--seed 2 .*not.*--seed 3.*--restart"):
        selfcheck.run_selfcheck(2, 3, build, out, deviate=False, source="model",
                                scheduler=scheduler, progress=lambda line: None)
    assert len(log.read_text().split()) == 3


def test_fleet_diagnoses_every_dataset_and_reports_the_bad_one(tmp_path, scheduler):
    fleet = tmp_path / "fleet"
    make_dataset(fleet / "axis1", ModelParams().with_effect("valve_lag", corner_frequency=20.0),
                 seed=1, names=PLUMBING)
    make_dataset(fleet / "axis2", ModelParams().with_values({"flow.gain_charge": 0.9,
                                                             "flow.gain_discharge": 0.9}),
                 seed=2, names=PLUMBING)
    shutil.copytree(fleet / "axis1", fleet / "axis3")
    csv = fleet / "axis3" / "sweep.csv"
    lines = csv.read_text().splitlines()
    lines[5] = "1,2,x"
    csv.write_text("\n".join(lines))
    out = tmp_path / "out"
    (out / "axis3").mkdir(parents=True)
    (out / "axis3" / "diagnosis.json").write_text("{}")  # an earlier run's: removed

    status = main(["diagnose", str(fleet / "axis*"), "--out", str(out), "--scheduler",
                   scheduler, "--quiet"])
    assert status == 1  # one dataset failed
    result = json.loads((out / "fleet.json").read_text())
    assert result["schema"] == "jetpipe.fleet/1"
    assert (result["datasets"], result["succeeded"], result["failed"]) == (3, 2, 1)
    rows = {r["name"]: r for r in result["actuators"]}
    assert [r["name"] for r in result["actuators"]][-1] == "axis3"  # failures last
    assert "sweep.csv" in rows["axis3"]["error"] and "line 6" in rows["axis3"]["error"]
    assert not (out / "axis3" / "diagnosis.json").exists()
    ok = result["actuators"][:2]
    assert ok[0]["gap"]["nominal"] >= ok[1]["gap"]["nominal"]  # sorted by gap
    assert rows["axis1"]["verdict"]["effect"] == "valve_lag"
    assert rows["axis2"]["calibration"]["significant"]
    assert rows["axis2"]["calibration"]["off"]["flow_gain_charge"] == pytest.approx(0.9, abs=0.03)
    for name in ("axis1", "axis2"):
        diag = json.loads((out / name / "diagnosis.json").read_text())
        assert diag["gap"]["nominal"] == rows[name]["gap"]["nominal"]
        assert (out / name / "report.html").exists() and (out / name / "augmented.yaml").exists()
    page = (out / "fleet.html").read_text()
    assert "data:image/png;base64," in page and "sweep.csv" in page
    assert page.index("axis3") > page.index("axis1")


def test_fleet_arguments(tmp_path):
    for name in ("a/x", "b/x", "c/y"):
        (tmp_path / name).mkdir(parents=True)
    dirs, fleet = dataset_dirs([str(tmp_path / "c" / "y")])
    assert dirs == [tmp_path / "c" / "y"] and not fleet  # one dataset: as before
    dirs, fleet = dataset_dirs([str(tmp_path / "*" / "y")])
    assert fleet  # a glob is a fleet, even of one
    with pytest.raises(DatasetError, match="matches no dataset directory"):
        dataset_dirs([str(tmp_path / "*" / "z")])
    with pytest.raises(DatasetError, match="two datasets named x"):
        names_of(dataset_dirs([str(tmp_path / "*" / "x")])[0])


def test_closing_a_local_cluster_tolerates_a_worker_reaped_late_and_nothing_else():
    """Dask kills a worker process that does not stop and gives the kill 5 s to be reaped; on a
    loaded host that can run out (TimeoutError) with the process gone: not the caller's failure.
    Any other error in closing still surfaces."""

    class Late:
        def __init__(self, error):
            self.error, self.closed = error, False

        def close(self):
            self.closed = True
            raise self.error

    late = Late(TimeoutError())
    close_local(late)
    assert late.closed
    with pytest.raises(OSError):
        close_local(Late(OSError("scheduler gone")))
