#!/usr/bin/env bash
# Set up rebarlib on a fresh Debian/Ubuntu machine: system libraries, a virtual environment in
# .venv, and the project with its test extras. Safe to run again (it only adds what is missing).
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
# libusb: Open3D's import needs it; libgomp1: Open3D's OpenMP; pango/harfbuzz + fonts: WeasyPrint;
# poppler-utils: pdftoppm, to look at report pages; python3-venv: the virtual environment.
PKGS="libusb-1.0-0 libgomp1 libpango-1.0-0 libpangoft2-1.0-0 libharfbuzz0b libharfbuzz-subset0 fonts-dejavu-core poppler-utils python3-venv python3-pip"
missing=""
for p in $PKGS; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
if [ -n "$missing" ]; then
  echo "Installing system packages:$missing"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[dev]"
echo "rebarlib is set up in .venv ($(.venv/bin/python --version))"
