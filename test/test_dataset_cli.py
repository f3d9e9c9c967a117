"""Experiment CSV reading and ``jetpipe simulate``: replay, bad input, nothing half-written."""

import numpy as np
import pytest

from jetpipe_ros.cli import main
from jetpipe_ros.dataset import DatasetError, read_experiment
from jetpipe_ros.model import ModelParams, simulate


def write_csv(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    return path


def test_simulate_replays_the_command_with_the_model(tmp_path):
    t = np.arange(3000) * 1e-3
    u = 0.8 * np.sign(np.sin(2 * np.pi * 1.0 * t) + 1e-12)
    src = write_csv(tmp_path / "in.csv", "t,u,ignored", [(a, b, 7) for a, b in zip(t, u)])
    out = tmp_path / "out.csv"
    assert main(["simulate", "--input", str(src), "--out", str(out)]) == 0
    exp = read_experiment(out)
    trace = simulate(ModelParams(), u)
    np.testing.assert_allclose(exp.y, trace.y, atol=1e-9)
    np.testing.assert_allclose(exp.p1, trace.p1, rtol=1e-8)
    assert exp.y.max() > 0.005


def test_simulate_locked_and_with_params(tmp_path):
    src = write_csv(tmp_path / "in.csv", "t,u", [(k * 1e-3, 1.15) for k in range(2000)])
    params = tmp_path / "p.yaml"
    params.write_text(ModelParams().with_effect("supply_pressure", pressure=7e5).to_ros_yaml())
    out = tmp_path / "out.csv"
    assert main(["simulate", "--params", str(params), "--input", str(src), "--out", str(out),
                 "--locked"]) == 0
    exp = read_experiment(out)
    assert np.all(exp.y == 0.0)
    assert exp.p1[-1] < 6.0e5


@pytest.mark.parametrize(("header", "rows", "message"), [
    ("t,volts", [(0, 1), (0.001, 1)], "missing column(s) u"),
    ("t,u", [(0, 1), (0.001, "x")], "line 3, column 'u': not a number"),
    ("t,u", [(0, 1), (0.001, "inf")], "line 3, column 'u': non-finite"),
    ("t,u", [(0, 1), (0.002, 1), (0.001, 1)], "line 4, column 't': time is not strictly"),
    ("t,u", [(0, 1)], "at least 2 data rows"),
])
def test_malformed_input_names_file_line_column_and_writes_nothing(tmp_path, capsys, header,
                                                                   rows, message):
    src = write_csv(tmp_path / "in.csv", header, rows)
    out = tmp_path / "out.csv"
    assert main(["simulate", "--input", str(src), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(src) in err and message in err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [src]


def test_simulate_fills_lost_rows_of_the_command(tmp_path):
    """Rows lost by the logger (3 between 1 and 5 ms) were refused as irregular sampling; they
    are filled now, the command held at the row before the gap (what the valve saw)."""
    src = write_csv(tmp_path / "in.csv", "t,u", [(0, 1), (0.001, 2), (0.005, -1), (0.006, 0.5)])
    out = tmp_path / "out.csv"
    assert main(["simulate", "--input", str(src), "--out", str(out)]) == 0
    exp = read_experiment(out)
    np.testing.assert_array_equal(exp.t, np.arange(7) * 1e-3)
    np.testing.assert_array_equal(exp.u, [1, 2, 2, 2, 2, -1, 0.5])


def test_missing_experiment_file_is_reported():
    with pytest.raises(DatasetError, match="cannot open"):
        read_experiment("/nonexistent/x.csv")
