"""Bar diameters on synthetic captures: the paper's method against the refined one (Table 6 shape).

    python benchmarks/bench_diameter.py [--quick] [--methods paper,refined] [--masks truth,dilated,...]

Captures: the paper's set-up (lower Φ14, upper Φ12, spacing 200; 400/500/600 mm; tilt 0-15°;
several seeds), the site-like slab (Φ8 at 150) and slabs with Φ10/Φ16/Φ20 bars; realistic
sensor, sun shadows (random sun) and 30 % rusty bars. Each capture is measured with the true
axes (``bars_from_truth``) and, when ``rebarlib._inspect.inspect`` exists, with the detected
axes; with the true mask, the true mask dilated / eroded by 1 px (the typical bias of a
learnt mask), the shipped model's mask (``SegmentationModel.default()``) and the
fused colour + depth mask (``fuse_masks``) when those exist. ``--camera d435-848`` renders the
same scenes with another camera (``CAMERAS``), ``--seed-offset`` fresh seeds of them,
``--pixel-samples 3`` anti-aliased colour images (with ``--blur 0.8 --jpeg 90``: softened by a
lens and stored as JPEG, as a photograph is), ``--sensor noisy`` (or ``flying``, ``clean``)
another depth-sensor model (``SENSORS``), ``--ribs relief`` deformed bars with their ribs in
relief (a real bar's silhouette) instead of a smooth envelope, ``--depth-shift 2,-1`` the depth
image moved against the colour image (a colour-depth misregistration; the model and fused masks are
registered to the depth as ``inspect`` does, ``registered_mask``). ``--heights 300,350
--seeds 1,2,3,4``: the paper set-up only, at other camera heights and with other seeds (how
the sizing depends on the capture distance).

Per capture: bars (visible bars in the truth), wrong (measured, nominal size not the true one),
hidden (reported hidden under upper bars), nm (not measured). Summary: correct % =
(bars − hidden − wrong) / (bars − hidden) as in the paper's Table 6, measured %, wrong sizes
with confidence ≥ 0.9, median time of ``measure_diameters`` per capture, and the measured-width
error against the true rib envelope (truth ``envelope_mm``). Which bars are hidden is not taken
from the measurement alone: 'h.¬tr' counts the bars reported hidden that the true axes and the true
mask do not report hidden, and 'right%tr' is the bars sized right over the bars the truth does not
hide (the stricter figure, which counts slivers and bars cut lengthwise by the border: bars the
image shows but whose width it does not); 'right%w' is the bars sized right over the bars whose
whole width the truth's image shows (``_visibility.shows_width``: both edges in the image and
neither under a nearer bar, over at least ``SHOWS_WIDTH_D`` of the bar's diameters), drawn from
the truth alone: the "visible bars" of the target, as the paper's Table 6 left out the bars the
upper bars obstruct. Then how honest each width's uncertainty (``width_sigma_mm``) is
against its error from the true envelope, and the same for the bars sized from one edge and the
axis (``one_sided_share``) against those sized between two edges.

Targets (issue 5): refined with the model or fused mask ≥ 99.5 % of the visible bars sized right
('right%w') over ≥ 300 bars, no
wrong size with high confidence; ≤ 0.2 s per capture (median).
"""

from __future__ import annotations

import argparse
import re
import time
from collections import defaultdict
from dataclasses import replace

import numpy as np

from _cameras import CAMERAS, SENSORS
from _visibility import SHOWS_WIDTH_D, shows_width
from rebarlib import design_from_dict
from rebarlib.diameter import bars_from_truth, imaginary_plane, measure_diameters
from rebarlib.diameter.barsizes import ENVELOPE_SIGMA_MM, bar_system
from rebarlib.data import paper_design, site_design
from rebarlib.synth import Appearance, Deviations, misregister, rib_envelope_mm, synth_capture

HIGH_CONFIDENCE = 0.9
MATCH_MM = 25.0  # a detected axis within this of a true axis (and parallel) is that bar
MATCH_DEG = 8.0


def _design(lower_mm, upper_mm, spacing_mm=200):
    return design_from_dict(
        {
            "slab": {"id": f"L{lower_mm}-U{upper_mm}"},
            "design": {
                "cover_mm": 20,
                "layer_distance_mm": 30 + lower_mm + upper_mm,
                "lower": {"diameter_mm": lower_mm, "spacing_mm": spacing_mm},
                "upper": {"diameter_mm": upper_mm, "spacing_mm": spacing_mm},
            },
        }
    )


