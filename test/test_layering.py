"""Dependencies point one way (README, Layout): each subpackage imports only from lower layers,
and nothing below the ROS nodes imports ROS."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "jetpipe_ros"

#: Lowest first. A module may import its own subpackage and anything in a lower layer.
LAYERS = (
    # atomic writes and strict JSON/YAML; where the data files are; CLI argument types; child
    # processes; report figures; progress lines; the measured signals' topics
    ("fileio", "package_data", "arguments", "children", "figures", "progress", "topics"),
    ("compiled_cache",),  # the compiled model's cache kept fresh (writes with fileio)
    ("model",),  # the physics
    ("dataset",),  # data I/O, checked against the model's limits
    ("control",),  # the PID law
    ("campaign", "replay"),  # plans, signals, offline runner; replaying a CSV
    ("plant",),  # a stand-in for real hardware written apart from the model's effects
    ("identify", "diagnosis", "bag"),  # the paper's procedures; the gap diagnosis; bags
    ("workflows",),  # running and judging the diagnosis: cluster, report, fleet, selfcheck
    ("twin",),  # the model beside the hardware: live gap, capture, trend
    ("nodes",),  # ROS 2 shells
    ("cli", "showcase", "showcase_twin"),  # entry points
)
LAYER = {name: i for i, names in enumerate(LAYERS) for name in names}
#: Top-level packages of ROS 2 itself (rosbags and mcap are plain Python libraries).
ROS = {"rclpy", "std_msgs", "sensor_msgs", "rosgraph_msgs", "rcl_interfaces",
       "builtin_interfaces", "ament_index_python", "diagnostic_msgs", "std_srvs"}


def _imports(path: Path) -> list[str]:
    """Absolute module names imported anywhere in ``path`` (inside functions too)."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
        elif isinstance(node, ast.Import):
            names.extend(alias.name for alias in node.names)
    return names


def _modules() -> list[tuple[str, Path]]:
    """(subpackage or top-level module, file) of every module but the package's __init__."""
    return [(p.relative_to(PACKAGE).parts[0].removesuffix(".py"), p)
            for p in sorted(PACKAGE.rglob("*.py")) if p != PACKAGE / "__init__.py"]


def test_every_subpackage_has_a_layer():
    assert {group for group, _ in _modules()} <= set(LAYER)


def test_imports_point_down_and_only_nodes_import_ros():
    wrong = []
    for group, path in _modules():
        where = f"{path.relative_to(PACKAGE.parent)} ({group})"
        for name in _imports(path):
            parts = name.split(".")
            if parts[0] == "jetpipe_ros" and len(parts) > 1 and parts[1] != group \
                    and LAYER[parts[1]] >= LAYER[group]:
                wrong.append(f"{where} imports {name}, not below it")
            optional_index = group == "package_data" and parts[0] == "ament_index_python"
            if parts[0] in ROS and group != "nodes" and not optional_index:
                wrong.append(f"{where} imports ROS ({name}); only nodes may")
    assert wrong == []


def test_the_diagnosis_neither_runs_itself_nor_renders():
    """The diagnosis (data, candidates, calibration, fits, scores, verdict) is apart from
    running and judging it: no Dask, no figures, no plant, nothing of ``workflows``."""
    outward = ("distributed", "dask", "matplotlib", "jetpipe_ros.plant", "jetpipe_ros.workflows")
    wrong = [f"{path.relative_to(PACKAGE.parent)} imports {name}"
             for group, path in _modules() if group == "diagnosis"
             for name in _imports(path) if name.startswith(outward)]
    assert wrong == []


#: What the plant may take from the model: parameter names and containers, errors, the output
#: layout and the actuator's interface contract; nothing that computes physics.
PLANT_FROM_MODEL = {
    "jetpipe_ros.model": {"ModelParams", "ParameterError", "Trace"},
    "jetpipe_ros.model.params": {"ParamSpec", "check_value"},
    "jetpipe_ros.model.errors": {"ParameterError"},
    "jetpipe_ros.model.kernel": {"N_OUT", "OUT_T", "OUT_U", "OUT_Y", "OUT_V", "OUT_P1", "OUT_P2",
                                 "OUT_FRICTION", "OUT_FORCE", "OUT_UEQ", "OUT_Y_MEAS",
                                 "OUT_P1_MEAS", "OUT_P2_MEAS"},
    "jetpipe_ros.model.actuator": {"REGULATOR_KEYS", "replay_command"},
}


def _imported_names(path: Path) -> list[tuple[str, str]]:
    """(module, name) of every ``import`` and ``from ... import`` in ``path`` (a plain
    ``import a.b`` as (a.b, ""))."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.extend((node.module, alias.name) for alias in node.names)
        elif isinstance(node, ast.Import):
            out.extend((alias.name, "") for alias in node.names)
    return out


def test_the_plant_takes_only_names_and_containers_from_the_model():
    """The self-check's plant is written apart from the model: its flow map, valve chain,
    friction and volumes are its own, so a structural error of the model can show in it. It
    may read the model's parameter names and values (a deviated bench is described the same
    way), its errors and output layout, nothing that computes."""
    wrong = []
    for group, path in _modules():
        if group != "plant":
            continue
        for module, name in _imported_names(path):
            if not (module == "jetpipe_ros.model" or module.startswith("jetpipe_ros.model.")):
                continue
            if name not in PLANT_FROM_MODEL.get(module, set()):
                wrong.append(f"{path.relative_to(PACKAGE.parent)} imports "
                             f"{module}{'.' + name if name else ''}")
    assert wrong == []


def test_the_plant_rule_catches_physics():
    """The rule above fails on the imports the plant used to have (a test that cannot fail is
    no test)."""
    before = ("from jetpipe_ros.model.flow import chamber_inflow\n"
              "from jetpipe_ros.model.valve import discretise_valve\n"
              "from jetpipe_ros.model import kernel as k\n")
    names = [(node.module, alias.name) for node in ast.walk(ast.parse(before))
             if isinstance(node, ast.ImportFrom) for alias in node.names]
    assert all(name not in PLANT_FROM_MODEL.get(module, set()) for module, name in names)
