"""``rebar inspect``: cover, layer distance, bars and spacings of one or more captures.

For every capture folder ``CAPTURE`` it writes ``OUT/<CAPTURE folder name>/`` with
``result.json`` (:meth:`InspectionResult.to_json` plus the ``"manifest"`` of what it was made
from), ``bars.csv``, ``spacings.csv`` and ``counts.csv``, prints one summary line per capture,
and ends with ``OUT/summary.csv`` (one row per capture). It never writes into a capture folder
(an input), and refuses two captures with the same folder name (their results would overwrite
each other).

Captures are inspected by ``--jobs`` local processes or on a dask cluster (``--dask``), with a
progress bar on standard error. Every output path is checked before anything is computed; the
folder is locked while the run writes to it; each capture's results are written to a temporary
folder and renamed into place, so they are always whole. A capture that fails is reported and
the others go on (exit status 1 at the end). ``--resume`` keeps the results that were made from
the same capture files, design file, method, options and rebarlib version.
"""

from __future__ import annotations

import csv
import io
import json
import sys
from pathlib import Path

from ._status import MEASURED, NOT_MEASURED

OUTPUT_FILES = ("result.json", "bars.csv", "spacings.csv", "counts.csv")
SUMMARY_NAME = "summary.csv"


def add_parser(sub):
    p = sub.add_parser(
        "inspect",
        help="measure cover, layer distance, bars and spacings of captures",
        description="Inspect RGB-D captures against a design: writes OUT/<capture>/result.json, "
        "bars.csv, spacings.csv and counts.csv, prints a summary per capture and "
        "writes OUT/summary.csv.",
    )
    p.add_argument("captures", nargs="+", metavar="CAPTURE", help="capture folder(s) (as `rebar synth` writes)")
    p.add_argument("--design", required=True, help="design.toml of the slab")
    p.add_argument("--out", required=True, metavar="DIR", help="results folder (one sub-folder per capture)")
    p.add_argument(
        "--method",
        choices=("refined", "paper"),
        default="refined",
        help="refined (default, ours) or paper (the published procedure)",
    )
    p.add_argument(
        "--no-diameters", action="store_true", help="geometry only: skip the bar diameters (method.md stage 3)"
    )
    p.add_argument(
        "--mask-source",
        choices=("fused", "model", "depth"),
        default=None,
        help="rebar mask for the diameters (default: fused for refined, model for paper)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed of the RANSAC / sampling steps")
    p.add_argument(
        "--calibration",
        metavar="FILE",
        default=None,
        help="calibration file from `rebar calibrate`: its intrinsics and depth correction are "
        "applied, and its uncertainties replace the device profile's (docs/uncertainty.md)",
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--jobs",
        type=int,
        default=None,
        metavar="N",
        help="local worker processes (default: all cores; 1: one capture at a time here)",
    )
    where.add_argument(
        "--dask",
        metavar="ADDRESS",
        default=None,
        help="run on the dask.distributed cluster whose scheduler is at ADDRESS "
        "(e.g. tcp://10.0.0.5:8786); its workers must see the capture "
        "folders at the same paths",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="skip captures whose results in OUT are whole and were made from the "
        "same capture files, design, method, options and rebarlib version",
    )
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar and no line per capture (errors and the last line still show)",
    )
    return p


def _fmt(m) -> str:
    if not m.ok:
        return NOT_MEASURED
    unc = f" ± {m.uncertainty_mm:.1f}" if m.uncertainty_mm is not None else ""
    return f"{m.value_mm:.1f}{unc} mm"


def summary_line(res) -> str:
    """One line: cover, layer distance, bars found and the worst spacing deviation."""
    bars = res.bars
    n_meas = int((bars["status"] == MEASURED).sum()) if len(bars) else 0
    sp = res.spacings
    worst = ""
    if sp is not None and len(sp) and "deviation_mm" in sp and sp["deviation_mm"].notna().any():
        dev = sp["deviation_mm"].dropna()
        worst = f", worst spacing deviation {dev.iloc[dev.abs().argmax()]:+.1f} mm"
    return (
        f"{res.capture}: cover {_fmt(res.cover)}, layer distance {_fmt(res.layer_distance)}, "
        f"top cover {_fmt(res.top_cover)}, {n_meas}/{len(bars)} bars measured, "
        f"{0 if sp is None else len(sp)} spacings{worst} [{res.method}]"
    )


def _is_capture_folder(path: Path) -> bool:
    return (path / "depth.png").exists() or (path / "camera.json").exists()


def _check_paths(captures, out: Path) -> list:
    """Every input and output path, checked before anything is computed; the result folders."""
    from ._checks import RebarInputError
    from ._outdir import check_out_folder

    for c in captures:
        if not c.is_dir():
            raise RebarInputError(f"CAPTURE {c}: not a folder (expected a capture folder with depth.png, camera.json)")
    names = [c.resolve().name for c in captures]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise RebarInputError(
            f"CAPTURE: several captures named {dup}; their results would overwrite each other "
            "in --out (rename the folders or inspect them into different --out folders)"
        )
    if SUMMARY_NAME in names:
        raise RebarInputError(f"CAPTURE: a capture folder named {SUMMARY_NAME} would collide with the batch summary")
    check_out_folder(out, names)
    if (out / SUMMARY_NAME).is_dir():
        raise RebarInputError(f"--out {out}: {out / SUMMARY_NAME} is a folder; the batch summary is written there")
    inputs = {c.resolve() for c in captures}
    targets = [out / n for n in names]
    for c, tgt in zip(captures, targets):
        r = tgt.resolve()
        if r in inputs or _is_capture_folder(r) or any(r == p or p in r.parents for p in inputs):
            raise RebarInputError(
                f"--out {out}: the results of {c} would be written into a capture folder ({tgt}); "
                "choose a results folder outside the captures"
            )
    return targets


