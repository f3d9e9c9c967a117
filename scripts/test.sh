#!/usr/bin/env bash
# Run the whole test suite in .venv (created first if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x .venv/bin/python ] && .venv/bin/python -c "import jetpipe_ros, rclpy, numba" 2>/dev/null \
  || scripts/setup_venv.sh
exec .venv/bin/python -m pytest test -q "$@"
