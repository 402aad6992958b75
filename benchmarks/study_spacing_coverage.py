"""Study: whether the stated uncertainty of a spacing covers its error, by how its two bars were seen.

Reads the results a ``bench_verdicts.py`` cache already holds (``slab_*/result_*.json`` next to
each capture's ``truth.json``); nothing is inspected again. Each measured bar is matched to the
nearest true bar of its layer whose axis is parallel to it (within about 11°) and within 20 mm of
the bar's middle; a measured spacing whose two bars are matched to a pair of neighbours the truth
spaces is compared with that truth. Each spacing is put in the worst kind of its two bars:

- ``lap``: a bar matched to a piece of a lap (``bench_verdicts.py --laps N``);
- ``one edge, under a nearer bar``: seen from one edge over at least half its sections
  (``one_sided_share``) and partly under nearer bars over at least half (``occluded_fraction``);
- ``one edge``: seen from one edge over at least half its sections;
- ``two edges``: the others.

Printed per kind: how many spacings, the share within 2 u of the truth (u: the spacing's stated
standard uncertainty), |error| / u at the 95th percentile and its largest, |error| at the 95th
percentile (mm), u's median; then the spacings beyond 3 u, largest first.

Usage::

    python benchmarks/study_spacing_coverage.py --cache DIR [--cache DIR2 ...]

docs/decisions/076-a-lone-lap-piece-is-spaced-as-it-lies.md has the figures.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

_KINDS = ("two edges", "one edge", "one edge, under a nearer bar", "lap")


def _axis(rec: dict, a: str, b: str) -> tuple:
    p0 = np.array([rec[f"{a}_{c}_mm"] for c in "xyz"], float)
    p1 = np.array([rec[f"{b}_{c}_mm"] for c in "xyz"], float)
    return p0, p1


def _match(bar: dict, truth_bars: list) -> dict | None:
    """The true bar of ``bar``'s layer, parallel to it, whose axis passes nearest its middle
    (within 20 mm); None if there is none."""
    s, e = _axis(bar, "start", "end")
    mid, d = (s + e) / 2, (e - s) / np.linalg.norm(e - s)
    best = None
    for t in truth_bars:
        if t["layer"] != bar["layer"]:
            continue
        q0 = np.asarray(t["axis_start_mm"], float)
        q1 = np.asarray(t["axis_end_mm"], float)
        td = (q1 - q0) / np.linalg.norm(q1 - q0)
        if abs(float(td @ d)) < 0.98:
            continue
        v = mid - q0
        off = float(np.linalg.norm(v - (v @ td) * td))
        if off < 20.0 and (best is None or off < best[0]):
            best = (off, t)
    return None if best is None else best[1]


def _kind(bar: dict, true_bar: dict) -> str:
    if true_bar.get("lap_partner") is not None:
        return "lap"
    one = float(bar.get("one_sided_share") or 0.0) >= 0.5
    covered = float(bar.get("occluded_fraction") or 0.0) >= 0.5
    return "one edge, under a nearer bar" if one and covered else "one edge" if one else "two edges"


def rows_of(result: dict, truth: dict, where: str = "") -> list:
    """One row per measured spacing of ``result`` whose bars match a pair the truth spaces."""
    matched, kinds = {}, {}
    for b in result.get("bars") or []:
        if b.get("status") != "measured":
            continue
        t = _match(b, truth["bars"])
        if t is not None:
            matched[b["bar_id"]] = t["id"]
            kinds[b["bar_id"]] = _kind(b, t)
    true_sp = {}
    for s in truth["spacings"]:
        true_sp[(s["bar_a"], s["bar_b"])] = true_sp[(s["bar_b"], s["bar_a"])] = s["spacing_mm"]
    out = []
    for s in result.get("spacings") or []:
        u = s.get("uncertainty_mm")
        if s.get("status") != "measured" or u is None or not u > 0:
            continue
        key = (matched.get(s["bar_a"]), matched.get(s["bar_b"]))
        if key not in true_sp:
            continue
        kind = max((kinds[s["bar_a"]], kinds[s["bar_b"]]), key=_KINDS.index)
        err = float(s["spacing_mm"]) - true_sp[key]
        out.append(
            {
                "kind": kind,
                "err": err,
                "u": float(u),
                "z": abs(err) / float(u),
                "where": f"{where} bars {s['bar_a']}-{s['bar_b']}",
            }
        )
    return out


def study(caches: list) -> pd.DataFrame:
    rows = []
    for cache in caches:
        for folder in sorted(Path(cache).glob("slab_*")):
            meta = folder / "slab.json"
            if not meta.exists():
                continue
            for cap in json.loads(meta.read_text())["captures"]:
                rp, tp = folder / f"result_{cap}.json", folder / cap / "truth.json"
                if rp.exists() and tp.exists():
                    where = f"{Path(cache).name}/{folder.name}/{cap}"
                    rows += rows_of(json.loads(rp.read_text()), json.loads(tp.read_text()), where)
    return pd.DataFrame(rows, columns=["kind", "err", "u", "z", "where"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", action="append", required=True, help="a bench_verdicts.py cache (repeatable)")
    args = ap.parse_args(argv)
    df = study(args.cache)
    if df.empty:
        print("no measured spacing matched to the truth")
        return 1
    print(f"{len(df)} measured spacings matched to the truth, {len(args.cache)} cache(s)\n")
    print("| kind | spacings | within 2u % | \\|e\\|/u p95 | \\|e\\|/u max | \\|e\\| p95 mm | u p50 mm |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for kind in _KINDS:
        k = df[df.kind == kind]
        if len(k):
            within = 100.0 * float((k.z <= 2).mean())
            z95, zmax = float(k.z.quantile(0.95)), float(k.z.max())
            e95, u50 = float(np.percentile(k.err.abs(), 95)), float(k.u.median())
            print(f"| {kind} | {len(k)} | {within:.2f} | {z95:.2f} | {zmax:.2f} | {e95:.2f} | {u50:.2f} |")
    far = df[df.z > 3].sort_values("z", ascending=False)
    print(f"\n{len(far)} beyond 3 u:")
    for r in far.itertuples():
        print(f"- {r.where}: error {r.err:+.2f} mm, u {r.u:.2f} mm ({r.kind})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
