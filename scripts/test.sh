#!/usr/bin/env bash
# Run the test suite in the venv of a ROS 2 distro (created first if missing); arguments go to
# pytest. ROS_DISTRO_WHEELS=jazzy runs it on Jazzy (.venv-jazzy) instead of Kilted (.venv);
# TEST_JOBS=n sets the processes of the first stage (default: one per core).
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
# Two stages: the tests that are pure computation on every core (pytest-xdist), then the tests
# that talk ROS one at a time (their nodes keep their 1 kHz pace and time-outs on a quiet
# machine). Arguments go to both; a stage that selects nothing (pytest exit 5) is not a failure.
# --dist loadgroup: a module whose fixtures are costly (a campaign simulated, a diagnosis) marks
# itself xdist_group and runs on one worker, so they are built once, not once per worker.
# The numba kernels are compiled first, each in a process of its own (test/compile_kernels.py): on
# a fresh clone both workers would otherwise compile the same ones at once.
"$VENV/bin/python" test/compile_kernels.py
status=0
"$VENV/bin/python" -m pytest test -q --durations=15 -m "not ros" -n "${TEST_JOBS:-auto}" --dist loadgroup \
  "$@" || status=$?
[ "$status" -eq 5 ] && status=0
ros=0
"$VENV/bin/python" -m pytest test -q --durations=15 -m ros "$@" || ros=$?
[ "$ros" -eq 5 ] && ros=0
[ "$status" -ne 0 ] && exit "$status"
exit "$ros"
