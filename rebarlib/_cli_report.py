"""``rebar report SLAB_DIR --out report.pdf``: judge a slab's captures and write its acceptance record.

A slab folder holds ``design.toml`` and one folder per capture. With ``--results DIR`` the
inspection results are read from ``DIR/<capture>/result.json`` (as ``rebar inspect --out DIR``
writes them); without it every capture is inspected here first.

Nothing a user gave is written over: the report and its exports are refused inside a capture
folder, on the design file or on a results folder's files, and on an existing report unless
``--force``; every output path is checked before anything is computed. Results read with
``--results`` must carry a manifest (``rebarlib._manifest``) that matches the captures and the
design they are judged against, all from one method and one rebarlib version.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from . import _cli_floor as _floor
from ._checks import RebarInputError
from ._terminal import clean

#: Longest file name made from a slab id when ``--out`` is a folder (before the suffix).
MAX_STEM_CHARS = 80


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "report",
        help="write a slab's acceptance report (PDF or HTML) with CSV/JSON exports",
        description="Judge every capture of a slab against its design.toml and the tolerance preset, "
        "and write the acceptance record. Next to the report: <stem>_checkpoints.csv "
        "and <stem>_acceptance.json.",
    )
    p.add_argument("slab_dir", metavar="SLAB_DIR", help="folder with design.toml and one folder per capture")
    p.add_argument(
        "--out",
        required=True,
        help="report file to write (e.g. out/S-101.pdf), or a folder: the report is then "
        "named after the slab id (out/S-101.pdf)",
    )
    p.add_argument(
        "--force", action="store_true", help="replace an existing report and exports (inputs are never written over)"
    )
    p.add_argument(
        "--results",
        metavar="DIR",
        help="read DIR/<capture>/result.json (from `rebar inspect --out DIR`) instead of inspecting",
    )
    p.add_argument(
        "--format",
        choices=("pdf", "html"),
        default=None,
        help="report format (default: from the --out suffix, else pdf)",
    )
    p.add_argument(
        "--standard",
        metavar="NAME_OR_TOML",
        default=None,
        help="tolerance preset (GB50204-2015, ACI117-318, EN13670-class1, custom) or a .toml "
        "file; default: the design's [slab] standard",
    )
    p.add_argument(
        "--decision-rule",
        metavar="RULE",
        default=None,
        help="judge under this decision rule instead of the preset's or the design's: simple, guarded, "
        '"shared risk" or proven (docs/uncertainty.md); the report names the rule it used',
    )
    p.add_argument(
        "--method",
        choices=("paper", "refined"),
        default="refined",
        help="inspection method when the captures are inspected here (default: refined)",
    )
    p.add_argument("--no-exports", action="store_true", help="do not write the CSV/JSON exports")
    _floor.add_arguments(p)  # SLAB_DIR may be a floor: a folder of slab folders
    return p


def _names_folder(out) -> bool:
    """Whether ``--out`` names a folder: an existing one, or a path ending in a separator."""
    return Path(out).is_dir() or str(out).endswith(("/", "\\"))


def report_format(out, fmt: str | None) -> str:
    """The report's format: ``fmt`` where given, else html for an ``--out`` file ending in
    ``.html`` / ``.htm``, else pdf (also for a folder)."""
    if fmt:
        return fmt
    if _names_folder(out):
        return "pdf"
    return "html" if Path(out).suffix.lower() in (".html", ".htm") else "pdf"


def report_paths(out, *, slab_id: str, fmt: str | None, exports: bool) -> tuple[Path, str, list]:
    """Where the report and its exports go: ``(report, format, [report, csv, json])``.

    ``out`` names the report file, or a folder (an existing one, or a path ending in ``/``):
    the report is then ``<out>/<slab id>.<format>``, the id reduced to letters, digits, ``.``,
    ``_`` and ``-`` and cut to :data:`MAX_STEM_CHARS`.
    """
    fmt = report_format(out, fmt)
    folder, out = _names_folder(out), Path(out)
    if folder:
        stem = re.sub(r"[^A-Za-z0-9._-]+", "_", slab_id).strip("._")[:MAX_STEM_CHARS] or "report"
        out = out / f"{stem}.{fmt}"
    paths = [out]
    if exports:
        paths += [out.with_name(out.stem + "_checkpoints.csv"), out.with_name(out.stem + "_acceptance.json")]
    return out, fmt, paths


def check_outputs(paths, *, inputs=(), input_folders=(), force: bool = False) -> None:
    """Refuse, before anything is computed, an output path that would write over an input or an
    earlier report, or that cannot be written.

    ``inputs``: files never written over (the design file, the results' files); ``input_folders``:
    folders nothing is written into (the capture folders: a new file there would change the
    capture; and each capture's results folder, which ``rebar inspect`` replaces whole). An
    existing output is replaced only with ``force``.
    """
    files = {Path(f).resolve() for f in inputs}
    folders = [Path(d).resolve() for d in input_folders]
    for path in paths:
        path = Path(path)
        real = path.resolve()
        if real in files:
            raise RebarInputError(f"--out {path}: is an input of this report; refusing to write over it")
        inside = next((d for d in folders if real == d or d in real.parents), None)
        if inside is not None:
            raise RebarInputError(
                f"--out {path}: lies inside the input folder {inside} (a capture, or its "
                "results); refusing to write into it (choose a path outside)"
            )
        if path.is_dir():
            raise RebarInputError(
                f"--out {path}: is a folder; name the report file, or give the folder "
                "with a trailing / to name the report after the slab"
            )
        for parent in path.absolute().parents:
            if parent.exists() and not parent.is_dir():
                raise RebarInputError(f"--out {path}: {parent} is a file, so the report cannot be written below it")
        if path.exists() and not force:
            raise RebarInputError(f"--out {path}: exists; pass --force to replace it")


def check_manifests(pairs: list, *, design_path) -> None:
    """Refuse results that were not made from these captures and this design, or that mix
    methods or rebarlib versions; the message says which capture and what differs.

    ``pairs``: ``(capture folder, result dict read from its result.json)``.
    """
    from ._manifest import manifest_problems

    problems = []
    for folder, r in pairs:
        for why in manifest_problems(r.get("manifest"), capture_folder=folder, design_path=design_path):
            problems.append(f"result of {Path(folder).name}: {why}")
    manifests = [r.get("manifest") for _, r in pairs if isinstance(r.get("manifest"), dict)]
    for key, what in (("method", "methods"), ("rebarlib_version", "rebarlib versions")):
        seen = sorted({str(m.get(key)) for m in manifests})
        if len(seen) > 1:
            problems.append(f"the results mix {what}: {', '.join(seen)} (re-run `rebar inspect` on every capture)")
    if problems:
        raise RebarInputError("--results: refusing results that do not belong to this report: " + "; ".join(problems))


def _clouds(slab_dir) -> list:
    """Scanned cloud files of a slab folder that holds no capture folder (their results come from
    ``rebar inspect-cloud``). Beside captures, a .csv or .txt is an export, not a scan."""
    from .cloud_io import cloud_files
    from .report import find_captures

    return [] if find_captures(slab_dir) else cloud_files(slab_dir)


def _name(capture: Path) -> str:
    """A capture's name in the results folder: a folder's name, a cloud file's stem."""
    return capture.stem if capture.is_file() else capture.name


def _result_files(results_dir) -> list:
    rdir = Path(results_dir)
    return [p for p in rdir.rglob("*") if p.is_file()] if rdir.is_dir() else []


def _read_result(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RebarInputError(f"{path}: not a valid result.json ({exc})") from None
    if not isinstance(data, dict) or "capture" not in data or "measurements" not in data:
        raise RebarInputError(f"{path}: not an inspection result (expected the keys 'capture' and 'measurements')")
    return data


def collect_results(slab_dir, *, results_dir=None, design=None, method: str = "refined", design_path=None):
    """Results of every capture of a slab, and the captures that have none (with the reason).

    With ``results_dir`` and ``design_path``, the results' manifests are checked against the
    slab's captures and that design file (:func:`check_manifests`).

    Returns ``(results, missing)``: a list of result dicts / InspectionResults in capture order and
    a list of ``(capture name, reason)``.
    """
    from .report import find_captures

    captures = find_captures(slab_dir)
    clouds = _clouds(slab_dir)
    if clouds and results_dir is None:
        raise RebarInputError(
            f"{slab_dir}: scanned clouds ({clouds[0].name}, ...) are judged from their results: "
            "run `rebar inspect-cloud` and pass its output with --results DIR"
        )
    captures += clouds
    if not captures:
        raise RebarInputError(f"{slab_dir}: no capture folders (sub-folders with camera.json) in the slab folder")
    results, missing = [], []
    if results_dir is not None:
        rdir = Path(results_dir)
        if not rdir.is_dir():
            raise RebarInputError(f"--results {rdir}: folder not found (expected <capture>/result.json inside)")
        pairs = []
        for cap in captures:
            path = rdir / _name(cap) / "result.json"
            if path.is_file():
                pairs.append((cap, _read_result(path)))
            else:
                missing.append((_name(cap), f"no result: {path} does not exist"))
        if design_path is not None:
            check_manifests(pairs, design_path=design_path)
        results = [r for _, r in pairs]
        return results, missing
    try:
        from ._inspect import inspect
    except ModuleNotFoundError as exc:  # the geometry stage is not part of this installation
        if exc.name != "rebarlib._inspect":
            raise
        raise RebarInputError(
            "the inspection stage (rebarlib._inspect) is not available: run "
            "`rebar inspect` elsewhere and pass its output with --results DIR"
        ) from None
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
    from contextlib import nullcontext

    from ._pdf_writer import PdfWriter

    # WeasyPrint loads in a helper process while this one reads the results and judges the slab
    with nullcontext() if report_format(args.out, args.format) == "html" else PdfWriter() as writer:
        return _run(args, writer)


def _run(args, writer) -> int:
    from ._design import load_design
    from .acceptance import evaluate, load_tolerances
    from .report import build_report, find_captures

    slab = Path(args.slab_dir)
    design_path = slab / "design.toml" if slab.is_dir() else slab
    design = with_rule(load_design(design_path), getattr(args, "decision_rule", None))
    tolerances = _tolerances(args.standard, design, load_tolerances)
    out, fmt, outputs = report_paths(args.out, slab_id=design.slab_id, fmt=args.format, exports=not args.no_exports)
    captures = find_captures(slab) if slab.is_dir() else []
    if args.results and slab.is_dir():
        captures += _clouds(slab)
    result_folders = [Path(args.results) / _name(c) for c in captures] if args.results else []
    check_outputs(
        outputs,
        inputs=[design_path, *(_result_files(args.results) if args.results else [])],
        input_folders=[*captures, *result_folders],
        force=args.force,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    results, missing = collect_results(
        slab, results_dir=args.results, design=design, method=args.method, design_path=design_path
    )
    acc = evaluate(results, design, tolerances, missing_captures=missing)
    path = build_report(slab, design, acc, out_path=out, format=fmt, exports=not args.no_exports, pdf_writer=writer)
    n_items = len(acc.items)
    counts = acc.items["verdict"].value_counts().to_dict()
    print(
        clean(
            f"slab {design.slab_id}: {acc.verdict.upper()} ({len(results)} capture(s)"
            + (f", {len(missing)} without result" if missing else "")
            + f"; {n_items} items: "
            + ", ".join(f"{v} {k}" for k, v in counts.items())
            + ")"
        )
    )
    for r in acc.reasons:
        print(f"  - {clean(r)}")
    print(clean(f"report: {path}"))
    if not args.no_exports:
        print(clean(f"exports: {outputs[1]}, {outputs[2]}"))
    sys.stdout.flush()
    return 0


def with_rule(design, rule):
    """``design`` judged under the decision rule ``rule`` (``--decision-rule``; None: as it is),
    the name checked before anything is computed."""
    if rule is None:
        return design
    from dataclasses import replace

    from ._decision import check_rule

    return replace(design, tolerances={**design.tolerances, "decision_rule": check_rule(rule, "--decision-rule")})


def _tolerances(standard, design, load_tolerances):
    """The tolerances the report judges by, resolved before anything is computed: ``--standard``,
    else the design's ``[slab] standard`` (an unknown name is refused, naming the design file)."""
    if standard:
        return load_tolerances(standard)
    try:
        load_tolerances(design.standard)
    except RebarInputError as exc:
        raise RebarInputError(f"{design.source}: slab.standard = {design.standard!r}: {exc}") from None
    return None
