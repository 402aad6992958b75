#!/usr/bin/env bash
# The main job on the shipped examples: inspect every capture of each example slab and write the
# slab's PDF acceptance report to out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
for slab in examples/*/; do
  name=$(basename "$slab")
  captures=$(find "$slab" -mindepth 1 -maxdepth 1 -type d | sort)
  .venv/bin/rebar inspect $captures --design "$slab/design.toml" --out "out/$name"
  .venv/bin/rebar report "$slab" --results "out/$name" --out "out/$name.pdf" --force  # a re-run replaces it
done
echo "Reports: $(ls out/*.pdf | tr '\n' ' ')"
