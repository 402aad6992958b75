"""Real-photo segmentation benchmark: how the colour model's mask holds on photos it was not made
from.

The repository holds no third-party photos: each set is read from a folder given on the command
line (docs/real_photos.md says where the development sets come from, how to extract them and how
they are scored)::

    python benchmarks/bench_real_photos.py --set dtu=/tmp/realsets/dtu --set lab=/tmp/realsets/yzh_lab
    python benchmarks/bench_real_photos.py --set dtu=... --models a.onnx b.onnx --per-image

A folder is read in one of three layouts, found from its files:

* ``orig_N.png`` with ``ransac_N.png``: rough reference masks, moved by ``--ref-shift NAME=DX,DY``
  pixels (the DTU set's masks lie about (+10, -8) px off their photos) and cleaned: only the
  straight, bar-thin parts of the reference count as bars; what the reference marks besides
  (a board's edge, a patch of ground) is left out of the score (:func:`ransac_reference`);
* ``NAME.jpg`` / ``.png`` with a LabelMe ``NAME.json``: every polygon is a bar, except those
  labelled ``column`` (a cage's outline);
* ``NAME.jpg`` / ``.png`` with ``NAME.mask.png`` (non-zero = rebar); a photo with neither a mask
  nor a LabelMe file is a background photo: every pixel is background.

Scoring is tolerant, since reference masks of real photos are drawn by hand or by a rough
method (``--tol-px``, default 4 px at 640 px of width, scaled with the image's width):

* **precision**: the share of the predicted pixels within the tolerance of a reference bar;
* **recall**: the share of the reference's *core* (the bars shrunk by half the tolerance, so
  that a reference edge drawn a pixel or two off does not count) that is predicted;
* **Dice** = 2PR / (P + R), **IoU** = Dice / (2 - Dice): the paper's formulas with these
  tolerant counts;
* **marked**: the share of the image predicted as rebar (the reference's share beside it);
  **background marked**: the share of the pixels farther than the tolerance from any reference
  bar (and outside the left-out parts) that are predicted.

Counts are summed over a set's photos. The synthetic test's table is
``benchmarks/bench_segmentation.py``.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from rebarlib.segmentation import SegmentationModel

ROOT = Path(__file__).resolve().parents[1]
IMAGE_EXT = (".png", ".jpg", ".jpeg")


def _disk(r: int):
    r = max(int(round(r)), 0)
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def _dilate(mask, r):
    return cv2.dilate(mask.astype(np.uint8), _disk(r)).astype(bool) if r > 0 else mask.copy()


def _erode(mask, r):
    return cv2.erode(mask.astype(np.uint8), _disk(r)).astype(bool) if r > 0 else mask.copy()


def _line_kernel(length: int, angle: float):
    k = np.zeros((length, length), np.uint8)
    c = (length - 1) / 2
    dx, dy = c * np.cos(angle), c * np.sin(angle)
    cv2.line(k, (int(round(c - dx)), int(round(c - dy))), (int(round(c + dx)), int(round(c + dy))), 1)
    return k


def ransac_reference(raw, shift=(0, 0), *, thick_px: int = 9, line_px: int = 41):
    """(bars, left_out) from a rough reference mask: ``raw`` moved by ``shift`` (dx, dy); the
    bars are its parts that survive an opening with a straight line of ``line_px`` pixels in one
    of 12 directions (long and straight) and lie away from its parts thicker than ``2 thick_px
    + 1`` px (a board's edge, a patch of ground); the rest of the reference, grown by 4 px, is
    left out of the score."""
    dx, dy = shift
    m = np.float32([[1, 0, dx], [0, 1, dy]])
    ref = cv2.warpAffine(raw.astype(np.uint8), m, raw.shape[::-1], flags=cv2.INTER_NEAREST) > 0
    u8 = ref.astype(np.uint8)
    thick = cv2.morphologyEx(u8, cv2.MORPH_OPEN, _disk(thick_px)) > 0
    straight = np.zeros_like(ref)
    for a in np.arange(12) * np.pi / 12:
        straight |= cv2.morphologyEx(u8, cv2.MORPH_OPEN, _line_kernel(line_px, a)) > 0
    bars = straight & ~_dilate(thick, thick_px + 3)
    left_out = _dilate(ref & ~bars, 4) & ~bars
    return bars, left_out


def _multi_scale(model, rgb, scales, **kw):
    """The mean of the model's probability maps of ``rgb`` resized by each of ``scales`` (area
    averaging to shrink, bilinear to enlarge), each brought back to the photo's size."""
    H, W = rgb.shape[:2]
    maps = []
    for f in scales:
        if f == 1:
            maps.append(model.predict_proba(rgb, **kw))
            continue
        size = (max(1, round(W * f)), max(1, round(H * f)))
        small = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA if f < 1 else cv2.INTER_LINEAR)
        maps.append(cv2.resize(model.predict_proba(small, **kw), (W, H), interpolation=cv2.INTER_LINEAR))
    return maps[0] if len(maps) == 1 else np.mean(maps, axis=0)


