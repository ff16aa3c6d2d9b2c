#!/usr/bin/env bash
# Installs what is missing, then opens the app; without a screen, runs the headless demo.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
    exec .venv/bin/sketch2colab-studio "$@"
else
    echo "No screen found: running the headless demo (results in ./demo_out)."
    exec .venv/bin/sketch2colab demo -o demo_out "$@"
fi
