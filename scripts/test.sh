#!/usr/bin/env bash
# Run the test suite: unit and ground-truth tests, doctests and the notebooks. Both tiers by
# default; pass pytest arguments to narrow it, e.g. the fast tier: bash scripts/test.sh -m "not slow"
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# On every core (pytest-xdist; at most 4 worker processes, each loads the model and the libraries),
# one test file per worker at a time so that a file's shared fixtures are built once
# (docs/decisions/077-tests-on-every-core.md). Pass -n 0 to run in this process alone.
.venv/bin/python -m pytest -n auto --maxprocesses 4 --dist loadfile "$@"
