#!/usr/bin/env bash
# Run the test suite: unit and ground-truth tests, doctests and the notebooks. Both tiers by
# default; pass pytest arguments to narrow it, e.g. the fast tier: bash scripts/test.sh -m "not slow"
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python -m pytest "$@"
