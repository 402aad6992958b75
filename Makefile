# Shortcuts for the two README commands and a few more.
.PHONY: setup demo test examples bench
setup:
	bash scripts/setup.sh
demo:
	bash scripts/demo.sh
test:
	bash scripts/test.sh
examples: setup
	.venv/bin/python examples/make_examples.py
bench: setup
	.venv/bin/python benchmarks/run_all.py
