"""Study: how far a capture's rebar mask reads its bars wide or narrow, against the renders' truth,
and how well the bars' stack heights tell it on the capture itself.

Reads the results a ``bench_verdicts.py`` cache already holds (``slab_*/result_*.json`` next to
each capture's ``truth.json``); nothing is inspected again. Each bar with an axis is matched to
the nearest true bar of its layer (its axis within 8 mm of the bar's middle). Printed:

1. per diameter status (and the first words of its reason): how many bars, and their mask width
   (``width_median_mm``) less the true bar's rib envelope, median and 10th / 90th percentiles;
   the cloud's width less the envelope, median;
2. the bars sized (status "measured"): how many to their true size, how many to another (each
   named: slab, capture, bar, size given, true size, confidence);
3. per capture with at least 5 such bars seen from both edges: the mask's true lean (median of
   width less envelope) against the lean read on the capture, the median of mask width less stack
   height (``stack_mm``: a top-level bar's top above the bars it rests on) over at least 5 bars
   that have one; the error's median and spread (IQR), and their correlation.

Usage::

    python benchmarks/study_mask_lean.py --cache DIR [--cache DIR2 ...]

docs/verdicts.md ("Slabs rendered a way not tried before") has the figures.
"""

from __future__ import annotations

import argparse
import json
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

MATCH_MM = 8.0
MIN_BARS = 5


def _nearest_true_bar(bar: dict, truth: dict):
    """The true bar of the same layer whose axis passes nearest the bar's middle, if within
    ``MATCH_MM``."""
    s = np.array([bar["start_x_mm"], bar["start_y_mm"], bar["start_z_mm"]])
    e = np.array([bar["end_x_mm"], bar["end_y_mm"], bar["end_z_mm"]])
    m = (s + e) / 2
    best, best_d = None, np.inf
    for t in truth["bars"]:
        if t["layer"] != bar["layer"]:
            continue
        a0, a1 = np.array(t["axis_start_mm"]), np.array(t["axis_end_mm"])
        d = (a1 - a0) / np.linalg.norm(a1 - a0)
        v = m - a0
        dist = float(np.linalg.norm(v - (v @ d) * d))
        if dist < best_d:
            best, best_d = t, dist
    return best if best_d <= MATCH_MM else None


def _num(v) -> float:
    return float(v) if v is not None else np.nan


def study(cache: Path) -> None:
    by_kind = defaultdict(list)  # kind -> [(mask - envelope, cloud - envelope)]
    captures = []  # (true lean, lean from stacks)
    right, wrong = 0, []
    for f in sorted(cache.glob("slab_*/result_*.json")):
        cap = f.parent / f.name[len("result_") : -len(".json")]
        truth = json.loads((cap / "truth.json").read_text(encoding="utf-8"))
        lean, stack = [], []
        for b in json.loads(f.read_text(encoding="utf-8"))["bars"]:
            if b.get("start_x_mm") is None:
                continue
            t = _nearest_true_bar(b, truth)
            if t is None:
                continue
            w, env = _num(b.get("width_median_mm")), t["envelope_mm"]
            if b["diameter_status"] == "measured":
                if abs(_num(b.get("nominal_mm")) - t["diameter_mm"]) < 0.01:
                    right += 1
                else:
                    wrong.append(
                        (
                            f.parent.name,
                            cap.name,
                            b["bar_id"],
                            b.get("nominal_mm"),
                            t["diameter_mm"],
                            b.get("confidence"),
                        )
                    )
            reason = re.split(r"[0-9(]", (b.get("diameter_reason") or "").split(":")[0])[0].strip()
            kind = f"{b['diameter_status']}: {reason}" if reason else b["diameter_status"]
            by_kind[kind].append((w - env, _num(b.get("cloud_width_mm")) - env))
            both_edges = (b.get("one_sided_share") or 0.0) <= 0.3 and b["diameter_status"] != "hidden"
            if np.isfinite(w) and both_edges:
                lean.append(w - env)
                if np.isfinite(_num(b.get("stack_mm"))):
                    stack.append(w - b["stack_mm"])
        if len(lean) >= MIN_BARS:
            captures.append((float(np.median(lean)), float(np.median(stack)) if len(stack) >= MIN_BARS else np.nan))
    print(f"\n## {cache}\n")
    print("| bars | n | mask − envelope p50 (p10, p90) mm | cloud − envelope p50 mm |")
    print("|---|---:|---|---:|")
    for kind, rows in sorted(by_kind.items(), key=lambda kv: -len(kv[1])):
        m = np.array([r[0] for r in rows])
        c = np.array([r[1] for r in rows])
        if not np.isfinite(m).any():
            continue
        p10, p50, p90 = np.nanpercentile(m, [10, 50, 90])
        cloud = f"{np.nanmedian(c):+.2f}" if np.isfinite(c).any() else "—"
        print(f"| {kind} | {len(rows)} | {p50:+.2f} ({p10:+.2f}, {p90:+.2f}) | {cloud} |")
    print(f"\nsized: {right} to their true size, {len(wrong)} to another")
    for slab, cap, bar, got, true_mm, conf in wrong:
        print(f"- {slab} {cap} bar {bar}: sized Φ{got:g}, truly Φ{true_mm:g} (confidence {conf})")
    true = np.array([c[0] for c in captures])
    est = np.array([c[1] for c in captures])
    ok = np.isfinite(est)
    print(
        f"\ncaptures: {len(captures)}; true lean p50 {np.median(true):+.2f} mm (p10 {np.percentile(true, 10):+.2f}, "
        f"p90 {np.percentile(true, 90):+.2f})"
    )
    if ok.sum() >= 3:
        err = est[ok] - true[ok]
        q75, q25 = np.percentile(err, [75, 25])
        print(
            f"lean read from stack heights ({ok.sum()} captures): error p50 {np.median(err):+.2f} mm, "
            f"IQR {q75 - q25:.2f} mm, correlation with the true lean {np.corrcoef(est[ok], true[ok])[0, 1]:.2f}"
        )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", action="append", required=True, type=Path, help="a bench_verdicts.py cache")
    args = ap.parse_args(argv)
    for cache in args.cache:
        study(cache)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
