"""dataset.yaml: reading, validation naming the field, atomic writing."""

import numpy as np
import pytest

from jetpipe_ros.dataset import DatasetError, Entry, read_dataset, write_dataset


def columns(n=50, u=0.5):
    t = np.arange(n) * 1e-3
    return {"t": t, "u": np.full(n, u), "y": np.zeros(n), "p1": np.full(n, 4e5),
            "p2": np.full(n, 4e5)}


def test_round_trip_keeps_entries_and_signals(tmp_path):
    root = write_dataset(tmp_path / "ds", [
        (Entry("a.csv", piston="locked", role="train"), columns(u=1.0)),
        (Entry("b.csv", load_force=12.5, role="holdout", extra={"note": "x"}), columns()),
    ])
    ds = read_dataset(root)
    assert [e.name for e in ds.entries] == ["a", "b"]
    assert ds.entries[0].locked and not ds.entries[1].locked
    assert ds.entries[1].load_force == 12.5 and ds.entries[1].extra == {"note": "x"}
    assert [e.name for e, _ in ds.with_role("holdout")] == ["b"]
    np.testing.assert_array_equal(ds.experiments[0].u, 1.0)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("entry, field", [
    ({"piston": "free"}, "'file'"),
    ({"file": "a.csv", "piston": "clamped"}, "'piston'"),
    ({"file": "a.csv", "role": "test"}, "'role'"),
    ({"file": "a.csv", "load_force": "heavy"}, "'load_force'"),
    ({"file": "../a.csv"}, "'file'"),
])
def test_bad_entry_names_the_field(tmp_path, entry, field):
    write_dataset(tmp_path / "ds", [(Entry("a.csv"), columns())])
    import yaml
    (tmp_path / "ds" / "dataset.yaml").write_text(yaml.safe_dump({"experiments": [entry]}))
    with pytest.raises(DatasetError, match=f"experiments\\[0\\].*{field}"):
        read_dataset(tmp_path / "ds")


def test_missing_index_or_csv_is_named(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match="dataset.yaml: missing") as refused:
        read_dataset(tmp_path / "empty")
    assert "would read" not in str(refused.value)
    # CSVs without an index: the index they would need is spelled out, and it reads.
    write_dataset(tmp_path / "bare", [(Entry("b.csv"), columns()), (Entry("a.csv"), columns())])
    (tmp_path / "bare" / "dataset.yaml").unlink()
    with pytest.raises(DatasetError, match="For the 2 CSV file") as refused:
        read_dataset(tmp_path / "bare")
    (tmp_path / "bare" / "dataset.yaml").write_text(str(refused.value).split("would read:\n")[1])
    assert [e.file for e in read_dataset(tmp_path / "bare").entries] == ["a.csv", "b.csv"]
    write_dataset(tmp_path / "ds", [(Entry("a.csv"), columns())])
    (tmp_path / "ds" / "a.csv").unlink()
    with pytest.raises(DatasetError, match="a.csv: cannot open"):
        read_dataset(tmp_path / "ds")


def test_failed_write_leaves_nothing_and_existing_data_is_kept(tmp_path):
    bad = columns()
    bad["y"][3] = np.nan
    with pytest.raises(DatasetError, match="non-finite"):
        write_dataset(tmp_path / "ds", [(Entry("a.csv"), columns()), (Entry("b.csv"), bad)])
    assert list(tmp_path.iterdir()) == []
    write_dataset(tmp_path / "ds", [(Entry("a.csv"), columns())])
    with pytest.raises(DatasetError, match="not empty"):
        write_dataset(tmp_path / "ds", [(Entry("c.csv"), columns())])
    assert read_dataset(tmp_path / "ds").entries[0].file == "a.csv"
