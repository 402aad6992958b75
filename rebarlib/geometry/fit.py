"""The cross-section model: a cylinder of known radius fitted to one bar's points (slab frame),
robustly, and kept on the side of the points that faces the camera.
"""

from __future__ import annotations

import math

import numpy as np


#: added to the Gauss-Newton normal matrix of :func:`_fit_bar` (made once, not per iteration)
_RIDGE = 1e-9 * np.eye(4)


def _median(x) -> float:
    """``np.median`` of a 1-D float array, without its generic machinery (the same number: the
    middle value, or the mean of the two middle values; NaN if any value is NaN). The fits
    below take a median of a few hundred values at each of their iterations, where
    ``np.median``'s own overhead was most of the cost."""
    n = len(x)
    if n == 0:
        return float(np.median(x))  # NaN, with numpy's warning
    k = n // 2
    p = np.partition(x, [k - 1, k, n - 1] if n % 2 == 0 else [k, n - 1])
    if np.isnan(p[-1]):
        return float("nan")
    return float((p[k - 1] + p[k]) / 2) if n % 2 == 0 else float(p[k])


def _fit_bar(t, s, h, radius, *, iters: int = 12, max_fit_points: int = 1500, start=None, parallel=False, ray=None):
    """Robust fit of a cylinder of known radius to one bar's points (slab frame).

    Model: across-offset ``a0 + a1·t``, height ``b0 + b1·t``; residual = distance to the axis −
    radius. Gauss–Newton with Tukey weights at 4 robust std devs, from ``start`` (offset, drift,
    height, height drift at the points' mean ``t``) or from under the points' top. ``parallel``
    keeps the drift across at 0: the axis parallel to its direction.

    ``ray``: per point (or one for all), the across and height components ``(us, uh)`` of the
    unit line of sight along which its depth noise lies. The distance of a noisy point from the
    axis reads long by about ``σ² b² / 2r`` (``b`` the noise direction's share along the
    circle): a plain fit of a fixed radius then moves the axis toward the points, by about
    σ²/2r for a bar seen from above (0.25 mm at σ 2 mm on Φ14's 8.1 mm envelope radius). With
    ``ray`` the Gauss-Newton equations take that expected part out (:func:`_noise_bias`), σ
    measured on the fit's own residuals.
    Returns (params, weights, rms, (se of the offset, se of the height)).
    """
    tc = t - t.mean()
    a = (
        np.array(start, float)
        if start is not None
        else np.array([np.median(s), 0.0, np.percentile(h, 95) - radius, 0.0])
    )
    if parallel:
        a[1] = 0.0
    # the iterations run on at most max_fit_points evenly spread points (1500 points place an
    # axis to well under 0.1 mm); the final weights are then computed on all points
    step_n = max(1, len(t) // max_fit_points)
    ts, ss, hs = tc[::step_n], s[::step_n], h[::step_n]
    if ray is not None:
        us, uh = (np.broadcast_to(np.asarray(x, float), t.shape)[::step_n] for x in ray)
    w = np.ones(len(ts))
    sigma = 1.0
    for it in range(iters):
        ds = ss - a[0] - a[1] * ts
        dh = hs - a[2] - a[3] * ts
        rho = np.hypot(ds, dh) + 1e-9
        r = rho - radius
        if it > 0:
            pos = w > 0
            sigma = max(1.4826 * _median(np.abs(r[pos])) if pos.any() else 1.0, 0.2)
        u = r / (4.685 * sigma)
        w = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
        if w.sum() < 6:
            break
        cs, ch = ds / rho, dh / rho
        J = np.array([-cs, -ts * cs, -ch, -ts * ch])
        if parallel:  # no drift across: its column is left out (its step is 0)
            J[1] = 0.0
        JW = J * w
        rhs = -JW @ r
        if ray is not None:
            rhs = rhs - _noise_bias(cs, ch, rho, r, w, us, uh, ts, parallel)
        try:
            step = np.linalg.solve(JW @ J.T + _RIDGE, rhs)
        except np.linalg.LinAlgError:
            break
        a = a + step
        if np.abs(step).max() < 1e-4 and (ray is None or it > 0):
            break
    ds = s - a[0] - a[1] * tc
    dh = h - a[2] - a[3] * tc
    r = np.hypot(ds, dh) - radius
    u = r / (4.685 * sigma)
    w = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
    keep = w > 0
    rms = float(np.sqrt(np.mean(r[keep] ** 2))) if keep.any() else float("nan")
    # standard errors of the centred parameters (offset and height at the points' mean t)
    # (the kept points' rows only: the same numbers as all rows' then the kept ones)
    ds, dh, tk = ds[keep], dh[keep], tc[keep]
    rho = np.hypot(ds, dh) + 1e-9
    J = np.column_stack([-ds / rho, -tk * ds / rho, -dh / rho, -tk * dh / rho])
    try:
        cov = np.linalg.inv(J.T @ J) * (rms**2 if np.isfinite(rms) else 1.0)
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        se = np.full(4, np.inf)
    # back to t (not centred)
    a0 = a[0] - a[1] * t.mean()
    b0 = a[2] - a[3] * t.mean()
    return (a0, a[1], b0, a[3]), w, rms, (float(se[0]), float(se[2]))


def _noise_bias(cs, ch, rho, r, w, us, uh, ts, parallel) -> np.ndarray:
    """Expected value of the Gauss-Newton right-hand side ``Σ w r n`` that depth noise alone
    adds, at the current axis (for :func:`_fit_bar`; ``(cs, ch)`` the points' unit normals,
    ``(us, uh)`` their lines of sight, ``ts`` their centred positions along).

    A point moved by ``e`` along a line of sight with radial part ``a`` and part ``b`` along
    the circle lies ``e a + e² b² / 2ρ`` from the axis, and its normal turns by ``e b / ρ``; so
    ``E[r n] = σ² (b² / 2ρ) n + σ² (a b / ρ) τ`` (τ the circle's tangent), to first order in
    σ²/ρ. σ² is the fit's: its weighted squared residuals over the weighted ``a²``.
    """
    a = us * cs + uh * ch
    b = uh * cs - us * ch
    den = float(np.sum(w * a**2))
    if den <= 0.1 * float(np.sum(w)):
        return np.zeros(4)
    var = _ray_variance(r, a, w)
    ms = var * (b**2 / (2 * rho) * cs - a * b / rho * ch)
    mh = var * (b**2 / (2 * rho) * ch + a * b / rho * cs)
    out = np.array([np.sum(w * ms), np.sum(w * ts * ms), np.sum(w * mh), np.sum(w * ts * mh)])
    if parallel:
        out[1] = 0.0
    return out


def _ray_variance(r, a, w) -> float:
    """Variance of the depth noise along the lines of sight, from a fit's residuals ``r`` (radial)
    and the lines of sight's radial shares ``a`` (weights ``w``): ``Σ w r² / Σ w a²`` over the
    points seen nearly face on (``a² ≥ 0.5``; all points where fewer than 20 are). A point seen
    obliquely, small ``a``, shows little of the depth noise in its residual but all of what moves
    points across the lines of sight (the pixels' jitter, edge pixels): divided by a small ``a²``,
    that was read as depth noise several times too large (a bar seen on one side only, 72° of its
    cross-section: σ² 1.19 mm² against about 0.4 mm² from the sensor, and its underside moved
    0.45 mm down)."""
    k = (w > 0) & (a**2 >= 0.5)
    if k.sum() < 20:
        k = w > 0
    return float(np.sum(w[k] * r[k] ** 2)) / max(float(np.sum(w[k] * a[k] ** 2)), 1e-9)


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


def _refit_along_rays(fit, t, s, h, r, camera, c, d, n2):
    """``fit`` refitted from where it is with the bias of the depth noise taken out
    (:func:`_fit_bar`'s ``ray``): each point's line of sight from ``camera`` (slab frame; ``s``
    offsets across less ``c``, ``d`` and ``n2`` the bar's direction and plan normal)."""
    (a0, a1, b0, b1), _, _, _ = fit
    tm = float(t.mean())
    cam = np.asarray(camera, float)
    vs = s + c - float(cam[:2] @ n2)
    vt = t - float(cam[:2] @ d)
    vh = h - float(cam[2])
    norm = np.sqrt(vs**2 + vt**2 + vh**2) + 1e-9
    return _fit_bar(
        t, s, h, r, start=(a0 + a1 * tm, a1, b0 + b1 * tm, b1), parallel=a1 == 0.0, ray=(vs / norm, vh / norm)
    )


#: Candidate offsets across the line of sight tried by :func:`_place_along_rays`.
_ALONG_GRID = 81


def _place_along_rays(fit, t, s, h, r, camera, c, d, n2):
    """The axis placed from the points' ranges along their lines of sight, where a stereo
    camera's depth noise lies (docs/decisions/048): ``(offset, height, u_offset, u_height,
    noise)`` at the points' mean ``t`` (``s`` offsets across less ``c``, as :func:`_fit_bar`
    takes them), with the standard uncertainties of that placing and the depth noise's robust
    SD along the lines of sight (mm); None where it cannot be made.

    In the bar's cross-section every line of sight passes through the camera's projection, and
    depth noise moves a point along its own line only: its direction from the camera is exact
    (up to the pixel's jitter), its range is noisy. A circle of radius ``r`` centred at range
    ``l0`` in direction ``θ0`` is met by the line at angle ``θ`` at the range
    ``l0 cos(θ − θ0) − √(r² − l0² sin²(θ − θ0))`` (the near side); the residual is the
    point's range less that, additive in the noise, so no noise bias needs taking out (the
    circle fit's distances to the axis read long by ``σ² b² / 2ρ``, which
    :func:`_noise_bias` removes only to first order in σ/ρ). For each of
    :data:`_ALONG_GRID` positions of the axis across the lines of sight, between those that
    leave the points' span (2nd to 98th percentile) inside the circle's silhouette, the range
    ``l0`` is the robust mean that zeroes the residuals; the position with the least clipped
    sum of squares (at three robust SDs) is kept. Each ``u``: the spread of the positions'
    offsets or heights within four noise variances of that least sum (a 2 SD interval, read as
    ±2u) with the range's own standard error ``σ/√n`` in quadrature. The drift along the bar is ``fit``'s."""
    (a0, a1, b0, b1), w, _, _ = fit
    keep = w > 0
    if keep.sum() < 20:
        return None
    t, s, h = t[keep], s[keep], h[keep]
    tm = float(np.mean(t))
    cam = np.asarray(camera, float)
    cs, ch = float(cam[:2] @ n2) - c, float(cam[2])
    vs = s - a1 * (t - tm) - cs
    vh = h - b1 * (t - tm) - ch
    ell = np.hypot(vs, vh)
    th = np.arctan2(vh, vs)
    thc = float(np.arctan2(np.mean(vh), np.mean(vs)))
    L = float(np.mean(ell))
    x = L * np.tan(np.angle(np.exp(1j * (th - thc))))
    lo, hi = np.percentile(x, [2, 98])
    x_a, x_b = (hi - r, lo + r) if lo + r > hi - r else (0.5 * (lo + hi),) * 2

    def ranged(x0, clip):
        th0 = thc + math.atan(x0 / L)
        dd = th - th0
        sin_dd, cos_dd = np.sin(dd), np.cos(dd)

        def res_at(l0):
            m = l0 * sin_dd
            return ell - (l0 * cos_dd - np.sqrt(np.clip(r * r - m * m, 0.0, None)))

        l0 = L + r
        l0 += _median(res_at(l0))
        for _ in range(2):
            res = res_at(l0)
            k = np.abs(res) < clip
            if k.sum() < 10:
                break
            l0 += float(np.mean(res[k]))
        return l0, th0, res_at(l0)

    l_mid, _, res_mid = ranged(0.5 * (x_a + x_b), math.inf)
    noise = 1.4826 * _median(np.abs(res_mid - _median(res_mid)))
    if not np.isfinite(noise) or noise <= 0:
        return None
    prof = []
    for x0 in np.linspace(x_a, x_b, _ALONG_GRID):
        l0, th0, res = ranged(x0, 3 * noise)
        cost = float(np.sum(np.minimum(res**2, 9 * noise**2)))
        prof.append((cs + l0 * math.cos(th0), ch + l0 * math.sin(th0), cost))
    prof = np.array(prof)
    best = int(np.argmin(prof[:, 2]))
    near = prof[:, 2] - prof[best, 2] <= 4 * noise**2
    se = noise / math.sqrt(len(t))
    u_s = math.hypot(float(np.ptp(prof[near, 0])) / 4, se)
    u_h = math.hypot(float(np.ptp(prof[near, 1])) / 4, se)
    return float(prof[best, 0]), float(prof[best, 1]), u_s, u_h, float(noise)
