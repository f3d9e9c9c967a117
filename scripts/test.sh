#!/usr/bin/env bash
# Run the test suite in the venv of a ROS 2 distro (created first if missing); arguments go to
# pytest. ROS_DISTRO_WHEELS=jazzy runs it on Jazzy (.venv-jazzy) instead of Kilted (.venv).
set -euo pipefail
cd "$(dirname "$0")/.."
DISTRO=${ROS_DISTRO_WHEELS:-kilted}
case "$DISTRO" in
  kilted) VENV=${VENV:-.venv} ;;
  jazzy) VENV=${VENV:-.venv-jazzy} ;;
  *) echo "[test] unknown ROS 2 distro '$DISTRO': kilted or jazzy" >&2; exit 2 ;;
esac
# Set up (again) when the venv is missing, broken, or older than the requirements.
case "$DISTRO" in kilted) ROS_REQ=requirements-ros.txt ;; jazzy) ROS_REQ=requirements-ros-jazzy.txt ;; esac
WANT=$(cat requirements.txt "$ROS_REQ" setup.py | sha256sum | cut -d' ' -f1)
[ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c "import jetpipe_ros, rclpy, numba" 2>/dev/null \
  && [ "$(cat "$VENV/requirements.sha" 2>/dev/null)" = "$WANT" ] \
  || VENV="$VENV" scripts/setup_venv.sh "$DISTRO"
exec "$VENV/bin/python" -m pytest test -q --durations=25 "$@"
