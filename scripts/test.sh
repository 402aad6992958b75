#!/usr/bin/env bash
# Run the test suite (unit tests, ground-truth tests, doctests and the notebooks).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python -m pytest "$@"
