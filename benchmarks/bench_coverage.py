"""Does the stated uncertainty cover the error? Coverage of the uncertainty budget on synthetic
captures whose camera has systematic errors drawn from its device profile.

    python benchmarks/bench_coverage.py --quick      # 8 captures
    python benchmarks/bench_coverage.py              # 36 captures
    python benchmarks/bench_coverage.py --diameters  # also the bars' widths (slower)
    python benchmarks/bench_coverage.py --seed 7     # other scenes and error draws
    python benchmarks/bench_coverage.py --derive     # also the fits' random term's two constants

Set-up: the paper's slab (lower Φ14, upper Φ12 @ 200, layer distance 85, cover 15 or 25; 20 in
the quick run) seen from 400-600 mm (quick: 450, 600) with tilts 0-15°, rendered with three
cameras: the reference Gemini-2-like unit (its ``camera.json`` says "rebarlib synthetic
(Gemini-2-like)", which picks the Gemini 2 profile), the same with 2.5 times the stereo
noise, and a RealSense D435 at 848 x 480 (device "Intel RealSense D435", its own profile).
For every capture the camera's systematic errors are drawn anew from the profile's limits,
uniformly, as the budget assumes: a stereo error ``k z²`` (``SensorModel.bias_mm_per_m2``), a
depth scale (``depth_scale_error``) and a focal-length error (``focal_error``). The principal
point and the colour-depth registration are exact in these renders, so their terms are not
exercised here.

Per quantity (cover, layer distance, top of the upper bars, every matched spacing, with
``--diameters`` every bar's width against its rib envelope) it prints the error's mean and
RMS, the median stated u, and the share of errors within 1 u and within 2 u (k = 2). Target
(issue 59): within 2 u for at least 95 % and at most 99.9 % of the measurements of each
quantity. A quantity whose truth the capture does not show (no bar of that level measured) is
left out.

``--derive`` estimates the two constants of the heights' random term (``rebarlib.uncertainty``,
docs/decisions/022): the bars' scatter about their level's common error as a share of their
fits' residual RMS (``BAR_FIT_SHARE_OF_RMS``), from every level's bars' errors against their own
truth; and the part common to a level (``LEVEL_FIT_COMMON_MM``), from the mean heights' errors
once the drawn systematic errors (times the budget's own sensitivities) and that scatter are
taken out. Derive them on training seeds (59, 7), never on the held-out one (2026).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace

import numpy as np
import pandas as pd

from _cameras import CAMERAS
from bench_geometry import match_bars, paper_design
from rebarlib._inspect import inspect
from rebarlib.devices import device_for
from rebarlib.synth import Deviations, SensorModel, synth_capture
from rebarlib.uncertainty import BAR_FIT_SHARE_OF_RMS, _level_fits_u

#: per mean height: the bar levels it is read from, and the budget's key
HEIGHT_LEVELS = {
    "cover": ("cover", (("lower", "bottom"),)),
    "layer distance": ("layer_distance", (("lower", "bottom"), ("upper", "bottom"))),
    "upper top": ("upper_top", (("upper", "top"),)),
}
#: the systematic inputs the renders draw, by the budget's term name
DRAWN = {
    "depth_scale_error": "depth scale",
    "bias_mm_per_m2": "depth non-linearity (stereo k z²)",
    "focal_error": "focal length",
}

SETS = {  # name: (camera, sensor, device string written with the capture)
    "gemini2": ("gemini2", SensorModel(), "rebarlib synthetic (Gemini-2-like)"),
    "gemini2-noisy": ("gemini2", SensorModel(disparity_sigma_px=0.2), "rebarlib synthetic (Gemini-2-like)"),
    "d435-848": ("d435-848", SensorModel(), "Intel RealSense D435"),
}


def draw_errors(device: str, rng) -> dict:
    """Systematic errors of one camera, drawn uniformly within its profile's limits."""
    prof, _ = device_for(device)
    lim = prof.depth_limits()
    return {
        "bias_mm_per_m2": float(rng.uniform(-1, 1) * lim["quad_mm_per_m2"]),
        "depth_scale_error": float(rng.uniform(-1, 1) * lim["scale"]),
        "depth_offset_mm": float(rng.uniform(-1, 1) * lim["offset_mm"]),
        "focal_error": float(rng.uniform(-1, 1) * prof.focal_percent / 100),
    }


def cases(quick: bool, seed: int = 59):
    rng = np.random.default_rng(seed)
    heights = (450, 600) if quick else (400, 500, 600)
    # (cover, tilts): the full run sees cover 15 at tilts 0 and 10, cover 25 at 5 and 15
    grid = ((20, (5, 15)),) if quick else ((15, (0, 10)), (25, (5, 15)))
    out = []
    for name in ("gemini2", "d435-848") if quick else SETS:
        for cover, tilts in grid:
            for h in heights:
                for tilt in tilts:
                    out.append(
                        (
                            name,
                            cover,
                            h,
                            tilt,
                            float(rng.uniform(0, 180)),
                            float(rng.uniform(0, 360)),
                            int(rng.integers(1e6)),
                            draw_errors(SETS[name][2], rng),
                        )
                    )
    return out


