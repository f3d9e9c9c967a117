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
# Two stages, side by side: the tests that are pure computation on every core (pytest-xdist),
# at the lowest CPU priority, and the tests that talk ROS one at a time at normal priority. The
# ROS tests mostly wait on their nodes' real-time pace and time-outs: given the CPU whenever they
# want it (nice 19 leaves the computation about 1.5 % of a core they claim), their nodes keep
# their 1 kHz pace as on a quiet machine, and the computation takes the time they leave idle
# (run one after the other, the ROS stage added about 4 minutes to the suite). Each stage's
# lines are prefixed with its name. Arguments go to both; a stage that selects nothing (pytest
# exit 5) is not a failure.
# --dist loadgroup: a module whose fixtures are costly (a campaign simulated, a diagnosis) marks
# itself xdist_group and runs on one worker, so they are built once, not once per worker.
# The numba kernels are compiled first, each in a process of its own (test/compile_kernels.py): on
# a fresh clone both workers would otherwise compile the same ones at once.
"$VENV/bin/python" test/compile_kernels.py
prefixed() {  # prefixed NAME COMMAND...: run COMMAND, its output prefixed; its exit status
  local name=$1
  shift
  "$@" 2>&1 | sed -u "s/^/[$name] /"
  return "${PIPESTATUS[0]}"
}
prefixed compute nice -n 19 "$VENV/bin/python" -m pytest test -q --durations=15 -m "not ros" \
  -n "${TEST_JOBS:-auto}" --dist loadgroup "$@" &
compute=$!
ros=0
prefixed ros "$VENV/bin/python" -m pytest test -q --durations=15 -m ros "$@" || ros=$?
status=0
wait "$compute" || status=$?
[ "$status" -eq 5 ] && status=0
[ "$ros" -eq 5 ] && ros=0
[ "$status" -ne 0 ] && exit "$status"
exit "$ros"