def _straight_parts(mask, length_px):
    """The parts of ``mask`` that survive an opening by a straight line of ``length_px`` pixels in
    one of 12 directions (long, straight structures)."""
    u8 = mask.astype(np.uint8)
    out = np.zeros_like(mask)
    n = max(3, int(round(length_px)) | 1)
    for a in np.arange(12) * np.pi / 12:
        out |= cv2.morphologyEx(u8, cv2.MORPH_OPEN, _line_kernel(n, a)) > 0
    return out


def _hysteresis(proba, low: float, high: float):
    """The pixels above ``low`` connected (8 neighbours) to a pixel above ``high``."""
    n, lab = cv2.connectedComponents((proba > low).astype(np.uint8), connectivity=8)
    keep = np.zeros(n, bool)
    keep[np.unique(lab[proba > high])] = True
    keep[0] = False
    return keep[lab]


def _normalised(rgb, how: str):
    """The photo with its colours normalised before the network (training/README.md, 'At
    inference'): ``grayworld`` (each channel scaled to the image's mean grey), ``stretch`` (the
    1st-99th percentile stretched to 0-255), ``clahe`` (contrast-limited equalisation of the
    lightness, 8 x 8 tiles, limit 2), ``gammaG`` (each value to the power G)."""
    if how == "none":
        return rgb
    f = rgb.astype(np.float32)
    if how == "grayworld":
        g = f.reshape(-1, 3).mean(axis=0)
        return np.clip(f * (g.mean() / g), 0, 255).astype(np.uint8)
    if how == "stretch":
        lo, hi = np.percentile(f, (1, 99))
        return np.clip((f - lo) * 255 / max(hi - lo, 1e-6), 0, 255).astype(np.uint8)
    if how == "clahe":
        lab = cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB)
        lab[..., 0] = cv2.createCLAHE(2.0, (8, 8)).apply(lab[..., 0])
        return cv2.cvtColor(lab, cv2.COLOR_LAB2RGB)
    if how.startswith("gamma"):
        return cv2.LUT(rgb, (255 * (np.arange(256) / 255.0) ** float(how[5:])).astype(np.uint8))
    raise ValueError(how)


def _labelme_mask(path: Path, shape):
    spec = json.loads(path.read_text(encoding="utf-8"))
    mask = np.zeros(shape, np.uint8)
    for s in spec.get("shapes", []):
        if s.get("label") == "column":
            continue
        pts = np.round(np.asarray(s["points"], float)).astype(np.int32)
        if s.get("shape_type", "polygon") == "polygon" and len(pts) >= 3:
            cv2.fillPoly(mask, [pts], 1)
    return mask > 0


def load_set(folder: Path, shift=(0, 0)):
    """[(name, RGB image, reference bars (bool), left-out pixels (bool))] of one folder."""
    items = []
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_EXT)
    for p in files:
        if p.name.startswith("ransac_") or p.name.endswith(".mask.png"):
            continue
        bgr = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if bgr is None:
            continue
        rgb = np.ascontiguousarray(bgr[:, :, ::-1])
        shape = rgb.shape[:2]
        left_out = np.zeros(shape, bool)
        ransac = folder / re.sub(r"^orig_", "ransac_", p.name)
        if p.name.startswith("orig_") and ransac.exists():
            raw = cv2.imread(str(ransac), cv2.IMREAD_GRAYSCALE) > 127
            ref, left_out = ransac_reference(raw, shift)
        elif p.with_suffix(".json").exists():
            ref = _labelme_mask(p.with_suffix(".json"), shape)
        elif p.with_name(p.stem + ".mask.png").exists():
            ref = cv2.imread(str(p.with_name(p.stem + ".mask.png")), cv2.IMREAD_GRAYSCALE) > 0
        else:
            ref = np.zeros(shape, bool)
        items.append((p.stem, rgb, ref, left_out))
    return items


