"""Domain-randomised training scenes for the rebar segmentation network: a fast 2-D compositor.

The shipped network learnt our renderer's look (issue 57): one formwork texture family, one
light model, bars of a few colours. Real photos vary the ground, the light, the bars' surface,
the clutter and the camera far more. Rendering all that in 3-D is too slow on a CPU, so this
module composes scenes in 2-D, each one from ``numpy.random.default_rng([seed, index])``:

* a **background** of 1-3 procedural textures blended by noise masks (plywood, film-faced
  board, plastic sheeting, concrete and blinding, soil, gravel, sand, grass, steel deck,
  sawdust, debris, snow; puddles on top; sky and buildings behind cages and starter bars), each
  with random colours, contrasts and scales: statistics, not a fixed palette;
* **bars** as shaded strips under a random homography (a slab mesh in perspective, a beam or
  column cage from the side, starter bars against the sky, a loose pile), with mill scale,
  black, rust, dust, concrete splashes, epoxy or zinc, ribs or none, 3-80 px wide at full
  resolution, casting shadows on the ground;
* **clutter** that is not rebar, under and over the bars: tie wire, spacers, conduits and
  hoses, cables, timber, boards and tags, boots and legs, tools;
* **light**: overcast, low sun with hard shadows, flash, night floodlight, colour temperature,
  exposure; **camera**: motion and focus blur, noise, white balance, vignetting, tone mapping,
  JPEG.

A scene is composed at full resolution (``FULL`` × ``FULL``) with its exact mask (a pixel is
rebar where a bar covers more than half of it and nothing lies over it), then area-resized to
half, as ``SegmentationModel`` feeds a photo to the network (sidecar ``input.scale`` 0.5).

``python training/domain_random.py --work .segdata_dr --n 2000`` writes ``dr/NNNNN.jpg`` (the
network's input, JPEG 92) and ``dr/NNNNN.png`` (the full-resolution mask, 1 bit per pixel);
files already there are kept, so an interrupted run resumes.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import cv2
import numpy as np

DR_SEED = 20261126
FULL = 640  # side of a composed scene, full-resolution pixels; the stored input is half


# ---------------------------------------------------------------------------------------------
# noise and textures (float32 images in 0..1, linear light)


def fractal(rng, h, w, scale, octaves=4, persistence=0.5):
    """Smooth random field in about -1..1: octaves of bicubically enlarged white noise, the
    coarsest with cells of ``scale`` px."""
    out = np.zeros((h, w), np.float32)
    amp, total = 1.0, 0.0
    for _ in range(octaves):
        cells = max(2.0, scale)
        gh, gw = int(h / cells) + 3, int(w / cells) + 3
        g = rng.standard_normal((gh, gw)).astype(np.float32)
        big = cv2.resize(g, (int(gw * cells), int(gh * cells)), interpolation=cv2.INTER_CUBIC)
        out += amp * big[:h, :w]
        total += amp
        amp *= persistence
        scale /= 2
    return out / (total * 0.7)


def _colour(rng, base, jitter=0.25, wild=0.08):
    """A colour near ``base`` (RGB 0..1); with probability ``wild`` any colour at all."""
    if rng.random() < wild:
        return rng.uniform(0.05, 0.9, 3).astype(np.float32)
    c = np.asarray(base, np.float32) * rng.uniform(1 - jitter, 1 + jitter, 3)
    return np.clip(c * rng.uniform(0.6, 1.4), 0.01, 1).astype(np.float32)


def _two_tone(rng, h, w, c1, c2, scale, contrast):
    t = 0.5 + 0.5 * np.clip(contrast * fractal(rng, h, w, scale), -1, 1)
    return c1 * (1 - t[..., None]) + c2 * t[..., None]


def tex_concrete(rng, h, w):
    grey = rng.uniform(0.25, 0.75)
    c = _colour(rng, (grey, grey * 0.98, grey * 0.94), 0.08)
    img = c * (1 + rng.uniform(0.05, 0.25) * fractal(rng, h, w, rng.uniform(20, 300)))[..., None]
    img *= (1 + rng.uniform(0.02, 0.12) * rng.standard_normal((h, w)).astype(np.float32))[..., None]
    pores = rng.random((h, w)) < rng.uniform(0, 0.01)
    pores = cv2.dilate(pores.astype(np.uint8), np.ones((2, 2), np.uint8)) > 0
    img[pores] *= rng.uniform(0.3, 0.7)
    return img


def tex_wood(rng, h, w, film=False):
    if film:
        base = rng.choice(
            [(0.35, 0.2, 0.12), (0.12, 0.1, 0.09), (0.5, 0.35, 0.1), (0.45, 0.12, 0.08), (0.6, 0.55, 0.4)]
        )
        c = _colour(rng, base, 0.2)
        img = c * (1 + 0.08 * fractal(rng, h, w, rng.uniform(50, 400)))[..., None]
        sheen = np.clip(fractal(rng, h, w, 400, 2), 0, 1) * rng.uniform(0, 0.25)
        img = img + sheen[..., None]
    else:
        c1 = _colour(rng, (0.75, 0.55, 0.35), 0.2)
        c2 = c1 * rng.uniform(0.55, 0.85)
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        a = rng.uniform(0, math.pi)
        u = xx * math.cos(a) + yy * math.sin(a)
        warp = fractal(rng, h, w, rng.uniform(40, 200)) * rng.uniform(5, 40)
        t = 0.5 + 0.5 * np.sin((u + warp) * 2 * math.pi / rng.uniform(4, 30))
        img = c1 * (1 - t[..., None] * 0.6) + c2 * (t[..., None] * 0.6)
    if rng.random() < 0.5:  # panel seams
        pitch = rng.uniform(150, 600)
        a = rng.uniform(0, math.pi)
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        u = (xx * math.cos(a) + yy * math.sin(a)) % pitch
        img[u < rng.uniform(1, 3)] *= rng.uniform(0.3, 0.7)
    return img


def tex_plastic(rng, h, w):
    c = _colour(rng, rng.choice([(0.05, 0.05, 0.06), (0.15, 0.3, 0.6), (0.85, 0.85, 0.85), (0.6, 0.62, 0.6)]), 0.15)
    ridges = 1 - np.abs(fractal(rng, h, w, rng.uniform(30, 200), 3))
    img = c * (0.7 + 0.3 * ridges)[..., None]
    return img + (np.clip(ridges - 0.8, 0, 1) * rng.uniform(0, 2))[..., None]


def tex_ground(rng, h, w, kind):
    bases = {
        "soil": (0.3, 0.2, 0.12),
        "sand": (0.7, 0.6, 0.42),
        "snow": (0.9, 0.92, 0.97),
        "sawdust": (0.78, 0.62, 0.4),
    }
    c = _colour(rng, bases[kind], 0.15)
    img = _two_tone(rng, h, w, c * 0.7, c * 1.15, rng.uniform(10, 200), rng.uniform(0.5, 1.5))
    fine = rng.uniform(0.03, 0.2) * rng.standard_normal((h, w)).astype(np.float32)
    img *= (1 + cv2.GaussianBlur(fine, (0, 0), rng.uniform(0.5, 1.5)))[..., None]
    if kind == "snow":
        img = img * 0.9 + np.float32([0.0, 0.02, 0.08]) * (fractal(rng, h, w, 150)[..., None] > 0)
    if kind == "sawdust":
        flakes = rng.random((h, w)) < 0.02
        img[flakes] = img[flakes] * 0.3 + 0.7 * np.float32([0.95, 0.85, 0.6])
    return img


def tex_gravel(rng, h, w):
    img = _colour(rng, (0.35, 0.33, 0.3), 0.2) * np.ones((h, w, 3), np.float32)
    size = rng.uniform(3, 25)
    for _ in range(min(2500, int(h * w / size**2 * 0.8))):
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        ax = (int(size * rng.uniform(0.4, 1)), int(size * rng.uniform(0.3, 0.8)))
        col = tuple(float(v) for v in _colour(rng, (0.5, 0.48, 0.45), 0.35, 0.02))
        cv2.ellipse(img, (int(cx), int(cy)), ax, rng.uniform(0, 180), 0, 360, col, -1)
    shade = 1 + 0.15 * fractal(rng, h, w, size, 2)
    return img * shade[..., None]


def tex_grass(rng, h, w):
    img = tex_ground(rng, h, w, "soil")
    for _ in range(min(3000, int(h * w / rng.uniform(40, 400)))):
        x, y = rng.uniform(0, w), rng.uniform(0, h)
        ln, a = rng.uniform(5, 40), rng.normal(-math.pi / 2, 0.6)
        col = _colour(rng, rng.choice([(0.2, 0.45, 0.1), (0.55, 0.55, 0.25), (0.4, 0.35, 0.2)]), 0.3, 0.0)
        cv2.line(
            img,
            (int(x), int(y)),
            (int(x + ln * math.cos(a)), int(y + ln * math.sin(a))),
            tuple(float(v) for v in col),
            int(rng.integers(1, 3)),
            cv2.LINE_AA,
        )
    return img


def tex_steel_deck(rng, h, w):
    c = _colour(rng, (0.55, 0.57, 0.6), 0.15)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    a = rng.uniform(0, math.pi)
    u = (xx * math.cos(a) + yy * math.sin(a)) / rng.uniform(20, 120)
    prof = np.clip(np.abs((u % 1.0) - 0.5) * 4 - 0.5, -0.5, 0.5)
    img = c * (0.85 + 0.3 * prof)[..., None]
    return img * (1 + 0.05 * fractal(rng, h, w, 100))[..., None]


def tex_sky(rng, h, w):
    top = _colour(rng, rng.choice([(0.35, 0.55, 0.9), (0.75, 0.78, 0.82), (0.9, 0.9, 0.92)]), 0.1)
    bottom = np.clip(top * 1.1 + 0.1, 0, 1)
    t = np.linspace(0, 1, h, dtype=np.float32)[:, None, None]
    img = top * (1 - t) + bottom * t + np.zeros((1, w, 1), np.float32)
    clouds = np.clip(fractal(rng, h, w, rng.uniform(80, 400)), 0, 1)[..., None]
    img = img * (1 - clouds * rng.uniform(0, 0.7)) + clouds * rng.uniform(0, 0.7)
    for _ in range(int(rng.integers(0, 6))):  # buildings, with windows
        x0, x1 = sorted(rng.uniform(-50, w + 50, 2))
        y0 = rng.uniform(0.1 * h, 0.9 * h)
        col = tuple(float(v) for v in _colour(rng, (0.5, 0.48, 0.45), 0.4, 0.2))
        cv2.rectangle(img, (int(x0), int(y0)), (int(x1), h), col, -1)
        pitch = rng.uniform(8, 40)
        wc = tuple(float(v) for v in _colour(rng, (0.3, 0.35, 0.4), 0.5))
        for yy in np.arange(y0 + pitch / 2, h, pitch):
            for xx in np.arange(x0 + pitch / 2, x1 - pitch / 2, pitch):
                cv2.rectangle(img, (int(xx), int(yy)), (int(xx + pitch / 2), int(yy + pitch / 2)), wc, -1)
    return img


GROUNDS = ("concrete", "plywood", "film", "plastic", "soil", "sand", "gravel", "grass", "steel_deck", "sawdust", "snow")


def texture(rng, h, w, kind):
    """One background texture (H, W, 3) float32 of ``kind`` (one of ``GROUNDS`` or "sky")."""
    if kind == "concrete":
        return tex_concrete(rng, h, w)
    if kind in ("plywood", "film"):
        return tex_wood(rng, h, w, film=kind == "film")
    if kind == "plastic":
        return tex_plastic(rng, h, w)
    if kind == "gravel":
        return tex_gravel(rng, h, w)
    if kind == "grass":
        return tex_grass(rng, h, w)
    if kind == "steel_deck":
        return tex_steel_deck(rng, h, w)
    if kind == "sky":
        return tex_sky(rng, h, w)
    return tex_ground(rng, h, w, kind)


def background(rng, h, w, kinds=None):
    """1-3 ground textures blended by soft noise masks, sometimes with a puddle or debris."""
    kinds = kinds or list(rng.choice(GROUNDS, int(rng.integers(1, 4)), replace=False))
    img = texture(rng, h, w, kinds[0])
    for k in kinds[1:]:
        m = fractal(rng, h, w, rng.uniform(100, 500), 3) + rng.uniform(-0.5, 0.5)
        m = np.clip(m * rng.uniform(2, 20), 0, 1)[..., None]
        img = img * (1 - m) + texture(rng, h, w, k) * m
    if rng.random() < 0.15:  # a puddle: darker, smoother, reflecting the sky
        m = np.clip((fractal(rng, h, w, rng.uniform(80, 300), 3) - 0.4) * 8, 0, 1)[..., None]
        wet = cv2.GaussianBlur(img, (0, 0), 2) * 0.45 + _colour(rng, (0.3, 0.35, 0.45)) * 0.25
        img = img * (1 - m) + wet * m
    if rng.random() < 0.3:  # debris: fragments of any colour
        for _ in range(int(rng.integers(3, 30))):
            pts = rng.uniform(0, 1, (int(rng.integers(3, 7)), 2)) * rng.uniform(5, 40)
            pts += rng.uniform(0, [w, h])
            col = tuple(float(v) for v in _colour(rng, (0.5, 0.5, 0.5), 0.5, 0.3))
            cv2.fillPoly(img, [pts.astype(np.int32)], col, cv2.LINE_AA)
    return img.astype(np.float32)


# ---------------------------------------------------------------------------------------------
# bars and tubes: shaded strips, possibly ribbed

BAR_STYLES = {  # albedo (RGB, linear 0..1), texture contrast, specular, rust patches
    "mill_scale": ((0.22, 0.24, 0.28), 0.15, 0.25, 0.0),
    "black": ((0.07, 0.07, 0.08), 0.2, 0.2, 0.0),
    "rust_light": ((0.32, 0.24, 0.2), 0.25, 0.12, 0.5),
    "rust_heavy": ((0.38, 0.18, 0.08), 0.35, 0.05, 1.0),
    "dusty": ((0.45, 0.42, 0.38), 0.2, 0.05, 0.2),
    "splashed": ((0.25, 0.24, 0.24), 0.2, 0.1, 0.0),
    "epoxy": ((0.12, 0.42, 0.2), 0.08, 0.45, 0.0),
    "galvanised": ((0.55, 0.57, 0.58), 0.25, 0.6, 0.0),
}
RUST = np.float32([0.42, 0.2, 0.08])
SPLASH = np.float32([0.6, 0.6, 0.57])


def bar_style(rng, name=None):
    """A bar surface: a style of ``BAR_STYLES`` with its colours and ribs jittered."""
    name = name or str(rng.choice(list(BAR_STYLES)))
    albedo, contrast, spec, rust = BAR_STYLES[name]
    return {
        "name": name,
        "albedo": _colour(rng, albedo, 0.2, 0.03),
        "contrast": contrast * rng.uniform(0.5, 1.5),
        "spec": spec * rng.uniform(0.3, 1.5),
        "rust": rust * rng.uniform(0.3, 1.0),
        "splash": name == "splashed" or rng.random() < 0.1,
        "ribs": rng.random() < 0.75,
        "rib_pitch": rng.uniform(0.5, 0.9),
        "rib_angle": rng.uniform(-0.9, 0.9),
        "rib_height": rng.uniform(0.04, 0.12),
        "rib_contrast": rng.uniform(0.15, 0.6),
    }


def draw_strip(img, cover, p0, p1, w0, w1, style, light, tile, rng):
    """Draw a straight shaded strip from ``p0`` to ``p1`` (x, y full-resolution pixels), ``w0``
    to ``w1`` px wide, over ``img`` (blended by coverage); ``cover`` (or None) takes the
    maximum coverage. ``light``: dict with the cross-section light ``lx``, ``lz``, ``ambient``
    and the light's colour; ``tile``: a noise tile for the surface texture."""
    h, w = img.shape[:2]
    p0, p1 = np.asarray(p0, np.float32), np.asarray(p1, np.float32)
    d = p1 - p0
    length = float(np.hypot(*d))
    if length < 1:
        return
    d /= length
    n = np.float32([-d[1], d[0]])
    r = max(w0, w1) * 0.62 + 2
    corners = np.stack([p0 - d * 2 + n * r, p1 + d * 2 + n * r, p1 + d * 2 - n * r, p0 - d * 2 - n * r])
    x0, y0 = np.maximum(np.floor(corners.min(0)).astype(int), 0)
    x1, y1 = np.minimum(np.ceil(corners.max(0)).astype(int) + 1, [w, h])
    if x0 >= x1 or y0 >= y1:
        return
    canvas = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillPoly(canvas, [np.round(corners - [x0, y0]).astype(np.int32)], 1)
    ys, xs = np.nonzero(canvas)
    if len(ys) == 0:
        return
    px = np.stack([xs + x0 + 0.5, ys + y0 + 0.5], 1).astype(np.float32) - p0
    s, t = px @ d, px @ n
    hw = 0.5 * (w0 + (w1 - w0) * np.clip(s / length, 0, 1))
    rib = np.zeros_like(s)
    if style.get("ribs"):
        period = max(2.0, style["rib_pitch"] * 2 * float(np.mean([w0, w1])))
        phase = (s + t * style["rib_angle"]) / period
        rib = np.maximum(0, np.cos(2 * np.pi * phase)) ** 3
        hw = hw * (1 + style["rib_height"] * rib)
    cov = np.clip(hw - np.abs(t) + 0.5, 0, 1) * np.clip(s + 0.5, 0, 1) * np.clip(length - s + 0.5, 0, 1)
    keep = cov > 0
    s, t, hw, rib, cov, ys, xs = (a[keep] for a in (s, t, hw, rib, cov, ys, xs))
    u = np.clip(t / np.maximum(hw, 0.5), -1, 1)
    nz = np.sqrt(1 - u**2)
    shade = light["ambient"] + light["diffuse"] * np.maximum(0, u * light["lx"] + nz * light["lz"])
    shade *= 1 + style.get("rib_contrast", 0) * (rib - 0.3) * (1 if style.get("ribs") else 0)
    T = tile.shape[0]
    ti = (np.abs(s).astype(np.int32) % T, np.abs(t * 1.7 + 97).astype(np.int32) % T)
    tex = tile[ti]
    col = style["albedo"] * (1 + style["contrast"] * tex)[:, None]
    if style.get("rust", 0) > 0:
        patch = np.clip((tile[(ti[0] // 7 + 31) % T, (ti[1] // 7 + 53) % T] + 1 - 2 * style["rust"]) * 3, 0, 1)[:, None]
        col = col * (1 - patch) + RUST * (1 + 0.3 * tex)[:, None] * patch
    if style.get("splash"):
        sp = (tile[(ti[0] // 3 + 11) % T, (ti[1] // 3 + 7) % T] > 0.9)[:, None]
        col = np.where(sp, SPLASH, col)
    spec = style["spec"] * np.exp(-(((u - light["u_spec"]) / 0.18) ** 2))
    out = col * shade[:, None] * light["colour"] + (spec[:, None] * light["colour"])
    a = cov[:, None]
    Y, X = ys + y0, xs + x0
    img[Y, X] = img[Y, X] * (1 - a) + out * a
    if cover is not None:
        cover[Y, X] = np.maximum(cover[Y, X], cov)


def draw_tube(img, rng, light, tile, pts, width, colour, corrugated=False):
    """A smooth tube (conduit, hose, cable) along the polyline ``pts``: not rebar."""
    style = {
        "albedo": colour,
        "contrast": 0.05,
        "spec": rng.uniform(0.1, 0.6),
        "rust": 0,
        "ribs": corrugated,
        "rib_pitch": rng.uniform(0.2, 0.4),
        "rib_angle": 0.0,
        "rib_height": 0.05,
        "rib_contrast": 0.4,
    }
    for a, b in zip(pts[:-1], pts[1:]):
        draw_strip(img, None, a, b, width, width, style, light, tile, rng)


def _curve(rng, p0, p1, bend, n=12):
    """Points of a quadratic Bezier from p0 to p1, bulging by ``bend`` px."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    c = (p0 + p1) / 2 + np.array([-d[1], d[0]]) / max(np.hypot(*d), 1) * bend
    t = np.linspace(0, 1, n)[:, None]
    return (1 - t) ** 2 * p0 + 2 * (1 - t) * t * c + t**2 * p1


# ---------------------------------------------------------------------------------------------
# layouts: where the bars lie (a list of (p0, p1, w0, w1, layer) in full-resolution pixels)


def _homography(rng, size, tilt):
    """A random view of a plane: rotation, scale about 1, perspective up to ``tilt``."""
    a = rng.uniform(0, 2 * math.pi)
    c, s = math.cos(a), math.sin(a)
    k = rng.uniform(0.8, 1.25)
    half = size / 2
    rot = np.array([[c * k, -s * k, 0], [s * k, c * k, 0], [0, 0, 1]])
    persp = np.array([[1, 0, 0], [0, 1, 0], [rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt), 1]])
    shift = np.array([[1, 0, half], [0, 1, half], [0, 0, 1]])
    return shift @ persp @ rot


def _project(H, pts):
    q = np.c_[pts, np.ones(len(pts))] @ H.T
    det = abs(np.linalg.det(H))
    return q[:, :2] / q[:, 2:], np.sqrt(det / np.abs(q[:, 2]) ** 3)


def _mesh(rng, size, H, width, spacing, angle, reach, layer, ends=0.0):
    """A family of parallel bars on the plane (world px), projected through ``H``."""
    bars = []
    d = np.array([math.cos(angle), math.sin(angle)])
    n = np.array([-d[1], d[0]])
    off = rng.uniform(0, spacing)
    for k in np.arange(-reach, reach, spacing):
        if rng.random() < 0.05:  # a bar missing
            continue
        c = n * (k + off + rng.normal(0, spacing * 0.03))
        lo, hi = -reach, reach
        if rng.random() < ends:  # the bar ends inside the view
            lo = rng.uniform(-reach, 0) if rng.random() < 0.5 else lo
            hi = rng.uniform(0, reach) if rng.random() < 0.5 else hi
        (q0, q1), (s0, s1) = _project(H, np.array([c + d * lo, c + d * hi]))
        if np.all(np.isfinite([q0, q1])) and min(s0, s1) > 0.2:
            bars.append((q0, q1, width * s0, width * s1, layer))
    return bars


def _log_uniform(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def layout_slab(rng, size):
    """One or two meshes of two bar families in perspective (the upper and lower layers)."""
    H = _homography(rng, size, rng.uniform(0, 0.0012))
    reach = size * 2.5
    bars = []
    w = _log_uniform(rng, 3, 60)
    layers = 2 if rng.random() < 0.35 else 1
    for layer in range(layers):
        wl = w * (rng.uniform(0.6, 1.0) if layer else 1.0)
        a = rng.uniform(0, math.pi)
        for fam in range(2):
            sp = max(3.5 * wl, _log_uniform(rng, 25, 300))
            ang = a + fam * (math.pi / 2 + rng.normal(0, 0.05))
            bars += _mesh(
                rng,
                size,
                H,
                wl * rng.uniform(0.7, 1.3),
                sp,
                ang,
                reach,
                layer=2 * (layers - 1 - layer) + fam,
                ends=0.15,
            )
    return bars, "ground"


def layout_cage(rng, size):
    """A beam or column cage from the side: main bars one way, links across."""
    H = _homography(rng, size, rng.uniform(0, 0.0008))
    w_main = _log_uniform(rng, 6, 80)
    w_link = w_main * rng.uniform(0.35, 0.8)
    reach = size * 1.6
    a = rng.uniform(-0.3, 0.3) + (math.pi / 2 if rng.random() < 0.5 else 0)
    span = rng.uniform(0.3, 1.0) * size
    n_main = int(rng.integers(2, 7))
    bars = []
    d = np.array([math.cos(a), math.sin(a)])
    n = np.array([-d[1], d[0]])
    offs = np.sort(rng.uniform(-span / 2, span / 2, n_main))
    for k, o in enumerate(offs):
        (q0, q1), (s0, s1) = _project(H, np.array([n * o - d * reach, n * o + d * reach]))
        bars.append((q0, q1, w_main * s0, w_main * s1, 1 + (k % 2)))
    pitch = max(3 * w_link, _log_uniform(rng, 30, 250))
    for t in np.arange(-reach, reach, pitch):
        ext = span / 2 + w_main
        (q0, q1), (s0, s1) = _project(H, np.array([d * t - n * ext, d * t + n * ext]))
        bars.append((q0, q1, w_link * s0, w_link * s1, 0 if rng.random() < 0.4 else 3))
    return bars, "sky" if rng.random() < 0.6 else "ground"


def layout_starters(rng, size):
    """Starter bars standing up against the sky, ending inside the view."""
    bars = []
    rows = int(rng.integers(1, 3))
    for row in range(rows):
        w = _log_uniform(rng, 4, 60) * (0.6 if row else 1.0)
        n = int(rng.integers(2, 10))
        xs = np.sort(rng.uniform(-0.1 * size, 1.1 * size, n))
        for x in xs:
            top = rng.uniform(0.02, 0.6) * size
            lean = rng.normal(0, 0.05) * size
            bottom = size * rng.uniform(1.0, 1.3)
            bars.append((np.array([x + lean, top]), np.array([x, bottom]), w * 0.95, w, 1 - row))
    return bars, "sky"


def layout_pile(rng, size):
    """Loose bars in all directions (a stockpile, offcuts)."""
    bars = []
    for k in range(int(rng.integers(1, 12))):
        p0 = rng.uniform(-0.2, 1.2, 2) * size
        a = rng.uniform(0, math.pi)
        ln = rng.uniform(0.2, 2.0) * size
        p1 = p0 + ln * np.array([math.cos(a), math.sin(a)])
        w = _log_uniform(rng, 3, 70)
        bars.append((p0, p1, w, w * rng.uniform(0.85, 1.15), k))
    return bars, "ground"


LAYOUTS = {
    "slab": (layout_slab, 0.5),
    "cage": (layout_cage, 0.17),
    "starters": (layout_starters, 0.1),
    "pile": (layout_pile, 0.13),
    "none": (None, 0.1),
}


# ---------------------------------------------------------------------------------------------
# light, clutter, camera

KELVIN = {
    2700: (1.0, 0.7, 0.42),
    4000: (1.0, 0.86, 0.72),
    5500: (1.0, 0.97, 0.93),
    6500: (0.95, 0.97, 1.0),
    9000: (0.8, 0.88, 1.0),
}


def _light(rng, mode):
    """The light of a scene: colour, exposure and the cross-section shading of its bars."""
    temp = KELVIN[int(rng.choice(list(KELVIN)))] if rng.random() < 0.6 else KELVIN[5500]
    colour = np.float32(temp) * rng.uniform(0.9, 1.1, 3).astype(np.float32)
    lx = rng.uniform(-0.95, 0.95)
    light = {
        "mode": mode,
        "colour": colour,
        "lx": lx,
        "lz": math.sqrt(1 - lx**2),
        "u_spec": lx * 0.5 + rng.normal(0, 0.1),
        "sun": rng.uniform(0, 2 * math.pi),
    }
    if mode == "overcast":
        light.update(ambient=rng.uniform(0.5, 0.8), diffuse=rng.uniform(0.2, 0.5))
    elif mode == "sun":
        light.update(ambient=rng.uniform(0.15, 0.45), diffuse=rng.uniform(0.7, 1.1))
    elif mode == "flash":
        light.update(
            ambient=rng.uniform(0.1, 0.3), diffuse=rng.uniform(0.8, 1.2), lx=0.0, lz=1.0, u_spec=rng.normal(0, 0.1)
        )
    else:  # night floodlight
        light.update(
            ambient=rng.uniform(0.05, 0.2),
            diffuse=rng.uniform(0.6, 1.0),
            colour=np.float32(KELVIN[2700]) * rng.uniform(0.8, 1.2, 3).astype(np.float32),
        )
    return light


def _soft_shapes(rng, size, n, big=True):
    """A soft-edged (0..1) map of ``n`` random shadow casters: half-planes, people, boards."""
    m = np.zeros((size, size), np.float32)
    for _ in range(n):
        kind = rng.random()
        if kind < 0.35 and big:  # the edge of a building's or a slab's shadow
            a, c = rng.uniform(0, 2 * math.pi), rng.uniform(0.2, 0.8) * size
            yy, xx = np.mgrid[0:size, 0:size]
            m = np.maximum(
                m, ((xx - size / 2) * math.cos(a) + (yy - size / 2) * math.sin(a) > c - size / 2).astype(np.float32)
            )
        elif kind < 0.7:  # a person: head, body, legs
            x, y, s = rng.uniform(0, size), rng.uniform(0, size), rng.uniform(0.1, 0.5) * size
            cv2.ellipse(m, (int(x), int(y)), (int(s * 0.12), int(s * 0.15)), 0, 0, 360, 1, -1)
            cv2.rectangle(m, (int(x - s * 0.18), int(y + s * 0.12)), (int(x + s * 0.18), int(y + s * 0.6)), 1, -1)
            for lx in (-0.1, 0.1):
                cv2.line(
                    m,
                    (int(x + lx * s), int(y + s * 0.6)),
                    (int(x + lx * s * 1.5), int(y + s * 1.1)),
                    1,
                    max(1, int(s * 0.09)),
                )
        else:  # a board or formwork edge
            pts = rng.uniform(-0.2, 1.2, (4, 2)) * size
            cv2.fillPoly(m, [pts.astype(np.int32)], 1)
    return m


def add_clutter(img, cover, rng, light, tile, n, over):
    """``n`` things that are not rebar; ``over``: they lie on the bars (the mask loses them)."""
    size = img.shape[0]
    for _ in range(n):
        kind = rng.choice(["wire", "spacer", "tube", "cable", "timber", "board", "boot", "tool"])
        layer = np.zeros((size, size), np.float32)
        col = _colour(rng, (0.5, 0.5, 0.5), 0.5, 0.4)
        if kind in ("tube", "cable"):
            p0, p1 = rng.uniform(-0.2, 1.2, (2, 2)) * size
            w = rng.uniform(8, 45) if kind == "tube" else rng.uniform(2, 10)
            tcol = _colour(
                rng,
                rng.choice(
                    [
                        (0.85, 0.35, 0.05),
                        (0.1, 0.3, 0.7),
                        (0.9, 0.8, 0.1),
                        (0.05, 0.05, 0.05),
                        (0.85, 0.85, 0.85),
                        (0.7, 0.1, 0.1),
                        (0.5, 0.5, 0.52),
                    ]
                ),
                0.15,
                0.1,
            )
            before = img.copy()
            draw_tube(
                img,
                rng,
                light,
                tile,
                _curve(rng, p0, p1, rng.normal(0, 0.3) * size),
                w,
                tcol,
                corrugated=kind == "tube" and rng.random() < 0.4,
            )
            if over and cover is not None:
                cover[np.any(np.abs(img - before) > 1e-6, axis=2)] = 0
            continue
        x, y = rng.uniform(0, size, 2)
        s = rng.uniform(10, 160)
        if kind == "wire":
            pts = (np.cumsum(rng.normal(0, 4, (12, 2)), 0) + [x, y]).astype(np.int32)
            cv2.polylines(layer, [pts], False, 1, 1, cv2.LINE_AA)
            col = _colour(rng, (0.2, 0.2, 0.22), 0.3)
        elif kind in ("spacer", "boot"):
            cv2.ellipse(
                layer, (int(x), int(y)), (int(s * 0.3), int(s * 0.2)), rng.uniform(0, 180), 0, 360, 1, -1, cv2.LINE_AA
            )
            if kind == "boot":
                col = _colour(rng, (0.1, 0.1, 0.1), 0.5, 0.2)
        else:  # timber, board or tag, tool: a rotated rectangle (a tool: two)
            rect = ((x, y), (s * rng.uniform(0.3, 3), s * rng.uniform(0.1, 0.6)), rng.uniform(0, 180))
            cv2.fillPoly(layer, [cv2.boxPoints(rect).astype(np.int32)], 1, cv2.LINE_AA)
            if kind == "tool":
                rect2 = ((x, y), (s * 0.2, s * 0.8), rect[2])
                cv2.fillPoly(layer, [cv2.boxPoints(rect2).astype(np.int32)], 1, cv2.LINE_AA)
            if kind == "timber":
                col = _colour(rng, (0.7, 0.55, 0.35), 0.2)
            if kind == "board":
                col = _colour(rng, (0.9, 0.9, 0.88), 0.1, 0.3)
        shade = light["ambient"] + light["diffuse"] * light["lz"]
        bx, by, bw, bh = cv2.boundingRect((layer > 0).astype(np.uint8))
        if bw == 0:
            continue
        win = (slice(by, by + bh), slice(bx, bx + bw))
        a = layer[win][..., None]
        paint = (col * shade * light["colour"]) * (1 + 0.1 * tile[win][..., None])
        img[win] = img[win] * (1 - a) + paint * a
        if over and cover is not None:
            cover[win][layer[win] > 0.5] = 0


def _cast_bar_shadows(img, bars, rng, light):
    size = img.shape[0]
    m = np.zeros((size, size), np.float32)
    dist = rng.uniform(2, 40)
    off = dist * np.array([math.cos(light["sun"]), math.sin(light["sun"])])
    for p0, p1, w0, w1, _ in bars:
        a, b = np.asarray(p0) + off, np.asarray(p1) + off
        if np.all(np.abs(np.r_[a, b]) < 1e5):
            cv2.line(m, tuple(int(v) for v in a), tuple(int(v) for v in b), 1, max(1, int((w0 + w1) / 2)), cv2.LINE_AA)
    m = cv2.GaussianBlur(m, (0, 0), rng.uniform(0.5, 3) + dist / 15)
    img *= (1 - rng.uniform(0.3, 0.7) * m)[..., None]


def _apply_light(img, rng, light):
    size = img.shape[0]
    mode = light["mode"]
    if mode == "sun" and rng.random() < 0.7:
        m = cv2.GaussianBlur(_soft_shapes(rng, size, int(rng.integers(1, 4))), (0, 0), rng.uniform(0.7, 8))
        sky = np.float32([0.75, 0.85, 1.1])
        img *= 1 - (m * rng.uniform(0.4, 0.75))[..., None] * (2 - sky)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32) / size - 0.5
    if mode == "flash":
        cx, cy = rng.normal(0, 0.15, 2)
        img *= (1 / (1 + rng.uniform(1, 5) * ((xx - cx) ** 2 + (yy - cy) ** 2)))[..., None]
    elif mode == "night":
        a = rng.uniform(0, 2 * math.pi)
        grad = np.clip(0.6 + 0.8 * (xx * math.cos(a) + yy * math.sin(a)), 0.1, 1.2)
        img *= grad[..., None] * rng.uniform(0.2, 0.6)
    # auto exposure, often off: the mean linear level lands anywhere from dark to bright
    img *= math.exp(rng.uniform(math.log(0.05), math.log(0.5))) / max(float(img.mean()), 1e-3)


def _camera(img, rng, night):
    """Lens, sensor and processing, at full resolution: float linear in, uint8 sRGB out."""
    size = img.shape[0]
    if rng.random() < 0.4:  # vignetting
        yy, xx = np.mgrid[0:size, 0:size].astype(np.float32) / size - 0.5
        img *= (1 - rng.uniform(0.1, 0.6) * (xx**2 + yy**2) * 2)[..., None]
    if rng.random() < 0.2:  # motion blur
        k = np.zeros((15, 15), np.float32)
        ln = int(rng.integers(2, 8))
        a = rng.uniform(0, math.pi)
        cv2.line(
            k,
            (int(7 - ln * math.cos(a)), int(7 - ln * math.sin(a))),
            (int(7 + ln * math.cos(a)), int(7 + ln * math.sin(a))),
            1,
            1,
        )
        img = cv2.filter2D(img, -1, k / k.sum())
    if rng.random() < 0.3:  # focus
        img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.5, 2.5))
    img *= rng.uniform(0.85, 1.15, 3).astype(np.float32)  # white balance
    sigma = rng.uniform(0, 0.03) + (rng.uniform(0.01, 0.05) if night else 0)
    img = (
        img
        + rng.normal(0, sigma, img.shape[:2] + (1,)).astype(np.float32)
        + rng.normal(0, sigma / 2, img.shape).astype(np.float32)
    )
    # to display gamma, through a look-up table (linear 0..4 in 4096 steps)
    gamma = (np.arange(4096, dtype=np.float32) / 1023) ** (1 / rng.uniform(1.8, 2.6))
    img = gamma[np.clip(img * 1023, 0, 4095).astype(np.int32)]
    if rng.random() < 0.35:  # phone HDR: local contrast, lifted shadows
        small = cv2.resize(img, (size // 8, size // 8), interpolation=cv2.INTER_AREA)
        base = cv2.resize(cv2.GaussianBlur(small, (0, 0), rng.uniform(1.5, 5)), (size, size))
        img = base ** rng.uniform(0.6, 0.9) + rng.uniform(0.3, 1.2) * (img - base)
    out = np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8)
    if rng.random() < 0.5:  # an S-curve
        k = rng.uniform(3, 8)
        x = np.arange(256) / 255
        lo, hi = 1 / (1 + math.exp(k / 2)), 1 / (1 + math.exp(-k / 2))
        curve = (1 / (1 + np.exp(-k * (x - 0.5))) - lo) / (hi - lo)
        out = np.clip(curve * 255 + 0.5, 0, 255).astype(np.uint8)[out]
    if rng.random() < 0.7:
        q = int(rng.integers(35, 96))
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, q])
        out = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    return out


def _cracks(img, rng, n):
    """``n`` cracks: dark, jagged, branching lines 1-3 px wide (the dark cracks of real concrete
    and blinding, which a network of straight strips takes for thin bars)."""
    size = img.shape[0]
    m = np.zeros((size, size), np.float32)
    for _ in range(n):
        p = rng.uniform(0, size, 2)
        a = rng.uniform(0, 2 * math.pi)
        w = int(rng.integers(1, 4))
        tips = [(p, a, int(rng.integers(10, 60)))]
        while tips:
            p, a, steps = tips.pop()
            pts = [p.copy()]
            for _ in range(steps):
                a += rng.normal(0, 0.35)
                p = p + rng.uniform(3, 9) * np.array([math.cos(a), math.sin(a)])
                pts.append(p.copy())
                if rng.random() < 0.04 and len(tips) < 6:  # a branch
                    tips.append((p.copy(), a + rng.choice([-1, 1]) * rng.uniform(0.4, 1.2), int(rng.integers(5, 25))))
            cv2.polylines(m, [np.round(pts).astype(np.int32)], False, 1, w, cv2.LINE_AA)
    depth = rng.uniform(0.35, 0.85)
    img *= (1 - depth * m)[..., None]


def _weeds(img, rng, light):
    """A patch of weeds and grass: dense thin blades, many dark, some in shadow."""
    size = img.shape[0]
    cx, cy = rng.uniform(0, size, 2)
    r = rng.uniform(0.1, 0.6) * size
    shade = light["ambient"] + light["diffuse"] * light["lz"]
    for _ in range(int(rng.integers(100, 1500))):
        x, y = cx + rng.normal(0, r / 2), cy + rng.normal(0, r / 2)
        ln, a = rng.uniform(8, 70), rng.normal(-math.pi / 2, 0.9)
        bend = rng.normal(0, 0.3)
        pts = [(x, y)]
        for k in range(4):
            a += bend
            x, y = x + ln / 4 * math.cos(a), y + ln / 4 * math.sin(a)
            pts.append((x, y))
        col = _colour(
            rng, rng.choice([(0.15, 0.35, 0.08), (0.45, 0.45, 0.2), (0.3, 0.25, 0.15), (0.05, 0.08, 0.04)]), 0.3
        )
        col = col * shade * light["colour"] * rng.uniform(0.3, 1.2)
        cv2.polylines(
            img,
            [np.round(pts).astype(np.int32)],
            False,
            tuple(float(v) for v in col),
            int(rng.integers(1, 4)),
            cv2.LINE_AA,
        )


def _person(img, cover, rng, light, tile):
    """A person (behind the bars, or in front: then the mask loses what it covers): hair, a
    head, clothes of any colour (dark ones often), arms and legs."""
    size = img.shape[0]
    layer = np.zeros((size, size), np.float32)
    hair = np.zeros((size, size), np.float32)
    x, y, s = rng.uniform(0, size), rng.uniform(-0.2, 0.8) * size, rng.uniform(0.3, 1.5) * size
    head = (int(x), int(y)), (int(s * 0.06), int(s * 0.08))
    cv2.ellipse(layer, head[0], head[1], 0, 0, 360, 1, -1, cv2.LINE_AA)
    cv2.ellipse(hair, (head[0][0], head[0][1] - int(s * 0.02)), (int(s * 0.065), int(s * 0.07)), 0, 180, 360, 1, -1)
    body = np.zeros((size, size), np.float32)
    cv2.rectangle(body, (int(x - s * 0.13), int(y + s * 0.1)), (int(x + s * 0.13), int(y + s * 0.45)), 1, -1)
    for sx in (-1, 1):  # arms and legs
        cv2.line(
            body,
            (int(x + sx * s * 0.12), int(y + s * 0.12)),
            (int(x + sx * s * rng.uniform(0.15, 0.35)), int(y + s * rng.uniform(0.3, 0.5))),
            1,
            max(1, int(s * 0.06)),
        )
        cv2.line(
            body,
            (int(x + sx * s * 0.07), int(y + s * 0.45)),
            (int(x + sx * s * rng.uniform(0.05, 0.15)), int(y + s * 0.9)),
            1,
            max(1, int(s * 0.08)),
        )
    shade = light["ambient"] + light["diffuse"] * light["lz"]
    clothes = _colour(
        rng, rng.choice([(0.03, 0.03, 0.04), (0.1, 0.12, 0.2), (0.8, 0.35, 0.05), (0.4, 0.4, 0.4)]), 0.3, 0.3
    )
    skin = _colour(rng, rng.choice([(0.6, 0.42, 0.32), (0.35, 0.22, 0.15), (0.75, 0.55, 0.45)]), 0.1, 0.0)
    hair_col = _colour(rng, rng.choice([(0.02, 0.02, 0.02), (0.15, 0.08, 0.04), (0.5, 0.4, 0.25)]), 0.2, 0.0)
    streaks = 1 + 0.5 * np.abs(fractal(rng, size, size, rng.uniform(2, 6), 2))
    t = tile[:size, :size]
    for m, col, tex in ((body, clothes, 1 + 0.25 * t), (layer, skin, 1 + 0.05 * t), (hair, hair_col, streaks)):
        a = cv2.GaussianBlur(m, (0, 0), 0.7)[..., None]
        img[:] = img * (1 - a) + (col * shade * light["colour"] * tex[..., None]) * a
        if cover is not None:
            cover[m > 0.5] = 0


def _indoor(img, rng, light, tile):
    """A room behind the bars (a cage prefabricated in a workshop, a yard's office, a lab): a wall
    above a floor line, with tables and benches, shelves, boxes and screens, a window or a door,
    cables on the floor and the tables, sometimes people. Everything is flat-shaded: straight dark
    edges and strips that are not the shaded cylinder of a bar."""
    size = img.shape[0]
    shade = light["ambient"] + light["diffuse"] * light["lz"]
    lit = light["colour"] * shade
    t = tile[:size, :size, None]
    horizon = int(rng.uniform(0.35, 1.0) * size)
    wall = _colour(rng, rng.choice([(0.75, 0.74, 0.7), (0.55, 0.6, 0.62), (0.7, 0.65, 0.5), (0.3, 0.3, 0.32)]), 0.2)
    ramp = np.linspace(rng.uniform(0.7, 1.1), rng.uniform(0.7, 1.1), size, dtype=np.float32)[:, None, None]
    room = np.broadcast_to(wall * ramp, (size, size, 3)).copy()
    room *= 1 + 0.05 * t
    if horizon < size:
        floor = _colour(rng, rng.choice([(0.45, 0.45, 0.45), (0.5, 0.4, 0.3), (0.25, 0.3, 0.3)]), 0.25)
        room[horizon:] = floor * (1 + 0.15 * t[horizon:])
        cv2.line(room, (0, horizon), (size, horizon), tuple(float(v) for v in wall * 0.5), int(rng.integers(2, 12)))

    def flat(pts, col, edge=None, width=0):
        poly = np.round(pts).astype(np.int32)
        cv2.fillPoly(room, [poly], tuple(float(v) for v in col), cv2.LINE_AA)
        if edge is not None:
            cv2.polylines(room, [poly], True, tuple(float(v) for v in edge), width, cv2.LINE_AA)

    for _ in range(int(rng.integers(0, 3))):  # a window (bright, framed) or a door
        x0, y0 = rng.uniform(-0.1, 0.9) * size, rng.uniform(0, 0.5) * horizon
        w, h = rng.uniform(0.1, 0.4) * size, rng.uniform(0.2, 0.6) * horizon
        frame = _colour(rng, rng.choice([(0.9, 0.9, 0.9), (0.1, 0.1, 0.1), (0.4, 0.3, 0.2)]), 0.1)
        glass = _colour(rng, (0.8, 0.85, 0.95), 0.2) * rng.uniform(1.0, 2.0)
        box = np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]])
        flat(box, glass if rng.random() < 0.6 else frame * 0.8, frame, int(rng.integers(2, 9)))
        for k in range(int(rng.integers(0, 3))):  # glazing bars
            xk = x0 + w * (k + 1) / 3
            cv2.line(room, (int(xk), int(y0)), (int(xk), int(y0 + h)), tuple(float(v) for v in frame), 3)
    for _ in range(int(rng.integers(1, 5))):  # tables, benches, shelves, cupboards
        x0 = rng.uniform(-0.2, 0.9) * size
        w = rng.uniform(0.15, 0.7) * size
        y0 = rng.uniform(0.3, 1.0) * horizon
        top = rng.uniform(0.01, 0.05) * size
        col = _colour(rng, rng.choice([(0.8, 0.8, 0.78), (0.5, 0.35, 0.2), (0.2, 0.2, 0.22), (0.35, 0.45, 0.6)]), 0.2)
        edge = col * rng.uniform(0.2, 0.6)
        dz = rng.uniform(-0.1, 0.1) * size
        flat(np.array([[x0, y0], [x0 + w, y0 + dz], [x0 + w, y0 + dz + top], [x0, y0 + top]]), col)
        front = rng.uniform(0.004, 0.02) * size  # the table's front edge: a dark flat band
        flat(
            np.array(
                [[x0, y0 + top], [x0 + w, y0 + dz + top], [x0 + w, y0 + dz + top + front], [x0, y0 + top + front]]
            ),
            edge,
        )
        if rng.random() < 0.6:  # a cupboard or the dark space under a bench
            h = rng.uniform(0.1, 0.4) * size
            flat(
                np.array([[x0, y0 + top], [x0 + w, y0 + dz + top], [x0 + w, y0 + dz + top + h], [x0, y0 + top + h]]),
                col * rng.uniform(0.15, 0.9),
                edge,
                int(rng.integers(1, 4)),
            )
        for _ in range(int(rng.integers(0, 4))):  # boxes and screens on it
            bw, bh = rng.uniform(0.04, 0.2) * size, rng.uniform(0.03, 0.2) * size
            bx = x0 + rng.uniform(0, max(1.0, w - bw))
            c2 = _colour(rng, rng.choice([(0.05, 0.05, 0.06), (0.6, 0.5, 0.35), (0.85, 0.85, 0.85)]), 0.3, 0.2)
            flat(np.array([[bx, y0 - bh], [bx + bw, y0 - bh], [bx + bw, y0], [bx, y0]]), c2, c2 * 0.4, 2)
    for _ in range(int(rng.integers(0, 4))):  # cables: thin dark curves
        p0, p1 = rng.uniform(0, size, 2), rng.uniform(0, size, 2)
        pts = _curve(rng, p0, p1, rng.uniform(-0.4, 0.4) * size, n=24)
        col = _colour(rng, rng.choice([(0.03, 0.03, 0.03), (0.5, 0.5, 0.5), (0.7, 0.3, 0.1)]), 0.2, 0.2)
        cv2.polylines(
            room,
            [np.round(pts).astype(np.int32)],
            False,
            tuple(float(v) for v in col),
            int(rng.integers(2, 7)),
            cv2.LINE_AA,
        )
    a = np.ones((size, size), np.float32)
    if rng.random() < 0.4:  # the room seen through the mesh over part of the photo only
        a = np.clip(fractal(rng, size, size, rng.uniform(150, 400), 2) * 4 + rng.uniform(-1, 2), 0, 1)
    img[:] = img * (1 - a[..., None]) + room * lit * a[..., None]
    for _ in range(int(rng.integers(0, 4)) if rng.random() < 0.6 else 0):
        _person(img, None, rng, light, tile)


def _hard_negatives(img, cover, rng, light, tile, over):
    """What the stage-7 network still marked on real photos, none of it rebar: cracks, weeds
    and people under the bars (``over`` False), people in front of them (``over`` True)."""
    if not over:
        if rng.random() < 0.45:
            _cracks(img, rng, int(rng.integers(1, 12)))
        if rng.random() < 0.25:
            _weeds(img, rng, light)
        if rng.random() < 0.15:
            _person(img, None, rng, light, tile)
    elif rng.random() < 0.08:
        _person(img, cover, rng, light, tile)


def _thick_cable(img, cover, rng, light, tile):
    """A thick, smooth, dark cable or hose as wide as a bar (8-45 px), lying in loose curves:
    a shaded cylinder like a plain bar, but it bends. Over the bars it cuts their mask."""
    size = img.shape[0]
    pts = [rng.uniform(-0.1, 1.1, 2) * size]
    for _ in range(int(rng.integers(1, 4))):  # one to three bends of a cable lying loose
        pts.append(pts[-1] + rng.normal(0, 0.45, 2) * size)
    path = np.concatenate(
        [_curve(rng, a, b, rng.choice([-1, 1]) * rng.uniform(0.12, 0.5) * size, n=20) for a, b in zip(pts, pts[1:])]
    )
    col = _colour(
        rng, rng.choice([(0.02, 0.02, 0.025), (0.06, 0.06, 0.08), (0.25, 0.25, 0.27), (0.05, 0.1, 0.2)]), 0.2, 0.1
    )
    before = img.copy() if cover is not None else None
    draw_tube(img, rng, light, tile, path, rng.uniform(8, 45), col, corrugated=rng.random() < 0.15)
    if cover is not None:
        cover[np.any(np.abs(img - before) > 1e-6, axis=2)] = 0


def _long_hair(img, rng, light):
    """Long dark hair out of focus (a person close behind the bars): a bundle of many fine
    strands that follow one wavy flow, 20-160 px across, blurred. Dark, long and narrow like a
    bar, but made of strands and never straight."""
    size = img.shape[0]
    m = np.zeros((size, size), np.float32)
    x0, y0 = rng.uniform(0, size, 2)
    a0 = rng.uniform(0, 2 * math.pi)
    spread = rng.uniform(20, 160)
    length = rng.uniform(0.3, 1.2) * size
    wave, phase = rng.uniform(0.002, 0.02), rng.uniform(0, 2 * math.pi)
    steps = 40
    for _ in range(int(rng.integers(60, 300))):
        off = rng.normal(0, spread / 3)
        x, y, a = x0 - off * math.sin(a0), y0 + off * math.cos(a0), a0 + rng.normal(0, 0.05)
        pts = [(x, y)]
        for k in range(steps):
            a += 0.25 * math.sin(wave * k * length / steps * 6 + phase) * 0.2 + rng.normal(0, 0.02)
            x, y = x + length / steps * math.cos(a), y + length / steps * math.sin(a)
            pts.append((x, y))
        cv2.polylines(m, [np.round(pts).astype(np.int32)], False, rng.uniform(0.4, 1.0), 1, cv2.LINE_AA)
    m = np.clip(cv2.GaussianBlur(m, (0, 0), rng.uniform(0.5, 5)) * rng.uniform(1.5, 3), 0, 1)
    shade = light["ambient"] + light["diffuse"] * light["lz"]
    col = _colour(rng, rng.choice([(0.02, 0.015, 0.01), (0.08, 0.05, 0.03), (0.3, 0.2, 0.12)]), 0.2, 0.0)
    img[:] = img * (1 - m[..., None]) + (col * shade * light["colour"]) * m[..., None]


def _curves(img, cover, rng, light, tile, over):
    """What the stage-9 networks still marked on real photos: thick smooth cables and hoses and
    long dark hair (``over`` False: behind or under the bars; True: a cable over them)."""
    if not over:
        for _ in range(int(rng.integers(1, 4))):
            _thick_cable(img, None, rng, light, tile)
        if rng.random() < 0.5:
            _long_hair(img, rng, light)
    elif rng.random() < 0.2:
        _thick_cable(img, cover, rng, light, tile)


def _defocus(img, rng):
    """Everything drawn so far (what lies behind the bars) out of focus: a photo of a cage or of
    starter bars taken from close, focused on the bars, shows the room, the people and the ground
    behind them as soft blobs, the bars sharp in front. A disc-like blur (a Gaussian of 1.5-10 px
    at 640 px, a fifth of the frame at most), sometimes stronger towards the top (further away)."""
    size = img.shape[0]
    sigma = float(rng.uniform(1.5, 10.0)) * size / FULL
    far = cv2.GaussianBlur(img, (0, 0), sigma)
    if rng.random() < 0.4:  # a floor or a table in focus at the bottom, the blur growing upwards
        near = cv2.GaussianBlur(img, (0, 0), max(0.5, sigma * 0.2))
        y0 = rng.uniform(0.4, 1.0) * size
        w = np.clip((y0 - np.arange(size, dtype=np.float32)) / (0.3 * size) + 0.0, 0, 1)[:, None, None]
        return (near * (1 - w) + far * w).astype(np.float32)
    return far.astype(np.float32)


def _bar_out_of_focus(img, cover, sigma, draw):
    """``draw(img, cover)`` a bar as usual, then blur the picture where it lies: a bar nearer the
    camera than the focus (the front bars of a cage photographed from close) shows soft edges
    and no ribs, while its label stays the bar's footprint, as an annotator outlines it."""
    before = cover.copy()
    drawn = img.copy()
    draw(drawn, cover)
    foot = ((cover > 0.5) & ~(before > 0.5)).astype(np.float32)
    if not foot.any():
        return drawn
    soft = cv2.GaussianBlur(drawn, (0, 0), sigma)
    alpha = np.clip(cv2.GaussianBlur(cv2.dilate(foot, np.ones((3, 3), np.uint8)), (0, 0), sigma) * 2.0, 0, 1)
    return (drawn * (1 - alpha[..., None]) + soft * alpha[..., None]).astype(np.float32)


def _bundle(bars, rng):
    """Bars packed side by side: 1-4 more bars parallel to one of ``bars``, each a tenth of a
    width to one and a half widths from the last. Where real photos show them: a column cage's
    side seen at a slant (its main bars foreshortened into a tight group), bundled bars, lap
    splices, a cage's corner. A network that has seen bars only one by one, with background
    between them, misses such a group or marks it as one dark blob; labelled bar by bar, the
    gaps stay background."""
    if not bars:
        return bars
    out = list(bars)
    for _ in range(int(rng.integers(1, 3))):
        p0, p1, w0, w1, order = bars[int(rng.integers(len(bars)))]
        v = np.asarray(p1, float) - np.asarray(p0, float)
        d = v / max(float(np.hypot(*v)), 1e-6)
        n = np.array([-d[1], d[0]]) * (1 if rng.random() < 0.5 else -1)
        q0, q1, v0, v1 = np.asarray(p0, float), np.asarray(p1, float), w0, w1
        for _ in range(int(rng.integers(1, 5))):
            gap = rng.uniform(0.1, 1.5)
            k = rng.uniform(0.85, 1.1)
            u0, u1 = w0 * k, w1 * k
            q0 = q0 + n * (v0 + u0) / 2 * (1 + gap)
            q1 = q1 + n * (v1 + u1) / 2 * (1 + gap)
            v0, v1 = u0, u1
            out.append((q0.copy(), q1.copy(), u0, u1, order))
    return out


def scene(index, seed=DR_SEED, size=FULL, hard=False, indoor=0.0, curves=0.0, dof=0.0, near_blur=0.0, bundles=0.0):
    """Composed scene ``index``: ((size, size, 3) uint8 RGB, (size, size) bool rebar mask).

    ``hard``: also draw the hard negatives of :func:`_hard_negatives`, from a random stream of
    their own (``default_rng([seed, index, 1])``), so every other draw of the scene stays as
    it was without them. ``indoor``: the probability of a room behind the bars (:func:`_indoor`),
    drawn from a stream of its own too (``default_rng([seed, index, 2])``). ``curves``: the
    probability of thick cables and long hair (:func:`_curves`), stream ``[seed, index, 3]``.
    ``dof``: the probability that a cage, starter bars or a room behind the bars is out of focus
    (:func:`_defocus`), stream ``[seed, index, 4]``. ``near_blur``: the probability that some bars
    of a cage or of starter bars are nearer than the focus (:func:`_bar_out_of_focus`), stream
    ``[seed, index, 5]``. ``bundles``: the probability that some bars come packed side by side
    (:func:`_bundle`), stream ``[seed, index, 6]``."""
    rng = np.random.default_rng([int(seed), int(index)])
    rng_hard = np.random.default_rng([int(seed), int(index), 1]) if hard else None
    rng_curves = np.random.default_rng([int(seed), int(index), 3])
    curvy = curves > 0 and rng_curves.random() < curves
    names = list(LAYOUTS)
    kind = names[int(rng.choice(len(names), p=[LAYOUTS[k][1] for k in names]))]
    bars, behind = LAYOUTS[kind][0](rng, size) if LAYOUTS[kind][0] else ([], "ground")
    rng_bundle = np.random.default_rng([int(seed), int(index), 6])
    if bundles > 0 and rng_bundle.random() < bundles:
        bars = _bundle(bars, rng_bundle)
    light = _light(rng, str(rng.choice(["overcast", "sun", "sun", "flash", "night"], p=[0.3, 0.25, 0.2, 0.13, 0.12])))
    if behind == "sky":
        img = texture(rng, size, size, "sky")
        if rng.random() < 0.6:  # ground or a wall below a horizon
            y = int(rng.uniform(0.3, 0.95) * size)
            img[y:] = background(rng, size - y, size)
        if rng.random() < 0.5:  # depth of field: the far background blurred
            img = cv2.GaussianBlur(img, (0, 0), rng.uniform(1, 6))
    else:
        img = background(rng, size, size)
    tile = fractal(rng, 256, 256, rng.uniform(3, 30), 3)
    tile = np.tile(tile, (int(math.ceil(size / 256)), int(math.ceil(size / 256))))
    img = img * (light["ambient"] + light["diffuse"] * light["lz"])
    img = img * light["colour"]
    add_clutter(img, None, rng, light, tile, int(rng.integers(0, 6)), over=False)
    rng_room = np.random.default_rng([int(seed), int(index), 2])
    room = indoor > 0 and rng_room.random() < indoor
    if room:
        _indoor(img, rng_room, light, tile)
    if rng_hard is not None:
        _hard_negatives(img, None, rng_hard, light, tile, over=False)
    if curvy:
        _curves(img, None, rng_curves, light, tile, over=False)
    if light["mode"] == "sun" and behind == "ground":
        _cast_bar_shadows(img, bars, rng, light)
    rng_dof = np.random.default_rng([int(seed), int(index), 4])
    if dof > 0 and (kind in ("cage", "starters") or room) and rng_dof.random() < dof:
        img = _defocus(img, rng_dof)
    cover = np.zeros((size, size), np.float32)
    style = bar_style(rng)
    rng_near = np.random.default_rng([int(seed), int(index), 5])
    near = near_blur > 0 and kind in ("cage", "starters") and rng_near.random() < near_blur
    sigma_near = float(rng_near.uniform(1.0, 4.0)) * size / FULL
    for p0, p1, w0, w1, _ in sorted(bars, key=lambda b: b[4]):
        st = style if rng.random() < 0.85 else bar_style(rng)
        if near and rng_near.random() < 0.35:  # a bar nearer than the focus: soft, its label sharp
            img = _bar_out_of_focus(
                img, cover, sigma_near, lambda im, cov: draw_strip(im, cov, p0, p1, w0, w1, st, light, tile, rng)
            )
        else:
            draw_strip(img, cover, p0, p1, w0, w1, st, light, tile, rng)
    add_clutter(img, cover, rng, light, tile, int(rng.integers(0, 5)), over=True)
    if rng_hard is not None:
        _hard_negatives(img, cover, rng_hard, light, tile, over=True)
    if curvy:
        _curves(img, cover, rng_curves, light, tile, over=True)
    _apply_light(img, rng, light)
    out = _camera(img, rng, light["mode"] == "night")
    return out, cover > 0.5


# ---------------------------------------------------------------------------------------------
# the data step


def write_sample(
    index,
    folder: Path,
    seed=DR_SEED,
    size=FULL,
    quality=92,
    hard=False,
    indoor=0.0,
    curves=0.0,
    dof=0.0,
    near_blur=0.0,
    bundles=0.0,
) -> bool:
    """Write scene ``index`` as ``NNNNN.jpg`` (the network's input: half of ``size``, area
    averaged) and ``NNNNN.png`` (the full-resolution mask, 1 bit per pixel). False where both
    were already there (nothing written: the data step resumes)."""
    f_img, f_mask = folder / f"{index:05d}.jpg", folder / f"{index:05d}.png"
    if f_img.exists() and f_mask.exists():
        return False
    rgb, mask = scene(
        index, seed, size, hard=hard, indoor=indoor, curves=curves, dof=dof, near_blur=near_blur, bundles=bundles
    )
    small = cv2.resize(rgb, (size // 2, size // 2), interpolation=cv2.INTER_AREA)
    tmp = f_mask.with_suffix(".tmp.png")
    cv2.imwrite(str(tmp), mask.astype(np.uint8) * 255, [cv2.IMWRITE_PNG_COMPRESSION, 9, cv2.IMWRITE_PNG_BILEVEL, 1])
    tmp.replace(f_mask)
    tmp = f_img.with_suffix(".tmp.jpg")
    cv2.imwrite(str(tmp), small[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
    tmp.replace(f_img)
    return True


def _write_job(job):
    index, folder, seed, size, hard, indoor, curves, dof, near_blur, bundles = job
    cv2.setNumThreads(1)
    return write_sample(
        index,
        folder,
        seed,
        size,
        hard=hard,
        indoor=indoor,
        curves=curves,
        dof=dof,
        near_blur=near_blur,
        bundles=bundles,
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", default=".segdata_dr", help="folder; the scenes go to WORK/dr/")
    ap.add_argument("--n", type=int, default=2000, help="scenes 0..N-1")
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--seed", type=int, default=DR_SEED)
    ap.add_argument("--size", type=int, default=FULL)
    ap.add_argument("--hard", action="store_true", help="also draw the hard negatives (cracks, weeds, people)")
    ap.add_argument("--indoor", type=float, default=0.0, help="probability of a room behind the bars (0: none)")
    ap.add_argument(
        "--curves", type=float, default=0.0, help="probability of thick cables and long dark hair (0: none)"
    )
    ap.add_argument(
        "--dof",
        type=float,
        default=0.0,
        help="probability that what lies behind a cage, starter bars or a room is out of focus (0: never)",
    )
    ap.add_argument(
        "--near-blur",
        type=float,
        default=0.0,
        help="probability that some bars of a cage or of starter bars are nearer than the focus (0: never)",
    )
    ap.add_argument(
        "--bundles",
        type=float,
        default=0.0,
        help="probability that some bars come packed side by side (a cage's side at a slant, laps; 0: never)",
    )
    ap.add_argument("--jobs", type=int, default=1, help="processes; scenes are written in index order, about")
    args = ap.parse_args(argv)
    folder = Path(args.work) / "dr"
    folder.mkdir(parents=True, exist_ok=True)
    t0, made = time.time(), 0
    jobs = [
        (i, folder, args.seed, args.size, args.hard, args.indoor, args.curves, args.dof, args.near_blur, args.bundles)
        for i in range(args.first, args.n)
    ]
    if args.jobs > 1:
        from multiprocessing import Pool

        with Pool(args.jobs) as pool:
            for k, wrote in enumerate(pool.imap(_write_job, jobs, chunksize=2)):
                made += wrote
                if k % 500 == 0:
                    print(f"{args.first + k}/{args.n} ({made} written) {time.time() - t0:.0f} s", flush=True)
    else:
        for i, *_ in jobs:
            made += write_sample(
                i,
                folder,
                args.seed,
                args.size,
                hard=args.hard,
                indoor=args.indoor,
                curves=args.curves,
                dof=args.dof,
                near_blur=args.near_blur,
                bundles=args.bundles,
            )
            if i % 100 == 0:
                print(f"{i}/{args.n} ({made} written) {time.time() - t0:.0f} s", flush=True)
    print(f"done: {made} written, {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
