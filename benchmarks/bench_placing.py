"""How often are two captures of a slab placed on each other wrongly? (docs/decisions/028)

Two checks of ``rebarlib._across.register`` against the truth:

* ``--cache DIR``: every pair of captures of every slab of a verdict-benchmark cache
  (``benchmarks/bench_verdicts.py --cache DIR``, with its follow-up captures if any), from their
  saved results, compared with the renders' true camera poses;
* ``--windows N``: pairs of windows cut from N scenes of the verdict benchmark's generator (six
  windows of 500-800 x 350-550 mm a slab, every other one within 160 mm of the one before, any
  heading), each window's bars fitted as straight lines (their bow included) with ``--noise`` mm
  of normal noise across: many more pairs than renders allow, without rendering.

A placing is wrong when it puts a point of the mesh more than 5 mm from where the other capture
sees it. Prints the pairs, those placed, those wrong and the largest error of the right ones.

    python benchmarks/bench_placing.py --cache /tmp/verdicts
    python benchmarks/bench_placing.py --windows 100 --seed 3
    python benchmarks/bench_placing.py --windows 60 --seed 4 --noise 1.0
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from bench_verdicts import _slab_plan
from rebarlib import load_design
from rebarlib._across import register
from rebarlib.geometry.plane import Plane, plane_frame, to_slab_frame

WRONG_MM = 5.0


def _gate(design) -> float:
    return 0.25 * min(design.lattice(la).level(lv).spacing_mm for la in ("lower", "upper") for lv in ("bottom", "top"))


def _cache_pairs(cache: Path):
    """(slab, a, b, result a, result b, true error function, gate) for every pair of captures."""
    for sd in sorted(cache.glob("slab_*")):
        meta = json.loads((sd / "slab.json").read_text())
        design = load_design(sd / "design.toml")
        names = list(meta["captures"]) + sorted(p.name[7:-5] for p in sd.glob("result_F*.json"))
        res = {
            n: json.loads((sd / f"result_{n}.json").read_text()) for n in names if (sd / f"result_{n}.json").exists()
        }
        cams = {n: json.loads((sd / n / "truth.json").read_text())["camera"] for n in res}
        ns = list(res)
        for i in range(len(ns)):
            for j in range(i + 1, len(ns)):
                yield (
                    sd.name,
                    res[ns[i]],
                    res[ns[j]],
                    _pose_error(res[ns[i]], res[ns[j]], cams[ns[i]], cams[ns[j]]),
                    _gate(design),
                )


def _pose_error(ra, rb, ca, cb):
    """The largest distance (mm) between where a placing puts three plan points of capture a in
    capture b's frame and where they truly are (through the renders' camera poses)."""

    def plane(r):
        return Plane(np.array(r["formwork"]["normal"]), r["formwork"]["offset_mm"])

    pa, pb = plane(ra), plane(rb)
    Ra = plane_frame(pa)

    def err(reg):
        e = 0.0
        for x, y in ((-200, -200), (0, 0), (200, 100)):
            q = np.array([x, y, 0.0])
            cam = Ra.T @ (q - np.array([0, 0, pa.offset_mm]))
            w = np.array(ca["rotation_world_to_camera"]).T @ cam + np.array(ca["centre_world_mm"])
            c = np.array(cb["rotation_world_to_camera"]) @ (w - np.array(cb["centre_world_mm"]))
            e = max(e, float(np.linalg.norm(reg.to_b(q[:2]) - to_slab_frame(c[None], pb)[0][:2])))
        return e

    return err


def _window(scene, c, yaw, size, rng, name, noise):
    """A result dict of the bars a window sees: each bar's seen stretch fitted as a straight line,
    its offset moved by ``noise`` (mm, normal); 5 % of the bars not found. The window's frame is
    its plan frame (formwork normal -z at 500 mm)."""
    R = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    half = np.array(size) / 2
    bars = []
    for b in scene.bars:
        P = np.asarray(b.axis)
        t = np.linspace(0, 1, 200)
        seg = np.array([np.interp(t * (len(P) - 1), np.arange(len(P)), P[:, i]) for i in range(2)]).T
        q = (seg - c) @ R
        inside = np.all(np.abs(q) <= half, axis=1)
        if inside.sum() < 10 or rng.random() < 0.05:
            continue
        pts = q[inside]
        m = pts.mean(0)
        d = np.linalg.svd(pts - m)[2][0]
        s = (pts - m) @ d
        off = rng.normal(0, noise) * np.array([-d[1], d[0]])
        a, e = m + s.min() * d + off, m + s.max() * d + off
        if np.linalg.norm(e - a) < 100:
            continue
        rec = {"bar_id": len(bars), "layer": b.layer, "level": b.level}
        for key, p in (("start", a), ("end", e)):  # slab frame (x, y) = camera (x, -y) here
            rec.update({f"{key}_x_mm": p[0], f"{key}_y_mm": -p[1], f"{key}_z_mm": 470.0})
        bars.append(rec)
    res = {"capture": name, "formwork": {"normal": [0, 0, -1.0], "offset_mm": 500.0}, "bars": bars, "positions": []}
    return res, R


def _window_pairs(n: int, seed: int, noise: float):
    rng = np.random.default_rng(seed)
    for k in range(n):
        kk = 1000 * (seed + 1) + k
        design, scene, *_ = _slab_plan(kk, Path("/tmp") / "rebarlib_placing" / f"s{kk}")
        wins = []
        for j in range(6):
            c = rng.uniform(-500, 500, 2) if j % 2 == 0 else wins[-1][2] + rng.uniform(-160, 160, 2)
            yaw = rng.uniform(0, 2 * math.pi)
            size = (rng.uniform(500, 800), rng.uniform(350, 550))
            r, R = _window(scene, c, yaw, size, rng, f"w{j}", noise)
            wins.append((r, R, c))
        for i in range(len(wins)):
            for j in range(i + 1, len(wins)):
                (ra, Ra, ca), (rb, Rb, cb) = wins[i], wins[j]

                def err(reg, Ra=Ra, ca=ca, Rb=Rb, cb=cb):
                    pts = np.array([[0.0, 0.0], [200.0, 100.0], [-200.0, -100.0]])
                    truth = ((pts @ Ra.T + ca) - cb) @ Rb
                    return float(np.max(np.linalg.norm(reg.to_b(pts) - truth, axis=1)))

                yield f"scene {kk}", ra, rb, err, _gate(design)


def run(pairs) -> dict:
    out = {"pairs": 0, "placed": 0, "wrong": 0, "worst_right_mm": 0.0}
    for name, ra, rb, err, gate in pairs:
        out["pairs"] += 1
        reg, _ = register(ra, rb, gate)
        if reg is None:
            continue
        out["placed"] += 1
        e = err(reg)
        if e > WRONG_MM:
            out["wrong"] += 1
            print(f"  wrong: {name} {ra['capture']} / {rb['capture']}: {e:.0f} mm off", flush=True)
        else:
            out["worst_right_mm"] = max(out["worst_right_mm"], e)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", help="a verdict-benchmark cache (bench_verdicts.py --cache)")
    ap.add_argument("--windows", type=int, default=0, help="scenes to cut window pairs from")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--noise", type=float, default=0.3, help="noise across the windows' bars (mm)")
    args = ap.parse_args(argv)
    if not args.cache and not args.windows:
        ap.error("give --cache DIR and/or --windows N")
    print("| source | pairs | placed | wrong | worst error of the right ones (mm) |\n|---|---:|---:|---:|---:|")
    rows = []
    if args.cache:
        rows.append((f"renders in {args.cache}", run(_cache_pairs(Path(args.cache)))))
    if args.windows:
        rows.append(
            (
                f"{args.windows} scenes' windows, seed {args.seed}, noise {args.noise} mm",
                run(_window_pairs(args.windows, args.seed, args.noise)),
            )
        )
    for src, r in rows:
        print(f"| {src} | {r['pairs']} | {r['placed']} | {r['wrong']} | {r['worst_right_mm']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
