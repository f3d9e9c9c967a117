"""Files the product writes and reads: atomic writes, strict JSON, YAML with YAML 1.2 numbers.

Every file the tools write goes through a temporary file (or directory) beside its target that
is renamed into place once complete, so a failure never leaves a half-written file behind and an
existing target is either replaced whole or left as it was. Files are written 0644 and
directories 0755 (as rosbag2 does), whatever the umask of the temporary names. A file-system
problem raises :class:`FileError`, one line naming the path and the reason.

JSON is strict (RFC 8259): NaN and infinities become ``null`` before ``json.dumps(...,
allow_nan=False)``, so no parser refuses what the product writes.

YAML is read with PyYAML's safe loader plus the YAML 1.2 (core schema) float rule, which
ROS parameter files also follow: ``2e0`` and ``1.0e300`` are numbers (YAML 1.1 reads them as
strings). A key given twice in one mapping is an error naming the key and both lines.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import yaml

FILE_MODE = 0o644  #: permissions of every file written
DIR_MODE = 0o755  #: permissions of every directory written


class FileError(OSError):
    """A file or directory cannot be read or written; the message names the path and why."""


def _reason(exc: OSError) -> str:
    """``path: reason`` of an OSError (the path it failed on, when it names one)."""
    where = exc.filename if exc.filename is not None else ""
    return f"{where}: {exc.strerror or exc}" if where else str(exc.strerror or exc)


# -- checking targets before the work ---------------------------------------------------------


def _existing_ancestor(path: Path) -> Path:
    for parent in (path, *path.parents):
        if parent.exists() or parent.is_symlink():
            return parent
    return Path(".")


def _probe(directory: Path, what: str) -> None:
    """Raise FileError unless a file can be created in ``directory`` (or its nearest existing
    ancestor, where the missing parents would be made)."""
    base = _existing_ancestor(directory)
    if not base.is_dir():
        raise FileError(f"{what}: {base} is not a directory")
    try:
        fd, name = tempfile.mkstemp(prefix=".jetpipe-probe.", dir=base)
    except OSError as exc:
        raise FileError(f"{what}: cannot write in {base}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(name)


def output_file(path: str | os.PathLike[str], what: str = "output") -> Path:
    """Check that a file can be written at ``path`` before any work: a non-empty path, not a
    directory, its directory writable (missing parents are made when written). Returns it."""
    if not str(path).strip():
        raise FileError(f"{what}: empty path; give a file name")
    target = Path(path)
    if target.is_dir():
        raise FileError(f"{what}: {target} is a directory; give a file name")
    _probe(target.parent, f"{what} {target}")
    return target


def output_dir(path: str | os.PathLike[str], what: str = "output directory") -> Path:
    """Check that directory ``path`` can be written (created, or filled if it exists) before
    any work: a non-empty path, not an existing file, writable. Returns it."""
    if not str(path).strip():
        raise FileError(f"{what}: empty path; give a directory")
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise FileError(f"{what}: {target} exists and is not a directory")
    _probe(target if target.is_dir() else target.parent, f"{what} {target}")
    return target


# -- atomic writes ----------------------------------------------------------------------------


def _stage(path: Path, data: str | bytes) -> Path:
    """Write ``data`` to a new temporary file (mode 0644) beside ``path``; its name."""
    if path.is_dir():
        raise FileError(f"{path}: is a directory; cannot write a file there")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb" if isinstance(data, bytes) else "w", newline="" if
                       isinstance(data, str) else None) as handle:
            handle.write(data)
        os.chmod(tmp, FILE_MODE)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(tmp)


def write_files(contents: Mapping[str | os.PathLike[str], str | bytes]) -> None:
    """Write several files as one: all replaced, or (on an error) none changed.

    Each file is first written to a temporary file beside it; only when all are complete are
    they renamed into place, and a rename that fails puts back what the earlier ones replaced.
    """
    staged: list[tuple[Path, Path]] = []
    try:
        for path, data in contents.items():
            staged.append((Path(path), _stage(Path(path), data)))
        _commit(staged)
    except OSError as exc:
        raise FileError(f"cannot write {_reason(exc)}") from None
    finally:
        for _, tmp in staged:
            tmp.unlink(missing_ok=True)


def _commit(staged: list[tuple[Path, Path]]) -> None:
    backups: list[tuple[Path, Path | None]] = []  # (target, its previous content moved aside)
    try:
        for path, tmp in staged:
            backup = None
            if path.exists():
                backup = path.with_name(f".{path.name}.{os.getpid()}.bak")
                os.replace(path, backup)
            backups.append((path, backup))
            os.replace(tmp, path)
    except BaseException:
        for path, backup in reversed(backups):
            if backup is not None:
                os.replace(backup, path)
            else:
                path.unlink(missing_ok=True)
        raise
    for _, backup in backups:
        if backup is not None:
            backup.unlink(missing_ok=True)


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` atomically (0644)."""
    write_files({path: text})


def write_json(path: str | os.PathLike[str], obj: Any) -> None:
    """Write ``obj`` as strict JSON (see :func:`to_json`) atomically."""
    write_text(path, to_json(obj) + "\n")


