"""Benchmark scripts and the truth-only helpers they share (``_cameras``, ``_visibility``).

The scripts run as ``python benchmarks/<name>.py`` and import their helpers as top-level modules
(the script's folder is on ``sys.path`` then). Tests import the helpers as ``benchmarks._name``:
the repository root is on pytest's ``pythonpath`` (``pyproject.toml``), so no test edits
``sys.path``. The helpers read synthetic ground truth and never ship with the library.
"""
