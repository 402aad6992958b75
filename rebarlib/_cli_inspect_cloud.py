"""``rebar inspect-cloud``: bars, spacings, layer distance and cover of scanned point clouds.

For every cloud file ``CLOUD`` it writes ``OUT/<CLOUD file stem>/`` with ``result.json`` (the same
schema as ``rebar inspect``, with a ``"manifest"`` naming the cloud file and its digest),
``bars.csv``, ``spacings.csv`` and ``counts.csv``, and prints one summary line.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def add_parser(sub):
    p = sub.add_parser(
        "inspect-cloud",
        help="measure bars, spacings, layer distance and cover of scanned clouds",
        description="Inspect scanned point clouds (PLY, PCD, XYZ/PTS/CSV/TXT, NPZ, LAS/LAZ, E57) "
        "against a design: writes OUT/<cloud stem>/result.json and the CSVs.",
    )
    p.add_argument("clouds", nargs="+", metavar="CLOUD", help="point cloud file(s)")
    p.add_argument("--units", required=True, choices=("m", "mm"), help="unit of the clouds' coordinates")
    p.add_argument(
        "--up",
        choices=("+x", "-x", "+y", "-y", "+z", "-z"),
        default=None,
        help="the mesh's up axis in the clouds' frame (default: found, and the notes say how)",
    )
    p.add_argument("--design", required=True, help="design.toml of the slab")
    p.add_argument("--out", required=True, metavar="DIR", help="results folder (one sub-folder per cloud)")
    p.add_argument(
        "--min-length",
        type=float,
        default=100.0,
        metavar="MM",
        help="report a bar when at least this much of it is scanned (default 100 mm)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed of the sampling steps")
    return p


def run(args) -> int:
    from ._checks import RebarInputError
    from ._cli_inspect import summary_line
    from ._design import load_design
    from .scan import METHOD, cloud_manifest, inspect_cloud

    design = load_design(args.design)
    out = Path(args.out)
    clouds = [Path(c) for c in args.clouds]
    stems = [c.stem for c in clouds]
    dup = sorted({s for s in stems if stems.count(s) > 1})
    if dup:
        raise RebarInputError(f"CLOUD: several clouds named {dup}; their results would overwrite each other in --out")
    if out.exists() and not out.is_dir():
        raise RebarInputError(f"--out {out}: exists and is not a folder")
    failed = 0
    for c in clouds:
        try:
            res = inspect_cloud(
                c, design, units=args.units, up=args.up, min_length_mm=args.min_length, rng=args.seed, name=c.stem
            )
        except RebarInputError as exc:
            print(f"{c.name}: error: {exc}", file=sys.stderr)
            failed += 1
            continue
        tgt = out / c.stem
        tgt.mkdir(parents=True, exist_ok=True)
        data = res.to_dict()
        data["manifest"] = cloud_manifest(
            c,
            args.design,
            method=METHOD,
            options={"units": args.units, "up": args.up, "min_length_mm": args.min_length, "seed": args.seed},
        )
        (tgt / "result.json").write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
        res.bars.to_csv(tgt / "bars.csv", index=False)
        res.spacings.to_csv(tgt / "spacings.csv", index=False)
        res.counts.to_csv(tgt / "counts.csv", index=False)
        print(summary_line(res))
    if failed:
        print(f"{failed} of {len(clouds)} clouds failed", file=sys.stderr)
        return 1
    return 0
