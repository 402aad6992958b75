"""A bar seen from one side: its axis from its points' cross-section, the sides it was seen from
estimated with it.

A scanner sees the half of a bar's surface that faces it, and its range noise lies along its
rays; so the points of a bar seen from one direction form a streak in the bar's cross-section:
about ±r across the ray (the visible half circle, whatever the noise) and the range noise along
it, their mean 8r/(3π) ≈ 0.85 r from the axis toward the scanner (returns per unit of surface
∝ cos² of the incidence: the rays' density on the surface and the share that return; were every
ray to return, ∝ cos, the mean would be πr/4 ≈ 0.79 r, 0.06 r nearer). A bar
seen from several stations, or from a moving scanner, is a mixture of such streaks round one
axis. The mean of the points alone is the axis only where the sides balance; where one station
sees a bar and another does not (a bar above hides it), it is off by up to 0.85 r.

:func:`seen_sides_centre` fits that mixture: the axis (shared), a weight for each direction on a
grid over the upper half plane, and the noise along the rays; plus a share of points uniform
over the band (what else lies in it) and, over a formwork, the formwork's points (heights
normal about 0 with its measured noise). Each direction's streak is taken as a Gaussian with the
mean and covariance of the surface seen from there (:func:`visible_arc`: the half circle, less
what the bars above hide) plus the range noise along the ray; the axis is the weighted
least-squares centre of the streaks (an EM). Where the noise is well under the radius the points
lie on the arc and the streaks are not Gaussian; near σ ≈ r/2 a one-sided bar's points form a
round cloud whose side cannot be told: the caller applies the fit only where the noise along
the rays is at least the radius.

Given each point's position along the bar, the axis is a line (offset and height each with a
slope): the centres of stretches of equal counts along the bar, each the weighted least-squares
centre of its own points' streaks, and a precision- and Tukey-weighted line through them. The
directions, their weights and the noise stay the bar's.

A bar above running the same way cuts the section seen from a band of directions about 13° wide
(one 85 mm above and 103 mm aside), and what is seen moves from one side of the ray to the other
within it: a station between two steps of the grid sees a strip that neither step's streak holds.
After a fit on the grid, the grid is refined about the directions that hold points and the fit is
run again from its axis, the occluders placed about that axis (decision 034).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.fit import _median


def visible_arc(phi, radius_mm: float, occluders=(), k: int = 48):
    """The surface a scanner sees of a bar from each direction ``phi`` (radians from the vertical,
    in the bar's cross-section): the mean (J, 2) and covariance (J, 2, 2) of the returns' points
    about the axis, and the share (J,) of the half circle's returns that are not hidden.

    Returns fall on the half circle facing the scanner with density ∝ cos² of the incidence; a ray
    leaving the surface toward the scanner that passes within an occluder's radius of its centre
    (``occluders``: (across, height, radius) about this bar's axis, mm: the bars above it running
    the same way) hides its point (a bar of the lattice above casts a shadow along the whole bar)."""
    r = float(radius_mm)
    psi = (np.arange(k) + 0.5) / k * math.pi - math.pi / 2
    ang = phi[:, None] + psi[None, :]
    pts = r * np.stack([np.sin(ang), np.cos(ang)], axis=-1)  # (J, K, 2)
    wgt = np.broadcast_to(np.cos(psi) ** 2, ang.shape).copy()
    full = float(wgt[0].sum())
    u = np.stack([np.sin(phi), np.cos(phi)], axis=-1)[:, None, :]  # (J, 1, 2)
    for oa, oh, ro in occluders:
        d = pts - np.array([oa, oh])
        along = (d * u).sum(-1)
        perp2 = (d * d).sum(-1) - along**2
        wgt[(along < 0) & (perp2 < ro * ro)] = 0.0
    share = wgt.sum(axis=1) / full
    norm = np.maximum(wgt.sum(axis=1), 1e-12)[:, None]
    mean = (wgt[..., None] * pts).sum(axis=1) / norm
    dev = pts - mean[:, None, :]
    cov = np.einsum("jk,jka,jkb->jab", wgt, dev, dev) / norm[..., None]
    return mean, cov, share


def seen_sides_centre(
    a,
    h,
    radius_mm: float,
    *,
    centre0,
    sigma0_mm: float,
    half_mm: float,
    formwork_sd_mm: float | None = None,
    occluders=(),
    blur_mm: float = 1.0,
    step_deg: float = 10.0,
    iters: int = 40,
    along=None,
    passes: int = 3,
    around=None,
):
    """Axis (across, height) of a bar from its cross-section points, as the centre of a mixture of
    streaks seen from a grid of directions above it.

    Parameters
    ----------
    a, h : (N,) offsets across the bar (from its current line) and heights of its band's points, mm
    radius_mm : the bar's radius (its set's envelope)
    centre0 : (across, height) to start from, mm
    sigma0_mm : the range noise to start from, mm (fitted: the spread along the streaks)
    half_mm : the band's half width across (the uniform component's extent)
    formwork_sd_mm : over a formwork, its measured noise: a component of heights N(0, that)
        uniform across the band; None without
    occluders : (across, height, radius) of the bars above this one running the same way, about
        its axis at ``centre0``, mm (:func:`visible_arc`)
    blur_mm : spread of the surface beyond the circle's (ribs, roundness)
    step_deg : the grid of view directions, from the vertical, over (-90°, 90°)
    iters : EM steps at most
    along : None, or (N,) each point's position along the bar, scaled to about ±1: the axis is
        then a line, its across offset and height each ``value + slope * along``. The mixture of
        stations that see a bar changes along it (a nearer station returns more points), so the
        mean of its points drifts across along the bar and a straight line through them takes a
        slope that the streaks do not have
    passes : fits at most. A bar above cuts the section seen from some directions, and what is
        seen then changes fast with the direction (:func:`_view_directions`): after the fit on the
        grid, the grid is refined about the directions that hold points and the fit is run again
        from its axis, the occluders placed about that axis (what a bar above hides depends on
        where this bar is); again where the axis moved by more than a tenth of the radius
    around : (directions in radians, their weights) of a fit before: the grid is refined about
        them and the fit starts from their weights (set by the passes)

    Returns
    -------
    (centre, sigma, weights) : the axis (across, height) in mm (with ``along``: (across, height,
    across slope, height slope), the values at ``along`` = 0 and their change per unit of it), the
    range noise along the rays, the weight of each direction of the grid; None where the fit fails
    (too few points for the bar, a singular step, or an axis outside the band)
    """
    a = np.asarray(a, float)
    h = np.asarray(h, float)
    n = len(a)
    if n < 30:
        return None
    r = float(radius_mm)
    base = np.radians(np.arange(-90.0 + step_deg / 2, 90.0, step_deg))
    c0 = np.array(centre0, float)
    occ = [(oa - 0.0, oh - 0.0, ro) for oa, oh, ro in occluders]
    phi, (m_arc, cov_arc, share) = _view_directions(base, r, occ, None if around is None else around[0])
    keep = share > 0.05  # a direction from which the bar is (almost) hidden sends no returns
    if not keep.any():
        return None
    phi, m_arc, cov_arc = phi[keep], m_arc[keep], cov_arc[keep]
    su, cu = np.sin(phi), np.cos(phi)
    var_uu_arc = su * su * cov_arc[:, 0, 0] + 2 * su * cu * cov_arc[:, 0, 1] + cu * cu * cov_arc[:, 1, 1]
    c = np.r_[c0, 0.0, 0.0]  # across, height, and their slopes along
    s = None if along is None else np.asarray(along, float)
    s0 = np.zeros(n) if s is None else s
    if s is not None:
        # stretches of about equal counts along the bar, at least 150 points each, 3 to 12
        k = int(np.clip(n // 150, 3, 12))
        order = np.argsort(s, kind="stable")
        a, h, s, s0 = a[order], h[order], s[order], s0[order]
        bounds = np.linspace(0, n, k + 1).astype(int)
    sig = max(float(sigma0_mm), 0.3)
    # each direction starts with the share of the half plane nearest to it: a grid refined about
    # an occluder's shadow does not start with more weight there
    edges = np.r_[-math.pi / 2, 0.5 * (phi[1:] + phi[:-1]), math.pi / 2]
    weights = np.diff(edges) / float(np.sum(np.diff(edges)))
    if around is not None:
        # after a fit: each live direction's weight shared among the directions nearest to it,
        # by their widths (the fit starts where the last one ended, fewer steps)
        near = np.argmin(np.abs(phi[:, None] - around[0][None, :]), axis=1)
        per = np.bincount(near, weights=weights, minlength=len(around[0]))
        weights = np.maximum(around[1][near] * weights / per[near], 1e-3 * weights)
        weights /= float(weights.sum())
    span_h = float(np.ptp(h)) + 1.0
    log_uniform = -math.log(2 * half_mm * span_h)
    share_bg, share_fw = 0.05, (0.3 if formwork_sd_mm else 0.0)
    if formwork_sd_mm:
        log_fw = -0.5 * (h / formwork_sd_mm) ** 2 - math.log(formwork_sd_mm * math.sqrt(2 * math.pi) * 2 * half_mm)
    b2 = blur_mm**2
    index = np.flatnonzero(keep)
    for it in range(iters):
        # each direction's streak: covariance of its visible arc + the range noise along u + blur
        caa = cov_arc[:, 0, 0] + sig * sig * su * su + b2
        chh = cov_arc[:, 1, 1] + sig * sig * cu * cu + b2
        cah = cov_arc[:, 0, 1] + sig * sig * su * cu
        det = caa * chh - cah * cah
        if not np.all(det > 0):
            return None
        paa, phh, pah = chh / det, caa / det, -cah / det
        da = (a - c[0] - c[2] * s0)[:, None] - m_arc[None, :, 0]
        dh = (h - c[1] - c[3] * s0)[:, None] - m_arc[None, :, 1]
        q = paa * da * da + 2 * pah * da * dh + phh * dh * dh
        log_b = -0.5 * q - 0.5 * np.log(det) - math.log(2 * math.pi)
        share_bar = 1.0 - share_bg - share_fw
        log_b += np.log(np.maximum(weights * share_bar, 1e-300))[None]
        cols = [log_b, np.full((n, 1), math.log(share_bg) + log_uniform)]
        if formwork_sd_mm:
            cols.append((math.log(share_fw) + log_fw)[:, None])
        allp = np.hstack(cols)
        top = allp.max(axis=1, keepdims=True)
        e = np.exp(allp - top)
        resp = e / e.sum(axis=1, keepdims=True)
        rb = resp[:, : len(phi)]
        rj = rb.sum(axis=0)
        tot = float(rj.sum())
        if tot < 20:
            return None
        weights = rj / tot
        if it >= 4 and np.any(weights < 1e-4):
            # a direction that holds no points after a few steps gains none later: drop it (cost)
            live = weights >= 1e-4
            index, phi, m_arc, cov_arc = index[live], phi[live], m_arc[live], cov_arc[live]
            su, cu, var_uu_arc = su[live], cu[live], var_uu_arc[live]
            paa, phh, pah = paa[live], phh[live], pah[live]
            rj, rb, resp = rj[live], rb[:, live], np.hstack([rb[:, live], resp[:, len(live) :]])
            tot = float(rj.sum())
            weights = rj / tot
        share_bg = min(max(float(resp[:, len(phi)].sum()) / n, 1e-4), 0.5)
        if formwork_sd_mm:
            share_fw = min(max(float(resp[:, len(phi) + 1].sum()) / n, 1e-4), 0.95)
        # the centre: weighted least squares of p - m_j with each streak's precision P_j
        ma = a @ rb - rj * m_arc[:, 0]  # Σ_i R_ij (a_i - m_j,a)
        mh = h @ rb - rj * m_arc[:, 1]
        if s is None:
            H = np.array([[rj @ paa, rj @ pah], [rj @ pah, rj @ phh]])
            rhs = np.array([paa @ ma + pah @ mh, pah @ ma + phh @ mh])
        else:
            # the axis as a line through the centres of stretches along the bar, each the same
            # weighted least squares on its own points, the line robust to a stretch that holds
            # something else (a block or a chair under the bar)
            c_new = _line_through_stretches(a, h, rb, m_arc, paa, pah, phh, s, bounds)
            if c_new is None:
                return None
        if s is None:
            try:
                c_new = np.r_[np.linalg.solve(H, rhs), 0.0, 0.0]
            except np.linalg.LinAlgError:
                return None
        da = (a - c_new[0] - c_new[2] * s0)[:, None] - m_arc[None, :, 0]
        dh = (h - c_new[1] - c_new[3] * s0)[:, None] - m_arc[None, :, 1]
        t = da * su + dh * cu
        sig = math.sqrt(max(float((rb * t * t).sum() - rj @ var_uu_arc) / tot, 0.09))
        done = float(np.max(np.abs(c_new - c))) < 0.01
        c = c_new
        if done:
            break
    if not abs(c[0]) < half_mm:
        return None
    # each direction's weight summed into the base grid's step that holds it
    full = np.zeros(len(base))
    step = math.radians(step_deg)
    np.add.at(full, np.clip(np.floor((phi + math.pi / 2) / step).astype(int), 0, len(base) - 1), weights)
    moved = c[:2] - c0
    if occluders and passes > 1 and (around is None or float(np.hypot(*moved)) > 0.1 * r):
        again = seen_sides_centre(
            a,
            h,
            r,
            centre0=c[:2],
            sigma0_mm=sig,
            half_mm=half_mm,
            formwork_sd_mm=formwork_sd_mm,
            occluders=[(oa - moved[0], oh - moved[1], ro) for oa, oh, ro in occluders],
            blur_mm=blur_mm,
            step_deg=step_deg,
            iters=iters,
            along=s,  # the points sorted along above, with ``a`` and ``h``
            passes=passes - 1,
            around=(phi, weights),  # the directions left holding points, and their weights
        )
        if again is not None:
            return again
    return (c[:2] if s is None else c), sig, full


def _view_directions(base, radius_mm: float, occluders, around=None, levels: int = 4):
    """The view directions of the streak fit, and :func:`visible_arc` of each: the grid ``base``
    (radians from the vertical), refined where a bar above hides part of the surface, within a
    step of the grid of the directions ``around`` (None: not refined); with ``around``, only the
    directions within a step of it.

    Without occluders the mean of the surface seen moves by about 0.85 r per radian of view
    direction, so by 0.85 r x step between two steps of the grid: what the fit's choice of
    direction can put it off by. Where a bar above cuts the section, what is seen changes much
    faster: the edge of its shadow sweeps across the section by the occluder's distance per
    radian (a bar 85 mm above and 103 mm aside: 2.3 mm per degree, the section cut over 13°),
    and a station between two steps of the grid sees a strip that neither step's streak holds
    (decision 034). A step whose two ends' means differ by more than an unhidden bar's do over
    the grid's step is halved, ``levels`` times at most (10° to 0.625°)."""
    phi = np.asarray(base, float)
    arc = visible_arc(phi, radius_mm, occluders)
    if not occluders or around is None or len(around) == 0 or len(phi) < 2:
        return phi, arc
    step = float(phi[1] - phi[0])
    tol = 1.05 * 0.85 * radius_mm * step  # an unhidden bar's change over one step, and a margin
    near = np.asarray(around, float)
    for _ in range(levels):
        m, _, share = arc
        jump = np.hypot(*(m[1:] - m[:-1]).T)
        seen = (share[1:] > 0.05) | (share[:-1] > 0.05)
        mid = 0.5 * (phi[1:] + phi[:-1])
        close = np.min(np.abs(mid[:, None] - near[None, :]), axis=1) <= step
        split = np.flatnonzero((jump > tol) & seen & close)
        if len(split) == 0:
            break
        phi = np.sort(np.r_[phi, mid[split]])
        arc = visible_arc(phi, radius_mm, occluders)
    # the directions more than a step from those that held points are left out: the fit before
    # found none there
    keep = np.min(np.abs(phi[:, None] - near[None, :]), axis=1) <= step + 1e-9
    return phi[keep], tuple(x[keep] for x in arc)