def rows_of(res, cap, case, diameters: bool) -> list:
    name, cover, h, tilt, *_, errs = case
    tr = cap.truth
    base = {"set": name, "height": h, "tilt": tilt, **errs}
    out = []
    for q, key in (("cover", "cover_mm"), ("layer distance", "layer_distance_mm"), ("upper top", "upper_top_mm")):
        m = getattr(res, {"cover": "cover", "layer distance": "layer_distance", "upper top": "upper_top"}[q])
        if m.ok and tr.get(key) is not None and m.uncertainty_mm:
            out.append({**base, "quantity": q, "error": m.value_mm - tr[key], "u": m.uncertainty_mm})
    visible = {b["id"] for b in tr["bars"] if b["visible"]}
    mapping, _, tb = match_bars(res, tr, visible)
    tsp = {(s["bar_a"], s["bar_b"]): s["spacing_mm"] for s in tr["spacings"]}
    tsp.update({(b, a): v for (a, b), v in list(tsp.items())})
    for s in res.spacings.itertuples():
        ta, tb_ = mapping.get(s.bar_a), mapping.get(s.bar_b)
        if ta is None or tb_ is None or (ta, tb_) not in tsp or not np.isfinite(s.spacing_mm):
            continue
        out.append({**base, "quantity": "spacing", "error": s.spacing_mm - abs(tsp[(ta, tb_)]), "u": s.uncertainty_mm})
    if diameters and "width_uncertainty_mm" in res.bars:
        wcol = "width_used_mm" if "width_used_mm" in res.bars else "width_mm"
        for r in res.bars.itertuples():
            t = mapping.get(r.bar_id)
            w, u = getattr(r, wcol), r.width_uncertainty_mm
            if t is None or not np.isfinite(w) or not np.isfinite(u):
                continue
            out.append({**base, "quantity": "width", "error": w - tb[t]["envelope_mm"], "u": u})
    return out


def bar_errors(res, tb: dict, mapping: dict) -> list:
    """Each measured bar's fitted height (its underside; for the upper lattice's top level, its
    top: the axis plus the radius, as the stage reads it) against its true bar's, with its
    fit's residual RMS."""
    out = []
    for r in res.bars.itertuples():
        t = mapping.get(r.bar_id)
        if t is None or r.status != "measured" or not np.isfinite(r.underside_mm) or not np.isfinite(r.fit_rms_mm):
            continue
        top = (r.layer, r.level) == ("upper", "top")
        seen = r.underside_mm + 2 * r.radius_mm if top else r.underside_mm
        true = tb[t]["top_mm"] if top else tb[t]["underside_mm"]
        out.append({"layer": r.layer, "level": r.level, "error": seen - true, "fit_rms": r.fit_rms_mm})
    return out


def height_residuals(res, errs: dict, errors: dict) -> list:
    """Per mean height measured: its error less what the drawn systematic errors make of it by
    the budget's own sensitivities, and the bars' scatter part of the fits' term
    (``errors``: quantity -> error)."""
    out = []
    budget = res.extras.get("uncertainty", {}).get("measurements", {})
    for q, (key, _) in HEIGHT_LEVELS.items():
        if q not in errors or key not in budget:
            continue
        sens = {t["term"]: t["sensitivity"] for t in budget[key]["terms"]}
        drawn = sum(errs[k] * sens[name] for k, name in DRAWN.items())
        u_bars = _level_fits_u(res.bars, key)
        if u_bars is not None:
            out.append({"quantity": q, "residual": errors[q] - drawn, "u_bars": u_bars})
    return out


def derive(bars: pd.DataFrame, heights: pd.DataFrame) -> dict:
    """The two constants of the heights' random term from bar errors (``bars``: capture, layer,
    level, error, fit_rms) and mean heights' residuals (``heights``: residual, u_bars computed
    with the current ``BAR_FIT_SHARE_OF_RMS``).

    Share: each level's bars' errors about their mean, d = e - mean(e), have E[d²] = (n-1)/n u²
    for n bars of equal u = share x fit_rms; pooled over the levels with two bars or more,
    share² = Σ d² / Σ (n-1)/n fit_rms². Common: what the share's scatter does not explain of the
    residuals, u_c² = mean(residual² - u_bars²), u_bars rescaled to the new share."""
    g = bars.groupby(["capture", "layer", "level"])
    n = g["error"].transform("size")
    d = bars["error"] - g["error"].transform("mean")
    keep = n > 1
    share = math.sqrt(float((d[keep] ** 2).sum()) / float((((n - 1) / n) * bars["fit_rms"] ** 2)[keep].sum()))
    u_bars = heights["u_bars"] * share / BAR_FIT_SHARE_OF_RMS
    common2 = float((heights["residual"] ** 2 - u_bars**2).mean())
    return {
        "share_of_rms": share,
        "common_mm": math.sqrt(max(common2, 0.0)),
        "bars": int(keep.sum()),
        "levels": int(bars[keep].groupby(["capture", "layer", "level"]).ngroups),
        "heights": len(heights),
        "residual_rms_mm": float(np.sqrt((heights["residual"] ** 2).mean())),
        "residual_mean_mm": float(heights["residual"].mean()),
    }


