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


def _declare(root, **fields) -> None:
    """Set top-level ``fields`` of ``root``'s dataset.yaml (``units``, ``columns``)."""
    doc = yaml.safe_load((root / "dataset.yaml").read_text())
    doc.update(fields)
    (root / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))


def _copied(clean, root):
    """``clean`` copied to ``root``: its CSV's path, column names and data rows (text)."""
    shutil.copytree(clean, root)
    path = root / "sweep_1p5V.csv"
    header, *rows = path.read_text().splitlines()
    return path, header.split(","), rows


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
    # The position logged in mm from the retracted end stop, read back with its zero.
    assert np.max(np.abs(gauge.y - truth.y)) < 1e-12  # [m]
    assert "y: mm -> m (x 0.001, - 0.025 m)" in gauge.notes
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


@pytest.mark.parametrize("zero, words", [
    ("25", "expected a length and its unit"),
    ("25 bar", "expected a length and its unit"),
    ("2 m", "more than the 0.5 m"),
])
def test_a_bad_position_zero_is_refused_naming_it(clean, tmp_path, zero, words):
    root = tmp_path / "zero"
    shutil.copytree(clean, root)
    _declare(root, units={"position_zero": zero})
    with pytest.raises(DatasetError, match=f"dataset.yaml: units: position_zero: .*{words}"):
        read_dataset(root)


def test_a_position_zeroed_at_an_end_stop_is_refused_with_the_declaration_to_make(clean,
                                                                                 tmp_path):
    """The same record with y from the retracted end stop in m and nothing declared: refused,
    the message giving the declaration that reads it (the stroke's half, 25 mm)."""
    root = tmp_path / "end_stop"
    path, names, rows = _copied(clean, root)
    i = names.index("y")
    moved = [",".join(repr(float(v) + 0.025) if k == i else v
                      for k, v in enumerate(r.split(","))) for r in rows]
    path.write_text("\n".join([",".join(names), *moved]) + "\n")
    with pytest.raises(DatasetError, match=r"look measured from an end stop.*"
                                           r"units: \{position_zero: 25 mm\}"):
        read_dataset(root)
    _declare(root, units={"position_zero": "25 mm"})
    truth = read_dataset(clean).experiments[0]
    assert np.max(np.abs(read_dataset(root).experiments[0].y - truth.y)) < 1e-12


def test_a_position_and_command_counted_the_other_way_are_read_with_a_minus(clean, tmp_path):
    """A position sensor mounted the other way round and zeroed at the extended end stop (it
    reads 0 there and 25 mm at mid-stroke, rising as the piston retracts), and a valve wired
    the other way (the logged command is minus the contract's): declared ``y: -mm``,
    ``position_zero: 25 mm`` and ``u: -V``, both read back as the contract's, and said."""
    root = tmp_path / "reversed"
    path, names, rows = _copied(clean, root)
    iy, iu = names.index("y"), names.index("u")

    def logged(k, v):
        return (repr(25.0 - 1e3 * float(v)) if k == iy
                else repr(-float(v)) if k == iu else v)
    path.write_text("\n".join([",".join(names), *(",".join(logged(k, v) for k, v in
                                                             enumerate(r.split(",")))
                                                    for r in rows)]) + "\n")
    _declare(root, units={"y": "-mm", "position_zero": "25 mm", "u": "-V"})
    truth, read = read_dataset(clean).experiments[0], read_dataset(root).experiments[0]
    assert np.max(np.abs(read.y - truth.y)) < 1e-12  # [m]
    assert np.array_equal(read.u, truth.u)
    assert "y: -mm -> m (x -0.001: counted the other way round, + 0.025 m)" in read.notes
    assert "u: -V -> V (x -1: counted the other way round)" in read.notes


@pytest.mark.parametrize("units, words", [
    ({"p1": "-bar"}, r"column 'p1': '-bar': a pressure has no direction to reverse; chamber "
                     r"pressures logged under each other's names are renamed with columns: "
                     r"\{p1: p2, p2: p1\}"),
    ({"t": "-s"}, "column 't': '-s': a time has no direction to reverse"),
    ({"y": "-inch"}, "column 'y': unknown unit '-inch'; accepted: m, mm, cm, um; with a minus"),
])
def test_a_minus_where_there_is_no_direction_is_refused_naming_the_column(clean, tmp_path,
                                                                          units, words):
    root = tmp_path / "minus"
    shutil.copytree(clean, root)
    _declare(root, units=units)
    with pytest.raises(DatasetError, match=f"dataset.yaml: units: {words}"):
        read_dataset(root)


