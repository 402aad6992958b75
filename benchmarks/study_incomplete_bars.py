"""Why does a clean slab stay incomplete after the captures asked for? Bar by bar (issue 53).

For every clean slab of a verdict-benchmark cache (``benchmarks/bench_verdicts.py --cache DIR
--follow-advice``, judged already) whose verdict after the captures asked for is "incomplete",
lists each checkpoint left not measured: the capture, the bar (its true size through the
renders' bar ids), the camera's distance to the bar's middle, the bar's evidence (mask width and
its σ, point-cloud width, circle width, sections, share seen from one edge, visible length), the
reason, and for each other capture of the slab whether it shows the same rendered bar and what it
says of it.

    python benchmarks/study_incomplete_bars.py --cache /tmp/verdicts [--verdicts verdict_follow2.json]

``--placings`` instead checks every placing of two captures of every slab (the captures taken and
those asked for, as the verdict file lists them; ``rebarlib._across.register``, a capture's aim
included) against the renders' camera poses (``bench_placing``: wrong when a point of the mesh
lands more than 5 mm from where the other capture sees it), and lists the placings an aim chose
and the pairs an aim left unplaced, with why (docs/decisions/043), and the placings made through a
third capture placed on both, as ``resolve_across`` makes them (docs/decisions/044).

    python benchmarks/study_incomplete_bars.py --cache /tmp/verdicts --verdicts verdict_follow2.json --placings

``--evidence`` asks, from the renders' truth, what the captures of each such slab show that the
judgement does not use (docs/decisions/046): for each pair of captures, whether it is placed (or
why not) and which rendered bars both show, with how far apart along each bar their seen stretches
lie (negative: a gap); for each position left not measured, the rendered bar there, how many of
its pixels its own capture shows (the strip beside the bar above it, and the share of it with
depth), and what every other capture shows of it; for each bar left unsized, every other reading
of the same rendered bar and how far along it lies.

    python benchmarks/study_incomplete_bars.py --cache /tmp/verdicts --verdicts verdict.json --evidence
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def _fmt(x, f="{:.1f}"):
    return "–" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f.format(x)


def _bar_line(folder: Path, cap: str, bar: dict) -> str:
    try:
        from study_ambiguous_closer import _truth_id
    except ModuleNotFoundError:
        from benchmarks.study_ambiguous_closer import _truth_id

    tid = _truth_id(folder / cap, bar)
    truth = json.loads((folder / cap / "truth.json").read_text())
    tb = next((b for b in truth["bars"] if b["id"] == tid), None)
    mid = np.mean([[bar[f"{e}_{a}_mm"] for a in "xyz"] for e in ("start", "end")], axis=0)
    return (
        f"{cap} bar {bar['bar_id']} ({bar['layer']} {bar['level']}, true Φ{tb['diameter_mm']:g} id {tid}; "
        f"{np.linalg.norm(mid):.0f} mm away, {bar.get('visible_length_mm', 0):.0f} mm seen): "
        f"{bar.get('diameter_status')} Φ{_fmt(bar.get('nominal_mm'), '{:g}')} "
        f"mask {_fmt(bar.get('width_median_mm'))}±{_fmt(bar.get('width_sigma_mm'), '{:.2f}')} "
        f"cloud {_fmt(bar.get('cloud_width_mm'))} circle {_fmt(bar.get('circle_width_mm'))} "
        f"sections {bar.get('n_sections')} one-sided {_fmt(bar.get('one_sided_share'), '{:.2f}')} "
        f"hidden {bar.get('hidden')}; {str(bar.get('diameter_reason') or '')[:160]}"
        if tb
        else f"{cap} bar {bar['bar_id']}: no rendered bar"
    ), tid


def study(folder: Path, name: str = "verdict_follow.json") -> list:
    import rebarlib as R

    try:
        from study_ambiguous_closer import _truth_id
    except ModuleNotFoundError:
        from benchmarks.study_ambiguous_closer import _truth_id

    rec = json.loads((folder / name).read_text())
    caps = list(rec["captures"]) + list(rec.get("followups", []))
    results = [json.loads((folder / f"result_{c}.json").read_text()) for c in caps]
    acc = R.evaluate(results, R.load_design(folder / "design.toml"))
    cp = acc.checkpoints
    rows = cp[(cp["status"] == "not measured") & cp["item"].str.match("bar_(size|count)")]
    lines = [f"slab {rec['slab']:03d}: {rec['verdict']} ({', '.join(caps)}); incomplete {rec['incomplete']}"]
    for _, row in rows.iterrows():
        if str(row["item"]).startswith("bar_count"):
            lines.append(f"  - {row['capture']} {row['item']}: {str(row['reason'])[:240]}")
            continue
        cap, bid = str(row["capture"]), int(str(row["what"]).split()[-1])
        bar = next(b for b in results[caps.index(cap)]["bars"] if int(b["bar_id"]) == bid)
        text, tid = _bar_line(folder, cap, bar)
        lines.append(f"  - {text}")
        for c, r in zip(caps, results):
            if c == cap or tid is None:
                continue
            same = [b for b in r["bars"] if _truth_id(folder / c, b) == tid]
            for b in same:
                lines.append(f"    - also {_bar_line(folder, c, b)[0]}")
            if not same:
                lines.append(f"    - {c}: not found there")
    return lines


def _world(cam: dict, p) -> np.ndarray:
    return np.array(cam["rotation_world_to_camera"]).T @ np.asarray(p, float) + np.array(cam["centre_world_mm"])


def _stretch(cam: dict, tb: dict, origin: np.ndarray, d: np.ndarray) -> tuple:
    """The rendered bar's seen stretch along its world direction ``d`` from ``origin`` (mm)."""
    return tuple(sorted(float((_world(cam, tb[k]) - origin) @ d) for k in ("visible_start_mm", "visible_end_mm")))


