"""``rebar report SLAB_DIR --out report.pdf``: judge a slab's captures and write its acceptance record.

A slab folder holds ``design.toml`` and one folder per capture. With ``--results DIR`` the
inspection results are read from ``DIR/<capture>/result.json`` (as ``rebar inspect --out DIR``
writes them); without it every capture is inspected here first.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from . import _cli_floor as _floor
from ._checks import RebarInputError


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "report", help="write a slab's acceptance report (PDF or HTML) with CSV/JSON exports",
        description="Judge every capture of a slab against its design.toml and the tolerance preset, "
                    "and write the acceptance record. Next to the report: <stem>_checkpoints.csv "
                    "and <stem>_acceptance.json.")
    p.add_argument("slab_dir", metavar="SLAB_DIR", help="folder with design.toml and one folder per capture")
    p.add_argument("--out", required=True, help="report file to write (e.g. out/S-101.pdf)")
    p.add_argument("--results", metavar="DIR",
                   help="read DIR/<capture>/result.json (from `rebar inspect --out DIR`) instead of inspecting")
    p.add_argument("--format", choices=("pdf", "html"), default=None,
                   help="report format (default: from the --out suffix, else pdf)")
    p.add_argument("--standard", metavar="NAME_OR_TOML", default=None,
                   help="tolerance preset (GB50204-2015, ACI117-318, EN13670-class1, custom) or a .toml "
                        "file; default: the design's [slab] standard")
    p.add_argument("--method", choices=("paper", "refined"), default="refined",
                   help="inspection method when the captures are inspected here (default: refined)")
    p.add_argument("--no-exports", action="store_true", help="do not write the CSV/JSON exports")
    _floor.add_arguments(p)  # SLAB_DIR may be a floor: a folder of slab folders
    return p


def _read_result(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RebarInputError(f"{path}: not a valid result.json ({exc})") from None
    if not isinstance(data, dict) or "capture" not in data or "measurements" not in data:
        raise RebarInputError(f"{path}: not an inspection result (expected the keys 'capture' and 'measurements')")
    return data


def collect_results(slab_dir, *, results_dir=None, design=None, method: str = "refined"):
    """Results of every capture of a slab, and the captures that have none (with the reason).

    Returns ``(results, missing)``: a list of result dicts / InspectionResults in capture order and
    a list of ``(capture name, reason)``.
    """
    from .report import find_captures

    captures = find_captures(slab_dir)
    if not captures:
        raise RebarInputError(f"{slab_dir}: no capture folders (sub-folders with camera.json) in the slab folder")
    results, missing = [], []
    if results_dir is not None:
        rdir = Path(results_dir)
        if not rdir.is_dir():
            raise RebarInputError(f"--results {rdir}: folder not found (expected <capture>/result.json inside)")
        for cap in captures:
            path = rdir / cap.name / "result.json"
            if path.is_file():
                results.append(_read_result(path))
            else:
                missing.append((cap.name, f"no result: {path} does not exist"))
        return results, missing
    try:
        from ._inspect import inspect
    except ModuleNotFoundError as exc:  # the geometry stage is not part of this installation
        if exc.name != "rebarlib._inspect":
            raise
        raise RebarInputError("the inspection stage (rebarlib._inspect) is not available: run "
                              "`rebar inspect` elsewhere and pass its output with --results DIR") from None
    from ._capture import load_capture

    for cap in captures:
        try:
            results.append(inspect(load_capture(cap), design, method=method))
        except RebarInputError as exc:  # one unreadable capture must not hide the others
            missing.append((cap.name, f"inspection failed: {exc}"))
    return results, missing


def run(args) -> int:
    if _floor.is_floor(args.slab_dir):  # one report per slab and a floor summary
        return _floor.run_floor(args)
    from ._design import load_design
    from .acceptance import evaluate, load_tolerances
    from .report import build_report

    slab = Path(args.slab_dir)
    design = load_design(slab / "design.toml" if slab.is_dir() else slab)
    tolerances = load_tolerances(args.standard) if args.standard else None
    out = Path(args.out)
    fmt = args.format or ("html" if out.suffix.lower() in (".html", ".htm") else "pdf")
    out.parent.mkdir(parents=True, exist_ok=True)
    results, missing = collect_results(slab, results_dir=args.results, design=design, method=args.method)
    acc = evaluate(results, design, tolerances, missing_captures=missing)
    path = build_report(slab, design, acc, out_path=out, format=fmt, exports=not args.no_exports)
    n_items = len(acc.items)
    counts = acc.items["verdict"].value_counts().to_dict()
    print(f"slab {design.slab_id}: {acc.verdict.upper()} ({len(results)} capture(s)"
          + (f", {len(missing)} without result" if missing else "") + f"; {n_items} items: "
          + ", ".join(f"{v} {k}" for k, v in counts.items()) + ")")
    for r in acc.reasons:
        print(f"  - {r}")
    print(f"report: {path}")
    if not args.no_exports:
        print(f"exports: {path.with_name(path.stem + '_checkpoints.csv')}, "
              f"{path.with_name(path.stem + '_acceptance.json')}")
    sys.stdout.flush()
    return 0
