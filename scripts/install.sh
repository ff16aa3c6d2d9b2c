#!/usr/bin/env bash
# Installs everything Sketch2Colab Studio needs on a Debian or Ubuntu machine: system libraries for
# headless OpenGL (EGL/llvmpipe), Qt and virtual environments through apt, then the project into its
# own virtual environment `.venv` in the checkout (the system Python refuses system-wide pip
# installs, PEP 668). Idempotent: a second run only checks.
#
#   PYTHON=/path/to/python3   the interpreter the venv is built from (default: the system's)
#   TORCH_INDEX_URL=URL       where torch 2.13.0 comes from when no local copy is found
#                             (default: PyTorch's CPU-only index, so that no CUDA build is pulled)
set -euo pipefail
cd "$(dirname "$0")/.."

if [ -x /usr/bin/python3 ]; then PY=${PYTHON:-/usr/bin/python3}; else PY=${PYTHON:-python3}; fi
PY_VERSION=$("$PY" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')

APT_PACKAGES="libegl1 libgl1 libgl1-mesa-dri libegl-mesa0 libglib2.0-0 libfontconfig1 libdbus-1-3 \
libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 libxcb-image0 \
libxcb-render-util0 libxcb-shape0 libxcb-xinerama0 libxcb-randr0 xvfb xauth"
# The system Python's venv module (with pip) is a package of its own on Debian and Ubuntu.
if [ "$PY" = /usr/bin/python3 ]; then APT_PACKAGES="$APT_PACKAGES python${PY_VERSION}-venv"; fi
absent=$(for p in $APT_PACKAGES; do
    dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"; done)
if [ -n "$absent" ]; then
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -q
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends $APT_PACKAGES
fi

VENV=.venv
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c 'import pip' 2>/dev/null; then
    rm -rf "$VENV"
    "$PY" -m venv "$VENV"
fi
VPY=$VENV/bin/python

# torch first and pinned to the CPU build: a plain `pip install torch` on Linux takes a CUDA build
# of several GB. The CPU build is named 2.13.0+cpu: from pip's configured places when one has it
# (a local wheel folder), else from PyTorch's CPU-only index.
if ! "$VPY" -c "import torch, sys; sys.exit(torch.__version__ != '2.13.0+cpu')" 2>/dev/null; then
    "$VPY" -m pip install -q "torch==2.13.0+cpu" 2>/dev/null \
        || "$VPY" -m pip install -q "torch==2.13.0+cpu" --index-url "${TORCH_INDEX_URL:-https://download.pytorch.org/whl/cpu}"
fi
# Only when the project's requirements changed since the last install (pip's own resolve takes ~10 s).
stamp=$VENV/.installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
    "$VPY" -m pip install -q -e ".[test]"
    touch "$stamp"
fi