def _shared(ta: dict, tb: dict) -> list:
    """``[(id, layer/level, overlap mm)]``: rendered bars both captures show; the overlap of their
    seen stretches along the bar (negative: the gap between them)."""
    out = []
    for ba in ta["bars"]:
        bb = next((x for x in tb["bars"] if x["id"] == ba["id"]), None)
        if bb is None or not (ba["visible"] and bb["visible"]):
            continue
        o = _world(ta["camera"], ba["axis_start_mm"])
        d = _world(ta["camera"], ba["axis_end_mm"]) - o
        d /= np.linalg.norm(d)
        (a0, a1), (b0, b1) = _stretch(ta["camera"], ba, o, d), _stretch(tb["camera"], bb, o, d)
        out.append((ba["id"], f"{ba['layer']} {ba['level']}", min(a1, b1) - max(a0, b0)))
    return out


def _strip(folder: Path, tid: int) -> tuple:
    """``(pixels, pixels per mm of the bar's seen length, share with depth)`` the render shows of bar ``tid``."""
    import cv2

    ids = cv2.imread(str(folder / "bar_ids.png"), cv2.IMREAD_UNCHANGED).astype(int) - 1
    depth = cv2.imread(str(folder / "depth.png"), cv2.IMREAD_UNCHANGED)
    m = ids == tid
    tb = next(b for b in json.loads((folder / "truth.json").read_text())["bars"] if b["id"] == tid)
    n = int(m.sum())
    return n, n / max(tb["visible_length_mm"], 1e-9), float((depth[m] > 0).mean()) if n else 0.0


