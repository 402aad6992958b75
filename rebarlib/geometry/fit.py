"""The cross-section model: a cylinder of known radius fitted to one bar's points (slab frame),
robustly, and kept on the side of the points that faces the camera.
"""

from __future__ import annotations

import math

import numpy as np


def _fit_bar(t, s, h, radius, *, iters: int = 12, max_fit_points: int = 1500, start=None, parallel=False):
    """Robust fit of a cylinder of known radius to one bar's points (slab frame).

    Model: across-offset ``a0 + a1·t``, height ``b0 + b1·t``; residual = distance to the axis −
    radius. Gauss–Newton with Tukey weights at 4 robust std devs, from ``start`` (offset, drift,
    height, height drift at the points' mean ``t``) or from under the points' top. ``parallel``
    keeps the drift across at 0: the axis parallel to its direction.
    Returns (params, weights, rms).
    """
    tc = t - t.mean()
    a = (np.array(start, float) if start is not None
         else np.array([np.median(s), 0.0, np.percentile(h, 95) - radius, 0.0]))
    if parallel:
        a[1] = 0.0
    # the iterations run on at most max_fit_points evenly spread points (1500 points place an
    # axis to well under 0.1 mm); the final weights are then computed on all points
    step_n = max(1, len(t) // max_fit_points)
    ts, ss, hs = tc[::step_n], s[::step_n], h[::step_n]
    w = np.ones(len(ts))
    sigma = 1.0
    for it in range(iters):
        ds = ss - a[0] - a[1] * ts
        dh = hs - a[2] - a[3] * ts
        rho = np.hypot(ds, dh) + 1e-9
        r = rho - radius
        if it > 0:
            sigma = max(1.4826 * float(np.median(np.abs(r[w > 0]))) if np.any(w > 0) else 1.0, 0.2)
        u = r / (4.685 * sigma)
        w = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
        if w.sum() < 6:
            break
        cs, ch = ds / rho, dh / rho
        J = np.stack([-cs, -ts * cs, -ch, -ts * ch])
        if parallel:  # no drift across: its column is left out (its step is 0)
            J[1] = 0.0
        JW = J * w
        try:
            step = np.linalg.solve(JW @ J.T + 1e-9 * np.eye(4), -JW @ r)
        except np.linalg.LinAlgError:
            break
        a = a + step
        if np.abs(step).max() < 1e-4:
            break
    ds = s - a[0] - a[1] * tc
    dh = h - a[2] - a[3] * tc
    r = np.hypot(ds, dh) - radius
    u = r / (4.685 * sigma)
    w = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
    keep = w > 0
    rms = float(np.sqrt(np.mean(r[keep] ** 2))) if keep.any() else float("nan")
    # standard errors of the centred parameters (offset and height at the points' mean t)
    rho = np.hypot(ds, dh) + 1e-9
    J = np.column_stack([-ds / rho, -tc * ds / rho, -dh / rho, -tc * dh / rho])[keep]
    try:
        cov = np.linalg.inv(J.T @ J) * (rms**2 if np.isfinite(rms) else 1.0)
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        se = np.full(4, np.inf)
    # back to t (not centred)
    a0 = a[0] - a[1] * t.mean()
    b0 = a[2] - a[3] * t.mean()
    return (a0, a[1], b0, a[3]), w, rms, (float(se[0]), float(se[2]))


def _from_axis(params, t, s, h):
    """Offsets across and heights of points ``(t, s, h)`` from a bar axis ``(a0, a1, b0, b1)``
    (as :func:`_fit_bar` returns it)."""
    a0, a1, b0, b1 = params
    return s - a0 - a1 * t, h - b0 - b1 * t


def _rms_on(fit, ref, t, s, h, radius) -> float:
    """Root-mean-square residual of ``fit``'s cylinder over the points ``ref`` kept (the same
    points for both, so that a fit that drops more points does not look better)."""
    keep = ref[1] > 0
    if not keep.any():
        return math.inf
    ds, dh = _from_axis(fit[0], t[keep], s[keep], h[keep])
    return float(np.sqrt(np.mean((np.hypot(ds, dh) - radius) ** 2)))


def _facing_share(fit, t, s, h, camera, c, n2) -> float:
    """Share of a fit's inlier points whose outward normal (from the axis) points towards the
    camera (slab frame; ``s`` are offsets across less ``c``, ``n2`` the plan normal)."""
    keep = fit[1] > 0
    if not keep.any():
        return 0.0
    ds, dh = _from_axis(fit[0], t[keep], s[keep], h[keep])
    to_cam_s = float(np.asarray(camera[:2]) @ n2) - c - s[keep]
    to_cam_h = float(camera[2]) - h[keep]
    return float(np.mean(ds * to_cam_s + dh * to_cam_h > 0))


def _facing_fit(fit, t, s, h, r, camera, c, n2):
    """``fit`` if most of its points face the camera; else the fit from its centre mirrored
    through the points (the other side of a flank), if that one's do. Returns (fit, facing)."""
    if _facing_share(fit, t, s, h, camera, c, n2) >= 0.5:
        return fit, True
    (a0, a1, b0, b1), w, _, _ = fit
    tm = float(t.mean())
    keep = w > 0
    mid = float(np.median(s[keep] - a1 * (t[keep] - tm))) if keep.any() else float(np.median(s))
    a0c = a0 + a1 * tm
    start = (2 * mid - a0c, a1, b0 + b1 * tm, b1)
    other = _fit_bar(t, s, h, r, start=start)
    if _facing_share(other, t, s, h, camera, c, n2) >= 0.5:
        return other, True
    return fit, False
