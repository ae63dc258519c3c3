#!/usr/bin/env bash
# Installs VTK, the yardstick voxcube's experiments time themselves against: VTK, numpy and
# pillow from PyPI into the virtualenv /tmp/peers/venv, and Mesa's software OpenGL from Debian
# for its off-screen window. Idempotent; about 2 minutes on a fresh machine (needs root for apt).
set -euo pipefail
venv=/tmp/peers/venv
if [ -x "$venv/bin/python" ] && "$venv/bin/python" -c 'import vtk, numpy' 2>/dev/null; then exit 0; fi
apt-get update -qq >/dev/null
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv libosmesa6 libgl1-mesa-dri libegl-mesa0 >/dev/null
mkdir -p "$(dirname "$venv")"
python3 -m venv "$venv"
"$venv/bin/pip" install -q vtk numpy pillow
