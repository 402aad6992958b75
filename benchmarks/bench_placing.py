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

``--gain`` (with ``--cache``) says what any placing could gain on the captures the verdict
benchmark takes (not its follow-ups): per pair, the true overlap of the two views (the share of
each capture's formwork that the other's image shows, from the renders' poses) and whether it was
placed; per clean slab the benchmark leaves incomplete, each position and bar size left unjudged,
the other captures that truly show it over the length a verdict needs and whether they were
placed; and the slab's verdict were every pair placed by its true pose (an oracle placing, the
bound of what placing can gain).

``--features`` (with ``--cache``) measures whether image features could place two captures
(docs/decisions/035): per pair of the captures taken whose views overlap (a share of 0.3 or more
of each one's formwork in the other's image), SIFT keypoints of each colour image with valid
depth (a 3 x 3 window within 3 mm) lifted to 3-D, matched both ways under Lowe's ratio test
(0.8); how many of the matches are true (their points within 10 mm of each other under the true
pose), and the largest set a 3-D RANSAC (Kabsch on three matches, 10 mm) finds with its error.

    python benchmarks/bench_placing.py --cache /tmp/verdicts
    python benchmarks/bench_placing.py --cache /tmp/verdicts --gain
    python benchmarks/bench_placing.py --cache /tmp/verdicts --features
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

try:
    from bench_verdicts import _slab_plan
except ModuleNotFoundError:  # imported as the package ``benchmarks`` (the tests)
    from benchmarks.bench_verdicts import _slab_plan
from rebarlib import load_design
from rebarlib._camera import backproject, project
from rebarlib._capture import read_intrinsics
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


def _true_reg(ra, rb, ca, cb, name_a, name_b):
    """The true placing of capture a's plan frame in capture b's (``rebarlib._across.Registration``),
    fitted (Kabsch, 2-D) to a grid of plan points of a carried through the renders' camera poses."""
    from rebarlib._across import Registration

    def plane(r):
        return Plane(np.array(r["formwork"]["normal"]), r["formwork"]["offset_mm"])

    pa, pb = plane(ra), plane(rb)
    Ra = plane_frame(pa)
    q = np.array([[x, y, 0.0] for x in (-400, 0, 400) for y in (-400, 0, 400)])
    cam = (q - np.array([0, 0, pa.offset_mm])) @ Ra  # Ra^T (q - offset)
    w = cam @ np.array(ca["rotation_world_to_camera"]) + np.array(ca["centre_world_mm"])
    c = (w - np.array(cb["centre_world_mm"])) @ np.array(cb["rotation_world_to_camera"]).T
    x, y = q[:, :2], to_slab_frame(c, pb)[:, :2]
    mx, my = x.mean(0), y.mean(0)
    u, _, vt = np.linalg.svd((x - mx).T @ (y - my))
    R = (u @ vt).T
    if np.linalg.det(R) < 0:
        vt[-1] *= -1
        R = (u @ vt).T
    return Registration(name_a, name_b, R, my - mx @ R.T, 0, 0.0, math.inf)


def _world_to_image(w, cam, K):
    """Pixel coordinates (N, 2) of world points and whether each lies in the image (in front);
    ``K`` the capture's :class:`~rebarlib.Intrinsics`."""
    c = (w - np.array(cam["centre_world_mm"])) @ np.array(cam["rotation_world_to_camera"]).T
    uv = project(np.column_stack((c[:, :2], np.maximum(c[:, 2], 1e-6))), K)
    ok = (c[:, 2] > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < K.width) & (uv[:, 1] >= 0) & (uv[:, 1] < K.height)
    return uv, ok


def _intrinsics(folder: Path):
    return read_intrinsics(folder / "camera.json")[0]


def _formwork_share(fa: Path, fb: Path, ca, cb) -> float:
    """The share of capture a's view of the formwork (world z = 0, a 20 px grid) that capture b's
    image shows too."""
    Ka, Kb = _intrinsics(fa), _intrinsics(fb)
    u, v = np.meshgrid(np.arange(10, Ka.width, 20), np.arange(10, Ka.height, 20))
    rays = backproject(np.column_stack((u.ravel(), v.ravel())), np.ones(u.size), Ka)
    d = rays @ np.array(ca["rotation_world_to_camera"])  # camera to world: R^T r
    C = np.array(ca["centre_world_mm"])
    down = d[:, 2] < -1e-6
    w = C + (-C[2] / d[down, 2])[:, None] * d[down]
    _, ok = _world_to_image(w, cb, Kb)
    return float(ok.mean()) if len(ok) else 0.0


