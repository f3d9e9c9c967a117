#!/usr/bin/env bash
# Build the documentation (Sphinx, MyST Markdown, docs/) into out/docs/html, warnings as errors.
# Arguments go to sphinx-build. The venv is set up first if missing (scripts/setup_venv.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
"$VENV/bin/python" -c "import sphinx, myst_parser, jetpipe_ros" 2>/dev/null || scripts/setup_venv.sh
exec "$VENV/bin/python" -m sphinx -W --keep-going -q -b html docs out/docs/html "$@"