def test_chamber_pressures_logged_under_each_others_names_are_renamed(clean, tmp_path):
    """``columns: {p1: p2, p2: p1}`` reads a logger that crossed the two pressures."""
    root = tmp_path / "crossed"
    path, names, rows = _copied(clean, root)
    i, j = names.index("p1"), names.index("p2")
    names[i], names[j] = "p2", "p1"
    path.write_text("\n".join([",".join(names), *rows]) + "\n")
    _declare(root, columns={"p1": "p2", "p2": "p1"})
    truth, read = read_dataset(clean).experiments[0], read_dataset(root).experiments[0]
    assert np.array_equal(read.p1, truth.p1) and np.array_equal(read.p2, truth.p2)


def test_a_bench_loggers_export_reads_back_as_the_clean_record_a_row_early(clean, tmp_path):
    """The ``bench`` logger (a row early, 1 % of rows lost, jittered stamps, bar gauge and mm,
    a spreadsheet's export under its own column names, the time in ms): the reader gives back
    the clean record's grid, command and measurements, these a row early (which only the
    diagnosis's time base moves back), the lost rows marked and every conversion said."""
    truth = read_dataset(clean).experiments[0]
    root = tmp_path / "bench"
    shutil.copytree(clean, root)
    log("bench", root, seed=0)
    assert (root / "sweep_1p5V.csv").read_text().startswith("# ")
    got = read_dataset(root).experiments[0]
    n = got.t.size
    assert n == truth.t.size - 1 and np.array_equal(got.t, truth.t[:n])
    lost = ~got.valid
    assert lost.sum() == int(0.01 * n)  # of the rows the shift left
    assert np.array_equal(got.u[~lost], truth.u[:n][~lost])
    for s in ("y", "p1", "p2"):
        err = np.abs(getattr(got, s)[~lost] - getattr(truth, s)[1:n + 1][~lost])
        assert err.max() < (1e-12 if s == "y" else 1e-6), s  # [m], [Pa]
    notes = " | ".join(got.notes)
    for said in ("semicolon-separated, a decimal comma accepted", "Weg read as y",
                 "t: ms -> s", "y: mm -> m", "+ 101325 Pa", "snapped to the grid",
                 f"{lost.sum()} rows missing"):
        assert said in notes, said


def test_a_loggers_row_of_units_is_read_as_units_and_never_converts_unseen(clean, tmp_path):
    """A row of units under the header (what many loggers and spreadsheets write): in the
    contract's units it is read as such, said, and the record is the clean one; in mm and bar
    it is refused with the declaration to make (a row of units is read, never acted on: bar
    says neither gauge nor absolute); declared in dataset.yaml, it reads as the declaration
    says (the gauge_mm logger's record with its own row of units)."""
    path, header, rows = _copied(clean, tmp_path / "si")
    si = {"t": "s", "u": "V", "y": "m", "p1": "Pa", "p2": "Pa", "v": "m/s", "f_load": "N"}
    path.write_text("\n".join([",".join(header), ",".join(f"[{si.get(c, '-')}]" for c in header),
                               *rows]) + "\n")
    exp, = read_dataset(tmp_path / "si").experiments
    ref, = read_dataset(clean).experiments
    np.testing.assert_array_equal(exp.y, ref.y)
    assert exp.t.size == ref.t.size
    assert exp.notes[0].startswith("line 2 read as the columns' units (t s, u V, y m, p1 Pa")
    # The contract's units in the other spellings dataset.yaml takes for them.
    spelled = {**si, "p1": "Pa absolute", "p2": "Paa"}
    path.write_text("\n".join([",".join(header), ",".join(spelled.get(c, "-") for c in header),
                               *rows]) + "\n")
    exp, = read_dataset(tmp_path / "si").experiments
    np.testing.assert_array_equal(exp.p1, ref.p1)
    # A first row of other text is no row of units: refused as the number it is not.
    path.write_text("\n".join([",".join(header), ",".join("np.float64(0.0)" for _ in header),
                               *rows]) + "\n")
    with pytest.raises(DatasetError, match=r"line 2, column 't': neither a number nor a date "
                                           r"and time .*: 'np.float64\(0.0\)'"):
        read_dataset(tmp_path / "si")

    gauge = tmp_path / "gauge"
    shutil.copytree(clean, gauge)
    log("gauge_mm", gauge, seed=0)
    path = gauge / "sweep_1p5V.csv"
    header, *rows = path.read_text().splitlines()
    shown = {**si, "y": "mm", "p1": "bar", "p2": "bar"}
    path.write_text("\n".join([header, ",".join(shown.get(c, "-") for c in header.split(",")),
                               *rows]) + "\n")
    exp, = read_dataset(gauge).experiments  # declared by the logger: mm, bar gauge
    np.testing.assert_allclose(exp.y, ref.y, atol=1e-6)
    doc = yaml.safe_load((gauge / "dataset.yaml").read_text())
    del doc["units"]
    (gauge / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    with pytest.raises(DatasetError, match=r"line 2: a row of units \(s, V, mm, bar, bar.*\) "
                                           r"gives column 'y' in 'mm', where the contract reads "
                                           r"m: declare it in dataset.yaml \(units: \{y: mm\}"):
        read_dataset(gauge)
