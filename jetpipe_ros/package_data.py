"""The package's data files (``config/...``, ``msg_defs/...``) wherever the package is installed.

No ROS import (the ament index is consulted only if ``ament_index_python`` is importable), so the
lowest layers (campaign defaults, the topic contract) can find their files.
"""

from __future__ import annotations

import sys
from pathlib import Path

PACKAGE = "jetpipe_ros"


class PackageDataError(LookupError):
    """A data file of the package is not found; the message lists where it was looked for."""


def share_file(relative: str) -> Path:
    """Find a data file of the package (``config/...``, ``msg_defs/...``) wherever it lives.

    Looked for, first hit wins: beside the source package (a repo checkout, ``pip install -e``,
    ``colcon build --symlink-install``); in the ``share/jetpipe_ros`` of the install prefix the
    package was imported from (``colcon build``, ``pip install .``); in ``sys.prefix``; through
    the ament index. Raises :class:`PackageDataError` when none holds it.
    """
    here = Path(__file__).resolve().parent  # the jetpipe_ros package directory
    candidates = [here.parent / relative]
    if len(here.parents) > 3:  # <prefix>/lib/pythonX.Y/site-packages/jetpipe_ros
        candidates.append(here.parents[3] / "share" / PACKAGE / relative)
    candidates.append(Path(sys.prefix) / "share" / PACKAGE / relative)
    ament = _ament_share()
    if ament is not None:
        candidates.append(ament / relative)
    for path in candidates:
        if path.is_file():
            return path
    raise PackageDataError(f"{relative} not found; looked in: "
                           + ", ".join(str(p) for p in candidates))


def _ament_share() -> Path | None:
    """The package's share directory in the ament index, or None (no index, not listed)."""
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(PACKAGE))
    except (ImportError, LookupError, OSError):  # no ament_index, not indexed, no prefix path
        return None