def evidence(folder: Path, name: str = "verdict.json") -> list:
    """What the renders' truth says each capture of the slab shows of the positions and bars its
    judgement left not measured (docs/decisions/046)."""
    import rebarlib as R
    from rebarlib._across import register

    try:
        from bench_placing import _gate, _pose_error
        from study_ambiguous_closer import _truth_id
    except ModuleNotFoundError:
        from benchmarks.bench_placing import _gate, _pose_error
        from benchmarks.study_ambiguous_closer import _truth_id

    rec = json.loads((folder / name).read_text())
    caps = list(rec["captures"]) + list(rec.get("followups", []))
    res = {c: json.loads((folder / f"result_{c}.json").read_text()) for c in caps}
    tru = {c: json.loads((folder / c / "truth.json").read_text()) for c in caps}
    design = R.load_design(folder / "design.toml")
    lines = [f"slab {rec['slab']:03d}: {rec['verdict']} ({', '.join(caps)}); incomplete {rec['incomplete']}"]
    for i, a in enumerate(caps):
        for b in caps[i + 1 :]:
            reg, why = register(res[a], res[b], _gate(design))
            err = _pose_error(res[a], res[b], tru[a]["camera"], tru[b]["camera"])(reg) if reg else None
            how = f"placed, {err:.1f} mm off the truth" if reg else f"not placed: {why}"
            sh = _shared(tru[a], tru[b])
            both = ", ".join(f"{t} ({k}) {o:+.0f}" for t, k, o in sh) or "none"
            lines.append(f"  {a} / {b}: {how}; rendered bars both show, overlap along (mm): {both}")
    acc = R.evaluate(list(res.values()), design)
    cp = acc.checkpoints
    rows = cp[(cp["status"] == "not measured") & cp["item"].str.match("bar_(size|count)")]
    for _, row in rows.iterrows():
        cap = str(row["capture"])
        if str(row["item"]).startswith("bar_count"):
            for p in res[cap]["positions"]:
                if p["status"] != "not measured" or f"bar_count_{p['layer']}_{p['level']}" != row["item"]:
                    continue
                mid = np.mean([[p[f"{e}_{k}_mm"] for k in "xyz"] for e in ("start", "end")], axis=0)

                def dist(tb, mid=mid):
                    a0, a1 = np.array(tb["axis_start_mm"]), np.array(tb["axis_end_mm"])
                    u = (a1 - a0) / np.linalg.norm(a1 - a0)
                    return float(np.linalg.norm((mid - a0) - ((mid - a0) @ u) * u))

                row_bars = [tb for tb in tru[cap]["bars"] if (tb["layer"], tb["level"]) == (p["layer"], p["level"])]
                tb = min(row_bars, key=dist)
                n, w, dep = _strip(folder / cap, tb["id"])
                lines.append(
                    f"  - {cap} position {p['layer']} {p['level']} at {p['offset_mm']:.0f} mm "
                    f"({str(p['reason'])[:60]}…): rendered bar {tb['id']} ({dist(tb):.0f} mm off), "
                    f"here {tb['visible_length_mm']:.0f} mm seen, {n} px ({w:.1f} px per mm), {dep:.0%} with depth"
                )
                for c in caps:
                    if c == cap:
                        continue
                    ob = next(x for x in tru[c]["bars"] if x["id"] == tb["id"])
                    ov = next((o for t, _, o in _shared(tru[cap], tru[c]) if t == tb["id"]), None)
                    along = "" if ov is None else f", overlap along {ov:+.0f} mm"
                    lines.append(f"    - {c}: {ob['visible_length_mm']:.0f} mm seen, {ob['visible_pixels']} px{along}")
            continue
        bid = int(str(row["what"]).split()[-1])
        bar = next(b for b in res[cap]["bars"] if int(b["bar_id"]) == bid)
        text, tid = _bar_line(folder, cap, bar)
        lines.append(f"  - {text}")
        for c in caps:
            if c == cap or tid is None:
                continue
            ov = next((o for t, _, o in _shared(tru[cap], tru[c]) if t == tid), None)
            along = "" if ov is None else f" (overlap along {ov:+.0f} mm)"
            same = [b for b in res[c]["bars"] if _truth_id(folder / c, b) == tid]
            for b in same:
                lines.append(f"    - also{along} {_bar_line(folder, c, b)[0]}")
            if not same:
                lines.append(f"    - {c}: not found there")
    return lines


