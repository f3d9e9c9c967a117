"""The package builds with colcon, and the installed actuator_sim runs from the install space."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from jetpipe_ros.compiled_cache import STAMP

REPO = Path(__file__).resolve().parent.parent
PACKAGE_FILES = ("package.xml", "setup.py", "setup.cfg", "resource", "config", "msg_defs",
                 "jetpipe_ros")
STARTUP = 60.0  # [s] the installed kernel compiled by the fixture, loaded from numba's cache


@pytest.fixture(scope="module")
def workspace(tmp_path_factory, compiled_kernel) -> Path:
    """A colcon workspace holding a copy of the package, built."""
    colcon = shutil.which("colcon", path=str(Path(sys.executable).parent))
    if colcon is None:
        pytest.skip("colcon is not installed next to this Python")
    ws = tmp_path_factory.mktemp("colcon_ws")
    src = ws / "src" / "jetpipe_ros"
    src.mkdir(parents=True)
    for name in PACKAGE_FILES:
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, src / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            shutil.copy2(path, src / name)
    env = dict(os.environ)
    # The PyPI ROS wheels keep their ament index in the venv: colcon must see it.
    env["AMENT_PREFIX_PATH"] = os.pathsep.join(
        [sys.prefix, *filter(None, [os.environ.get("AMENT_PREFIX_PATH")])])
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    build = subprocess.run([colcon, "build"], cwd=ws, env=env, capture_output=True, text=True,
                           timeout=300)
    assert build.returncode == 0, build.stdout + build.stderr
    # Compile the installed copy's kernel once, as a process that starts nodes does
    # (compile_kernel; numba caches it beside the installed module): on a 2-core machine a cold
    # compile took 33-65 s, which the start-up test below is not about. Numba keys its cache by
    # the source's contents, not its path: the repository's (compiled_kernel), copied beside
    # the installed modules, loads; without it, this compiles.
    site = next((ws / "install" / "jetpipe_ros").glob("lib/python3*/site-packages"))
    for cached in (REPO / "jetpipe_ros").glob("**/__pycache__/*.nb[ic]"):
        target = site / cached.relative_to(REPO)
        if target.parent.parent.is_dir():
            target.parent.mkdir(exist_ok=True)
            shutil.copy2(cached, target)
    # With the digest of the sources it was built from (jetpipe_ros.compiled_cache), else the
    # installed package takes it as stale and removes it.
    stamp = REPO / "jetpipe_ros" / "__pycache__" / STAMP
    if stamp.is_file():
        (site / "jetpipe_ros" / "__pycache__").mkdir(exist_ok=True)
        shutil.copy2(stamp, site / "jetpipe_ros" / "__pycache__" / STAMP)
    subprocess.run([sys.executable, "-c", "from jetpipe_ros.model import compile_kernel; "
                    "compile_kernel()"], env={**env, "PYTHONPATH": str(site)}, cwd=ws,
                   check=True, timeout=600)
    return ws


@pytest.mark.ros  # beside the test below, in the stage that talks ROS: one build and compile
def test_executables_and_data_installed(workspace):
    prefix = workspace / "install" / "jetpipe_ros"
    for exe in ("actuator_sim", "controller", "id_recorder", "composed_campaign", "gap_monitor",
                "jetpipe"):
        assert os.access(prefix / "lib" / "jetpipe_ros" / exe, os.X_OK), exe
    share = prefix / "share" / "jetpipe_ros"
    for name in ("package.xml", "config/actuator.yaml", "msg_defs/topics.yaml"):
        assert (share / name).is_file(), name
    assert (prefix / "share/ament_index/resource_index/packages/jetpipe_ros").is_file()
    # Package data: diagnosis.json's schema beside the module that writes it.
    assert list(prefix.glob("lib/python3*/site-packages/jetpipe_ros/diagnosis/"
                            "diagnosis.schema.json")), "diagnosis.schema.json not installed"


def test_installed_actuator_sim_runs(workspace, launch):
    prefix = workspace / "install" / "jetpipe_ros"
    share = prefix / "share" / "jetpipe_ros"
    command = (f". {workspace / 'install' / 'setup.sh'} && exec "
               f"{prefix / 'lib' / 'jetpipe_ros' / 'actuator_sim'} --ros-args "
               f"--params-file {share / 'config' / 'actuator.yaml'}")
    proc = launch(["sh", "-c", command], python=False, cwd=workspace,
                  env={"PYTHONPATH": None, "AMENT_PREFIX_PATH": sys.prefix})
    line = proc.wait_for("started:", STARTUP)
    assert str(share / "msg_defs" / "topics.yaml") in line  # the installed contract
    assert proc.popen.poll() is None
    assert proc.stop() == 0  # SIGTERM: clean shutdown
    assert "total: stepped" in proc.output