def scenarios(quick: bool, seed_offset: int = 0, heights=None, seeds=None):
    """(name, design, synth_capture keywords) of every capture; ``seed_offset`` shifts every
    seed (fresh captures of the same set-ups, e.g. to check thresholds on held-out data).
    ``heights`` / ``seeds``: the paper set-up only, at these camera heights (mm) and seeds
    (how the sizing depends on the capture distance)."""
    out = []
    heights0, tilts, seeds0 = ((400, 600), (0, 15), (1,)) if quick else ((400, 500, 600), (0, 5, 10, 15), (1, 2))
    only_paper = heights is not None or seeds is not None
    heights, seeds = heights or heights0, seeds or seeds0
    for h in heights:
        for tilt in tilts:
            for seed in seeds:
                out.append((f"paper {h}/{tilt}°/s{seed}", paper_design(), dict(height_mm=h, tilt_deg=tilt, seed=seed)))
    if not only_paper:
        out += _other_scenarios(quick)
    if seed_offset:
        out = [(f"{n} +{seed_offset}", d, {**kw, "seed": kw["seed"] + seed_offset}) for n, d, kw in out]
    return out


def _other_scenarios(quick: bool):
    """The captures besides the paper set-up: the site-like slab, the Φ10/Φ16/Φ20 slabs and the
    slabs with bars of another size than designed."""
    out = []
    site = ((450, 10),) if quick else ((400, 0), (450, 10), (500, 5), (500, 15))
    for k, (h, tilt) in enumerate(site):
        out.append((f"site Φ8 {h}/{tilt}°", site_design(), dict(height_mm=h, tilt_deg=tilt, seed=10 + k)))
    others = (
        ((10, 10, 500), (20, 16, 550))
        if quick
        else ((10, 10, 450), (10, 10, 550), (16, 10, 500), (16, 10, 600), (20, 16, 500), (20, 16, 600))
    )
    for k, (lo, up, h) in enumerate(others):
        out.append(
            (
                f"Φ{lo}/Φ{up} {h}/8°",
                _design(lo, up, 150 if lo <= 10 else 200),
                dict(height_mm=h, tilt_deg=8, yaw_deg=7 * k, seed=20 + k),
            )
        )
    # a few bars of another size than designed, on a smaller slab so that they are in view
    wrong = ((450, 0, 30), (500, 10, 31)) if quick else ((450, 0, 30), (450, 10, 31), (500, 5, 32), (550, 15, 33))
    for h, tilt, seed in wrong:
        out.append(
            (
                f"wrong-size {h}/{tilt}°",
                paper_design(),
                dict(height_mm=h, tilt_deg=tilt, seed=seed, deviations=Deviations(wrong_size=3, slab_size_mm=800)),
            )
        )
    return out


def _morph(mask, px):
    import cv2

    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * abs(px) + 1, 2 * abs(px) + 1))
    op = cv2.dilate if px > 0 else cv2.erode
    return op(mask.astype(np.uint8), k).astype(bool)


def _capture(name, design, kw, app, cache, camera="gemini2", sensor="default", relief=False):
    intr = CAMERAS[camera]
    if relief:
        kw = {**kw, "deviations": replace(kw.get("deviations") or Deviations(), rib_relief=True)}
    if not cache:
        return synth_capture(design, sensor=SENSORS[sensor], appearance=app, intrinsics=intr, **kw)
    from pathlib import Path

    from rebarlib import load_capture, save_capture

    px = f"__px{app.pixel_samples}" if app.pixel_samples > 1 else ""
    px += f"__blur{app.blur_px:g}" if app.blur_px > 0 else ""
    px += f"__jpeg{app.jpeg_quality}" if app.jpeg_quality else ""
    px += "" if camera == "gemini2" else f"__{camera}"
    px += "" if sensor == "default" else f"__{sensor}"
    px += "__relief" if relief else ""
    folder = Path(cache) / ("".join(c if c.isalnum() else "_" for c in name) + px)
    if (folder / "truth.json").is_file():
        return load_capture(folder)
    cap = synth_capture(design, sensor=SENSORS[sensor], appearance=app, intrinsics=intr, **kw)
    save_capture(cap, folder)
    return load_capture(folder)