def score(pred, ref, left_out, tol_px: float) -> dict:
    """Tolerant counts of one photo (see the module's docstring)."""
    tol = max(1, int(round(tol_px)))
    near = _dilate(ref, tol)
    scored = ~left_out | near
    p = pred & scored
    core = _erode(ref, max(1, tol // 2))
    core = np.where(core.any(), core, ref)  # bars thinner than the erosion keep their pixels
    bg = ~near & ~left_out
    return {
        "pred": int(p.sum()),
        "pred_near": int((p & near).sum()),
        "core": int(core.sum()),
        "core_hit": int((core & pred).sum()),
        "bg": int(bg.sum()),
        "bg_marked": int((bg & pred).sum()),
        "pixels": int(pred.size),
        "marked": int(pred.sum()),
        "ref": int(ref.sum()),
    }


def summary(c: dict) -> dict:
    prec = c["pred_near"] / c["pred"] if c["pred"] else float("nan")
    rec = c["core_hit"] / c["core"] if c["core"] else float("nan")
    d = 2 * prec * rec / (prec + rec) if prec + rec > 0 else float("nan")
    return {
        "marked %": 100 * c["marked"] / c["pixels"],
        "ref %": 100 * c["ref"] / c["pixels"],
        "precision %": 100 * prec,
        "recall %": 100 * rec,
        "IoU %": 100 * d / (2 - d),
        "Dice %": 100 * d,
        "bg marked %": 100 * c["bg_marked"] / max(c["bg"], 1),
    }


def _fmt(v):
    return f"{v:7.2f}" if np.isfinite(v) else "    n/a"


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--set", action="append", default=[], metavar="NAME=FOLDER", required=True)
    ap.add_argument(
        "--ref-shift",
        action="append",
        default=[],
        metavar="NAME=DX,DY",
        help="move a set's rough reference masks by DX, DY px (dtu: 10,-8)",
    )
    ap.add_argument("--models", nargs="*", help="ONNX files (default: the shipped model)")
    ap.add_argument("--tol-px", type=float, default=4.0, help="tolerance at 640 px of width")
    ap.add_argument("--tiled", action="store_true", help="predict_proba(tiled=True) masks")
    ap.add_argument("--no-flips", action="store_true", help="without the sidecar's test-time flips")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--per-image", action="store_true")
    ap.add_argument("--save", default=None, help="folder for the predicted masks (PNG)")
    ap.add_argument(
        "--scales",
        default="1",
        help="comma-separated factors the photo is resized by before the network; their probability maps "
        "(brought back to the photo's size) are averaged (training/README.md, 'At inference')",
    )
    ap.add_argument(
        "--straight-px",
        type=int,
        default=0,
        help="keep only the mask's parts that survive an opening by a line this long (px at 640 px of "
        "width) in one of 12 directions (0: off)",
    )
    ap.add_argument(
        "--threshold", type=float, default=None, help="the probability a pixel needs (default: the model's)"
    )
    ap.add_argument(
        "--hysteresis",
        type=float,
        default=0.0,
        help="also keep pixels above this probability connected to one above the threshold (0: off)",
    )
    ap.add_argument(
        "--normalise",
        default="none",
        help="the photo's colours before the network: none, grayworld, stretch, clahe or gammaG (e.g. gamma0.8)",
    )
    args = ap.parse_args(argv)
    if not re.fullmatch(r"none|grayworld|stretch|clahe|gamma[0-9.]+", args.normalise):
        sys.exit(f"--normalise {args.normalise}: expected none, grayworld, stretch, clahe or gammaG (e.g. gamma0.8)")
    scales = [float(v) for v in args.scales.split(",")]
    if not scales or min(scales) <= 0:
        sys.exit(f"--scales {args.scales}: expected positive factors, e.g. 1,0.75")
    shifts = {k: tuple(float(v) for v in s.split(",")) for k, s in (a.split("=", 1) for a in args.ref_shift)}
    sets = {}
    for a in args.set:
        name, folder = a.split("=", 1)
        sets[name] = load_set(Path(folder), shifts.get(name, (0, 0)))
        if not sets[name]:
            sys.exit(f"--set {a}: no photos found")
    paths = [Path(p) for p in args.models] if args.models else [ROOT / "rebarlib/models/rebar_seg.onnx"]
    cols = ["marked %", "ref %", "precision %", "recall %", "IoU %", "Dice %", "bg marked %"]
    print(
        f"# Real-photo benchmark: tolerance {args.tol_px:g} px at 640 px width, "
        f"{'tiled' if args.tiled else 'whole image'}, flips {'off' if args.no_flips else 'as sidecar'}"
    )
    print(f"{'model':28s} {'set':8s} {'n':>3s} " + " ".join(f"{c[:11]:>11s}" for c in cols) + "   ms/img")
    for path in paths:
        model = SegmentationModel(path, threads=args.threads)
        for name, items in sets.items():
            tot, ms = {}, []
            for stem, rgb, ref, left_out in items:
                t0 = time.perf_counter()
                proba = _multi_scale(
                    model, _normalised(rgb, args.normalise), scales, tiled=args.tiled, flips=not args.no_flips
                )
                ms.append(1000 * (time.perf_counter() - t0))
                thr = model.threshold if args.threshold is None else args.threshold
                pred = _hysteresis(proba, args.hysteresis, thr) if args.hysteresis > 0 else proba > thr
                if args.straight_px > 0:
                    pred = _straight_parts(pred, args.straight_px * rgb.shape[1] / 640)
                c = score(pred, ref, left_out, args.tol_px * rgb.shape[1] / 640)
                tot = {k: tot.get(k, 0) + v for k, v in c.items()}
                if args.per_image:
                    s = summary(c)
                    print(f"  {stem:26s} {name:8s}     " + " ".join(f"{_fmt(s[k]):>11s}" for k in cols))
                if args.save:
                    out = Path(args.save) / path.stem / name
                    out.mkdir(parents=True, exist_ok=True)
                    cv2.imwrite(str(out / f"{stem}.png"), pred.astype(np.uint8) * 255)
            s = summary(tot)
            print(
                f"{path.stem[:28]:28s} {name:8s} {len(items):3d} "
                + " ".join(f"{_fmt(s[k]):>11s}" for k in cols)
                + f"   {np.median(ms):6.0f}"
            )


if __name__ == "__main__":
    main()