def _seen_length(ends_cam, ca, fb: Path, cb) -> float:
    """How much (mm) of the line between two camera-a points capture b's image shows."""
    Kb = _intrinsics(fb)
    w = ends_cam @ np.array(ca["rotation_world_to_camera"]) + np.array(ca["centre_world_mm"])
    pts = w[0] + np.linspace(0, 1, 61)[:, None] * (w[1] - w[0])
    _, ok = _world_to_image(pts, cb, Kb)
    return float(ok.mean() * np.linalg.norm(w[1] - w[0]))


def gain(cache: Path) -> None:
    """What any placing could gain on the captures the verdict benchmark takes (``--gain``)."""
    import rebarlib._across as A
    from rebarlib import evaluate
    from rebarlib._across import _ends, _judge_in, _same_bar, plan_sets
    from rebarlib._status import MEASURED, NOT_MEASURED

    print("\n## Pairs of the captures taken: true overlap and placing\n")
    print("| slab | truth | verdict | a / b | formwork of a in b | of b in a | placed (why not) |")
    print("|---|---|---|---|---:|---:|---|")
    rows = []
    for sd in sorted(cache.glob("slab_*")):
        meta = json.loads((sd / "slab.json").read_text())
        vfile = sd / "verdict.json"
        verdict = json.loads(vfile.read_text())["verdict"] if vfile.exists() else "?"
        design = load_design(sd / "design.toml")
        names = [n for n in meta["captures"] if (sd / f"result_{n}.json").exists()]
        res = [json.loads((sd / f"result_{n}.json").read_text()) for n in names]
        cams = [json.loads((sd / n / "truth.json").read_text())["camera"] for n in names]
        gate = _gate(design)
        truth = {}
        placed = {}
        for i in range(len(names)):
            for j in range(len(names)):
                if i != j:
                    truth[(names[i], names[j])] = _true_reg(res[i], res[j], cams[i], cams[j], names[i], names[j])
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                reg, why = register(res[i], res[j], gate)
                placed[(i, j)] = placed[(j, i)] = reg is not None
                share_ab = _formwork_share(sd / names[i], sd / names[j], cams[i], cams[j])
                share_ba = _formwork_share(sd / names[j], sd / names[i], cams[j], cams[i])
                print(
                    f"| {meta['slab']:03d} | {meta['defect'] or 'clean'} | {verdict} | {names[i]} / {names[j]} | "
                    f"{share_ab:.2f} | {share_ba:.2f} | {'yes' if reg is not None else 'no (' + why + ')'} |"
                )
        # the slab judged with every pair placed by its true pose
        real = A._register
        A._register = lambda sa, sb, g, na, nb, truth=truth: (truth[(na, nb)], "")
        try:
            oracle = evaluate(res, design)
        finally:
            A._register = real
        acc = evaluate(res, design)
        rows.append((meta, verdict, acc, oracle, res, names, cams, truth, placed, gate, sd))
    print("\n## Clean slabs left incomplete: what another capture of the slab shows\n")
    gained = 0
    for meta, verdict, acc, oracle, res, names, cams, truth, placed, gate, sd in rows:
        if meta["defect"] is not None or acc.verdict != "incomplete":
            continue
        print(f"- slab {meta['slab']:03d}: {acc.verdict}; all pairs placed by their true pose: {oracle.verdict}")
        gained += oracle.verdict == "accepted"
        sets = [plan_sets(r) for r in res]
        for i, r in enumerate(acc.results):
            for p in r.get("positions") or []:
                if p.get("status") != NOT_MEASURED or _ends(p) is None:
                    continue
                shows = []
                for j in range(len(names)):
                    if j == i:
                        continue
                    seen = _seen_length(_ends(p), cams[i], sd / names[j], cams[j])
                    plane = A._plane(r)
                    line = truth[(names[i], names[j])].to_b(A._position_line(p, plane))
                    key = (p.get("layer"), p.get("level"))
                    v = _judge_in(p, line, sets[j].get(key), res[j], gate, A.CountParams.min_evidence_mm)
                    shows.append(
                        f"{names[j]} shows {seen:.0f} mm, would judge it "
                        f"{v[0] if v else 'not'}, placed {'yes' if placed[(i, j)] else 'no'}"
                    )
                print(
                    f"  - {names[i]} position {p['layer']} {p['level']} at {float(p.get('offset_mm') or 0):.0f} mm "
                    f"({str(p.get('reason'))[:40]}…): " + ("; ".join(shows) or "no other capture")
                )
        cp = acc.checkpoints
        for _, row in cp[(cp["item"].str.startswith("bar_size")) & (cp["status"] == NOT_MEASURED)].iterrows():
            i = names.index(row["capture"])
            bars = {b["bar_id"]: b for b in res[i]["bars"]}
            b = bars.get(int(str(row["what"]).split()[-1]))
            key = (row["layer"], row["level"])
            st = sets[i].get(key)
            if b is None or st is None or b["bar_id"] not in st.bar_ids:
                continue
            seg = st.segs[st.bar_ids.index(b["bar_id"])]
            shows = []
            for j in range(len(names)):
                if j == i:
                    continue
                seen = _seen_length(_ends(b), cams[i], sd / names[j], cams[j])
                seg_b = truth[(names[i], names[j])].to_b(seg)
                other = None if key not in sets[j] else _same_bar(seg_b, sets[j][key], gate)
                ob = {x["bar_id"]: x for x in res[j]["bars"]}.get(other)
                sized = ob is not None and ob.get("diameter_status") == MEASURED
                shows.append(
                    f"{names[j]} shows {seen:.0f} mm, "
                    + (f"sized it Φ{ob['nominal_mm']:g}" if sized else "did not size it")
                    + f", placed {'yes' if placed[(i, j)] else 'no'}"
                )
            print(
                f"  - {names[i]} bar {b['bar_id']} ({key[0]} {key[1]}) size not measured "
                f"({str(row['reason'])[:40]}…): " + ("; ".join(shows) or "no other capture")
            )
    print(f"\nClean slabs incomplete that every pair placed by its true pose would accept: {gained}")
    moved = [(m["slab"], a.verdict, o.verdict) for m, _, a, o, *_ in rows if m["defect"] and a.verdict != o.verdict]
    print(f"Defective slabs whose verdict the true placing changes: {moved or 'none'}")


