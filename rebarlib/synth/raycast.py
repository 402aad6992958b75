"""The scene as triangles, and the rays cast into it: Open3D's ``RaycastingScene`` finds which
object a ray meets first (on slightly over-sized prisms), then the hit is refined analytically
against the true cylinder (or marched through a bar's ribs drawn in relief), so depths on bars
are exact to floating-point precision with the ideal sensor."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..diameter.barsizes import GB_RIB_PITCH as _GB_RIB_PITCH
from ..diameter.barsizes import GB_RIBS as _GB_RIBS
from .scene import SlabScene

__all__ = ["K_FORMWORK", "K_BAR", "K_SPACER", "K_CHAIR", "K_TIE"]

_N_SIDES = 16


def _prism(p0, p1, r, n=_N_SIDES):
    """Triangles of an n-sided prism circumscribing the cylinder p0-p1 of radius r (with caps)."""
    a = p1 - p0
    a = a / np.linalg.norm(a)
    u = np.cross(a, [0, 0, 1.0] if abs(a[2]) < 0.9 else [1.0, 0, 0])
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    rc = r / math.cos(math.pi / n) * 1.001
    ang = np.arange(n) * 2 * math.pi / n
    ring = rc * (np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * w)
    verts = np.vstack((p0 + ring, p1 + ring, p0, p1))
    i = np.arange(n)
    j = (i + 1) % n
    side = np.vstack((np.column_stack((i, j, n + i)), np.column_stack((j, n + j, n + i))))
    caps = np.vstack(
        (np.column_stack((np.full(n, 2 * n), j, i)), np.column_stack((np.full(n, 2 * n + 1), n + i, n + j)))
    )
    return verts, np.vstack((side, caps))


def _box(c, hs, yaw):
    """Triangles of a box of half-sizes ``hs`` centred on ``c``, turned ``yaw`` rad about z."""
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float) * hs
    cy, sy = math.cos(yaw), math.sin(yaw)
    R = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1.0]])
    verts = corners @ R.T + c
    tris = np.array(
        [
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],
        ]
    )
    return verts, tris


# object kinds, in the per-object table
K_FORMWORK, K_BAR, K_SPACER, K_CHAIR, K_TIE = 0, 1, 2, 3, 4


@dataclass
class _Geometry:
    """The scene as one triangle mesh, with a table per object (row 0: the formwork plane)."""

    verts: np.ndarray
    tris: np.ndarray
    tri_obj: np.ndarray  # object index of each triangle
    obj_kind: np.ndarray
    obj_bar: np.ndarray  # bar id of each object (-1 if not a bar segment)
    seg_p0: np.ndarray  # per object: cylinder segment (bars only)
    seg_p1: np.ndarray
    seg_r: np.ndarray
    # per object, for bars drawn in relief: core radius, rib height, rib spacing, shift of the
    # second side's ribs (share of a spacing), roll (rad) and the segment's start along its bar;
    # NaN core radius: a smooth cylinder of radius seg_r
    seg_rib: np.ndarray


def _relief_params(nominal_mm: float) -> tuple[float, float, float]:
    """Core radius, rib height and transverse-rib spacing (mm) of a GB 1499.2 crescent-rib bar;
    sizes not in the table scale from the nearest one."""
    key = min(_GB_RIBS, key=lambda s: abs(s - nominal_mm))
    d1, h = _GB_RIBS[key]
    k = nominal_mm / key
    return d1 * k / 2, h * k, _GB_RIB_PITCH[key] * k


def _relief_radius(s, psi, r1, h, pitch, shift):
    """Surface radius of a crescent-rib bar at ``s`` mm along it and ``psi`` rad around it from
    a longitudinal rib (arrays broadcast together).

    A core of radius ``r1``; two longitudinal ribs (psi = 0 and π) of height ``h``; transverse
    ribs every ``pitch`` on each side between them (those of the side psi in (π, 2π) shifted
    by ``shift`` x ``pitch``), highest (``h``) half-way round and tapering to the longitudinal
    ribs like a crescent. Rib tops 0.1 x the bar diameter wide, flanks at 45°."""
    top = 0.05 * 2 * (r1 + h)  # half the width of a rib's top
    ang = np.abs(np.mod(psi + np.pi / 2, np.pi) - np.pi / 2)  # angle to the nearer longitudinal rib
    longitudinal = h * np.clip((top + h - r1 * ang) / h, 0, 1)
    sin = np.sin(psi)
    x = s / pitch - np.where(sin < 0, shift, 0.0)
    x = np.abs(x - np.round(x)) * pitch  # distance along the bar to the nearest rib's middle
    transverse = h * np.abs(sin) * np.clip((top + h - x) / h, 0, 1)
    return r1 + np.maximum(longitudinal, transverse)


def _build_geometry(scene: SlabScene) -> _Geometry:
    """The triangles of every object of ``scene``: the formwork plane, each bar's segments as
    prisms (with their exact cylinders, and ribs where drawn in relief), the boxes and the rods."""
    half = scene.deviations.slab_size_mm * 2
    V = [np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], float)]
    T = [np.array([[0, 1, 2], [0, 2, 3]])]
    kinds, barid, p0s, p1s, rs = [K_FORMWORK], [-1], [np.zeros(3)], [np.zeros(3)], [0.0]
    no_rib = [math.nan] * 6
    ribs = [no_rib]
    relief = scene.deviations.ribs and scene.deviations.rib_relief
    # roll and rib shift of each bar belong to the slab (its key), not to the shot
    rib_rng = np.random.default_rng([scene.key, 2])
    for b in scene.bars:
        if relief:
            r1, h, pitch = _relief_params(b.nominal_mm)
            bar_rib = [r1, h, pitch, rib_rng.uniform(0, 1), rib_rng.uniform(0, 2 * math.pi)]
        s0 = 0.0
        for p0, p1 in zip(b.axis[:-1], b.axis[1:]):
            v, t = _prism(p0, p1, b.radius_mm)
            V.append(v), T.append(t)
            (kinds.append(K_BAR), barid.append(b.id), p0s.append(p0), p1s.append(p1), rs.append(b.radius_mm))
            ribs.append(bar_rib + [s0] if relief else no_rib)
            s0 += float(np.linalg.norm(p1 - p0))
    for c, hs, yaw, kind in scene.boxes:
        v, t = _box(c, hs, yaw)
        V.append(v), T.append(t)
        kinds.append(K_FORMWORK if kind == "edge_form" else K_SPACER), barid.append(-1)
        p0s.append(np.zeros(3)), p1s.append(np.zeros(3)), rs.append(0.0)
        ribs.append(no_rib)
    for p0, p1, r, kind in scene.rods:
        v, t = _prism(p0, p1, r, 8)
        V.append(v), T.append(t)
        kinds.append(K_CHAIR if kind == "chair" else K_TIE), barid.append(-1)
        p0s.append(np.zeros(3)), p1s.append(np.zeros(3)), rs.append(0.0)
        ribs.append(no_rib)
    offsets = np.cumsum([0] + [len(v) for v in V[:-1]])
    tris = np.vstack([t + o for t, o in zip(T, offsets)])
    tri_obj = np.concatenate([np.full(len(t), i) for i, t in enumerate(T)])
    return _Geometry(
        np.vstack(V),
        tris,
        tri_obj,
        np.array(kinds),
        np.array(barid),
        np.array(p0s),
        np.array(p1s),
        np.array(rs),
        np.array(ribs, float),
    )


class _Caster:
    """Open3D ray casting over the merged scene mesh (built once per render)."""

    def __init__(self, geo: _Geometry):
        import open3d as o3d

        self.o3d = o3d
        self.geo = geo
        mesh = o3d.t.geometry.TriangleMesh()
        mesh.vertex.positions = o3d.core.Tensor(geo.verts.astype(np.float32))
        mesh.triangle.indices = o3d.core.Tensor(geo.tris.astype(np.int32))
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(mesh)

    def first_hit(self, origins, dirs):
        """(t, object index, normal) of the first hit along each ray, bars exact; t = inf on a miss."""
        n = len(dirs)
        t = np.full(n, np.inf)
        obj = np.full(n, -1)
        normal = np.zeros((n, 3))
        todo = np.arange(n)
        start = np.zeros(n)
        for _ in range(8):  # re-cast the few rays that pass through a prism but miss its cylinder
            if len(todo) == 0:
                break
            o = origins[todo] + dirs[todo] * start[todo, None]
            rays = np.hstack((o, dirs[todo])).astype(np.float32)
            ans = self.scene.cast_rays(self.o3d.core.Tensor(rays))
            th = ans["t_hit"].numpy().astype(np.float64) + start[todo]
            prim = ans["primitive_ids"].numpy().astype(np.int64)
            hit = np.isfinite(th)
            ob = np.where(hit, self.geo.tri_obj[np.where(hit, prim, 0)], -1)
            nrm = ans["primitive_normals"].numpy().astype(np.float64)
            is_bar = hit & (self.geo.obj_kind[np.maximum(ob, 0)] == K_BAR)
            # exact cylinder intersection for bar hits (or the relief of a bar's ribs)
            tb, nb, ok = _ray_cylinder(
                origins[todo][is_bar],
                dirs[todo][is_bar],
                self.geo.seg_p0[ob[is_bar]],
                self.geo.seg_p1[ob[is_bar]],
                self.geo.seg_r[ob[is_bar]],
            )
            rib = self.geo.seg_rib[ob[is_bar]]
            relief = np.isfinite(rib[:, 0])
            if relief.any():
                sel_b = np.flatnonzero(is_bar)[relief]
                tb[relief], nb[relief], ok[relief] = _ray_relief(
                    origins[todo][sel_b],
                    dirs[todo][sel_b],
                    self.geo.seg_p0[ob[sel_b]],
                    self.geo.seg_p1[ob[sel_b]],
                    rib[relief],
                )
            th_b = th[is_bar]
            th_b[ok] = tb[ok]
            nrm[is_bar] = np.where(ok[:, None], nb, nrm[is_bar])
            th[is_bar] = th_b
            done = ~is_bar.copy()
            bar_idx = np.flatnonzero(is_bar)
            done[bar_idx[ok]] = True
            sel = todo[done]
            t[sel], obj[sel], normal[sel] = th[done], ob[done], nrm[done]
            # planar formwork: exact by construction; flip normals to face the ray
            retry = todo[~done]
            start[retry] = th[~done] + 1e-3
            todo = retry
        flip = (normal * dirs).sum(axis=1) > 0
        normal[flip] *= -1
        return t, obj, normal

    def occluded(self, origins, dirs, t_max, own=None):
        """Whether anything lies on each segment origin -> origin + t_max * dir. ``own``: per ray,
        the object it starts on where that is a bar in relief (else -1): its surface lies inside
        its own prism, which the ray leaves first (a rib does not shade the core beside it here)."""
        origins = np.asarray(origins, np.float64)
        start = np.zeros(len(origins))
        th = np.full(len(origins), np.inf)
        todo = np.arange(len(origins))
        own = np.full(len(origins), -1) if own is None else np.array(own)  # (a copy: cleared below)
        for _ in range(2):  # at most once through its own prism
            rays = np.hstack((origins[todo] + dirs[todo] * start[todo, None], dirs[todo])).astype(np.float32)
            ans = self.scene.cast_rays(self.o3d.core.Tensor(rays))
            t_k = ans["t_hit"].numpy().astype(np.float64)
            prim = ans["primitive_ids"].numpy().astype(np.int64)
            hit = np.isfinite(t_k)
            self_hit = hit & (own[todo] >= 0) & (self.geo.tri_obj[np.where(hit, prim, 0)] == own[todo])
            th[todo] = start[todo] + t_k
            own[todo] = -1
            start[todo[self_hit]] += t_k[self_hit] + 1e-3
            th[todo[self_hit]] = np.inf
            todo = todo[self_hit]
        return th < t_max


def _ray_cylinder(o, d, p0, p1, r):
    """Nearest intersection of rays o + t d with finite cylinders (side and caps)."""
    axis = p1 - p0
    L = np.linalg.norm(axis, axis=1)
    a = axis / L[:, None]
    w = o - p0
    da = (d * a).sum(1)
    wa = (w * a).sum(1)
    dp = d - da[:, None] * a
    wp = w - wa[:, None] * a
    A = (dp * dp).sum(1)
    B = (wp * dp).sum(1)
    C = (wp * wp).sum(1) - r * r
    disc = B * B - A * C
    with np.errstate(invalid="ignore", divide="ignore"):
        t_side = (-B - np.sqrt(np.maximum(disc, 0))) / A
    s = wa + t_side * da
    side_ok = (disc >= 0) & (A > 1e-12) & (s >= 0) & (s <= L) & (t_side > 0)
    t = np.where(side_ok, t_side, np.inf)
    n = np.zeros_like(o)
    pt = o + t_side[:, None] * d
    radial = pt - p0 - ((pt - p0) * a).sum(1)[:, None] * a
    n[side_ok] = radial[side_ok] / r[side_ok, None]
    for cap, sign in ((0.0, -1.0), (1.0, 1.0)):
        with np.errstate(invalid="ignore", divide="ignore"):
            tc = (cap * L - wa) / da
        pc = o + tc[:, None] * d - (p0 + cap * L[:, None] * a)
        inside = ((pc * pc).sum(1) - ((pc * a).sum(1)) ** 2) <= r * r
        better = inside & (tc > 0) & (tc < t)
        t = np.where(better, tc, t)
        n[better] = sign * a[better]
    return t, n, np.isfinite(t)


def _relief_frame(a):
    """Unit vectors u (level) and w across bar directions ``a`` (n, 3): psi is measured from u."""
    u = np.cross(a, [0.0, 0.0, 1.0])
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    return u, np.cross(a, u)


def _relief_gap(x, p0, a, u, w, rib):
    """Distance of points ``x`` from the axis minus the relief's radius there (< 0: inside the
    bar), and their position along the segment (mm)."""
    rel = x - p0
    s = (rel * a).sum(-1)
    radial = rel - s[..., None] * a
    rho = np.linalg.norm(radial, axis=-1)
    psi = np.arctan2((radial * w).sum(-1), (radial * u).sum(-1)) - rib[..., 4]
    return rho - _relief_radius(s + rib[..., 5], psi, rib[..., 0], rib[..., 1], rib[..., 2], rib[..., 3]), s


#: rays marched through the ribs' relief at a time: each ray's samples of one block are held at once
#: (about 4 kB a ray), so a supersampled image with many bars in view stays within a few hundred MB
RELIEF_CHUNK = 32768


def _ray_relief(o, d, p0, p1, rib, step_mm=0.03, block=48, bisections=12):
    """Nearest intersection of rays o + t d with bar segments drawn in relief (``rib`` rows as
    ``_Geometry.seg_rib``); (t, normal, hit). Marched in ``step_mm`` steps through the rib
    envelope's cylinder, then bisected: a ray that grazes between two ribs is a miss here. The
    rays go ``RELIEF_CHUNK`` at a time (each ray's result does not depend on the others)."""
    if len(o) > RELIEF_CHUNK:
        parts = [
            _ray_relief(*(x[i : i + RELIEF_CHUNK] for x in (o, d, p0, p1, rib)), step_mm, block, bisections)
            for i in range(0, len(o), RELIEF_CHUNK)
        ]
        return tuple(np.concatenate(x) for x in zip(*parts))
    n = len(o)
    t_hit, normal, hit = np.full(n, np.inf), np.zeros((n, 3)), np.zeros(n, bool)
    axis = p1 - p0
    L = np.linalg.norm(axis, axis=1)
    a = axis / L[:, None]
    u, w = _relief_frame(a)
    R = rib[:, 0] + rib[:, 1]
    dp = d - (d * a).sum(1)[:, None] * a
    wp = (o - p0) - ((o - p0) * a).sum(1)[:, None] * a
    A, B, C = (dp * dp).sum(1), (wp * dp).sum(1), (wp * wp).sum(1) - R * R
    disc = B * B - A * C
    good = (disc > 0) & (A > 1e-12)
    root = np.sqrt(np.where(good, disc, 0))
    t_in = np.where(good, np.maximum((-B - root) / np.where(good, A, 1), 0), np.inf)
    t_out = np.where(good, (-B + root) / np.where(good, A, 1), -np.inf)
    active = np.flatnonzero(good & (t_out > t_in))
    t_cur = t_in.copy()
    k = np.arange(block + 1)
    while len(active):
        i = active
        T = np.minimum(t_cur[i, None] + step_mm * k[None, :], t_out[i, None])  # (m, block+1)
        X = o[i, None, :] + T[..., None] * d[i, None, :]
        f, s = _relief_gap(X, p0[i, None, :], a[i, None, :], u[i, None, :], w[i, None, :], rib[i, None, :])
        inside = (f <= 0) & (s >= 0) & (s <= L[i, None])
        first = np.where(inside.any(axis=1), inside.argmax(axis=1), -1)
        found = first >= 0
        # bracket: the sample before the first one inside (at the entry itself: a hit there)
        j = np.flatnonzero(found)
        lo = T[j, np.maximum(first[j] - 1, 0)]
        hi = T[j, first[j]]
        ii = i[j]
        for _ in range(bisections):
            mid = (lo + hi) / 2
            fm, sm = _relief_gap(o[ii] + mid[:, None] * d[ii], p0[ii], a[ii], u[ii], w[ii], rib[ii])
            ins = (fm <= 0) & (sm >= 0) & (sm <= L[ii])
            hi = np.where(ins, mid, hi)
            lo = np.where(ins, lo, mid)
        t_hit[ii], hit[ii] = hi, True
        t_cur[i] = T[:, -1]
        active = i[~found & (T[:, -1] < t_out[i])]
    # normals: the gradient of the gap function at the hits (central differences)
    j = np.flatnonzero(hit)
    if len(j):
        x = o[j] + t_hit[j, None] * d[j]
        eps = 0.004
        g = np.zeros((len(j), 3))
        for c in range(3):
            e = np.zeros(3)
            e[c] = eps
            fp, _ = _relief_gap(x + e, p0[j], a[j], u[j], w[j], rib[j])
            fm, _ = _relief_gap(x - e, p0[j], a[j], u[j], w[j], rib[j])
            g[:, c] = fp - fm
        normal[j] = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-12)
    return t_hit, normal, hit
