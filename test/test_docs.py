"""The documentation builds with Sphinx, warnings as errors, and its generated tables follow the
code (docs/conf.py generates them from the parameter schema and the topic contract)."""

import subprocess
import sys
from pathlib import Path

from jetpipe_ros.model import SPECS

REPO = Path(__file__).resolve().parent.parent


def test_the_docs_build_without_warnings_and_show_every_parameter_and_topic(tmp_path):
    html = tmp_path / "html"
    run = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-E",
                          "-d", str(tmp_path / "doctrees"), "-b", "html", str(REPO / "docs"),
                          str(html)], capture_output=True, text=True, cwd=REPO)
    assert run.returncode == 0, run.stdout + run.stderr
    model = (html / "model.html").read_text()
    missing = [name for name in SPECS if name not in model]
    assert not missing, f"parameters missing from the model page: {missing}"
    node = (html / "node.html").read_text()
    for topic in ("voltage_cmd", "chamber1/pressure", "joint_states", "voltage_applied",
                  "position_setpoint", "lockstep_kick", "peer_timeout"):
        assert topic in node
    assert "jetpipe.diagnosis/2" in (html / "diagnosis.html").read_text()
    api = (html / "api.html").read_text()
    assert "run_campaign_offline" in api and "read_dataset" in api
