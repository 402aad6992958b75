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
    sigma_fixed: bool = False,
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
    sigma_fixed : hold the range noise at ``sigma0_mm`` instead of fitting it: on a bar seen from
        one side the noise and the axis's place along the rays trade against each other, and the
        caller holds the noise at its set's, measured on the set's bars (decision 045)

    Returns
    -------
    (centre, sigma, weights) : the axis (across, height) in mm (with ``along``: (across, height,
    across slope, height slope), the values at ``along`` = 0 and their change per unit of it), the
    range noise along the rays (fitted, or ``sigma0_mm`` held), the weight of each direction of the
    grid; None where the fit fails (too few points for the bar, a singular step, or an axis outside
    the band)
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
    # Every per-point, per-direction sum of the EM is a product of the points' moments about the
    # current axis, ``feats`` = (x², x·y, y², x, y, 1) with x, y the offset and height from it, and
    # a (J, 6) matrix of each direction's coefficients: one matrix product a step instead of a
    # dozen passes over (J, N) arrays (the same sums, in another order). Responsibilities are
    # (J, N): the sums over the directions run along the slow axis, vectorised over the points.
    if s is not None:
        starts = bounds[:-1]
        sk = (np.add.reduceat(s, starts) / np.diff(bounds)).tolist()  # the stretches' mean positions
    feats = _moments(a, h, c, s0)
    for it in range(iters):
        # each direction's streak: covariance of its visible arc + the range noise along u + blur
        caa = cov_arc[:, 0, 0] + sig * sig * su * su + b2
        chh = cov_arc[:, 1, 1] + sig * sig * cu * cu + b2
        cah = cov_arc[:, 0, 1] + sig * sig * su * cu
        det = caa * chh - cah * cah
        if not np.all(det > 0):
            return None
        paa, phh, pah = chh / det, caa / det, -cah / det
        # log density of each point in each direction's streak: -q/2 with q the Mahalanobis
        # distance of (x - m_a, y - m_h), expanded in the moments
        ma_, mh_ = m_arc[:, 0], m_arc[:, 1]
        ga, gh = paa * ma_ + pah * mh_, pah * ma_ + phh * mh_
        const = -0.5 * (ma_ * ga + mh_ * gh) - 0.5 * np.log(det) - math.log(2 * math.pi)
        share_bar = 1.0 - share_bg - share_fw
        const += np.log(np.maximum(weights * share_bar, 1e-300))
        coef = np.stack([-0.5 * paa, -pah, -0.5 * phh, ga, gh, const], axis=1)
        rb = coef @ feats  # (J, N) log of each direction's share of each point
        top = np.maximum(rb.max(axis=0), math.log(share_bg) + log_uniform)
        if formwork_sd_mm:
            top = np.maximum(top, math.log(share_fw) + log_fw)
        rb -= top
        np.exp(rb, out=rb)
        e_bg = np.exp(math.log(share_bg) + log_uniform - top)
        z = rb.sum(axis=0) + e_bg
        if formwork_sd_mm:
            e_fw = np.exp(math.log(share_fw) + log_fw - top)
            z += e_fw
        rb /= z
        rj = rb.sum(axis=1)
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
            rj, rb = rj[live], rb[live]
            tot = float(rj.sum())
            weights = rj / tot
        share_bg = min(max(float((e_bg / z).sum()) / n, 1e-4), 0.5)
        if formwork_sd_mm:
            share_fw = min(max(float((e_fw / z).sum()) / n, 1e-4), 0.95)
        # the centre: weighted least squares of p - m_j with each streak's precision P_j
        if s is None:
            ma = rb @ a - rj * m_arc[:, 0]  # Σ_i R_ij (a_i - m_j,a)
            mh = rb @ h - rj * m_arc[:, 1]
            H = np.array([[rj @ paa, rj @ pah], [rj @ pah, rj @ phh]])
            rhs = np.array([paa @ ma + pah @ mh, pah @ ma + phh @ mh])
            try:
                c_new = np.r_[np.linalg.solve(H, rhs), 0.0, 0.0]
            except np.linalg.LinAlgError:
                return None
        else:
            # the axis as a line through the centres of stretches along the bar, each the same
            # weighted least squares on its own points, the line robust to a stretch that holds
            # something else (a block or a chair under the bar)
            # per point, Σ_j R_ij (P_j, P_j m_j): the directions contracted first, then the
            # stretches' sums
            v = np.stack([paa, pah, phh, paa * m_arc[:, 0] + pah * m_arc[:, 1], pah * m_arc[:, 0] + phh * m_arc[:, 1]])
            v = v @ rb  # (5, N)
            per = np.stack([v[0], v[1], v[2], a * v[0] + h * v[1] - v[3], a * v[1] + h * v[2] - v[4]])
            c_new = _line_through_stretches(*np.add.reduceat(per, starts, axis=1), sk)
            if c_new is None:
                return None
        # the noise along the rays: Σ R_ij t_ij² with t_ij = x_i su_j + y_i cu_j - (m_j · u_j),
        # from the moments about the new axis (which the next step starts from)
        feats = _moments(a, h, c_new, s0)
        mom = feats @ rb.T  # (6, J): Σ_i R_ij (x², xy, y², x, y, 1)
        k_u = m_arc[:, 0] * su + m_arc[:, 1] * cu
        tt = (
            su * su * mom[0]
            + 2 * su * cu * mom[1]
            + cu * cu * mom[2]
            - 2 * k_u * (su * mom[3] + cu * mom[4])
            + k_u * k_u * rj
        )
        if not sigma_fixed:
            sig = math.sqrt(max(float(tt.sum() - rj @ var_uu_arc) / tot, 0.09))
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
            sigma_fixed=sigma_fixed,
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


