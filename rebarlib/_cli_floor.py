"""``rebar report FLOOR_DIR --out DIR``: one report per slab of a floor, and a floor summary.

A floor folder holds no ``design.toml`` of its own but slab folders that do (each with its
capture folders, as ``rebar report SLAB_DIR`` takes them). Every slab is judged against its own
design and gets its report, ``DIR/<slab folder>.pdf`` (or ``.html``) with its exports;
``DIR/floor_summary.csv`` has one row per slab: its verdict and the items that failed or stay
open. The captures are inspected here, all slabs' at once in ``--jobs`` processes with a
progress bar, or read from ``--results RDIR/<slab folder>/<capture>/result.json`` (as
``rebar inspect --out RDIR/<slab folder>`` writes them).

A slab that cannot be judged (its design unreadable, its results not its own) is reported in
the summary with the reason, and the other slabs go on (exit status 1 at the end). Every
output path is checked before anything is computed, and ``DIR`` is locked while it is written.
"""

from __future__ import annotations

import csv
import io
import sys
from dataclasses import dataclass, field
from pathlib import Path

from ._status import FAIL, INCOMPLETE, NOT_MEASURED

FLOOR_SUMMARY = "floor_summary.csv"
#: Item verdicts listed as open (neither passed nor failed) in the floor summary.
OPEN = (NOT_MEASURED, INCOMPLETE)
FLOOR_COLUMNS = (
    "slab",
    "slab_id",
    "verdict",
    "failed_items",
    "open_items",
    "captures",
    "captures_without_result",
    "report",
    "reason",
)
#: Seed of the inspections made here (``rebar inspect``'s default), so a report can be made again.
SEED = 0


def _clean(text) -> str:
    """``text`` safe to print: a name from a file cannot start a line or move the cursor."""
    from ._terminal import clean

    return clean(text)


def add_arguments(p) -> None:
    """The floor's options on ``rebar report``'s parser."""
    p.add_argument(
        "--jobs",
        type=int,
        default=None,
        metavar="N",
        help="a floor folder: processes inspecting its captures (default: all cores)",
    )
    p.add_argument("--quiet", action="store_true", help="a floor folder: no progress bar, no line per slab")


def is_floor(folder) -> bool:
    """Whether ``folder`` is a floor: no ``design.toml`` in it, one in a sub-folder at least."""
    folder = Path(folder)
    return folder.is_dir() and not (folder / "design.toml").exists() and bool(find_slabs(folder))


def find_slabs(folder) -> list:
    """The slab folders of a floor folder (sub-folders holding a ``design.toml``), by name."""
    return sorted(p for p in Path(folder).iterdir() if p.is_dir() and (p / "design.toml").is_file())


@dataclass
class _Slab:
    folder: Path
    design: object = None
    captures: list = field(default_factory=list)
    results: list = field(default_factory=list)
    missing: list = field(default_factory=list)
    row: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.folder.name


def _outputs(out: Path, name: str, fmt: str, exports: bool) -> list:
    report = out / f"{name}.{fmt}"
    if not exports:
        return [report]
    return [report, out / f"{name}_checkpoints.csv", out / f"{name}_acceptance.json"]


def _check_out(out: Path, slabs: list, fmt: str, *, exports: bool, force: bool) -> None:
    from ._checks import RebarInputError
    from ._outdir import check_out_folder
    from .report import find_captures

    check_out_folder(out)
    real = out.resolve()
    for s in slabs:
        for cap in find_captures(s.folder):
            if real == cap.resolve() or cap.resolve() in real.parents:
                raise RebarInputError(
                    f"--out {out}: lies inside the capture folder {cap}; choose a folder outside the captures"
                )
        for path in _outputs(out, s.name, fmt, exports):
            if path.is_dir():
                raise RebarInputError(f"--out {out}: {path} is a folder; the report of slab {s.name} goes there")
            if path.exists() and not force:
                raise RebarInputError(f"--out {out}: {path} exists; pass --force to replace it")
    if (out / FLOOR_SUMMARY).is_dir():
        raise RebarInputError(f"--out {out}: {out / FLOOR_SUMMARY} is a folder; the floor summary goes there")


