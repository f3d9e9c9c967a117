"""Faults survived by the tools, in files: impossible values and unit mistakes in datasets,
unrecognised directories given to ``export --overwrite``, bags never closed (truncated at any
byte), file-system errors (read-only directories, directories as files, empty paths) as one-line
messages with nothing half-written, strict JSON, YAML 1.2 numbers and duplicate keys."""

from __future__ import annotations

import json
import math
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.typesys import get_typestore

from jetpipe_ros import fileio
from jetpipe_ros.bag import BagWriter, export_bag
from jetpipe_ros.bag.export import BagError
from jetpipe_ros.bag.writer import TYPESTORE
from jetpipe_ros.campaign import CampaignError, load_campaign
from jetpipe_ros.cli import main
from jetpipe_ros.dataset import DatasetError, Entry, read_dataset, write_dataset
from jetpipe_ros.model import ParameterError, load_params
from jetpipe_ros.nodes import interface

REPO = Path(__file__).resolve().parent.parent
NS = 1_000_000_000


def unprivileged() -> list[str]:
    """A command prefix under which file permissions hold even for root."""
    from test_faults_nodes import unprivileged as prefix
    return prefix()


#: Runs ``jetpipe`` once per command line given as JSON on stdin; prints, as JSON, each exit
#: status and what went to stderr (a traceback if it raised).
RUNNER = """
import contextlib, io, json, sys, traceback
from jetpipe_ros.cli import main
results = []
for args in json.load(sys.stdin):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            status = main(args)
        except SystemExit as exc:
            status = exc.code
        except BaseException:
            status = "raised"
            traceback.print_exc()
    results.append((status, err.getvalue()))
print(json.dumps(results))
"""