def _mask_sources(model_path=""):
    """Callables (capture, design) -> (H, W) mask (bool, or a float probability for the soft
    ones), or (mask, capture to measure on, registration) for the registered ones
    (``registered_mask``), for each available mask,
    and notes on the others. ``model_path``: an ONNX model (with its sidecar) to use instead of
    the shipped one for the "model" and "fused" masks (a candidate from ``training/``)."""
    sources = {
        "truth": lambda cap, design: cap.labels > 0,
        # the truth mask a pixel too wide / too narrow: a learnt mask's typical bias
        "dilated": lambda cap, design: _morph(cap.labels > 0, +1),
        "eroded": lambda cap, design: _morph(cap.labels > 0, -1),
    }
    notes = []
    try:
        from rebarlib import segmentation as seg
    except ImportError as e:  # not there yet
        return sources, [f"no rebarlib.segmentation ({e}): model and fused masks skipped"]
    model = None
    if hasattr(seg, "SegmentationModel"):
        try:
            model = seg.SegmentationModel(model_path) if model_path else seg.SegmentationModel.default()
            if model_path:
                notes.append(f"model and fused masks: {model_path}, not the shipped model")
        except Exception as e:  # noqa: BLE001 - report whatever keeps the model from loading
            notes.append(f"loading the segmentation model ({model_path or 'the shipped one'}) failed: {e!r}")
    else:
        notes.append("rebarlib.segmentation has no SegmentationModel yet")
    if model is not None:
        from rebarlib._inspect import registered_mask, widest_bar_px

        def registered(cap, **kw):
            # as inspect does for the refined method: the colour side moved onto the depth image
            # where the two are misregistered (--depth-shift); the capture the bars are then
            # measured on comes with the mask, and the registration (its depth_overreach_px
            # is what inspect fits the detected axes with)
            return registered_mask(cap, model=model, rng=0, soft=True, **kw)

        # soft masks (the probability where it agrees with the binary mask), as rebarlib.inspect
        # passes them: the refined method finds the edges to a fraction of a pixel, the paper's
        # method takes the pixels at >= 0.5. "model" and "fused" run the network on full-resolution
        # tiles of the image, as rebarlib.inspect does for the refined method; "-whole": on the
        # whole image down-scaled to the network's input (as for the paper's method, and what
        # these masks were before)
        sources["model"] = lambda cap, design: registered(
            cap, source="model", tiled=True, bar_width_px=widest_bar_px(cap, design)
        )
        sources["model-whole"] = lambda cap, design: registered(cap, source="model")
        if hasattr(seg, "fuse_masks") and hasattr(seg, "mask_from_depth"):
            # as the pipeline builds it (rebar_mask): colour mask, the network's probability for
            # the hysteresis, the depth mask (its own plane fit)
            sources["fused"] = lambda cap, design: registered(
                cap, source="fused", tiled=True, bar_width_px=widest_bar_px(cap, design)
            )
            sources["fused-whole"] = lambda cap, design: registered(cap, source="fused")
            # without the probability (no hysteresis): what this benchmark called "fused" before
            sources["fused-nohyst"] = lambda cap, design: np.asarray(
                seg.fuse_masks(
                    np.asarray(model.predict_mask(cap.color), bool),
                    seg.mask_from_depth(cap, rng=0),
                    depth_valid=cap.depth_mm > 0,
                ),
                bool,
            )
        else:
            notes.append("no fuse_masks / mask_from_depth yet: fused mask skipped")
    return sources, notes


def _jittered(bars, *, sigma_mm=1.0, rng=None):
    """The bars table with each axis moved by N(0, sigma_mm) across it (both directions
    perpendicular to the axis, the same shift at both ends): axes as a detector might find them."""
    rng = np.random.default_rng(rng)
    out = bars.copy()
    for k, r in enumerate(bars.itertuples(index=False)):
        p0 = np.array([r.start_x_mm, r.start_y_mm, r.start_z_mm])
        p1 = np.array([r.end_x_mm, r.end_y_mm, r.end_z_mm])
        v = (p1 - p0) / np.linalg.norm(p1 - p0)
        a = np.cross(v, [0.0, 0.0, 1.0])
        a /= np.linalg.norm(a)
        b = np.cross(v, a)
        shift = rng.normal(0, sigma_mm) * a + rng.normal(0, sigma_mm) * b
        for i, c in enumerate("xyz"):
            out.loc[out.index[k], f"start_{c}_mm"] = p0[i] + shift[i]
            out.loc[out.index[k], f"end_{c}_mm"] = p1[i] + shift[i]
    return out


def _design_radius_axes(bars, truth, declare=False):
    """The true axes moved along the line of sight so that the visible surface lies at the design
    envelope radius from them: what an axis fitted with the design radius looks like."""
    tb = {int(b["id"]): b for b in truth["bars"]}
    out = bars.copy()
    for k, r in enumerate(bars.itertuples(index=False)):
        b = tb[int(r.bar_id)]
        shift = (rib_envelope_mm(b["design_diameter_mm"]) - b["envelope_mm"]) / 2
        p0 = np.array([r.start_x_mm, r.start_y_mm, r.start_z_mm])
        p1 = np.array([r.end_x_mm, r.end_y_mm, r.end_z_mm])
        n = imaginary_plane(p0, p1).normal  # from the camera towards the axis
        for i, c in enumerate("xyz"):
            out.loc[out.index[k], f"start_{c}_mm"] = p0[i] + shift * n[i]
            out.loc[out.index[k], f"end_{c}_mm"] = p1[i] + shift * n[i]
    if declare:  # say so, as the geometry stage should: the cloud width then only vetoes
        out["axis_radius_mm"] = [rib_envelope_mm(tb[int(i)]["design_diameter_mm"]) / 2 for i in out.bar_id]
    return out