def _load_designs(slabs: list) -> None:
    from ._checks import RebarInputError
    from ._design import load_design
    from .report import find_captures

    for s in slabs:
        try:
            s.design = load_design(s.folder / "design.toml")
            s.captures = find_captures(s.folder)
            if not s.captures:
                raise RebarInputError(f"{s.folder}: no capture folders (sub-folders with camera.json)")
        except RebarInputError as exc:
            s.design, s.row = None, {"verdict": "not reported", "reason": str(exc)}


def _read_results(slabs: list, results_dir: Path, method: str) -> None:
    from . import _cli_report
    from ._checks import RebarInputError

    for s in (s for s in slabs if s.design is not None):
        try:
            s.results, s.missing = _cli_report.collect_results(
                s.folder, results_dir=results_dir / s.name, design=s.design, method=method
            )
            check = getattr(_cli_report, "check_manifests", None)
            if check is not None:
                pairs = [(s.folder / r["capture"], r) for r in s.results]
                check(pairs, design_path=s.folder / "design.toml")
        except RebarInputError as exc:
            s.design, s.row = None, {"verdict": "not reported", "reason": str(exc)}


def _inspect_all(slabs: list, *, method: str, jobs, quiet: bool) -> None:
    from ._cli_inspect import progress_bar
    from .batch import inspect_pairs

    todo = [(s, cap) for s in slabs if s.design is not None for cap in s.captures]
    found = {}
    bar = progress_bar(len(todo), quiet=quiet)
    try:
        pairs = [(cap, s.design) for s, cap in todo]
        for o in inspect_pairs(pairs, jobs=jobs, method=method, rng=SEED):
            found[o.index] = o
            bar.update(1)
    finally:
        bar.close()
    for i, (s, cap) in enumerate(todo):
        o = found[i]
        if o.ok:
            s.results.append(o.result)
        else:
            s.missing.append((cap.name, f"inspection failed: {o.error}"))


def _judge(s: _Slab, out: Path, fmt: str, *, exports: bool, standard, html_only: bool, rule=None):
    """Judge a slab: ``(acceptance, report path, HTML)``. With ``html_only`` the report's HTML is
    returned for a helper to render (:class:`PdfWriter`); else the report is written here and
    the HTML is None. ``rule``: ``--decision-rule`` (None: the preset's or the design's)."""
    from ._cli_report import with_rule
    from .acceptance import evaluate, load_tolerances
    from .report import build_report, render_html, report_context

    design = with_rule(s.design, rule)
    tolerances = load_tolerances(standard) if standard else None
    acc = evaluate(s.results, design, tolerances, missing_captures=s.missing)
    path = _outputs(out, s.name, fmt, exports)[0]
    if html_only:
        return acc, path, render_html(report_context(s.folder, design, acc))
    build_report(s.folder, design, acc, out_path=path, format=fmt, exports=exports)
    return acc, path, None


def _finish(s: _Slab, acc, path: Path, *, exports: bool, writer) -> None:
    """Wait for the slab's PDF (a failure makes the slab's row "not reported"), write its exports
    and its row of the floor summary."""
    from .report import write_exports

    if writer is not None:
        try:
            writer.collect()
        except (RuntimeError, OSError) as exc:
            s.row = {"verdict": "not reported", "reason": str(exc)}
            return
        if exports:
            write_exports(acc, path)
    items = acc.items
    s.row = {
        "slab_id": s.design.slab_id,
        "verdict": acc.verdict,
        "failed_items": ";".join(items.loc[items["verdict"] == FAIL, "item"]),
        "open_items": ";".join(items.loc[items["verdict"].isin(OPEN), "item"]),
        "captures_without_result": len(s.missing),
        "report": path.name,
        "reason": "",
    }


