#!/usr/bin/env bash
# Installs what is missing, then runs the whole test suite headless in the project's venv.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
export QT_QPA_PLATFORM=offscreen
exec .venv/bin/python -m pytest "$@"
