"""Tables of the documentation generated from the code, so that they cannot drift from it.

Called by ``conf.py`` before Sphinx reads the pages; writes MyST Markdown files into
``docs/_generated/`` (not tracked), which the pages include:

- ``params.md``: every model parameter of :data:`jetpipe_ros.model.SPECS` (name, default, unit,
  range, description), grouped by subsystem;
- ``topics.md``: the topic contract ``msg_defs/topics.yaml``;
- ``node_params.md``: the nodes' own parameters (``NODE_SPECS`` of each node, the controller's
  gains :data:`jetpipe_ros.control.SPECS`);
- ``tools_toctree.md``: a table of contents of the optional tool pages that exist.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable
from pathlib import Path

import yaml


def _cell(text: object) -> str:
    """A value as the text of one Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ").strip()


def _default(spec) -> str:  # noqa: ANN001 (a ParamSpec)
    value = spec.default
    if isinstance(value, list):
        if len(value) > 4:
            return f"{len(value)} values (the paper's)"
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    if value == "":
        return '""'
    return str(value)


def _range(spec) -> str:  # noqa: ANN001
    if spec.choices:
        return ", ".join(f"`{c}`" for c in spec.choices)
    if spec.low is None and spec.high is None:
        return ""
    low = "" if spec.low is None else f"{spec.low:g}"
    high = "" if spec.high is None else f"{spec.high:g}"
    return f"{low} to {high}"


def spec_table(specs: Iterable, name_prefix: str = "") -> str:
    """A Markdown table of parameter specs."""
    lines = ["| parameter | default | unit | range | description |",
             "|---|---|---|---|---|"]
    for s in specs:
        lines.append(f"| `{name_prefix}{s.name}` | {_cell(_default(s))} | {_cell(s.unit)} | "
                     f"{_cell(_range(s))} | {_cell(s.description)} |")
    return "\n".join(lines) + "\n"


GROUPS = {
    "valve": "Servo valve (Sec. 2.1, 2.4: Table 1, Eq. 4, 5, 9, 10)",
    "flow": "Mass flow map (Sec. 2.3, Eq. 8)",
    "chamber": "Chambers (Sec. 3, Eq. 11-13)",
    "mechanics": "Mechanics (Sec. 4.1, Eq. 14)",
    "friction": "Friction planes (Sec. 4.2, Eq. 20-27)",
    "sensors": "Sensors",
    "integration": "Integration",
    "effects": "Unmodelled effects (all off by default)",
}


def params_page() -> str:
    from jetpipe_ros.model import SPECS

    out = []
    for group, title in GROUPS.items():
        specs = [s for s in SPECS.values() if s.name.split(".")[0] == group]
        if not specs:
            continue
        out.append(f"### {title}\n\n{spec_table(specs)}")
    missing = {s.name for s in SPECS.values()} - {
        s.name for s in SPECS.values() if s.name.split(".")[0] in GROUPS}
    if missing:
        raise RuntimeError(f"parameters in no group of the docs: {sorted(missing)}")
    return "\n".join(out)


def topics_page(root: Path) -> str:
    contract = yaml.safe_load((root / "msg_defs" / "topics.yaml").read_text())
    qos = contract["qos"]
    lines = ["| topic | type | unit | from | to | QoS | meaning |",
             "|---|---|---|---|---|---|---|"]
    for t in contract["topics"]:
        q = qos[t["qos"]]
        lines.append(
            f"| `{t['name']}` | `{t['type']}` | {_cell(t['unit'])} | "
            f"{_cell(', '.join(t['publishers']))} | {_cell(', '.join(t['subscribers']))} | "
            f"{t['qos']}: {q['reliability']}, {q['history'].replace('_', ' ')} {q['depth']} | "
            f"{_cell(t['meaning'])} |")
    return "\n".join(lines) + "\n"


def node_params_page() -> str:
    sim = importlib.import_module("jetpipe_ros.nodes.actuator_sim")
    ctl = importlib.import_module("jetpipe_ros.nodes.controller")
    rec = importlib.import_module("jetpipe_ros.nodes.id_recorder")
    from jetpipe_ros.control import SPECS as PID

    dynamic = ", ".join(f"`{n}`" for n in sim.DYNAMIC)
    static = ", ".join(f"`{n}`" for n in sim.MODEL_STATIC)
    return (
        "### `actuator_sim`\n\n"
        "Besides every model parameter (the parameter table of the model page), which may be "
        f"changed at run time except {static}:\n\n"
        f"{spec_table(sim.NODE_SPECS.values())}\n"
        f"Changeable at run time: {dynamic}; the others are read-only.\n\n"
        "### `controller`\n\n"
        "The control law's parameters (changeable at run time):\n\n"
        f"{spec_table(PID.values())}\n"
        "The node's own (`sample_time` read-only):\n\n"
        f"{spec_table(ctl.NODE_SPECS.values())}\n"
        "### `id_recorder`\n\n"
        "All read-only:\n\n"
        f"{spec_table(rec.NODE_SPECS.values())}")


def tools_toctree(src: Path, pages: Iterable[str]) -> str:
    present = [p for p in pages if (src / f"{p}.md").is_file()]
    if not present:
        return "No optional tool page is installed in this copy of the documentation.\n"
    body = "\n".join(present)
    return f"```{{toctree}}\n:maxdepth: 2\n\n{body}\n```\n"


def write_all(root: Path, out: Path, tool_pages: Iterable[str]) -> None:
    """Write every generated page into ``out``; files whose text is unchanged are left alone
    (so Sphinx does not re-read the pages including them)."""
    out.mkdir(exist_ok=True)
    pages = {"params.md": params_page(), "topics.md": topics_page(root),
             "node_params.md": node_params_page(),
             "tools_toctree.md": tools_toctree(out.parent, tool_pages)}
    for name, text in pages.items():
        path = out / name
        if not path.is_file() or path.read_text() != text:
            path.write_text(text)
