"""The numba cache of the model is removed when a module it compiles in changes
(jetpipe_ros.compiled_cache): numba itself checks only the file that defines a cached function."""

from numba.core.caching import _CacheLocator

from jetpipe_ros.compiled_cache import STAMP, refresh, user_cache_dirs


def _tree(root):
    for name in ("model", "plant"):
        (root / name / "__pycache__").mkdir(parents=True)
        (root / name / "kernel.py").write_text("def advance(): return 1\n")
    (root / "diagnosis").mkdir()
    (root / "diagnosis" / "fit.py").write_text("x = 1\n")
    return root


def _cache(root):
    files = [root / "model" / "__pycache__" / "kernel.advance-1.py311.nbi",
             root / "model" / "__pycache__" / "kernel.advance-1.py311.1.nbc",
             root / "plant" / "__pycache__" / "loop.run-9.py311.nbi"]
    for f in files:
        f.write_bytes(b"compiled")
    return files


def test_a_changed_model_module_removes_the_cache_an_unchanged_one_keeps_it(tmp_path):
    root = _tree(tmp_path)
    assert not refresh(root)  # nothing cached yet: the digest of these sources is stored
    assert (root / "__pycache__" / STAMP).is_file()
    files = _cache(root)
    assert not refresh(root) and all(f.exists() for f in files)
    # A module the cached kernel calls changes, the kernel's own file does not.
    (root / "model" / "port.py").write_text("def law(): return 2\n")
    assert refresh(root)
    assert not any(f.exists() for f in files)
    files = _cache(root)  # compiled afresh from the new sources
    assert not refresh(root) and all(f.exists() for f in files)
    # A change outside the compiled packages keeps the cache.
    (root / "diagnosis" / "fit.py").write_text("x = 2\n")
    assert not refresh(root) and all(f.exists() for f in files)
    # A plant module changes: the model's cache goes too (the plant calls the model).
    (root / "plant" / "kernel.py").write_text("def advance(): return 3\n")
    assert refresh(root) and not any(f.exists() for f in files)


def test_a_cache_without_a_stored_digest_is_taken_as_stale(tmp_path):
    root = _tree(tmp_path)
    files = _cache(root)
    assert refresh(root) and not any(f.exists() for f in files)


def test_a_cache_under_numba_cache_dir_is_removed_too(tmp_path, monkeypatch):
    """With ``NUMBA_CACHE_DIR`` set numba keeps each source folder's cache in a folder of that
    directory named by its own rule; a change of the sources removes those files as well."""
    root = _tree(tmp_path / "src")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    dirs = user_cache_dirs(root)
    assert [d.name for d in dirs] == [
        _CacheLocator.get_suitable_cache_subpath(str(root / name / "kernel.py"))
        for name in ("model", "plant")]
    assert not refresh(root)
    files = []
    for d in dirs:
        d.mkdir(parents=True)
        files.append(d / "kernel.advance-1.py311.nbi")
        files[-1].write_bytes(b"compiled")
    (root / "model" / "port.py").write_text("def law(): return 2\n")
    assert refresh(root) and not any(f.exists() for f in files)
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert user_cache_dirs(root) == []