def _moments(a, h, c, s0):
    """(6, N) moments (x², x·y, y², x, y, 1) of the points about the axis ``c`` (across, height
    and their slopes along ``s0``): x, y each point's offset and height from it."""
    x = a - c[0] - c[2] * s0
    y = h - c[1] - c[3] * s0
    return np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)])


def _small_median(x) -> float:
    """The median of a short list of floats (the mean of the two middle values of an even one)."""
    p = sorted(x)
    k = len(p) // 2
    return (p[k - 1] + p[k]) / 2 if len(p) % 2 == 0 else p[k]


def _line_through_stretches(h00, h01, h11, r0, r1, sk, iters: int = 4):
    """(across, height, across slope, height slope) of a bar's axis: each stretch's centre (the
    streaks' weighted least squares on its points: ``h00``, ``h01``, ``h11`` (K,) each stretch's
    precision matrix Σ_i Σ_j R_ij P_j and ``r0``, ``r1`` its right-hand side
    Σ_i Σ_j R_ij P_j (p_i - m_j); ``sk`` the K stretches' mean positions along, a list), then a line
    through the centres, each weighted by its precision and Tukey-weighted (4.685 robust σ, at
    least the centres' own standard error) so that a stretch whose points something else pulls
    does not tilt it. None where a stretch's step is singular. The line's few values are plain
    floats: numpy's overhead on a dozen of them was most of the fit's cost."""
    det = h00 * h11 - h01 * h01
    if not np.all(det > 0):
        return None
    out = []
    for y, var in (
        ((h11 * r0 - h01 * r1) / det, h11 / det),  # the centres' offsets and their variances
        ((h00 * r1 - h01 * r0) / det, h00 / det),  # their heights
    ):
        out.append(_tukey_line(sk, y.tolist(), var.tolist(), iters))
    return np.array([out[0][0], out[1][0], out[0][1], out[1][1]])


def _tukey_line(x: list, y: list, var: list, iters: int):
    """(intercept, slope) of a line through points (x, y) of variances ``var``: weighted least
    squares, Tukey-weighted (4.685 robust σ of the residuals, at least the points' median
    standard error), ``iters`` times."""
    w0 = [1.0 / v for v in var]
    w = list(w0)
    se = math.sqrt(_small_median(var))
    b0 = b1 = 0.0
    for _ in range(iters):
        sw = sum(w)
        mx = sum(wi * xi for wi, xi in zip(w, x)) / sw
        my = sum(wi * yi for wi, yi in zip(w, y)) / sw
        sxx = sum(wi * (xi - mx) ** 2 for wi, xi in zip(w, x))
        b1 = sum(wi * (xi - mx) * (yi - my) for wi, xi, yi in zip(w, x, y)) / sxx if sxx > 0 else 0.0
        b0 = my - b1 * mx
        res = [yi - (b0 + b1 * xi) for xi, yi in zip(x, y)]
        scale = max(1.4826 * _small_median([abs(r) for r in res]), se) * 4.685
        w = [w0i * max(1.0 - (r / scale) ** 2, 0.0) ** 2 for w0i, r in zip(w0, res)]
        if not sum(w) > 0:
            w = list(w0)
    return b0, b1