def _keypoints(folder: Path):
    """SIFT keypoints of a capture's colour image with valid depth: their camera-frame points (mm)
    and descriptors."""
    import cv2

    K = _intrinsics(folder)
    scale = float(json.loads((folder / "camera.json").read_text()).get("depth_scale_mm", 1.0))
    grey = cv2.cvtColor(cv2.imread(str(folder / "color.png"), cv2.IMREAD_COLOR), cv2.COLOR_BGR2GRAY)
    depth = cv2.imread(str(folder / "depth.png"), cv2.IMREAD_UNCHANGED).astype(float) * scale
    kp, des = cv2.SIFT_create(nfeatures=8000, contrastThreshold=0.01).detectAndCompute(grey, None)
    H, W = depth.shape
    pts, keep = [], []
    for i, k in enumerate(kp):
        x, y = int(round(k.pt[0])), int(round(k.pt[1]))
        if not (1 <= x < W - 1 and 1 <= y < H - 1):
            continue
        w = depth[y - 1 : y + 2, x - 1 : x + 2]
        w = w[w > 0]
        if len(w) < 7 or w.max() - w.min() > 3.0:  # no depth, or a depth edge
            continue
        z = float(np.median(w))
        pts.append(backproject([k.pt], [z], K)[0])
        keep.append(i)
    return np.array(pts).reshape(-1, 3), (des[keep] if des is not None else np.zeros((0, 128), np.float32))


def _mutual_matches(da, db, ratio: float = 0.8) -> np.ndarray:
    import cv2

    if len(da) < 2 or len(db) < 2:
        return np.zeros((0, 2), int)
    bf = cv2.BFMatcher(cv2.NORM_L2)
    back = {m[0].queryIdx: m[0].trainIdx for m in bf.knnMatch(db, da, k=2) if m[0].distance < ratio * m[1].distance}
    out = [
        (m[0].queryIdx, m[0].trainIdx)
        for m in bf.knnMatch(da, db, k=2)
        if m[0].distance < ratio * m[1].distance and back.get(m[0].trainIdx) == m[0].queryIdx
    ]
    return np.array(out, int).reshape(-1, 2)


