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
            print("\n".join(study(sd, args.verdicts)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
