"""Sphinx configuration of the jetpipe_ros documentation (MyST Markdown pages).

Build: ``scripts/docs.sh`` (``sphinx-build -W``, warnings are errors). rosdoc2 finds this
directory through ``rosdoc2.yaml``; it executes this file from its own wrapper, so nothing here
relies on ``__file__``: paths come from ``app.srcdir`` in :func:`setup`.

Pages that must not drift from the code are generated at build time into ``_generated/`` (not
tracked) and included by the hand-written pages: the model's parameter table from
``jetpipe_ros/model/params.py``, the topic table from ``msg_defs/topics.yaml``, the nodes'
own parameters, and the list of the optional tool pages that exist.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

project = "jetpipe_ros"
author = "jetpipe_ros developers"
copyright = "jetpipe_ros developers, Apache-2.0"  # noqa: A001 (Sphinx's name)

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_generated", "Thumbs.db", ".DS_Store"]
autodoc_member_order = "bysource"
autodoc_typehints = "none"
# Optional dependencies the API page may meet while importing; the package's own must import.
autodoc_mock_imports = ["rclpy", "rcl_interfaces", "std_msgs", "sensor_msgs", "rosgraph_msgs"]
suppress_warnings = ["myst.header"]

try:
    import furo  # noqa: F401

    html_theme = "furo"
except ImportError:  # rosdoc2 sets its own theme anyway
    html_theme = "alabaster"
html_title = "jetpipe_ros"

#: Optional pages other tools add under docs/; each listed under "Tools" when present.
TOOL_PAGES = ("friction", "twin")


def _version(root: Path) -> str:
    text = (root / "package.xml").read_text()
    match = re.search(r"<version>([^<]+)</version>", text)
    return match.group(1) if match else "unknown"


def _generate(app) -> None:  # noqa: ANN001 (a Sphinx application)
    src = Path(app.srcdir)
    root = src.parent
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    app.config.version = app.config.release = _version(root)
    from docs_generate import write_all  # noqa: PLC0415 (beside this file, found via srcdir)

    write_all(root, src / "_generated", TOOL_PAGES)


def setup(app) -> dict:  # noqa: ANN001
    """Generate the tables before the sources are read."""
    srcdir = str(Path(app.srcdir))
    if srcdir not in sys.path:
        sys.path.insert(0, srcdir)
    app.connect("builder-inited", _generate)
    return {"parallel_read_safe": True}
