"""Numba's on-disk cache of the compiled model, kept from going stale in a source checkout.

Numba checks a cached function against the time stamp of the file that defines it, not of the
files whose jitted functions it calls and compiles in (numba issue #1833; its documentation:
"cache invalidation fails to recognize changes in functions defined in a different file"). After
a change to ``model/port.py`` alone, ``kernel.advance`` was loaded from the cache with the old
port law in it, and the tests of the new law failed against the old physics. So, when the package
is imported, a digest of the sources of the packages that hold compiled functions
(:data:`COMPILED`, together: the plant's loop calls the model's functions) is compared with the
one stored beside their caches; if it differs, their cache files are removed (numba compiles
afresh, once) and the new digest is stored. With ``NUMBA_CACHE_DIR`` set, numba keeps the
cache of each source directory under that directory instead (:func:`user_cache_dirs`), and those
files go too. An installed package whose directory cannot be written has its cache elsewhere
(numba's user-wide cache) and is left alone: reinstalling rewrites every file, and with them
every time stamp.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from jetpipe_ros.fileio import FileError, write_text

#: Sub-packages whose modules define ``njit(cache=True)`` functions.
COMPILED = ("model", "plant")
#: Where the digest of their sources is kept, under the package's own ``__pycache__``.
STAMP = "compiled-sources.sha256"


def sources_digest(root: Path) -> str:
    """SHA-256 over the names and contents of the ``.py`` files of :data:`COMPILED` under
    ``root``, in sorted order."""
    digest = hashlib.sha256()
    for name in COMPILED:
        for path in sorted((root / name).glob("*.py")):
            digest.update(path.relative_to(root).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


def user_cache_dirs(root: Path) -> list[Path]:
    """Where numba keeps the caches of :data:`COMPILED` under ``root`` when ``NUMBA_CACHE_DIR``
    is set (none otherwise): numba's rule for a user-provided cache directory (its
    ``_CacheLocator.get_suitable_cache_subpath``), ``<dir>/<folder name>_<SHA-1 of the folder's
    absolute path>``."""
    base = os.environ.get("NUMBA_CACHE_DIR")
    if not base:
        return []
    out = []
    for name in COMPILED:
        folder = os.path.abspath(root / name)
        out.append(Path(base) / f"{os.path.basename(folder)}_"
                                f"{hashlib.sha1(folder.encode()).hexdigest()}")
    return out


def refresh(root: Path) -> bool:
    """Remove the numba cache files of :data:`COMPILED` under ``root`` unless they were built
    from the present sources (the digest stored at the last refresh); store the present digest.
    Returns True when files were removed. Does nothing where the cache cannot be written."""
    stamp = root / "__pycache__" / STAMP
    digest = sources_digest(root)
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    removed = False
    for folder in [root / name / "__pycache__" for name in COMPILED] + user_cache_dirs(root):
        for path in folder.glob("*.nb[ic]"):
            try:
                path.unlink()
                removed = True
            except FileNotFoundError:  # another process removed it first
                pass
            except OSError:
                return False
    try:
        write_text(stamp, digest)
    except FileError:
        pass
    return removed
