#!/usr/bin/env bash
# The twin beside the hardware: install into .venv, then run the twin showcase (docs/twin.md).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup_venv.sh
exec .venv/bin/python -m jetpipe_ros.showcase_twin "$@"