def run(quick: bool, diameters: bool, seed: int = 59, derive_rows: list | None = None) -> pd.DataFrame:
    rows = []
    for case in cases(quick, seed):
        name, cover, h, tilt, mesh_yaw, cam_yaw, seed, errs = case
        camera, sensor, device = SETS[name]
        cap = synth_capture(
            paper_design(cover),
            height_mm=h,
            tilt_deg=tilt,
            yaw_deg=cam_yaw,
            deviations=Deviations(mesh_yaw_deg=mesh_yaw),
            sensor=replace(sensor, **errs),
            intrinsics=CAMERAS[camera],
            seed=seed,
            scene_seed=seed + 1,
        )
        cap = replace(cap, metadata={**cap.metadata, "device": device})
        t0 = time.perf_counter()
        res = inspect(cap, paper_design(cover), diameters=diameters, rng=seed)
        new = rows_of(res, cap, case, diameters)
        rows.extend(new)
        if derive_rows is not None:
            visible = {b["id"] for b in cap.truth["bars"] if b["visible"]}
            mapping, _, tb = match_bars(res, cap.truth, visible)
            k = len(derive_rows)
            derive_rows.append(
                (
                    [{"capture": k, **b} for b in bar_errors(res, tb, mapping)],
                    height_residuals(
                        res, errs, {r["quantity"]: r["error"] for r in new if r["quantity"] in HEIGHT_LEVELS}
                    ),
                )
            )
        c = [r for r in new if r["quantity"] == "cover"]
        print(
            f"  {name:13s} c{cover} {h} mm tilt {tilt:>2}°  k {errs['bias_mm_per_m2']:+6.2f} mm/m²  s "
            f"{100 * errs['depth_scale_error']:+.2f} %  f {100 * errs['focal_error']:+.2f} %  cover err "
            f"{c[0]['error'] if c else float('nan'):+.2f} (u {c[0]['u'] if c else float('nan'):.2f})  "
            f"{time.perf_counter() - t0:.1f} s",
            flush=True,
        )
    return pd.DataFrame(rows)


def report(df: pd.DataFrame) -> None:
    df = df.assign(z=(df["error"] / df["u"]).abs())
    order = ["cover", "layer distance", "upper top", "spacing", "width"]
    print("\nCoverage of the stated standard uncertainty u (k = 2: target 95 % <= within 2u <= 99.9 %)")
    print(
        f"{'quantity':15s} {'set':13s} {'n':>5s} {'mean err':>9s} {'RMS err':>8s} {'median u':>9s} "
        f"{'<= 1u':>7s} {'<= 2u':>7s}  target"
    )
    for q in order:
        sub = df[df["quantity"] == q]
        if not len(sub):
            continue
        for name, g in [("all", sub)] + list(sub.groupby("set")):
            share2 = float((g["z"] <= 2).mean())
            ok = "met" if 0.95 <= share2 <= 0.999 else ("too wide" if share2 > 0.999 else "MISSED")
            print(
                f"{q:15s} {name:13s} {len(g):5d} {g['error'].mean():+9.3f} {np.sqrt((g['error'] ** 2).mean()):8.3f} "
                f"{g['u'].median():9.3f} {100 * (g['z'] <= 1).mean():6.1f}% {100 * share2:6.1f}%  "
                f"{ok if name == 'all' else ''}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="8 captures instead of 36")
    ap.add_argument("--diameters", action="store_true", help="also the bars' widths (runs the diameter stage)")
    ap.add_argument("--seed", type=int, default=59, help="seed of the scenes and error draws (default 59)")
    ap.add_argument("--csv", help="write every measurement's error and u to this CSV")
    ap.add_argument("--derive", action="store_true", help="also estimate the heights' random term's constants")
    a = ap.parse_args()
    got = [] if a.derive else None
    df = run(a.quick, a.diameters, a.seed, got)
    if a.csv:
        df.to_csv(a.csv, index=False)
    report(df)
    if got is not None:
        bars = pd.DataFrame([b for bb, _ in got for b in bb])
        heights = pd.DataFrame([h for _, hh in got for h in hh])
        d = derive(bars, heights)
        print(
            f"\nThe heights' random term (seed {a.seed}): share of the fit's RMS {d['share_of_rms']:.3f} "
            f"({d['bars']} bars in {d['levels']} levels), common to a level {d['common_mm']:.3f} mm "
            f"({d['heights']} mean heights; residual after the drawn errors: mean {d['residual_mean_mm']:+.3f}, "
            f"RMS {d['residual_rms_mm']:.3f} mm)"
        )


if __name__ == "__main__":
    sys.exit(main())
