"""Would another capture size a bar the verdict benchmark left ambiguous? (docs/decisions/035)

For every bar a clean slab's sheet leaves unchecked because its size is ambiguous between two
sizes (the captures taken, ``benchmarks/bench_verdicts.py --cache DIR``, judged together),
renders the slab again from three poses aimed at the bar's seen middle (the capture's heading
kept): from 400 mm (the benchmark's lowest height) at the capture's tilt, from the capture's
height straight down, and from 400 mm straight down; inspects each and prints what the diameter
stage says of the same bar there (found through the renders' bar ids). Renders go under
``--out``.

    python benchmarks/study_ambiguous_closer.py --cache /tmp/verdicts --out /tmp/closer
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

#: the poses tried: (name, height (None: the capture's), tilt (None: the capture's))
POSES = (("closer", 400.0, None), ("straight down", None, 0.0), ("closer, straight down", 400.0, 0.0))


def _truth_id(folder: Path, bar: dict):
    """The rendered bar a result's bar is (the most frequent bar id along its axis), or None."""
    import cv2

    cj = json.loads((folder / "camera.json").read_text())
    K = np.array(cj["intrinsic_matrix"], float).reshape(3, 3).T
    ids = cv2.imread(str(folder / "bar_ids.png"), cv2.IMREAD_UNCHANGED)
    e = np.array([[bar[f"{k}_{a}_mm"] for a in "xyz"] for k in ("start", "end")])
    votes = []
    for s in np.linspace(0.1, 0.9, 17):
        p = e[0] + s * (e[1] - e[0])
        u, v = K[0, 0] * p[0] / p[2] + K[0, 2], K[1, 1] * p[1] / p[2] + K[1, 2]
        if 0 <= u < ids.shape[1] and 0 <= v < ids.shape[0] and ids[int(v), int(u)] > 0:
            votes.append(int(ids[int(v), int(u)]) - 1)
    return max(set(votes), key=votes.count) if votes else None


def _cases(cache: Path) -> list:
    """(slab folder, capture, bar id) of every bar a clean slab's sheet leaves not measured as
    ambiguous between two sizes (its captures taken, judged together)."""
    import rebarlib as R

    out = []
    for sd in sorted(cache.glob("slab_*")):
        meta = json.loads((sd / "slab.json").read_text())
        caps = [c for c in meta["captures"] if (sd / f"result_{c}.json").exists()]
        if meta["defect"] is not None or not caps:
            continue
        results = [json.loads((sd / f"result_{c}.json").read_text()) for c in caps]
        acc = R.evaluate(results, R.load_design(sd / "design.toml"))
        cp = acc.checkpoints
        rows = cp[cp["item"].str.startswith("bar_size") & (cp["status"] == "not measured")]
        for _, row in rows.iterrows():
            if str(row["reason"]).startswith("ambiguous"):
                out.append((str(sd), str(row["capture"]), int(str(row["what"]).split()[-1])))
    return out


def _study(args) -> str:
    import rebarlib as R

    try:
        from bench_verdicts import _render_one, _slab_plan
    except ModuleNotFoundError:
        from benchmarks.bench_verdicts import _render_one, _slab_plan

    folder, cap, bid, out_root = args
    sd = Path(folder)
    k = json.loads((sd / "slab.json").read_text())["slab"]
    bar = next(b for b in json.loads((sd / f"result_{cap}.json").read_text())["bars"] if b["bar_id"] == bid)
    tid = _truth_id(sd / cap, bar)
    truth = json.loads((sd / cap / "truth.json").read_text())
    tb = next(b for b in truth["bars"] if b["id"] == tid)
    cam = truth["camera"]
    vis = np.array([tb["visible_start_mm"], tb["visible_end_mm"]]) @ np.array(cam["rotation_world_to_camera"])
    mid = (vis + np.array(cam["centre_world_mm"])).mean(axis=0)[:2]
    out = Path(out_root) / f"{k:03d}_{cap}_{bid}"
    design, scene, _, _, specs = _slab_plan(k, out)
    spec = next(s for s in specs if s["name"] == cap)
    lines = [
        f"- slab {k:03d} {cap} bar {bid} (Φ{tb['diameter_mm']:g}, from {spec['h']:.0f} mm at {spec['tilt']:.0f}°): "
        f"{bar['diameter_reason'][:70]}…; sized from one edge on {bar.get('one_sided_share') or 0:.0%} of its sections"
    ]
    for name, h, tilt in POSES:
        h = spec["h"] if h is None else h
        tilt = spec["tilt"] if tilt is None else tilt
        new = dict(spec, name=f"X{len(lines)}", h=h, tilt=tilt, target=tuple(map(float, mid)), seed=[2026, k, 9, bid])
        _render_one(scene, new, out)
        r = R.inspect(R.load_capture(out / new["name"]), design, rng=0).to_dict()
        got = next((b for b in r["bars"] if _truth_id(out / new["name"], b) == tid), None)
        if got is None:
            lines.append(f"  - {name} ({h:.0f} mm, {tilt:.0f}°): the bar not found")
            continue
        size = f"Φ{got['nominal_mm']:g} (confidence {got['confidence']:.2f})" if got.get("nominal_mm") else ""
        lines.append(
            f"  - {name} ({h:.0f} mm, {tilt:.0f}°): {got['diameter_status']} {size}"
            + (f"; {str(got.get('diameter_reason'))[:80]}" if got.get("diameter_status") != "measured" else "")
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args(argv)
    cases = [(*c, args.out) for c in _cases(Path(args.cache))]
    with ProcessPoolExecutor(args.jobs) as ex:
        for text in ex.map(_study, cases):
            print(text, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
