#!/usr/bin/env bash
# Installs what is missing, then runs the whole test suite headless.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
export QT_QPA_PLATFORM=offscreen
python3 -m pytest "$@"