def _kabsch3(P, Q):
    mp, mq = P.mean(0), Q.mean(0)
    u, _, vt = np.linalg.svd((P - mp).T @ (Q - mq))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))])
    R = vt.T @ D @ u.T
    return R, mq - R @ mp


def _ransac3(P, Q, thr: float, rng, iters: int = 3000):
    """The largest set of matches one rigid motion carries within ``thr`` mm: (R, t, inliers) or None."""
    best = None
    if len(P) < 3:
        return None
    for _ in range(iters):
        idx = rng.choice(len(P), 3, replace=False)
        R, t = _kabsch3(P[idx], Q[idx])
        inl = np.linalg.norm(P @ R.T + t - Q, axis=1) < thr
        if best is None or inl.sum() > best.sum():
            best = inl
    R, t = _kabsch3(P[best], Q[best])
    return R, t, best


def features(cache: Path) -> None:
    """Can image features place two captures of a slab (``--features``)?"""
    rng = np.random.default_rng(0)
    print("| slab | formwork | a / b | rust a / b | overlap | matches | true | RANSAC set | its error (mm) |")
    print("|---|---|---|---|---:|---:|---:|---:|---:|")
    tot = {"pairs": 0, "matches": 0, "true": 0, "placed_right": 0}
    for sd in sorted(cache.glob("slab_*")):
        names = json.loads((sd / "slab.json").read_text())["captures"]
        truth = {n: json.loads((sd / n / "truth.json").read_text()) for n in names}
        kps = {}
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                a, b = names[i], names[j]
                ca, cb = truth[a]["camera"], truth[b]["camera"]
                share = min(_formwork_share(sd / a, sd / b, ca, cb), _formwork_share(sd / b, sd / a, cb, ca))
                if share < 0.3:
                    continue
                for n in (a, b):
                    if n not in kps:
                        kps[n] = _keypoints(sd / n)
                (Pa, Da), (Pb, Db) = kps[a], kps[b]
                m = _mutual_matches(Da, Db)
                Ra, Rb = np.array(ca["rotation_world_to_camera"]), np.array(cb["rotation_world_to_camera"])
                Rt, tt = Rb @ Ra.T, Rb @ (np.array(ca["centre_world_mm"]) - np.array(cb["centre_world_mm"]))
                A, B = Pa[m[:, 0]], Pb[m[:, 1]]
                true = int(np.sum(np.linalg.norm(A @ Rt.T + tt - B, axis=1) < 10.0))
                fit = _ransac3(A, B, 10.0, rng)
                n_set, err = 0, float("nan")
                if fit is not None:
                    R, t, inl = fit
                    n_set = int(inl.sum())
                    err = float(np.max(np.linalg.norm(A[inl] @ R.T + t - (A[inl] @ Rt.T + tt), axis=1)))
                app = truth[a]["appearance"], truth[b]["appearance"]
                print(
                    f"| {sd.name[-3:]} | {app[0]['formwork']} | {a} / {b} | {app[0]['rust_fraction']:g} / "
                    f"{app[1]['rust_fraction']:g} | {share:.2f} | {len(m)} | {true} | {n_set} | {err:.0f} |",
                    flush=True,
                )
                tot["pairs"] += 1
                tot["matches"] += len(m)
                tot["true"] += true
                tot["placed_right"] += n_set >= 3 and err <= WRONG_MM
    print(
        f"\n{tot['pairs']} pairs, {tot['matches']} matches, {tot['true']} of them true; "
        f"RANSAC sets within {WRONG_MM:g} mm of the true pose: {tot['placed_right']}"
    )


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
    ap.add_argument(
        "--gain", action="store_true", help="with --cache: what any placing could gain (true overlaps, per slab)"
    )
    ap.add_argument(
        "--features", action="store_true", help="with --cache: can SIFT features place two captures (true matches)"
    )
    args = ap.parse_args(argv)
    if not args.cache and not args.windows:
        ap.error("give --cache DIR and/or --windows N")
    if args.gain or args.features:
        if not args.cache:
            ap.error("--gain and --features need --cache DIR")
        if args.gain:
            gain(Path(args.cache))
        if args.features:
            features(Path(args.cache))
        return 0
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