def placings(cache: Path, name: str) -> dict:
    """Every pair of captures of every slab of ``cache`` (the verdict file ``name``'s captures and
    follow-ups) placed by ``register`` and checked against the renders' poses."""
    import rebarlib as R
    from rebarlib import _across
    from rebarlib._across import register

    try:
        from bench_placing import WRONG_MM, _gate, _pose_error
    except ModuleNotFoundError:
        from benchmarks.bench_placing import WRONG_MM, _gate, _pose_error

    out = {"pairs": 0, "placed": 0, "wrong": 0, "aimed pairs": 0, "placed by an aim": 0, "wrong by an aim": 0}
    out.update({"placed through a third": 0, "wrong through a third": 0})
    for sd in sorted(cache.glob("slab_*")):
        if not (sd / name).exists():
            continue
        rec = json.loads((sd / name).read_text())
        caps = list(rec["captures"]) + list(rec.get("followups") or [])
        gate = _gate(R.load_design(sd / "design.toml"))
        res = {c: json.loads((sd / f"result_{c}.json").read_text()) for c in caps}
        cams = {c: json.loads((sd / c / "truth.json").read_text())["camera"] for c in caps}
        regs, refused = {}, {}
        for i, a in enumerate(caps):
            for j, b in enumerate(caps[i + 1 :], i + 1):
                ra, rb = res[a], res[b]
                aims = [((r.get("extras") or {}).get("aimed_at") or {}).get("capture") for r in (ra, rb)]
                aimed = aims[1] == a or aims[0] == b
                out["pairs"] += 1
                out["aimed pairs"] += aimed
                reg, why = register(ra, rb, gate)
                if reg is None:
                    refused[(i, j)] = why
                    if aimed:
                        print(f"  {sd.name} {a} / {b}: not placed: {why}")
                    continue
                regs[(i, j)] = reg
                e = _pose_error(ra, rb, cams[a], cams[b])(reg)
                out["placed"] += 1
                out["wrong"] += e > WRONG_MM
                if reg.aimed:
                    out["placed by an aim"] += 1
                    out["wrong by an aim"] += e > WRONG_MM
                if reg.aimed or e > WRONG_MM:
                    how = f"; {reg.aimed}" if reg.aimed else ""
                    print(f"  {sd.name} {a} / {b}: placed {e:.1f} mm off the truth{how}")
        # the pairs resolve_across then places through a third capture placed on both (decision 044)
        pairwise, notes = set(regs), []
        _across._through_a_third(regs, refused, [_across.plan_sets(res[c]) for c in caps], caps, gate, notes)
        for (i, j), reg in sorted(regs.items()):
            if (i, j) in pairwise:
                continue
            e = _pose_error(res[caps[i]], res[caps[j]], cams[caps[i]], cams[caps[j]])(reg)
            out["placed"] += 1
            out["wrong"] += e > WRONG_MM
            out["placed through a third"] += 1
            out["wrong through a third"] += e > WRONG_MM
            print(f"  {sd.name} {caps[i]} / {caps[j]}: placed {e:.1f} mm off the truth through capture {reg.through}")
        for n in notes:
            if "not placed through" in n:
                print(f"  {sd.name}: {n}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True)
    ap.add_argument(
        "--verdicts",
        default="verdict_follow.json",
        help="the slabs' judged verdicts to read (verdict_follow2.json: after a second round)",
    )
    ap.add_argument("--placings", action="store_true", help="check every placing against the renders' poses")
    ap.add_argument("--evidence", action="store_true", help="what the captures show that the judgement does not use")
    args = ap.parse_args(argv)
    if args.placings:
        print(placings(Path(args.cache), args.verdicts))
        return 0
    for sd in sorted(Path(args.cache).glob("slab_*")):
        f = sd / args.verdicts
        if not f.exists():
            continue
        rec = json.loads(f.read_text())
        if rec["defect"] is None and not rec.get("truth_failed") and rec["verdict"] == "incomplete":
            print("\n".join((evidence if args.evidence else study)(sd, args.verdicts)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
