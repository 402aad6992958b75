"""``rebar inspect``: cover, layer distance, bars and spacings of one or more captures.

For every capture folder ``CAPTURE`` it writes ``OUT/<CAPTURE folder name>/`` with
``result.json`` (:meth:`InspectionResult.to_json`), ``bars.csv``, ``spacings.csv`` and
``counts.csv``, and prints one summary line. It never writes into a capture folder (an input),
and refuses two captures with the same folder name (their results would overwrite each other).
"""

from __future__ import annotations

import sys
from pathlib import Path

OUTPUT_FILES = ("result.json", "bars.csv", "spacings.csv", "counts.csv")


def add_parser(sub):
    p = sub.add_parser("inspect", help="measure cover, layer distance, bars and spacings of captures",
                       description="Inspect RGB-D captures against a design: writes OUT/<capture>/result.json, "
                                   "bars.csv, spacings.csv and counts.csv, and prints a summary per capture.")
    p.add_argument("captures", nargs="+", metavar="CAPTURE", help="capture folder(s) (as `rebar synth` writes)")
    p.add_argument("--design", required=True, help="design.toml of the slab")
    p.add_argument("--out", required=True, metavar="DIR", help="results folder (one sub-folder per capture)")
    p.add_argument("--method", choices=("refined", "paper"), default="refined",
                   help="refined (default, ours) or paper (the published procedure)")
    p.add_argument("--no-diameters", action="store_true",
                   help="geometry only: skip the bar diameters (method.md stage 3)")
    p.add_argument("--mask-source", choices=("fused", "model", "depth"), default=None,
                   help="rebar mask for the diameters (default: fused for refined, model for paper)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the RANSAC / sampling steps")
    return p


def _fmt(m) -> str:
    if not m.ok:
        return "not measured"
    unc = f" ± {m.uncertainty_mm:.1f}" if m.uncertainty_mm is not None else ""
    return f"{m.value_mm:.1f}{unc} mm"


def summary_line(res) -> str:
    """One line: cover, layer distance, bars found and the worst spacing deviation."""
    bars = res.bars
    n_meas = int((bars["status"] == "measured").sum()) if len(bars) else 0
    sp = res.spacings
    worst = ""
    if sp is not None and len(sp) and "deviation_mm" in sp and sp["deviation_mm"].notna().any():
        dev = sp["deviation_mm"].dropna()
        worst = f", worst spacing deviation {dev.iloc[dev.abs().argmax()]:+.1f} mm"
    return (f"{res.capture}: cover {_fmt(res.cover)}, layer distance {_fmt(res.layer_distance)}, "
            f"top cover {_fmt(res.top_cover)}, {n_meas}/{len(bars)} bars measured, "
            f"{0 if sp is None else len(sp)} spacings{worst} [{res.method}]")


def _is_capture_folder(path: Path) -> bool:
    return (path / "depth.png").exists() or (path / "camera.json").exists()


def run(args) -> int:
    from . import load_capture, load_design
    from ._checks import RebarInputError
    from ._inspect import inspect

    design = load_design(args.design)
    out = Path(args.out)
    captures = [Path(c) for c in args.captures]
    for c in captures:
        if not c.is_dir():
            raise RebarInputError(f"CAPTURE {c}: not a folder (expected a capture folder with depth.png, camera.json)")
    names = [c.resolve().name for c in captures]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise RebarInputError(f"CAPTURE: several captures named {dup}; their results would overwrite each other "
                              "in --out (rename the folders or inspect them into different --out folders)")
    inputs = {c.resolve() for c in captures}
    targets = [out / n for n in names]
    for c, tgt in zip(captures, targets):
        r = tgt.resolve()
        if r in inputs or _is_capture_folder(r) or any(r == p or p in r.parents for p in inputs):
            raise RebarInputError(f"--out {out}: the results of {c} would be written into a capture folder ({tgt}); "
                                  "choose a results folder outside the captures")
        if out.exists() and not out.is_dir():
            raise RebarInputError(f"--out {out}: exists and is not a folder")

    failed = 0
    for c, tgt in zip(captures, targets):
        try:
            cap = load_capture(c)
            res = inspect(cap, design, method=args.method, diameters=not args.no_diameters,
                          mask_source=args.mask_source, rng=args.seed)
        except RebarInputError as exc:
            print(f"{c.name}: error: {exc}", file=sys.stderr)
            failed += 1
            continue
        res.capture = c.resolve().name
        tgt.mkdir(parents=True, exist_ok=True)
        (tgt / "result.json").write_text(res.to_json() + "\n", encoding="utf-8")
        res.bars.to_csv(tgt / "bars.csv", index=False)
        res.spacings.to_csv(tgt / "spacings.csv", index=False)
        if res.counts is not None:
            res.counts.to_csv(tgt / "counts.csv", index=False)
        print(summary_line(res))
    if failed:
        print(f"{failed} of {len(captures)} captures failed", file=sys.stderr)
        return 1
    return 0