@contextmanager
def staged_directory(root: str | os.PathLike[str], replace: bool = False) -> Iterator[Path]:
    """A new, empty temporary directory beside ``root`` to fill; renamed to ``root`` when the
    ``with`` block ends without an error, removed otherwise.

    ``root`` must not exist, be an empty directory, or (``replace``) be a directory that is
    then replaced whole: moved aside, the new one renamed in, the old one deleted.
    """
    root = Path(root)
    if not str(root).strip():
        raise FileError("empty directory path")
    try:
        root.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{root.name}.", suffix=".tmp", dir=root.parent))
        os.chmod(tmp, DIR_MODE)
    except OSError as exc:
        raise FileError(f"cannot write {_reason(exc)}") from None
    try:
        yield tmp
        _swap_in(tmp, root, replace)
    except OSError as exc:
        if isinstance(exc, FileError):
            raise
        raise FileError(f"cannot write {_reason(exc)}") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _swap_in(tmp: Path, root: Path, replace: bool) -> None:
    if root.is_dir() and any(root.iterdir()):
        if not replace:
            raise FileError(f"{root}: directory is not empty")
        old = Path(tempfile.mkdtemp(prefix=f".{root.name}.", suffix=".old", dir=root.parent))
        os.replace(root, old / root.name)
        try:
            os.replace(tmp, root)
        except BaseException:
            os.replace(old / root.name, root)
            shutil.rmtree(old, ignore_errors=True)
            raise
        shutil.rmtree(old, ignore_errors=True)
    else:  # absent, or an empty directory (which rename replaces)
        os.replace(tmp, root)


# -- strict JSON ------------------------------------------------------------------------------


def sanitise(obj: Any) -> Any:
    """``obj`` with NaN/infinite floats as None, numpy scalars and arrays as Python values,
    tuples as lists and keys as strings: what strict JSON can hold."""
    if isinstance(obj, Mapping):
        return {str(k): sanitise(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [sanitise(v) for v in obj]
    if hasattr(obj, "tolist") and callable(obj.tolist):  # numpy arrays and scalars
        return sanitise(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def to_json(obj: Any, indent: int | None = 2) -> str:
    """Strict JSON text of ``obj`` (after :func:`sanitise`); no NaN or Infinity tokens."""
    return json.dumps(sanitise(obj), indent=indent, allow_nan=False)


# -- YAML -------------------------------------------------------------------------------------

_FLOAT_TAG = "tag:yaml.org,2002:float"
#: YAML 1.2 core schema floats (``2e0``, ``1.0e300``, ``.5``, ``.inf``) that are not integers.
_FLOAT_12 = re.compile(r"""^(?:[-+]?(?:[0-9]+\.[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?
                        |[-+]?[0-9]+[eE][-+]?[0-9]+
                        |[-+]?\.(?:inf|Inf|INF)
                        |\.(?:nan|NaN|NAN))$""", re.X)


class DuplicateKeyError(yaml.YAMLError):
    """A mapping gives the same key twice (YAML requires unique keys; PyYAML keeps the last)."""


class Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats, refusing a mapping key given twice."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        first: dict[Any, yaml.Mark] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=True)
            try:
                seen = first.get(key)
            except TypeError:  # an unhashable key: the base class reports it
                continue
            if seen is not None:
                mark = key_node.start_mark
                raise DuplicateKeyError(
                    f"line {mark.line + 1}, column {mark.column + 1}: key {key!r} given twice "
                    f"(first at line {seen.line + 1}); give each key once")
            first[key] = key_node.start_mark
        return super().construct_mapping(node, deep)


Loader.add_implicit_resolver(_FLOAT_TAG, _FLOAT_12, list("-+0123456789."))


def parse_yaml(stream: str | IO[str]) -> Any:
    """The document in ``stream`` (text or an open file), read with :class:`Loader`."""
    return yaml.load(stream, Loader=Loader)  # noqa: S506 - Loader is a SafeLoader


def load_yaml(path: str | os.PathLike[str]) -> Any:
    """The YAML document in file ``path`` (errors name it: OSError, yaml.YAMLError)."""
    with open(path, encoding="utf-8") as handle:
        return parse_yaml(handle)


def read_yaml(path: str | os.PathLike[str], error: type[Exception], what: str = "") -> Any:
    """The YAML document in file ``path``; a file that cannot be read or is not valid YAML
    raises ``error`` with one line naming the path (and ``what`` it is) and the reason."""
    try:
        return load_yaml(path)
    except OSError as exc:
        raise error(f"{path}: cannot read{' ' + what if what else ''}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise error(f"{path}: not valid YAML: {exc}") from None


def section_applies(key: str, node: str) -> bool:
    """Whether the section ``key`` of a ROS parameters file applies to the node ``node``
    (fully qualified, e.g. ``/axis1/actuator_sim``), as rcl matches them: a key without a
    leading slash is taken from the root (``actuator_sim`` is ``/actuator_sim`` and does not
    apply in a namespace), ``/**`` stands for any number of namespace levels and ``*`` for one
    name (``/**`` applies to every node, ``/**/actuator_sim`` to that node in any namespace)."""
    pattern = key if key.startswith("/") else "/" + key
    regex = re.escape(pattern).replace(r"/\*\*", "(?:/[^/]+)*").replace(r"\*", "[^/]*")
    return re.fullmatch(regex, node) is not None


def ros_sections(tree: Any, node: str) -> list[str]:
    """Keys of the ROS parameter sections (``key: {ros__parameters: ...}``) of a parsed
    parameters file ``tree`` that apply to the node ``node`` (:func:`section_applies`), in the
    file's order (rcl applies them in that order: a later section wins)."""
    if not isinstance(tree, Mapping):
        return []
    return [k for k, v in tree.items() if isinstance(k, str) and isinstance(v, Mapping)
            and "ros__parameters" in v and section_applies(k, node)]
