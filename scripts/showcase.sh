#!/usr/bin/env bash
# The main job: install into .venv, then run the showcase (see README).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup_venv.sh
exec .venv/bin/python -m jetpipe_ros.showcase "$@"
