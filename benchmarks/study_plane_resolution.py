"""How far is a formwork plane seen face-on off, from the depth's resolution alone? No scene: a
bare plane's depths through the synthetic sensor's chain, fitted as ``inspect`` fits the formwork
(docs/decisions/037).

    python benchmarks/study_plane_resolution.py              # 40 planes per camera and noise
    python benchmarks/study_plane_resolution.py --planes 10  # quicker

Each plane is face-on at a depth D, either drawn uniformly in 400-650 mm (where a camera meets a
formwork anywhere) or the coverage benchmark's 400, 500 and 600 mm in turn; 120 000 pixels drawn
over the image of the D435 at 848 x 480 or the Gemini 2 (``benchmarks/_cameras.py``). Their
depths go through what ``rebarlib.synth``'s sensor does to a depth (``SensorModel``): disparity
noise (0.08 px, or 2.5 times that), rounding to 1/8 px, a stereo error k z² and a depth scale
error drawn within the Gemini 2 profile's limits, and the stored 1 mm grid. Printed per camera
and noise, the error of the plane's depth against where the drawn errors alone put it
((1 + s)(D + k D² / 10⁶)): mean, SD and RMS, for

- ``mean``: the plain mean of every stored depth (the least any fit of the plane can do);
- ``mean, no grid``: the same without the 1 mm grid;
- ``fit``: ``fit_formwork`` as ``inspect`` calls it (threshold 6 mm); its refit keeps one level
  alone where more than half of the depths lie on it (the robust SD is then 0);
- three floors of the refit's robust SD that decision 037 measured and did not adopt:
  ``floor rounded normal`` (:func:`rounded_normal_floor`, the one also tried in the pipeline),
  ``floor gap/√12`` and ``floor gap/2`` (the depth's level gap, :func:`level_gap`, over √12 or 2).

The plane resolution term of the budget (``rebarlib.uncertainty.plane_resolution``) is 1 mm / √12
= 0.289 mm for all of these planes.
"""

from __future__ import annotations

import argparse
import math
from statistics import NormalDist

import numpy as np
import pandas as pd

from _cameras import CAMERAS
from rebarlib.devices import load_device
from rebarlib.geometry.plane import _lsq_plane, fit_formwork, paper_fit_formwork

THRESHOLD_MM = 6.0
PIXELS = 120_000


def level_gap(z) -> float:
    """The depth's level gap near a plane: per stored depth value, the larger gap to the next
    occupied value on either side; the median over the points."""
    v, c = np.unique(np.asarray(z, float), return_counts=True)
    if len(v) < 2:
        return 0.0
    g = np.diff(v)
    big = np.maximum(np.r_[g[0], g], np.r_[g, g[-1]])
    o = np.argsort(big)
    cw = np.cumsum(c[o])
    return float(big[o][np.searchsorted(cw, cw[-1] / 2)])


def rounded_normal_floor(depths) -> float:
    """Where more than half of the depths lie on one level (the median absolute deviation is then
    0), the SD of a normal error with that share p within the level's rounding cell (width w:
    half-way to the next occupied level on either side), ``w / (2 z)``, z the standard normal
    quantile of (1 + p) / 2, and at least the rounding's own ``w / sqrt(12)``; else 0."""
    v, c = np.unique(np.asarray(depths, float), return_counts=True)
    if len(v) < 2:
        return 0.0
    m = int(np.argmax(c))
    p = float(c[m]) / float(c.sum())
    if p < 0.5:
        return 0.0
    gaps = ([v[m] - v[m - 1]] if m > 0 else []) + ([v[m + 1] - v[m]] if m + 1 < len(v) else [])
    w = float(np.mean(gaps))
    z = NormalDist().inv_cdf((1.0 + min(p, 1.0 - 1e-9)) / 2.0)
    return max(w / (2.0 * z), w / math.sqrt(12.0))


def fit_with_floor(pts, floor_of, rng=0) -> float:
    """``fit_formwork``'s steps with the refit band's robust SD at least ``floor_of(depths)`` of
    the depths within the threshold; the plane's depth on the optical axis."""
    rng = np.random.default_rng(rng)
    sub = pts if len(pts) <= 30_000 else pts[rng.choice(len(pts), 30_000, replace=False)]
    plane, _ = paper_fit_formwork(sub, threshold_mm=THRESHOLD_MM, rng=rng)
    n, d = plane.normal, plane.offset_mm
    inl = np.abs(pts @ n + d) < THRESHOLD_MM
    floor = floor_of(pts[inl, 2])
    for _ in range(3):
        n, d = _lsq_plane(pts[inl])
        h = pts @ n + d
        sigma = max(1.4826 * float(np.median(np.abs(h[inl]))), floor)
        inl = np.abs(h) < max(4 * sigma, 0.5)
    return d / abs(n[2])


def one_plane(camera: str, sigma_px: float, depth: float, k: float, s: float, rng) -> dict:
    K = CAMERAS[camera]
    u, v = rng.uniform(0, K.width, PIXELS), rng.uniform(0, K.height, PIXELS)
    fb = K.fx * 50.0
    disp = np.round((fb / depth + sigma_px * rng.normal(size=PIXELS)) * 8) / 8
    z = fb / disp
    z = (1 + s) * (z + k * (z / 1000) ** 2)
    stored = np.round(z)
    pts = np.c_[(u - K.cx) / K.fx * stored, (v - K.cy) / K.fy * stored, stored]
    ideal = (1 + s) * (depth + k * (depth / 1000) ** 2)
    plane, _ = fit_formwork(pts, threshold_mm=THRESHOLD_MM, rng=0)
    return {
        "camera": camera,
        "noise px": sigma_px,
        "mean": stored.mean() - ideal,
        "mean, no grid": z.mean() - ideal,
        "fit": plane.offset_mm / abs(plane.normal[2]) - ideal,
        "floor rounded normal": fit_with_floor(pts, rounded_normal_floor) - ideal,
        "floor gap/√12": fit_with_floor(pts, lambda z: level_gap(z) / math.sqrt(12)) - ideal,
        "floor gap/2": fit_with_floor(pts, lambda z: level_gap(z) / 2) - ideal,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--planes", type=int, default=40, help="planes per camera and noise (default 40)")
    ap.add_argument("--seed", type=int, default=11)
    args = ap.parse_args()
    lim = load_device("gemini2").depth_limits()
    pd.set_option("display.width", 200)
    cols = ["mean", "mean, no grid", "fit", "floor rounded normal", "floor gap/√12", "floor gap/2"]
    for mode in ("uniform 400-650 mm", "the benchmark's 400, 500, 600 mm"):
        rng = np.random.default_rng(args.seed)
        rows = []
        for camera in ("d435-848", "gemini2"):
            for sigma_px in (0.08, 0.2):
                for i in range(args.planes):
                    depth = rng.uniform(400, 650) if mode.startswith("uniform") else (400.0, 500.0, 600.0)[i % 3]
                    k = rng.uniform(-1, 1) * lim["quad_mm_per_m2"]
                    s = rng.uniform(-1, 1) * lim["scale"]
                    rows.append(one_plane(camera, sigma_px, depth, k, s, rng))
        t = pd.DataFrame(rows).groupby(["camera", "noise px"])[cols]
        print(f"\nFace-on planes at {mode}, {args.planes} per camera and noise: the plane's depth error (mm)")
        for what, f in (("mean", "mean"), ("SD", "std"), ("RMS", lambda x: float(np.sqrt(np.mean(x**2))))):
            print(f"{what}:")
            print(t.agg(f).round(3).to_string())


if __name__ == "__main__":
    main()