def _line_through_stretches(a, h, rb, m_arc, paa, pah, phh, s, bounds, iters: int = 4):
    """(across, height, across slope, height slope) of a bar's axis: each stretch's centre (the
    streaks' weighted least squares on its points, ``bounds`` the stretches' first indices into
    the points sorted along), then a line through the centres, each weighted by its precision and
    Tukey-weighted (4.685 robust σ, at least the centres' own standard error) so that a stretch
    whose points something else pulls does not tilt it. None where a stretch's step is singular."""
    starts = bounds[:-1]
    j = rb.shape[1]
    sums = np.add.reduceat(np.hstack([rb, a[:, None] * rb, h[:, None] * rb]), starts, axis=0)
    rk, ra, rh = sums[:, :j], sums[:, j : 2 * j], sums[:, 2 * j :]  # (K, J): Σ_i∈k R_ij (1, a_i, h_i)
    ma = ra - rk * m_arc[None, :, 0]
    mh = rh - rk * m_arc[None, :, 1]
    H = np.empty((len(starts), 2, 2))
    H[:, 0, 0], H[:, 0, 1], H[:, 1, 1] = rk @ paa, rk @ pah, rk @ phh
    H[:, 1, 0] = H[:, 0, 1]
    rhs = np.stack([ma @ paa + mh @ pah, ma @ pah + mh @ phh], axis=-1)
    det = H[:, 0, 0] * H[:, 1, 1] - H[:, 0, 1] ** 2
    if not np.all(det > 0):
        return None
    cen = np.linalg.solve(H, rhs[..., None])[..., 0]  # (K, 2)
    var = np.stack([H[:, 1, 1] / det, H[:, 0, 0] / det], axis=-1)  # each centre's variance
    sk = np.add.reduceat(s, starts) / np.diff(bounds)
    out = []
    for j in (0, 1):
        y, w0 = cen[:, j], 1.0 / var[:, j]
        w = w0.copy()
        se = math.sqrt(_median(var[:, j]))
        for _ in range(iters):
            sw = float(w.sum())
            mx, my = float(w @ sk) / sw, float(w @ y) / sw
            sxx = float(w @ (sk - mx) ** 2)
            b1 = float(w @ ((sk - mx) * (y - my))) / sxx if sxx > 0 else 0.0
            b0 = my - b1 * mx
            res = y - (b0 + b1 * sk)
            scale = max(1.4826 * _median(np.abs(res)), se) * 4.685
            w = w0 * np.clip(1 - (res / scale) ** 2, 0, None) ** 2
            if w.sum() <= 0:
                w = w0
        out.append((b0, b1))
    return np.array([out[0][0], out[1][0], out[0][1], out[1][1]])
