# Shortcuts for the README's commands and a few more.
.PHONY: setup demo test test-fast lint docs examples bench
setup:
	bash scripts/setup.sh
demo:
	bash scripts/demo.sh
test:          # both tiers: the README's test command
	bash scripts/test.sh
test-fast:     # the default tier, without the tests marked slow (a few minutes on 2 cores)
	bash scripts/test.sh -m "not slow"
lint: setup
	.venv/bin/ruff check .
	.venv/bin/ruff format --check .
# The HTML site in docs/_build/html. Notebooks are executed once and cached; CI passes
# SPHINXOPTS="-W --keep-going -D nb_execution_mode=off" (its slow tier already runs them).
SPHINXOPTS ?= -W --keep-going
docs: setup
	.venv/bin/python -c "import sphinx, myst_nb" 2>/dev/null || .venv/bin/python -m pip install -q -e ".[docs]"
	.venv/bin/sphinx-build -b html $(SPHINXOPTS) docs docs/_build/html
examples: setup
	.venv/bin/python examples/make_examples.py
bench: setup
	.venv/bin/python benchmarks/run_all.py