def run_cli(commands: list[list[str]], ro: bool = False) -> list[tuple[int, str]]:
    """(exit status, stderr) of ``jetpipe`` for each command line, in one subprocess (under
    :func:`unprivileged` if ``ro``, so that read-only directories are read-only for it)."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    argv = [*(unprivileged() if ro else []), sys.executable, "-c", RUNNER]
    done = subprocess.run(argv, env=env, input=json.dumps(commands), capture_output=True,
                          text=True, timeout=300, check=True)
    return [tuple(r) for r in json.loads(done.stdout.splitlines()[-1])]


def read_only_dir(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    path.chmod(0o555)
    return path


# -- a small campaign bag, written as id_recorder writes it -----------------------------------

EXPERIMENTS = [("charge", True, 300), ("square", False, 400), ("last", False, 500)]


def write_bag(path: Path, ns: str = "/fb", close: bool = True,
              sync_every: int = 0, seed: int = 0,
              pressures: tuple[str, ...] = ("chamber1/pressure", "chamber2/pressure")
              ) -> tuple[BagWriter, dict]:
    """A bag of three experiments (events after each), synced every ``sync_every`` samples
    (as the recorder's periodic syncs would); returns the writer and the data. Bags of another
    ``seed`` hold other values; the pressure topics not in ``pressures`` are not in the bag
    (a rig without those sensors, recorded by anything that records what is there)."""
    store = get_typestore(TYPESTORE)
    topics = {f"{ns}/{t.name}" if not t.name.startswith("/") else t.name: t.type
              for t in interface.load_topics().values()
              if "pressure" not in t.name or t.name in pressures}
    bag = BagWriter(path, topics)
    js_t, fp_t = store.types["sensor_msgs/msg/JointState"], store.types[
        "sensor_msgs/msg/FluidPressure"]
    header_t, time_t = store.types["std_msgs/msg/Header"], store.types[
        "builtin_interfaces/msg/Time"]

    def header(k: int):
        return header_t(stamp=time_t(sec=k // 1000, nanosec=(k % 1000) * 1_000_000),
                        frame_id="actuator")

    def put(topic: str, k: int, msg, msgtype: str) -> None:
        bag.write(f"{ns}/{topic}", k * 1_000_000, store.serialize_cdr(msg, msgtype))

    data: dict[str, dict[str, np.ndarray]] = {}
    k = 0
    bag.event(0, event="campaign", source="test", experiments=len(EXPERIMENTS))
    for name, locked, n in EXPERIMENTS:
        start = k
        rng = np.random.default_rng(n + 1000 * seed)
        y = 0.0 if locked else 0.01 * np.sin(np.arange(n + 1) / 50.0)
        y = np.broadcast_to(y, (n + 1,))
        p1 = 4e5 + 1e5 * rng.random(n + 1)
        p2 = 4e5 - 1e5 * rng.random(n + 1)
        u = np.round(rng.uniform(-1, 1, n + 1), 3)
        for i in range(n + 1):
            put("joint_states", k, js_t(header=header(k), name=["piston"], position=np.array(
                [y[i]]), velocity=np.array([0.0]), effort=np.array([0.0])),
                "sensor_msgs/msg/JointState")
            for c, p in (("chamber1/pressure", p1[i]), ("chamber2/pressure", p2[i])):
                if c in pressures:
                    put(c, k, fp_t(header=header(k), fluid_pressure=p, variance=0.0),
                        "sensor_msgs/msg/FluidPressure")
            put("voltage_applied", k, js_t(header=header(k), name=["valve", "load"],
                                           position=np.array([u[i], math.nan]),
                                           velocity=np.array([], dtype=float),
                                           effort=np.array([math.nan, 0.0])),
                "sensor_msgs/msg/JointState")
            k += 1
            if sync_every and k % sync_every == 0:
                bag.sync()
        k -= 1  # the next experiment starts at this one's last sample + 1 row of u
        bag.event(k * 1_000_000, event="experiment", name=name, kind="open_loop",
                  locked=locked, role="train", load_force=0.0, regulated=False,
                  start_ns=start * 1_000_000, samples=n, dt=0.001, complete=True)
        data[name] = {"y": y[:n], "p1": p1[:n], "p2": p2[:n], "u": u[1:n + 1]}
        k += 1
    if close:
        bag.close()
    return bag, data


def test_synthetic_bag_exports(tmp_path):
    _, data = write_bag(tmp_path / "bag")
    ds = read_dataset(export_bag(tmp_path / "bag", tmp_path / "out", progress=lambda _: None))
    assert [e.name for e in ds.entries] == [n for n, _, _ in EXPERIMENTS]
    for entry, x in ds:
        np.testing.assert_allclose(x.p1, data[entry.name]["p1"], rtol=1e-8)
        np.testing.assert_allclose(x.u, data[entry.name]["u"])


def test_a_bag_without_pressure_topics_exports_the_position_alone(tmp_path):
    """A rig with no pressure sensor: no pressure topic in the bag. Each CSV has no p1, p2
    column, the export says so, and the dataset reads as position-only records."""
    _, data = write_bag(tmp_path / "bag", pressures=())
    said = []
    ds = read_dataset(export_bag(tmp_path / "bag", tmp_path / "out", progress=said.append))
    for entry, x in ds:
        header = (ds.root / entry.file).read_text().splitlines()[0]
        assert header == "t,u,y,v,f_load" and x.p1 is None and x.p2 is None
        np.testing.assert_allclose(x.y, data[entry.name]["y"], atol=1e-12)
        np.testing.assert_allclose(x.u, data[entry.name]["u"])
    assert "p1 and p2 not measured (no message on the topic) in every experiment" in said[-1]


def test_a_recording_without_campaign_events_exports_as_one_record(tmp_path):
    """A bag of a driver recorded with ``mode: record`` (no campaign events): stamps jittered by
    up to 0.2 ms, 30 joint_states samples lost, no chamber 2 sensor. One experiment: a row per
    joint_states stamp with the command applied after it (the voltage_applied stamped next,
    found where the next sample was lost too), the lost samples left for the dataset reader,
    which snaps the stamps and fills those rows; p2 not measured."""
    store = get_typestore(TYPESTORE)
    topics = {f"/rig/{t.name}": t.type for t in interface.load_topics().values()
              if t.name != "chamber2/pressure" and not t.name.startswith("/")}
    bag = BagWriter(tmp_path / "bag", topics)
    js_t, fp_t = store.types["sensor_msgs/msg/JointState"], store.types[
        "sensor_msgs/msg/FluidPressure"]
    header_t, time_t = store.types["std_msgs/msg/Header"], store.types[
        "builtin_interfaces/msg/Time"]
    rng = np.random.default_rng(3)
    n = 3000
    stamps = 5_000_000_000 + 1_000_000 * np.arange(n) + rng.integers(-200_000, 200_000, n)
    lost = set(rng.choice(np.arange(1, n - 2), 30, replace=False).tolist())
    u = np.round(rng.uniform(-1.0, 1.0, n), 3)  # u[k]: applied over [t_k, t_k+1)
    y, p1 = 0.01 * np.sin(np.arange(n) / 80.0), 4e5 + 1e5 * rng.random(n)

    def header(ns: int):
        return header_t(stamp=time_t(sec=int(ns) // 10**9, nanosec=int(ns) % 10**9),
                        frame_id="actuator")

    for k, ns in enumerate(stamps):
        put = lambda topic, msg, kind: bag.write(f"/rig/{topic}", int(ns),  # noqa: E731
                                                 store.serialize_cdr(msg, kind))
        if k not in lost:
            put("joint_states", js_t(header=header(ns), name=["piston"], position=np.array(
                [y[k]]), velocity=np.array([0.0]), effort=np.array([0.0])),
                "sensor_msgs/msg/JointState")
        put("chamber1/pressure", fp_t(header=header(ns), fluid_pressure=p1[k], variance=0.0),
            "sensor_msgs/msg/FluidPressure")
        if k > 0:  # the command applied over the sample that ends here
            put("voltage_applied", js_t(header=header(ns), name=["valve", "load"],
                                        position=np.array([u[k - 1], math.nan]),
                                        velocity=np.array([], dtype=float),
                                        effort=np.array([math.nan, 0.0])),
                "sensor_msgs/msg/JointState")
    bag.close()
    said = []
    ds = read_dataset(export_bag(tmp_path / "bag", tmp_path / "out", progress=said.append))
    ((entry, exp),) = list(ds)
    assert entry.name == "bag" and not entry.locked and entry.role is None
    assert entry.extra["lost_samples"] == len(lost)  # the last sample, no command after it,
    # is not in the span
    assert exp.t.size == n - 1 and np.allclose(np.diff(exp.t), 1e-3)  # snapped, filled
    measured = np.flatnonzero(exp.valid)
    assert sorted(set(range(n - 1)) - set(measured.tolist())) == sorted(lost)
    assert np.array_equal(exp.u[measured], u[measured])
    np.testing.assert_allclose(exp.y[measured], y[measured], atol=1e-12)
    np.testing.assert_allclose(exp.p1[measured], p1[measured], atol=1e-3)  # %.9g
    assert exp.p2 is None
    assert "no campaign events" in said[0] and "p2 not measured" in said[1]


# -- item 2: a bag never closed, cut at any byte -----------------------------------------------


def test_unclosed_bag_cut_anywhere_recovers_every_synced_experiment(tmp_path):
    bag, data = write_bag(tmp_path / "bag", close=False, sync_every=100)
    bag.sync()
    (mcap,) = (tmp_path / "bag").glob("*.mcap")
    full = mcap.read_bytes()
    assert not (tmp_path / "bag" / "metadata.yaml").exists()
    ds = read_dataset(export_bag(tmp_path / "bag", tmp_path / "all", progress=lambda _: None))
    assert [e.name for e in ds.entries] == ["charge", "square", "last"]
    # Cut the file at 40 places: each export keeps a prefix of the experiments, exactly.
    kept_counts = set()
    for cut in np.linspace(len(full) // 20, len(full) - 1, 40).astype(int):
        mcap.write_bytes(full[:cut])
        messages: list[str] = []
        try:
            ds = read_dataset(export_bag(tmp_path / "bag", tmp_path / f"cut{cut}",
                                         progress=messages.append))
        except BagError as exc:  # too early: no experiment complete yet
            assert "no complete experiment" in str(exc) or "expected one topic" in str(exc)
            continue
        names = [e.name for e in ds.entries]
        assert names == ["charge", "square", "last"][:len(names)]
        kept_counts.add(len(names))
        assert any("recovering it from the MCAP stream" in m for m in messages)
        assert any(m.startswith("recovered ") and "unreadable" in m for m in messages)
        for entry, x in ds:
            np.testing.assert_allclose(x.p1, data[entry.name]["p1"], rtol=1e-8)
    assert kept_counts == {1, 2, 3}


def test_closed_bag_with_truncated_file_is_recovered(tmp_path):
    _, data = write_bag(tmp_path / "bag")
    (mcap,) = (tmp_path / "bag").glob("*.mcap")
    full = mcap.read_bytes()
    mcap.write_bytes(full[: int(len(full) * 0.9)])  # metadata.yaml present, footer gone
    messages: list[str] = []
    ds = read_dataset(export_bag(tmp_path / "bag", tmp_path / "out", progress=messages.append))
    assert any("recovering it from the MCAP stream" in m for m in messages), messages
    # The cut takes the footer and the summary section behind the data: every experiment is
    # still there, whole and unchanged (none lost, none cut short, no value changed).
    assert [e.name for e in ds.entries] == ["charge", "square", "last"]
    for entry, x in ds:
        assert len(x.t) == len(data[entry.name]["p1"])
        np.testing.assert_allclose(x.p1, data[entry.name]["p1"], rtol=1e-8)
        np.testing.assert_allclose(x.p2, data[entry.name]["p2"], rtol=1e-8)
        np.testing.assert_allclose(x.u, data[entry.name]["u"])


def test_writer_syncs_once_the_period_has_passed(tmp_path):
    from jetpipe_ros.bag.recover import stream_messages
    from jetpipe_ros.bag.writer import SYNC_PERIOD

    bag, _ = write_bag(tmp_path / "bag", close=False)
    (mcap,) = (tmp_path / "bag").glob("*.mcap")
    assert sum(1 for _ in stream_messages(mcap)) < sum(bag.counts.values())  # in memory
    bag.synced -= SYNC_PERIOD  # as if the period had passed
    bag.sync_if_due()  # the recorder calls it every 0.1 s and at every write
    assert sum(1 for _ in stream_messages(mcap)) == sum(bag.counts.values())
    bag.close()


# -- item 1: export --overwrite only a dataset it wrote ---------------------------------------


def test_export_overwrite_refuses_what_it_did_not_write(tmp_path, monkeypatch):
    bags = tmp_path / "bags"
    _, run1 = write_bag(bags / "run1")
    _, run2 = write_bag(bags / "run2", seed=1)  # other values: a no-op overwrite would show
    work = tmp_path / "work"  # the current directory: a dataset, but never replaced
    export_bag(bags / "run2", work, progress=lambda _: None)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    monkeypatch.chdir(work)
    for target, reason in ((bags, "contains"), (bags / "run1", "is "),
                           (bags / "run1" / "data", "lies inside"), (tmp_path, "contains"),
                           (work, "current directory"), (Path("."), "current directory")):
        with pytest.raises(DatasetError, match=reason):
            export_bag(bags / "run1", target, overwrite=True, progress=lambda _: None)
    assert main(["export", str(bags / "run1"), ".", "--overwrite"]) == 2
    other = tmp_path / "notes"
    other.mkdir()
    (other / "thesis.tex").write_text("precious")
    with pytest.raises(DatasetError, match="refusing to overwrite: it has no dataset.yaml"):
        export_bag(bags / "run1", other, overwrite=True, progress=lambda _: None)
    (work / "thesis.tex").write_text("precious")  # a dataset plus a file it does not list
    monkeypatch.chdir(tmp_path / "bags")
    with pytest.raises(DatasetError, match="refusing to overwrite: it holds 'thesis.tex', "
                                           "which dataset.yaml does not list"):
        export_bag(bags / "run1", work, overwrite=True, progress=lambda _: None)
    after = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    assert after == sorted([*before, Path("notes"), Path("notes/thesis.tex"),
                            Path("work/thesis.tex")])
    # A dataset it wrote is replaced, whole.
    out = tmp_path / "data"
    export_bag(bags / "run1", out, progress=lambda _: None)
    with pytest.raises(DatasetError, match="not empty"):
        export_bag(bags / "run2", out, progress=lambda _: None)
    export_bag(bags / "run2", out, overwrite=True, progress=lambda _: None)
    replaced = read_dataset(out)
    assert [e.name for e in replaced.entries] == ["charge", "square", "last"]
    for entry, x in replaced:
        np.testing.assert_allclose(x.p1, run2[entry.name]["p1"], rtol=1e-8)
        np.testing.assert_allclose(x.u, run2[entry.name]["u"])
        assert not np.allclose(x.p1, run1[entry.name]["p1"])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries


def test_export_checks_the_output_before_reading_the_bag(tmp_path):
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "broken.mcap").write_bytes(b"garbage")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    with pytest.raises(DatasetError, match="not empty"):  # not a complaint about the bag
        export_bag(broken, tmp_path / "full", progress=lambda _: None)


# -- item 4: impossible values and unit mistakes ----------------------------------------------


def make_dataset(root: Path, **changes) -> Path:
    """A valid one-experiment dataset; ``changes`` replace columns (callables of the column)."""
    n = 2000
    t = np.arange(n) * 1e-3
    cols = {"t": t, "u": 0.5 * np.sign(np.sin(2 * np.pi * t)), "y": 0.01 * np.sin(t),
            "p1": 3e5 + 2e5 * np.sin(2 * np.pi * t), "p2": 3e5 - 2e5 * np.sin(2 * np.pi * t),
            "v": 0.01 * np.cos(t)}  # one chamber at a time vented to atmosphere (1 bar)
    for name, change in changes.items():
        cols[name] = change(cols[name].copy())
    root.mkdir(parents=True)
    text = "t,u,y,p1,p2,v\n" + "\n".join(",".join(f"{cols[c][i]:.9g}" for c in cols)
                                         for i in range(n)) + "\n"
    (root / "e.csv").write_text(text)
    (root / "dataset.yaml").write_text("experiments:\n  - {file: e.csv, role: train}\n")
    return root


def _set(index, value):
    def change(x):
        x[index] = value
        return x
    return change


@pytest.mark.parametrize("changes, message", [
    ({"p1": _set(99, 1e300)}, r"line 101, column 'p1': 1e\+300 Pa is not an absolute pressure"),
    ({"p2": lambda x: x / 1e5}, r"column 'p2': .* look like bar: multiply by 100000"),
    ({"p1": lambda x: x / 1e3}, r"column 'p1': .* look like kPa"),
    ({"p1": lambda x: x - 1.01325e5}, r"column 'p1': .* look like gauge pressure"),
    ({"y": lambda x: x * 1e3}, r"column 'y': .* look like mm: multiply by 0.001"),
    ({"y": lambda x: x + 0.025}, r"column 'y': .* look measured from an end stop"),
    ({"y": _set(5, 0.2)}, r"line 7, column 'y': 0.2 m is not a position within the stroke"),
    ({"u": lambda x: x * 1e3}, r"column 'u': .* look like mV"),
    ({"t": lambda x: x * 1e3}, r"column 't': .* looks like ms"),
    ({"v": _set(3, -1e9)}, r"line 5, column 'v'"),
])
def test_impossible_values_are_named(tmp_path, changes, message):
    root = make_dataset(tmp_path / "d", **changes)
    with pytest.raises(DatasetError, match=message) as info:
        read_dataset(root)
    assert str(root / "e.csv") in str(info.value)


def test_valid_dataset_passes(tmp_path):
    assert len(read_dataset(make_dataset(tmp_path / "d"))) == 1


@pytest.mark.parametrize("command", ["diagnose", "identify"])
def test_tools_refuse_impossible_values_and_write_nothing(tmp_path, command, capsys):
    root = make_dataset(tmp_path / "d", p1=_set(10, 1e300))
    out = tmp_path / ("out" if command == "diagnose" else "p.yaml")
    # diagnose in this process: with the default --jobs it would start a local Dask cluster in
    # the background only to close it after the refusal (about 10 s here; a local cluster
    # started, used and closed: test_diagnosis's lag_result).
    jobs = ["--jobs", "1"] if command == "diagnose" else []
    assert main([command, str(root), "--out", str(out), *jobs]) == 2
    (error,) = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert "column 'p1'" in error and "1e+300" in error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


# -- item 4: strict JSON ----------------------------------------------------------------------


def _strict(text: str):
    def refuse(token):
        raise ValueError(f"non-standard JSON token {token}")
    return json.loads(text, parse_constant=refuse)


def test_json_is_strict(tmp_path):
    obj = {"a": math.nan, "b": [np.float64(np.inf), -math.inf], "c": np.arange(2),
           "d": np.float32(1.5), "e": (1, 2)}
    fileio.write_json(tmp_path / "x.json", obj)
    assert _strict((tmp_path / "x.json").read_text()) == {
        "a": None, "b": [None, None], "c": [0, 1], "d": 1.5, "e": [1, 2]}


# -- item 5: file-system errors ---------------------------------------------------------------


def _one_line_error(result: tuple[int, str], *needles: str) -> None:
    status, stderr = result
    assert status == 2, stderr
    assert "Traceback" not in stderr, stderr
    lines = [line for line in stderr.splitlines() if "error" in line]
    assert len(lines) == 1, stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


def test_cli_file_system_errors(tmp_path):
    cmd = tmp_path / "cmd.csv"
    cmd.write_text("t,u\n0,0\n0.001,0.5\n0.002,0.5\n")
    ro = read_only_dir(tmp_path / "ro")
    data = make_dataset(tmp_path / "data")
    (tmp_path / "adir").mkdir()
    cases = [
        (["simulate", "--input", str(cmd), "--out", str(ro / "sim.csv")],
         ("--out", "Permission denied")),
        (["simulate", "--input", str(cmd), "--out", str(tmp_path / "adir")],
         ("is a directory",)),
        (["simulate", "--input", str(cmd), "--out", ""], ("empty path",)),
        (["identify", str(data), "--out", str(tmp_path / "adir")],
         ("is a directory",)),
        (["identify", str(data), "--out", str(ro / "p.yaml")],
         ("--out", "Permission denied")),
        (["identify", str(data), "--out", str(tmp_path / "p.yaml"), "--report",
          str(ro / "r.html")], ("--report", "Permission denied")),
        (["identify", str(data), "--out", ""], ("empty path",)),
        (["diagnose", str(data), "--out", str(ro / "diag")],
         ("--out", "Permission denied")),
        (["diagnose", str(data), "--out", ""], ("empty path",)),
        (["export", str(tmp_path / "nobag"), str(ro / "ds")], ("Permission denied",)),
        (["simulate", "--params", str(tmp_path / "adir"), "--input", str(cmd), "--out",
          str(tmp_path / "s.csv")], ("adir",)),
    ]
    results = run_cli([args for args, _ in cases], ro=True)
    for (_, needles), result in zip(cases, results):
        _one_line_error(result, *needles)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir", "cmd.csv", "data", "ro"]
    assert list(ro.iterdir()) == [] and list((tmp_path / "adir").iterdir()) == []


def test_jobs_must_be_positive(capsys):
    for jobs in ("0", "-3"):
        with pytest.raises(SystemExit) as info:
            main(["diagnose", "d", "--out", "o", "--jobs", jobs])
        assert info.value.code == 2
        assert "--jobs: expected a whole number >= 1" in capsys.readouterr().err


def test_write_files_is_all_or_nothing(tmp_path):
    first = tmp_path / "params.yaml"
    first.write_text("old")
    (tmp_path / "report.html").mkdir()  # the second target cannot be written
    with pytest.raises(fileio.FileError, match="report.html"):
        fileio.write_files({first: "new", tmp_path / "report.html": "page"})
    assert first.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["params.yaml", "report.html"]


def test_written_files_are_0644(tmp_path):
    fileio.write_text(tmp_path / "a.txt", "x")
    write_dataset(tmp_path / "ds", [(Entry("e.csv"), {"t": np.arange(3) * 1e-3,
                                                     "u": np.zeros(3)})])
    for path in (tmp_path / "a.txt", tmp_path / "ds" / "e.csv", tmp_path / "ds" / "dataset.yaml"):
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path
    assert stat.S_IMODE((tmp_path / "ds").stat().st_mode) == 0o755


# -- item 6: YAML 1.2 numbers, duplicate keys -------------------------------------------------


def test_yaml_12_floats_in_params(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("actuator_sim:\n  ros__parameters:\n    mechanics: {mass: 2e0}\n"
                    "    chamber: {dead_volume_1: 1.6e-4, initial_pressure_1: 4e5}\n")
    params = load_params(path)
    assert params["mechanics.mass"] == 2.0
    assert params["chamber.initial_pressure_1"] == 4e5
    path.write_text("mechanics: {mass: 1.0e300}\n")
    with pytest.raises(ParameterError, match="mechanics.mass"):  # a number, out of range
        load_params(path)
    assert fileio.parse_yaml("a: 2\nb: 0x10\nc: '2e0'\nd: .5\ne: 1_000.5") == {
        "a": 2, "b": 16, "c": "2e0", "d": 0.5, "e": 1000.5}


def test_duplicate_keys_are_refused_everywhere(tmp_path):
    params = tmp_path / "p.yaml"
    params.write_text("mechanics:\n  mass: 2.0\n  stroke: 0.05\n  mass: 3.0\n")
    with pytest.raises(ParameterError, match=r"p.yaml: .*line 4.*key 'mass' given twice "
                                             r"\(first at line 2\)"):
        load_params(params)
    plan = tmp_path / "plan.yaml"
    plan.write_text("experiments: []\nexperiments: []\n")
    with pytest.raises(CampaignError, match="plan.yaml: .*key 'experiments' given twice"):
        load_campaign(plan)
    root = make_dataset(tmp_path / "d")
    (root / "dataset.yaml").write_text("experiments:\n  - {file: e.csv, role: train, "
                                       "role: holdout}\n")
    with pytest.raises(DatasetError, match="dataset.yaml: .*key 'role' given twice"):
        read_dataset(root)


def test_merge_keys_are_not_duplicates():
    assert fileio.parse_yaml("base: &b {a: 1, b: 2}\nx:\n  <<: *b\n  a: 3\n")["x"] == {
        "a": 3, "b": 2}
    assert yaml.safe_load("a: 1") == {"a": 1}  # PyYAML itself is left as it is


def test_children_die_with_their_parent(tmp_path):
    """A node started by a parent that is killed without stopping it (SIGKILL; a test runner
    ended by SIGTERM runs no finalizer) ends too: it would otherwise keep publishing in its
    ROS domain. Also when a worker thread starts it and waits for it (the gap monitor's
    diagnosis): the kernel signals when the starting thread ends, which it does only after the
    child. Control: the same child started without the request outlives its parent (given a
    second: the kernel signals at once, the child ends in milliseconds)."""

    script = tmp_path / "parent.py"
    script.write_text(
        "import subprocess, sys, threading, time\n"
        "from jetpipe_ros.children import die_with_parent\n"
        "kw = {'preexec_fn': die_with_parent} if sys.argv[1] != 'off' else {}\n"
        "def start():\n"
        "    child = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'],"
        " **kw)\n"
        "    print(child.pid, flush=True)\n"
        "    child.wait()\n"
        "if sys.argv[1] == 'thread':\n"
        "    threading.Thread(target=start, daemon=True).start()\n"
        "else:\n"
        "    start()\n"
        "time.sleep(60)\n")
    alive = {}
    for mode in ("on", "thread", "off"):
        parent = subprocess.Popen([sys.executable, str(script), mode], stdout=subprocess.PIPE,
                                  text=True, cwd=Path(__file__).resolve().parents[1])
        child = int(parent.stdout.readline())
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + (10.0 if mode == "on" else 1.0)
        while time.monotonic() < deadline and _running(child):
            time.sleep(0.05)
        alive[mode] = _running(child)
        if alive[mode]:
            os.kill(child, signal.SIGKILL)
    assert alive == {"on": False, "thread": False, "off": True}


def _running(pid: int) -> bool:
    """True while ``pid`` runs (a zombie awaiting its reaper counts as ended)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False