def _axis_sources():
    sources = {
        "truth": lambda cap, design: bars_from_truth(cap.truth),
        # the true axes moved by 1 mm (σ) across: what detected axes may look like
        "jitter1": lambda cap, design: _jittered(bars_from_truth(cap.truth), sigma_mm=1.0, rng=0),
        "designr": lambda cap, design: _design_radius_axes(bars_from_truth(cap.truth), cap.truth),
        "designr+": lambda cap, design: _design_radius_axes(bars_from_truth(cap.truth), cap.truth, True),
    }
    try:
        from rebarlib._inspect import inspect
    except ImportError as e:
        return sources, [f"no rebarlib._inspect ({e}): detected axes skipped"]
    from bench_geometry import edge_trim  # the over-reach as inspect's mask step measures it

    def detected(cap, design, reach=None):
        # as inspect fits them: where the depth's bars reach beyond the colour's (edge fattening,
        # the over-reach its mask step measures; ``reach`` where the shipped model's "fused"
        # mask has measured it already), on the depth without that fringe; rng fixed:
        # reproducible
        if reach is None:
            reach = edge_trim(cap, design)
        return inspect(cap, design, diameters=False, edge_trim_px=reach, rng=0).bars

    sources["detected"] = detected
    return sources, []


def _match(bars, truth):
    """Truth bar id of each row of ``bars`` (-1 if none): the parallel true axis nearest to it."""
    out = []
    tb = [b for b in truth["bars"]]
    for r in bars.itertuples(index=False):
        p0 = np.array([r.start_x_mm, r.start_y_mm, r.start_z_mm], float)
        p1 = np.array([r.end_x_mm, r.end_y_mm, r.end_z_mm], float)
        v = (p1 - p0) / max(np.linalg.norm(p1 - p0), 1e-9)
        mid = (p0 + p1) / 2
        best, best_d = -1, MATCH_MM
        for b in tb:
            a0, a1 = np.asarray(b["axis_start_mm"], float), np.asarray(b["axis_end_mm"], float)
            w = (a1 - a0) / np.linalg.norm(a1 - a0)
            if np.degrees(np.arccos(min(abs(v @ w), 1.0))) > MATCH_DEG:
                continue
            d = mid - a0
            dist = np.linalg.norm(d - (d @ w) * w)
            if dist < best_d:
                best, best_d = int(b["id"]), dist
        out.append(best)
    return np.array(out, int)


def _unsizeable(cap, design):
    """(hidden, cut): ids of the visible bars that no mask can size, by the true axes and the true
    mask: mostly under nearer bars (reported hidden), or cut by the image border (in view, but
    fewer than the minimum cross-sections have both edges in the image, or the axis is outside
    it: half a bar along the border shows one edge only)."""
    df = measure_diameters(cap, bars_from_truth(cap.truth), cap.labels > 0, design=design)
    reason = df.diameter_reason.fillna("")
    cut = (df.diameter_status == "not measured") & (
        reason.str.contains("at the image border") | reason.str.contains("outside the image")
    )
    return {int(i) for i in df.bar_id[df.hidden]}, {int(i) for i in df.bar_id[cut]}


def _score(df, bars, truth, axes_name, truly_hidden=frozenset(), cut=frozenset(), shows=frozenset()):
    """Per-bar rows joined to the truth; bars of the truth not found by the axes count as such:
    (records, missed, missed and truly hidden). A bar that lies under nearer bars cannot be seen,
    so an axis detector that does not find it has missed no visible bar: it counts as hidden.
    ``truly_hidden``: the bars the true axes and the true mask report hidden (:func:`_unsizeable`);
    each record says whether its bar is one, so that a bar reported hidden that is not can be
    counted against the measurement. ``shows``: the bars whose whole width the truth's image shows
    (:func:`_visibility.shows_width`); each record says whether its bar is one, and each such bar
    no axis was found for is a ``missed-shows`` record."""
    tb = {int(b["id"]): b for b in truth["bars"]}
    visible = {int(i) for i in bars_from_truth(truth).bar_id}
    if axes_name in ("truth", "jitter1", "designr", "designr+"):  # bar ids are the truth's
        tid = df.bar_id.to_numpy()
    else:
        tid = _match(bars.set_index("bar_id").loc[df.bar_id].reset_index(), truth)
    recs = []
    seen = set()
    for r, t in zip(df.itertuples(index=False), tid):
        if t < 0 or t not in visible or t in seen:  # a spurious or duplicate axis
            recs.append(dict(kind="extra", status=r.diameter_status, nominal=r.nominal_mm, conf=r.confidence))
            continue
        seen.add(t)
        width = r.width_used_mm if r.diameter_status == "measured" else r.width_median_mm
        recs.append(
            dict(
                kind="bar",
                status=r.diameter_status,
                nominal=r.nominal_mm,
                conf=r.confidence,
                true=tb[t]["diameter_mm"],
                env=tb[t]["envelope_mm"],
                width=width,
                row=r,
                true_id=int(t),
                wrong_size=bool(tb[t]["wrong_size"]),
                cut=t in cut,
                truly_hidden=t in truly_hidden,
                shows=t in shows,
            )
        )
    missed = visible - seen
    missed_cut = (missed & set(cut)) - set(truly_hidden)
    recs += [dict(kind="missed-cut")] * len(missed_cut)
    recs += [dict(kind="missed-shows")] * len(missed & set(shows))
    return recs, len(missed), len(missed & set(truly_hidden))