def _absolute(path):
    """A path the workers can open whatever their working folder (a dask worker's is not ours)."""
    return None if path is None else str(Path(path).resolve())


def _options(args) -> dict:
    opts = {"diameters": not args.no_diameters, "mask_source": args.mask_source, "seed": args.seed}
    if getattr(args, "calibration", None):
        from .calibration import calibration_id

        opts["calibration"] = calibration_id(args.calibration)  # its file name and digest
    return opts


def _up_to_date(target: Path, capture: Path, design_path: Path, method: str, options: dict):
    """The stored result dict where ``target`` holds a whole result of these inputs, else None."""
    from . import __version__
    from ._manifest import manifest_problems

    if not all((target / f).is_file() for f in ("result.json", "bars.csv", "spacings.csv")):
        return None
    try:
        data = json.loads((target / "result.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    manifest = data.get("manifest") if isinstance(data, dict) else None
    if manifest_problems(manifest, capture_folder=capture, design_path=design_path, method=method, version=__version__):
        return None
    return data if manifest.get("options") == options else None


def result_files(res, data: dict) -> dict:
    """The files of one capture's result folder, as file name -> text (``data``: the result's
    ``to_dict()`` with its ``"manifest"``)."""
    files = {
        "result.json": json.dumps(data, indent=1) + "\n",
        "bars.csv": res.bars.to_csv(index=False),
        "spacings.csv": res.spacings.to_csv(index=False),
    }
    if res.counts is not None:
        files["counts.csv"] = res.counts.to_csv(index=False)
    return files


def summary_csv(rows) -> str:
    """``summary.csv``'s text: a header and one row per capture, empty cells where not measured."""
    from .batch import SUMMARY_COLUMNS

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r[k]) for k in SUMMARY_COLUMNS})
    return buf.getvalue()


def progress_bar(total: int, *, quiet: bool, unit: str = "capture"):
    """A tqdm bar on standard error (n/N, rate, time left); silent when ``quiet`` or when standard
    error is not a terminal."""
    from tqdm import tqdm

    disable = quiet or not (hasattr(sys.stderr, "isatty") and sys.stderr.isatty())
    return tqdm(total=total, unit=unit, file=sys.stderr, disable=disable, dynamic_ncols=True, smoothing=0.1)


def _say(bar, text: str, *, err: bool = False) -> None:
    """Print one line (made safe for the terminal) without breaking the progress bar."""
    from tqdm import tqdm

    from ._terminal import clean

    text = clean(text)
    stream = sys.stderr if err else sys.stdout
    if bar.disable:
        print(text, file=stream)
    else:
        tqdm.write(text, file=stream)


def run(args) -> int:
    from . import load_design
    from ._checks import RebarInputError
    from ._outdir import locked

    if args.jobs is not None and args.jobs < 1:
        raise RebarInputError(f"--jobs {args.jobs}: expected a number of processes >= 1")
    design_path = Path(args.design)
    design = load_design(design_path)
    out = Path(args.out)
    captures = [Path(c) for c in args.captures]
    targets = _check_paths(captures, out)
    with locked(out):
        return _run_locked(args, design, design_path, out, captures, targets)


def _run_locked(args, design, design_path, out, captures, targets) -> int:
    from ._manifest import make_manifest
    from ._outdir import write_file_atomically, write_folder_atomically
    from .batch import inspect_many, summary_row

    options = _options(args)
    rows = {}
    todo = []
    for i, (c, tgt) in enumerate(zip(captures, targets)):
        data = _up_to_date(tgt, c, design_path, args.method, options) if args.resume else None
        if data is not None:
            rows[i] = summary_row(tgt.name, "resumed", data)
        else:
            todo.append(i)
    failed = 0
    bar = progress_bar(len(todo), quiet=args.quiet)
    try:
        if len(rows) and not args.quiet:
            _say(bar, f"{len(rows)} of {len(captures)} captures resumed: their results in {out} are up to date")
        client = args.dask
        jobs = None if client else (args.jobs or None)
        outcomes = inspect_many(
            [captures[i] for i in todo],
            design,
            client=client,
            jobs=jobs,
            method=args.method,
            diameters=not args.no_diameters,
            mask_source=args.mask_source,
            rng=args.seed,
            calibration=_absolute(getattr(args, "calibration", None)),
        )
        for o in outcomes:
            i = todo[o.index]
            name = targets[i].name
            if not o.ok:
                failed += 1
                rows[i] = summary_row(name, "failed", None, o.seconds, o.error)
                _say(bar, f"{name}: error: {o.error}", err=True)
                bar.update(1)
                continue
            data = o.result.to_dict()
            data["manifest"] = make_manifest(captures[i], design_path, method=args.method, options=options)
            write_folder_atomically(out, name, result_files(o.result, data))
            rows[i] = summary_row(name, "ok", data, o.seconds)
            if not args.quiet:
                _say(bar, summary_line(o.result))
            bar.update(1)
    finally:
        bar.close()
        write_file_atomically(out / SUMMARY_NAME, summary_csv(rows[i] for i in sorted(rows)))
    n_ok = sum(r["status"] == "ok" for r in rows.values())
    from ._terminal import clean

    line = (
        f"{len(captures)} captures: {n_ok} inspected, {len(captures) - n_ok - failed} resumed, "
        f"{failed} failed; summary: {out / SUMMARY_NAME}"
    )
    print(clean(line), file=sys.stderr if failed else sys.stdout)
    return 1 if failed else 0
