"""Ribs in a bar's silhouette: the periodicity of its widths, of each of its edges and of the
shading along its face, and whether a capture's bars together show ribs.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from .._camera import project
from .bars import _candidates, _hits_footprints, _remap


def _rib_periodicity(
    s_mm, w_mm, *, band=(0.4, 1.2), oversample: int = 4, width_mm: float | None = None
) -> tuple[float, float]:
    """Strongest periodic component of a bar's section widths along it: ``(pitch_mm, p)``.

    The transverse ribs of a deformed bar make its silhouette's width periodic along the bar, at
    the rib pitch (about 0.5-0.7 x its diameter). The periodogram of the widths ``w_mm`` at their
    positions ``s_mm`` (irregular spacing is fine) is searched over pitches between ``band`` x the
    median width; ``p`` is the chance that noise alone gives a peak as strong (the peak of a
    periodogram of white noise normalised by its variance is exponential with mean 1, times the
    number of independent frequencies searched). ``(nan, 1.0)`` where there is too little to
    look at (fewer than 8 sections, constant widths, a bar shorter than three pitches, sections
    too far apart for the band, no peak inside the band: a spectrum rising to its edge).
    ``width_mm``: the bar's width the band is relative to, where ``w_mm`` is another signal along
    the bar (one edge's position, :func:`_edge_pitch`); default the median of ``w_mm``.

    Only pitches of at least two section spacings (the median one) are searched: sampled that
    sparsely, a shorter period is indistinguishable from a slow one mirrored about the sampling
    rate. Searching beyond it found "ribs" at a pitch just under the sections' spacing on smooth
    bars: the slow wander of a mask's width along the bar, mirrored (a mask computed at half the
    image's resolution, 3 of 38 captures looking ribbed).

    Examples
    --------
    >>> s = np.arange(200) * 1.3  # sections 1.3 mm apart
    >>> w = 12.4 + 0.8 * (np.cos(2 * np.pi * s / 8.0) > 0.5)  # crests every 8 mm
    >>> pitch, p = _rib_periodicity(s, w)
    >>> round(pitch, 1), p < 1e-6
    (8.0, True)
    >>> _rib_periodicity(s, 12.4 + np.random.default_rng(0).normal(0, 0.3, 200))[1] > 0.01
    True
    """
    s = np.asarray(s_mm, float)
    w = np.asarray(w_mm, float)
    if len(w) < 8:
        return math.nan, 1.0
    width = float(np.median(w)) if width_mm is None else float(width_mm)
    w = w - w.mean()
    var = float(w @ w) / len(w)
    length = float(s.max() - s.min())
    if var <= 1e-12 or width <= 0 or length < 3 * band[1] * width:
        return math.nan, 1.0
    fmin = 1 / (band[1] * width)
    fmax = min(1 / (band[0] * width), 0.5 / float(np.median(np.diff(np.sort(s)))))  # (Nyquist)
    if fmax <= fmin:
        return math.nan, 1.0
    f = np.linspace(fmin, fmax, int(math.ceil((fmax - fmin) * length * oversample)) + 1)
    power = _periodogram(s, w, f) / (len(w) * var)
    k = _band_peak(f, power, fmin, fmax, length)
    if k is None:
        return math.nan, 1.0
    return float(1 / f[k]), float(min(1.0, (fmax - fmin) * length * math.exp(-float(power[k]))))


def _periodogram(s, w, f):
    """|Σ w·exp(2πi·f·s)|² at the evenly spaced frequencies ``f``: the terms of each frequency are
    those of the one before times exp(2πi·Δf·s), a running product instead of a sine and a
    cosine per term (five times faster; it agrees with the direct sums to about 1e-13 of the
    peak).

    >>> s = np.array([0.0, 1.0, 2.5]); w = np.array([1.0, -2.0, 0.5]); f = np.linspace(0.1, 0.3, 3)
    >>> direct = np.abs(np.exp(2j * np.pi * np.outer(f, s)) @ w) ** 2
    >>> bool(np.allclose(_periodogram(s, w, f), direct))
    True
    """
    terms = np.empty((len(f), len(s)), complex)
    terms[0] = w * np.exp(2j * np.pi * f[0] * s)
    if len(f) > 1:
        terms[1:] = np.exp(2j * np.pi * (f[1] - f[0]) * s)
    np.cumprod(terms, axis=0, out=terms)
    x = terms.sum(axis=1)
    return x.real**2 + x.imag**2


def _band_peak(f, power, fmin, fmax, length):
    """Index of the strongest peak of a periodogram ``power`` at frequencies ``f`` (1/mm) inside
    [``fmin``, ``fmax``], or None: a period is a peak, a local maximum at least one resolution
    (1 / ``length``) inside the band. A width that wanders slowly along a smooth bar has a
    spectrum rising towards the longest pitch searched, and its largest value at the band's edge
    is that rise, not a period (seen: smooth Φ10 bars of a learnt mask with "clear" pitches at or
    next to 1.2 x their width)."""
    peak = np.zeros(len(f), bool)
    peak[1:-1] = (power[1:-1] > power[:-2]) & (power[1:-1] >= power[2:])
    peak &= (f >= fmin + 1 / length) & (f <= fmax - 1 / length)
    if not peak.any():
        return None
    return int(np.flatnonzero(peak)[power[peak].argmax()])


def _clear_pitch(pitch, p, length_mm, prm) -> tuple[float, float] | None:
    """``(pitch_mm, relative resolution)`` where a rib pitch read over ``length_mm`` of bar is
    clear (p < ``prm.rib_bar_p``); the resolution is half a periodogram bin, pitch / (2 x
    length). None otherwise."""
    if p < prm.rib_bar_p and math.isfinite(pitch) and length_mm > 0:
        return float(pitch), float(pitch) / (2 * length_mm)
    return None


def _edge_pitch(info, prm) -> tuple[float, float] | None:
    """A bar's rib pitch read from each of its edges on its own: ``(pitch_mm, relative
    resolution)`` where both edges are clearly periodic (p < ``prm.rib_bar_p`` each, from
    :func:`_rib_periodicity`) at one pitch (within a periodogram bin, pitch / length read), else
    None.

    The transverse ribs on the two sides of the longitudinal ribs need not be in step along the
    bar, so its width, the difference of its two edges, can hide the pitch each edge shows. Each
    edge is read against a straight line along the bar (an axis a little askew across the bar
    tilts it). The two edges' noise is independent, so both clear at one pitch is rarer from
    noise than one clear width."""
    s, lo, hi = info.edges
    good = np.isfinite(lo) & np.isfinite(hi)
    if good.sum() < prm.rib_min_sections:
        return None
    s, lo, hi = s[good], lo[good], hi[good]
    length = float(s.max() - s.min())
    width = float(np.median(hi - lo))
    pitches, ps = [], []
    for e in (lo, hi):
        e = e - np.polyval(np.polyfit(s, e, 1), s)
        pitch, p = _rib_periodicity(s, e, band=prm.rib_band, width_mm=width)
        if not p < prm.rib_bar_p:
            return None
        pitches.append(pitch)
        ps.append(p)
    pitch = float(np.mean(pitches))
    if abs(pitches[0] - pitches[1]) > pitch * pitch / length:
        return None
    return _clear_pitch(pitch, max(ps), length, prm)


def _face_pitch(bar, info, gray, intr, prm, fp=None, i=None) -> tuple[float, float] | None:
    """A bar's rib pitch read from the shading of its face: ``(pitch_mm, relative resolution)``
    where clear (p < ``prm.rib_bar_p``), else None.

    A transverse rib's flanks catch the light and shade on every side of a deformed bar that
    faces the camera, so the luminance along the bar between its edges is periodic at the rib
    spacing l. This holds at every roll of the bar: where the longitudinal ribs lie at the sides
    of the silhouette (a roll at which its width is constant along the bar and says least of its
    size), one side's transverse ribs face the camera full on. The luminance is read along
    ``prm.face_fractions`` of the way from one mask edge to the other, about a pixel apart, over
    the bar's clean cross-sections with both edges (``info.edges``; never under another bar,
    at the image border or at a crossing), less its slow changes (light, rust, shadows; a
    Gaussian over three of the longest pitches searched). The lines' periodograms, each
    normalised by its variance, are summed; the peak must lie inside ``prm.rib_band`` x the
    bar's width (:func:`_band_peak`, as for :func:`_rib_periodicity`). Its p-value takes the
    lines as one (their noise may be correlated: what one line shows, the next may show too):
    number of independent frequencies x exp(-peak / lines).

    A bar seen from one side only (too few sections with both edges; the other side under a
    nearer bar or beyond the image border, ``info.one_edges``) is read on its visible half:
    the same lines squeezed between its one edge and the axis (half the fractions, of the width
    twice the edge's distance from the axis). There a sample is kept only inside the image and
    outside the footprint of every nearer bar (``fp``, this bar's index ``i``): the bar over a
    sliver has ribs too, at its own spacing.

    The face lies nearer the camera than the plane γ the positions are measured in, so it is
    magnified on it by D / (D - h) (D the distance to the axis, h the face's height over it, a
    circle through the edges): the pitch is scaled back by (1 - h / D).
    """
    s_k, lo, hi = info.edges
    good = np.isfinite(lo) & np.isfinite(hi)
    fr = np.asarray(prm.face_fractions, float)
    one_side = good.sum() < prm.rib_min_sections
    if one_side:
        s_k, lo1, hi1 = info.one_edges
        lo = np.where(np.isfinite(lo1), lo1, hi1)  # the visible edge, and its mirror about the axis
        hi = -lo
        good = np.isfinite(lo)
        fr = fr / 2  # lines from the visible edge to the axis
    if gray is None or good.sum() < prm.rib_min_sections:
        return None
    order = np.argsort(s_k[good])
    s_k, lo, hi = s_k[good][order], lo[good][order], hi[good][order]
    pl = bar.plane
    mid = bar.p0 + float(np.median(s_k)) * pl.direction
    dist = float(np.linalg.norm(mid))
    ds = prm.face_step_px * float(mid[2]) / intr.fx  # mm along the bar between samples
    width = float(np.median(np.abs(hi - lo)))
    length = float(s_k[-1] - s_k[0])
    if width <= 0 or length < 3 * prm.rib_band[1] * width:
        return None
    n = int(length / ds) + 1
    s = s_k[0] + ds * np.arange(n)
    j = np.searchsorted(s_k, s).clip(1, len(s_k) - 1)
    gap = np.minimum(np.abs(s - s_k[j - 1]), np.abs(s - s_k[j]))
    keep = gap <= 1.01 * float(np.median(np.diff(s_k)))  # near a clean section
    lo_s, hi_s = np.interp(s, s_k, lo), np.interp(s, s_k, hi)
    t = lo_s[None, :] + fr[:, None] * (hi_s - lo_s)[None, :]  # (lines, n) mm across, in γ
    P = (bar.p0 + s[None, :, None] * pl.direction + t[..., None] * pl.across).reshape(-1, 3)
    uv = project(P, intr)
    lum = _remap(gray, uv[:, 0:1], uv[:, 1:2])[:, 0].reshape(len(fr), n).astype(float)
    m = np.broadcast_to(keep, lum.shape).astype(float)  # (lines, n): the samples read
    if one_side:
        m = m * _seen_samples(uv, P, gray, fp, i).reshape(m.shape)
    x, cnt, var = _detrended(lum, m, width, ds, n, prm)
    # a line read over less than half of the bar's clean length says too little (a sliver's
    # line that runs under the bar over it)
    varied = (var > 1e-9) & (cnt >= 0.5 * keep.sum())
    if not varied.any():
        return None
    nfft = 1 << int(math.ceil(math.log2(prm.face_oversample * n)))
    power = (np.abs(np.fft.rfft(x[varied], nfft, axis=1)) ** 2 / (cnt[varied] * var[varied])[:, None]).sum(axis=0)
    f = np.fft.rfftfreq(nfft, ds)
    fmin, fmax = 1 / (prm.rib_band[1] * width), min(1 / (prm.rib_band[0] * width), 0.5 / ds)
    k = _band_peak(f, power, fmin, fmax, length)
    if k is None:
        return None
    p = min(1.0, (fmax - fmin) * length * math.exp(-float(power[k]) / int(varied.sum())))
    # the face's mean height over the axis, on a circle through the edges
    h = float(np.mean(np.sqrt(np.clip(1 - (2 * fr - 1) ** 2, 0, 1)))) * width / 2
    return _clear_pitch(float(1 / f[k]) * (1 - h / dist), p, length, prm)


def _seen_samples(uv, P, gray, fp, i) -> np.ndarray:
    """Which samples (pixels ``uv`` of the points ``P``) of a bar seen from one side are its
    own: inside the image and outside the footprint of every nearer bar (``fp``, this bar's
    index ``i``; without them, inside the image)."""
    H, W = gray.shape[:2]
    seen = (uv[:, 0] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= H - 1)
    if fp is not None and i is not None:
        cand = _candidates(i, fp, [uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
        if len(cand):
            seen &= ~_hits_footprints(P, fp, cand)[1].any(axis=1)
    return seen


def _detrended(lum, m, width, ds, n, prm):
    """The face's lines of luminance ``lum`` (lines, n) less their slow changes (light, rust,
    shadows: a Gaussian over three of the longest pitches searched, normalised over the samples
    read, ``m``) and their means: ``(x, samples read per line, variance per line)``."""
    sig = 3 * prm.rib_band[1] * width / ds
    half = min(int(3 * sig), (n - 1) // 2)  # (np.convolve "same" keeps n samples while n >= the kernel)
    x_g = np.arange(-half, half + 1)
    g = np.exp(-0.5 * (x_g / sig) ** 2)
    x = np.array(
        [
            (row - np.convolve(row * mk, g, "same") / np.maximum(np.convolve(mk, g, "same"), 1e-9)) * mk
            for row, mk in zip(lum, m)
        ]
    )
    cnt = np.maximum(m.sum(axis=1), 1.0)  # samples read per line (a line with none has no variance)
    x -= (x.sum(axis=1) / cnt)[:, None] * m
    var = (x**2).sum(axis=1) / cnt
    return x, cnt, var


def _ribs_in_view(reads, prm, sizes=None) -> float:
    """Chance that noise alone gives the periodicity the capture's bars show together (Fisher's
    method over the bars' :func:`_rib_periodicity` reads ``(pitch_mm, p)``, the p-values each
    floored at ``prm.rib_p_floor`` so that one striped bar does not make a capture); 1.0 with
    fewer than ``prm.rib_min_bars`` bars to look at. The bars of one capture are seen by one
    camera at similar distances: where it resolves the ribs of some, it resolves those of all.

    Ribs also repeat at one pitch on every bar of a size (the standard's spacing), while a mask's
    own texture or noise gives each bar a pitch of its own: 1.0 too unless at least
    ``prm.rib_min_bars`` bars show a pitch clearly (p < ``prm.rib_bar_p``) within
    ``prm.rib_pitch_tol`` of the median clear pitch of their size (``sizes``, one key per bar,
    e.g. its design size; None: one size). Seen on a learnt mask of smooth bars: 2-3 bars of a
    capture clearly periodic, at pitches 6.5-16 mm for one size; ribs in relief: every clear pitch
    within 1 % of the true one."""
    sizes = [0] * len(reads) if sizes is None else list(sizes)
    clear = defaultdict(list)
    for (pitch, p), key in zip(reads, sizes):
        if p < prm.rib_bar_p and math.isfinite(pitch):
            clear[key].append(pitch)
    agree = sum(int(np.sum(np.abs(np.array(v) / np.median(v) - 1) <= prm.rib_pitch_tol)) for v in clear.values())
    if agree < prm.rib_min_bars:
        return 1.0
    ps = [max(p, prm.rib_p_floor) for pitch, p in reads if math.isfinite(pitch)]
    half = -float(np.sum(np.log(ps)))  # χ² / 2, with 2 x len(ps) degrees of freedom
    if half <= 0:
        return 1.0
    j = np.arange(len(ps))
    log_terms = j * math.log(half) - np.array([math.lgamma(k + 1) for k in j]) - half
    top = float(log_terms.max())
    return float(min(1.0, math.exp(top) * np.exp(log_terms - top).sum()))