def _z(row, env) -> float:
    """How far a bar's width used lies from its true envelope, in its stated σ with the size
    table's own (what the confidence is computed from)."""
    return (row.width_used_mm - env) / np.hypot(row.width_sigma_mm, ENVELOPE_SIGMA_MM)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a few captures only")
    ap.add_argument("--methods", default="paper,refined")
    ap.add_argument("--masks", default="truth,dilated,eroded,model,fused")
    ap.add_argument("--edges", default="check", help="refined colour edges: check, replace or mask (none)")
    ap.add_argument("--axes", default="truth,jitter1,designr,designr+,detected")
    ap.add_argument("--show-wrong", action="store_true", help="print every wrong size")
    ap.add_argument("--only", default="", help="only captures whose name contains this")
    ap.add_argument(
        "--cloud",
        default="fuse",
        choices=("fuse", "veto", "off"),
        help="refined: use_cloud True (fuse), 'veto' or False (off)",
    )
    ap.add_argument("--heights", default="", help="H1,H2,...: the paper set-up only, at these camera heights (mm)")
    ap.add_argument("--seeds", default="", help="S1,S2,...: the paper set-up only, with these seeds")
    ap.add_argument("--seed-offset", type=int, default=0, help="shift every seed (held-out captures)")
    ap.add_argument("--cache", default="", help="folder to keep rendered captures in (re-runs are faster)")
    ap.add_argument(
        "--pixel-samples",
        type=int,
        default=1,
        help="rays per pixel side for the colour image (Appearance.pixel_samples; 1: aliased)",
    )
    ap.add_argument(
        "--blur",
        type=float,
        default=0.0,
        help="Gaussian blur σ (px) of the colour image, as a real lens and demosaicing "
        "soften edges (Appearance.blur_px; 0: none)",
    )
    ap.add_argument(
        "--jpeg",
        type=int,
        default=0,
        help="JPEG round trip of the colour image at this quality (Appearance.jpeg_quality; 0: none)",
    )
    ap.add_argument(
        "--camera",
        default="gemini2",
        choices=sorted(CAMERAS),
        help="camera the captures are rendered with (CAMERAS): the reference Gemini 2, or another",
    )
    ap.add_argument(
        "--sensor",
        default="default",
        choices=sorted(SENSORS),
        help="depth-sensor model the captures are rendered with (SENSORS): the default, or "
        "3x the flying pixels, 2.5x the stereo noise, no edge effects",
    )
    ap.add_argument(
        "--ribs",
        default="envelope",
        choices=("envelope", "relief"),
        help="deformed bars drawn as their rib envelope (smooth), or with the ribs in relief "
        "(Deviations.rib_relief: a core of d1, crescent and longitudinal ribs, random roll)",
    )
    ap.add_argument(
        "--depth-shift",
        default="0,0",
        help="DU,DV: shift the depth image this many pixels against the colour image (a "
        "colour-depth misregistration, as a camera's factory alignment leaves); the model "
        "and fused masks are registered as inspect does. Only the detected axes are "
        "meaningful then: the true axes belong to the colour image, not the moved depth",
    )
    ap.add_argument(
        "--model", default="", help="ONNX segmentation model for the model and fused masks (default: the shipped one)"
    )
    ap.add_argument("--dump", default="", help="write every bar's row, joined to the truth, to this CSV")
    ap.add_argument(
        "--reasons",
        action="store_true",
        help="print why bars were not measured (diameter_reason, numbers left out) per combination",
    )
    args = ap.parse_args()
    depth_shift = tuple(map(int, args.depth_shift.split(",")))
    mask_src, notes = _mask_sources(args.model)
    axis_src, notes2 = _axis_sources()
    notes += notes2
    mask_src = {k: v for k, v in mask_src.items() if k in args.masks.split(",")}
    axis_src = {k: v for k, v in axis_src.items() if k in args.axes.split(",")}
    methods = args.methods.split(",")
    combos = [(m, k, a) for a in axis_src for k in mask_src for m in methods]
    for n in notes:
        print("note:", n)
    app = Appearance(
        rust_fraction=0.3, pixel_samples=args.pixel_samples, blur_px=args.blur, jpeg_quality=args.jpeg or None
    )  # random sun per seed: shadows of the upper bars on the lower
    per_capture = []
    dump = []  # every bar row joined to the truth (--dump)
    recs = defaultdict(list)
    times = defaultdict(list)
    cpu = defaultdict(list)  # the machine may be shared: CPU time is the fairer figure
    missed = defaultdict(int)
    missed_hidden = defaultdict(int)
    reasons = defaultdict(lambda: defaultdict(int))
    ints = lambda text: tuple(int(x) for x in text.split(",")) if text else None  # noqa: E731
    for name, design, kw in scenarios(args.quick, args.seed_offset, ints(args.heights), ints(args.seeds)):
        if args.only not in name:
            continue
        cap = _capture(name, design, kw, app, args.cache, args.camera, args.sensor, args.ribs == "relief")
        if depth_shift != (0, 0):
            cap = misregister(cap, *depth_shift)
        masks, measured_on = {}, {}  # measured_on: the capture with the colour moved onto the depth
        reach = None  # the over-reach the shipped model's fused mask measured (inspect's)
        for k, f in mask_src.items():
            m = f(cap, design)
            masks[k], measured_on[k] = m[:2] if isinstance(m, tuple) else (m, cap)
            if k == "fused" and not args.model and isinstance(m, tuple):
                reach = m[2]["depth_overreach_px"]
        axes = {}
        for a, f in axis_src.items():
            try:
                axes[a] = f(cap, design, reach) if a == "detected" else f(cap, design)
            except Exception as e:  # noqa: BLE001 - a failing detector is reported, not fatal
                print(f"note: {name}: axes '{a}' failed: {e!r}")
        row = {"capture": name, "bars": len(bars_from_truth(cap.truth))}
        hidden_truth, cut_truth = _unsizeable(cap, design)
        shows = shows_width(cap)
        for combo in combos:
            m, k, a = combo
            if a not in axes:
                continue
            t0, c0 = time.perf_counter(), time.process_time()
            df = measure_diameters(
                measured_on[k],
                axes[a],
                masks[k],
                design=design,
                method=m,
                colour_edges=False if args.edges == "mask" else args.edges,
                use_cloud={"fuse": True, "veto": "veto", "off": False}[args.cloud],
            )
            times[combo].append(time.perf_counter() - t0)
            cpu[combo].append(time.process_time() - c0)
            rr, n_missed, n_missed_hidden = _score(df, axes[a], cap.truth, a, hidden_truth, cut_truth, shows)
            recs[combo] += rr
            missed[combo] += n_missed
            missed_hidden[combo] += n_missed_hidden
            for r in rr:
                if r["kind"] == "bar" and r["status"] != "measured":
                    why = re.sub(r"-?\d+(\.\d+)?", "#", r["row"].diameter_reason)
                    reasons[combo][why if why.startswith(f"{r['status']}: ") else f"{r['status']}: {why}"] += 1
            if n_missed > n_missed_hidden:
                reasons[combo]["no axis found for the bar"] += n_missed - n_missed_hidden
            if n_missed_hidden:
                reasons[combo]["no axis found for the bar (hidden under nearer bars)"] += n_missed_hidden
            bars_rr = [r for r in rr if r["kind"] == "bar"]
            dump += [
                {
                    "capture": name,
                    "method": m,
                    "mask": k,
                    "axes": a,
                    "true_id": r["true_id"],
                    "true_mm": r["true"],
                    "true_envelope_mm": r["env"],
                    "wrong_size": r["wrong_size"],
                    "shows_width": r["shows"],
                    **r["row"]._asdict(),
                }
                for r in bars_rr
            ]
            if args.show_wrong:
                for r in bars_rr:
                    if r["status"] == "measured" and r["nominal"] != r["true"]:
                        print(f"    wrong {combo}: true Φ{r['true']:g} (envelope {r['env']}) -> {r['row']}")
            row[combo] = (
                sum(r["status"] == "measured" and r["nominal"] != r["true"] for r in bars_rr),
                sum(r["status"] == "hidden" for r in bars_rr) + n_missed_hidden,
                sum(r["status"] == "not measured" for r in bars_rr) + n_missed - n_missed_hidden,
            )
        per_capture.append(row)
        print(f"  done {name}", flush=True)

    # Table 6 shape: per capture, bars, then wrong / hidden / not measured per combination
    heads = [f"{m[:3]}|{k[:5]}|{a[:3]}" for m, k, a in combos]
    if args.dump:
        import pandas as pd

        pd.DataFrame(dump).to_csv(args.dump, index=False)
        print(f"\n{len(dump)} bar rows written to {args.dump}")
    print("\nPer capture: wrong/hidden/not measured (method|mask|axes)")
    print(f"{'capture':<22}{'bars':>5} " + " ".join(f"{h:>17}" for h in heads))
    for row in per_capture:
        cells = [("%d/%d/%d" % row[c]) if c in row else "-" for c in combos]
        print(f"{row['capture']:<22}{row['bars']:>5} " + " ".join(f"{c:>17}" for c in cells))

    print(
        f"\nSummary over {len(per_capture)} captures (hidden: reported hidden, or not found by the axes and "
        "hidden under nearer bars by the truth; of those, 'h.noax' had no axis; 'cut': of the other bars, "
        "those the true axes and true mask cannot size because the image border cuts them (one edge "
        "only, or under 8 cross-sections with both); 'meas.%¬cut': measured % of the bars neither "
        "hidden nor cut; 'h.¬tr': bars reported hidden that the true axes and true mask do not report "
        "hidden; 'right%tr': bars measured to their true size, % of the bars not hidden by the truth; "
        f"'right%w': the same, % of the bars whose whole width the truth's image shows over {SHOWS_WIDTH_D:g} "
        "of their diameters or more (both edges in the image, neither under a nearer bar), and 'w.n': "
        "how many bars those are)"
    )
    print(
        f"{'method':<8}{'mask':<13}{'axes':<9}{'bars':>6}{'hidden':>7}{'meas.':>7}{'n.m.':>6}{'wrong':>6}"
        f"{'wrong≥0.9':>10}{'correct%':>9}{'measured%':>10}{'cut':>5}{'meas.%¬cut':>11}{'extra':>6}{'h.noax':>7}"
        f"{'h.¬tr':>6}{'right%tr':>9}{'w.n':>5}{'right%w':>8}{'median s':>9}{'cpu s':>7}"
    )
    for combo in combos:
        rr = [r for r in recs[combo] if r["kind"] == "bar"]
        if not rr and not missed[combo]:
            continue
        nb = len(rr) + missed[combo]
        hidden = sum(r["status"] == "hidden" for r in rr) + missed_hidden[combo]
        meas = [r for r in rr if r["status"] == "measured"]
        wrong = [r for r in meas if r["nominal"] != r["true"]]
        wrong_hi = [r for r in wrong if r["conf"] >= HIGH_CONFIDENCE]
        extra = sum(r["kind"] == "extra" for r in recs[combo])
        base = max(nb - hidden, 1)
        cut = sum(r["status"] != "hidden" and r["cut"] for r in rr) + sum(
            r["kind"] == "missed-cut" for r in recs[combo]
        )
        meas_uncut = sum(not r["cut"] for r in meas)
        false_hidden = sum(r["status"] == "hidden" and not r["truly_hidden"] for r in rr)
        truly_hidden = sum(r["truly_hidden"] for r in rr) + missed_hidden[combo]
        right = len(meas) - len(wrong)
        n_shows = sum(r["shows"] for r in rr) + sum(r["kind"] == "missed-shows" for r in recs[combo])
        right_shows = sum(r["shows"] and r["nominal"] == r["true"] for r in meas)
        m, k, a = combo
        print(
            f"{m:<8}{k:<13}{a:<9}{nb:>6}{hidden:>7}{len(meas):>7}{nb - hidden - len(meas):>6}{len(wrong):>6}"
            f"{len(wrong_hi):>10}{100 * (base - len(wrong)) / base:>9.2f}{100 * len(meas) / base:>10.1f}"
            f"{cut:>5}{100 * meas_uncut / max(base - cut, 1):>11.1f}"
            f"{extra:>6}{missed_hidden[combo]:>7}{false_hidden:>6}"
            f"{100 * right / max(nb - truly_hidden, 1):>9.1f}{n_shows:>5}{100 * right_shows / max(n_shows, 1):>8.1f}"
            f"{np.median(times[combo]):>9.3f}{np.median(cpu[combo]):>7.3f}"
        )

    print(
        "\nBars of another size than designed: flagged (measured, right size, not matching the design), "
        "not measured (of those, 'alerted': the reason says 'possible wrong size' and names the true size), "
        "missed (measured as another size); 'false alerts': bars of the design size given that reason"
    )
    print(
        f"{'method':<8}{'mask':<13}{'axes':<9}{'bars':>6}{'flagged':>9}{'n.m.':>6}{'alerted':>9}{'missed':>8}"
        f"{'false alerts':>14}"
    )

    def alert(r):
        reason = getattr(r.get("row"), "diameter_reason", "") or ""
        return r["status"] != "measured" and reason.startswith("possible wrong size")

    for combo in combos:
        ws = [r for r in recs[combo] if r["kind"] == "bar" and r["wrong_size"]]
        if not ws:
            continue
        flagged = sum(r["status"] == "measured" and r["nominal"] == r["true"] for r in ws)
        as_other = sum(r["status"] == "measured" and r["nominal"] != r["true"] for r in ws)
        alerted = sum(alert(r) and f"Φ{r['true']:g} " in r["row"].diameter_reason for r in ws)
        false_alerts = sum(alert(r) for r in recs[combo] if r["kind"] == "bar" and not r["wrong_size"])
        m, k, a = combo
        print(
            f"{m:<8}{k:<13}{a:<9}{len(ws):>6}{flagged:>9}{len(ws) - flagged - as_other:>6}{alerted:>9}"
            f"{as_other:>8}{false_alerts:>14}"
        )

    print("\nWidth used for the size (mask, cloud or both) − true rib envelope (mm), bars measured with the true axes")
    print(f"{'method':<8}{'mask':<13}{'n':>6}{'bias':>7}{'|err| median':>13}{'p90':>7}{'p99':>7}{'max':>7}")
    for combo in combos:
        m, k, a = combo
        if a != "truth":
            continue
        err = np.array(
            [r["width"] - r["env"] for r in recs[combo] if r["kind"] == "bar" and r["status"] == "measured"], float
        )
        if len(err) == 0:
            continue
        ae = np.abs(err)
        print(
            f"{m:<8}{k:<13}{len(err):>6}{np.median(err):>7.2f}{np.median(ae):>13.2f}"
            f"{np.percentile(ae, 90):>7.2f}{np.percentile(ae, 99):>7.2f}{ae.max():>7.2f}"
        )

    print(
        "\nHow honest the uncertainty is (refined): z = (width_used_mm - true envelope) / σ, σ = width_sigma_mm\n"
        "with the size table's 0.15 mm (what the confidence is computed from), over the bars measured or left\n"
        "ambiguous; for a normal error |z| would read 0.67, 1.00, 1.64, 1.96, 2.58 and 4.6 % beyond 2. 'ambig.\n"
        "nearer': ambiguous bars whose nearer size (named in the reason) is the true one"
    )
    print(
        f"{'method':<8}{'mask':<13}{'axes':<9}{'n':>6}{'p50':>6}{'p68':>6}{'p90':>6}{'p95':>6}{'p99':>6}"
        f"{'max':>7}{'>2σ %':>7}{'ambig. nearer':>15}"
    )
    for combo in combos:
        m, k, a = combo
        rs = [r for r in recs[combo] if r["kind"] == "bar" and np.isfinite(getattr(r["row"], "width_sigma_mm", np.nan))]
        if m != "refined" or not rs:
            continue
        z = np.array([_z(r["row"], r["env"]) for r in rs])
        az = np.abs(z)
        amb = [r for r in rs if str(r["row"].diameter_reason).startswith("ambiguous")]
        near = sum(f"nearer {bar_system('GB1499.2').label(r['true'])} " in str(r["row"].diameter_reason) for r in amb)
        print(
            f"{m:<8}{k:<13}{a:<9}{len(z):>6}"
            + "".join(f"{np.percentile(az, q):>6.2f}" for q in (50, 68.27, 90, 95, 99))
            + f"{az.max():>7.2f}{100 * (az > 2).mean():>7.1f}{f'{near} of {len(amb)}':>15}"
        )

    print(
        "\nMask widths from two edges against widths from one edge and the axis (refined;\n"
        "bars with at least half their sections one-sided, one_sided_share >= 0.5, against\n"
        "bars with none): the mask width (width_median_mm) − true envelope, its median and\n"
        "RMS, and |z| as above over those measured or left ambiguous. A one-sided width is\n"
        "off by twice the axis's error across the bar"
    )
    print(
        f"{'method':<8}{'mask':<13}{'axes':<9}{'sides':<6}{'n':>6}{'bias':>7}{'rms':>7}{'n z':>6}"
        f"{'|z| p50':>8}{'p95':>6}{'max':>7}"
    )
    for combo in combos:
        m, k, a = combo
        if m != "refined":
            continue
        rs = [(r["row"], r["env"]) for r in recs[combo] if r["kind"] == "bar" and np.isfinite(r["row"].width_median_mm)]
        for label, pick in (("two", lambda s: s == 0), ("one", lambda s: s >= 0.5)):
            g = [(row, env) for row, env in rs if pick(row.one_sided_share)]
            if not g:
                continue
            err = np.array([row.width_median_mm - env for row, env in g], float)
            az = np.abs([_z(row, env) for row, env in g if np.isfinite(row.width_sigma_mm)])
            zs = f"{np.median(az):>8.2f}{np.percentile(az, 95):>6.2f}{az.max():>7.2f}" if len(az) else ""
            print(
                f"{m:<8}{k:<13}{a:<9}{label:<6}{len(g):>6}{np.median(err):>7.2f}"
                f"{np.sqrt(np.mean(err**2)):>7.2f}{len(az):>6}" + zs
            )

    if args.reasons:
        print("\nWhy bars were not measured (diameter_reason, numbers left out), per combination")
        for combo in combos:
            if not reasons[combo]:
                continue
            print("  " + "|".join(combo))
            for why, n in sorted(reasons[combo].items(), key=lambda kv: -kv[1]):
                print(f"    {n:5d}  {why}")


if __name__ == "__main__":
    main()