def floor_summary_csv(slabs: list) -> str:
    """``floor_summary.csv``: one row per slab, in the floor's order."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=FLOOR_COLUMNS, lineterminator="\n")
    w.writeheader()
    for s in slabs:
        row = {"slab": s.name, "captures": len(s.captures), **s.row}
        w.writerow({k: row.get(k, "") for k in FLOOR_COLUMNS})
    return buf.getvalue()


def _line(s: _Slab) -> str:
    r = s.row
    if r.get("verdict") == "not reported":
        return _clean(f"slab {s.name}: NOT REPORTED: {r['reason']}")
    extra = "".join(
        f"; {what}: {r[key].replace(';', ', ')}"
        for key, what in (("failed_items", "failed"), ("open_items", "open"))
        if r.get(key)
    )
    return _clean(f"slab {s.name} ({r['slab_id']}): {r['verdict'].upper()}{extra}; report {r['report']}")


def run_floor(args) -> int:
    """``rebar report FLOOR_DIR --out DIR``: see the module's description."""
    from contextlib import nullcontext

    from ._checks import RebarInputError
    from ._cli_inspect import progress_bar
    from ._outdir import locked, write_file_atomically
    from ._pdf_writer import PdfWriter
    from .report import templates_dir

    floor, out = Path(args.slab_dir), Path(args.out)
    if getattr(args, "jobs", None) is not None and args.jobs < 1:
        raise RebarInputError(f"--jobs {args.jobs}: expected a number of processes >= 1")
    if getattr(args, "decision_rule", None) is not None:
        from ._decision import check_rule

        args.decision_rule = check_rule(args.decision_rule, "--decision-rule")  # refused before any work
    if out.suffix.lower() in (".pdf", ".html", ".htm"):
        raise RebarInputError(
            f"--out {out}: {floor} is a floor (a folder of slab folders): give a folder for its reports, not a file"
        )
    fmt = args.format or "pdf"
    exports = not args.no_exports
    slabs = [_Slab(p) for p in find_slabs(floor)]
    _check_out(out, slabs, fmt, exports=exports, force=bool(getattr(args, "force", False)))
    if args.results and not Path(args.results).is_dir():
        raise RebarInputError(f"--results {args.results}: folder not found (expected <slab>/<capture>/result.json)")
    quiet = bool(getattr(args, "quiet", False))
    with locked(out):
        _load_designs(slabs)
        if args.results:
            _read_results(slabs, Path(args.results), args.method)
        else:
            _inspect_all(slabs, method=args.method, jobs=getattr(args, "jobs", None), quiet=quiet)
        bar = progress_bar(len(slabs), quiet=quiet, unit="slab")
        try:  # PDFs: a helper process renders a slab's report while the next slab is judged
            with PdfWriter() if fmt == "pdf" else nullcontext() as writer:
                pending = None  # (slab, acceptance, path) whose row waits for its PDF
                for s in slabs:
                    made = None
                    if s.design is not None:
                        try:
                            acc, path, html = _judge(
                                s,
                                out,
                                fmt,
                                exports=exports,
                                standard=args.standard,
                                html_only=writer is not None,
                                rule=args.decision_rule,
                            )
                            made = (s, acc, path)
                        except RebarInputError as exc:
                            s.row = {"verdict": "not reported", "reason": str(exc)}
                    if pending is not None:
                        _finish(*pending, exports=exports, writer=writer)
                        bar.update(1)
                    if made is None:
                        bar.update(1)
                    elif writer is not None:
                        writer.submit(html, path, templates_dir())
                    pending = made
                if pending is not None:
                    _finish(*pending, exports=exports, writer=writer)
                    bar.update(1)
        finally:
            bar.close()
            write_file_atomically(out / FLOOR_SUMMARY, floor_summary_csv(slabs))
    if not quiet:
        for s in slabs:
            print(_line(s))
    failed = [s for s in slabs if s.row.get("verdict") == "not reported"]
    counts = {}
    for s in slabs:
        counts[s.row["verdict"]] = counts.get(s.row["verdict"], 0) + 1
    tally = ", ".join(f"{n} {v}" for v, n in sorted(counts.items()))
    line = f"floor {floor.name}: {len(slabs)} slabs: {tally}; summary: {out / FLOOR_SUMMARY}"
    print(_clean(line), file=sys.stderr if failed else sys.stdout)
    return 1 if failed else 0
