"""Plot helpers for the notebooks and the report: one place, never copied between notebooks.

Interactive figures are plotly (imported lazily); image overlays are numpy/OpenCV arrays so the
report can embed them too.
"""

from __future__ import annotations

import numpy as np

from ._camera import Intrinsics, project
from ._status import MEASURED

__all__ = [
    "cloud_figure",
    "image_figure",
    "overlay_mask",
    "draw_axes",
    "decimate",
    "LAYER_COLORS",
    "plane_mesh_trace",
    "axis_traces",
    "table_axes",
    "draw_bar_table",
    "plan_figure",
    "hex_rgb",
]

#: Colours used everywhere for the two lattices and the formwork.
LAYER_COLORS = {"formwork": "#b0a48c", "lower": "#1f77b4", "upper": "#d62728", "noise": "#999999"}


def decimate(n: int, max_points: int, *, rng=None) -> np.ndarray:
    """Indices of at most ``max_points`` of ``n`` items, chosen at random (sorted).

    Examples
    --------
    >>> decimate(10, 3, rng=0).shape
    (3,)
    """
    rng = np.random.default_rng(rng)
    if n <= max_points:
        return np.arange(n)
    return np.sort(rng.choice(n, max_points, replace=False))


def cloud_figure(
    points, *, groups=None, colors=None, max_points: int = 30_000, title: str = "", marker_size: float = 1.5, rng=0
):
    """A 3-D scatter of ``points`` (N, 3) mm, decimated to ``max_points`` to stay light.

    ``groups`` : (N,) labels (str or int); each group is its own trace, coloured from ``colors``
    (a dict label -> colour) when given. Camera-frame clouds are shown with y and z flipped so
    that "up" on screen is towards the camera.
    """
    import plotly.graph_objects as go

    pts = np.asarray(points, float)
    idx = decimate(len(pts), max_points, rng=rng)
    pts = pts[idx]
    fig = go.Figure()
    if groups is None:
        fig.add_trace(
            go.Scatter3d(
                x=pts[:, 0],
                y=-pts[:, 1],
                z=-pts[:, 2],
                mode="markers",
                marker=dict(size=marker_size, color=-pts[:, 2], colorscale="Viridis"),
                name="points",
            )
        )
    else:
        g = np.asarray(groups)[idx]
        for label in sorted(set(g.tolist()), key=str):
            sel = g == label
            kw = {} if colors is None or label not in colors else {"color": colors[label]}
            fig.add_trace(
                go.Scatter3d(
                    x=pts[sel, 0],
                    y=-pts[sel, 1],
                    z=-pts[sel, 2],
                    mode="markers",
                    marker=dict(size=marker_size, **kw),
                    name=str(label),
                )
            )
    fig.update_layout(
        title=title,
        scene=dict(aspectmode="data", xaxis_title="x mm", yaxis_title="-y mm", zaxis_title="-z mm"),
        margin=dict(l=0, r=0, t=40, b=0),
        legend=dict(itemsizing="constant"),
    )
    return fig


def axis_traces(starts, ends, *, names=None, color="black", width=5):
    """Plotly 3-D line traces from ``starts`` to ``ends`` (K, 3) mm, in cloud_figure's display frame."""
    import plotly.graph_objects as go

    traces = []
    for i, (a, b) in enumerate(zip(np.asarray(starts, float), np.asarray(ends, float))):
        traces.append(
            go.Scatter3d(
                x=[a[0], b[0]],
                y=[-a[1], -b[1]],
                z=[-a[2], -b[2]],
                mode="lines",
                line=dict(color=color, width=width),
                showlegend=False,
                name=str(names[i]) if names is not None else f"axis {i}",
            )
        )
    return traces


def plane_mesh_trace(normal, offset_mm, points, *, color=LAYER_COLORS["formwork"], opacity=0.3):
    """A translucent square of the plane ``normal . x + offset = 0`` spanning ``points`` (N, 3)."""
    import plotly.graph_objects as go

    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    pts = np.asarray(points, float)
    centre = pts.mean(axis=0)
    centre = centre - (n @ centre + offset_mm) * n
    u = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    r = float(np.ptp(pts, axis=0).max()) / 2
    corners = np.array([centre + r * (su * u + sv * v) for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    return go.Mesh3d(
        x=corners[:, 0],
        y=-corners[:, 1],
        z=-corners[:, 2],
        i=[0, 0],
        j=[1, 2],
        k=[2, 3],
        color=color,
        opacity=opacity,
        name="formwork plane",
    )


def image_figure(rgb, *, title: str = "", width: int = 800):
    """An RGB image (H, W, 3) uint8 as a plotly figure (pixel coordinates shown on hover)."""
    import plotly.graph_objects as go

    img = np.asarray(rgb)
    h, w = img.shape[:2]
    fig = go.Figure(go.Image(z=img))
    fig.update_layout(title=title, width=width, height=int(width * h / w) + 60, margin=dict(l=0, r=0, t=40, b=0))
    return fig


def overlay_mask(rgb, mask, *, color=(255, 0, 0), alpha: float = 0.5) -> np.ndarray:
    """``rgb`` with the pixels of ``mask`` (H, W) bool tinted by ``color`` (a float mask, a
    rebar probability such as ``rebar_mask(..., soft=True)``, counts where it is >= 0.5).

    Examples
    --------
    >>> img = np.zeros((2, 2, 3), np.uint8)
    >>> overlay_mask(img, np.eye(2, dtype=bool), color=(200, 0, 0), alpha=0.5)[0, 0].tolist()
    [100, 0, 0]
    """
    out = np.asarray(rgb).astype(np.float32).copy()
    m = np.asarray(mask)
    m = m >= 0.5 if np.issubdtype(m.dtype, np.floating) else m.astype(bool)
    out[m] = (1 - alpha) * out[m] + alpha * np.asarray(color, np.float32)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def draw_axes(rgb, starts, ends, intrinsics: Intrinsics, *, labels=None, colors=None, thickness: int = 2) -> np.ndarray:
    """``rgb`` with bar axes (camera-frame end points, mm) projected and drawn, optionally labelled.

    ``colors`` : one RGB tuple per axis (default red).
    """
    import cv2

    out = np.ascontiguousarray(np.asarray(rgb, np.uint8).copy())
    a = project(np.asarray(starts, float), intrinsics)
    b = project(np.asarray(ends, float), intrinsics)
    for i in range(len(a)):
        col = tuple(int(c) for c in (colors[i] if colors is not None else (255, 0, 0)))
        p, q = tuple(int(round(x)) for x in a[i]), tuple(int(round(x)) for x in b[i])
        cv2.line(out, p, q, col, thickness, cv2.LINE_AA)
        if labels is not None:
            m = ((a[i] + b[i]) / 2).astype(int)
            cv2.putText(
                out,
                str(labels[i]),
                (int(m[0]) + 4, int(m[1]) - 4),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.5,
                (255, 255, 255),
                3,
                cv2.LINE_AA,
            )
            cv2.putText(
                out, str(labels[i]), (int(m[0]) + 4, int(m[1]) - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.5, col, 1, cv2.LINE_AA
            )
    return out


def hex_rgb(color: str) -> tuple:
    """``"#1f77b4"`` -> ``(31, 119, 180)``.

    Examples
    --------
    >>> hex_rgb("#ff8000")
    (255, 128, 0)
    """
    c = color.lstrip("#")
    return tuple(int(c[i : i + 2], 16) for i in (0, 2, 4))


def table_axes(bars) -> tuple[np.ndarray, np.ndarray]:
    """Axis start and end points (K, 3) mm of a bar table (``start_x_mm`` ... ``end_z_mm``)."""
    starts = bars[["start_x_mm", "start_y_mm", "start_z_mm"]].to_numpy(float)
    ends = bars[["end_x_mm", "end_y_mm", "end_z_mm"]].to_numpy(float)
    return starts, ends


def draw_bar_table(rgb, bars, intrinsics: Intrinsics, *, color_by: str = "layer") -> np.ndarray:
    """``rgb`` with every bar of a bar table drawn and labelled with its id, coloured by layer
    (``color_by="layer"``) or grey for bars whose ``status`` is not "measured"."""
    starts, ends = table_axes(bars)
    colors = []
    for rec in bars.itertuples():
        if getattr(rec, "status", MEASURED) != MEASURED:
            colors.append((160, 160, 160))
        else:
            colors.append(hex_rgb(LAYER_COLORS.get(getattr(rec, color_by), "#000000")))
    return draw_axes(rgb, starts, ends, intrinsics, labels=bars["bar_id"].tolist(), colors=colors)


def plan_figure(bars, spacings=None, *, title: str = "plan view"):
    """A top view of the bar axes (camera x / y, mm) with each measured spacing written between
    its two bars. Camera-frame x and y are close to plan coordinates for a camera looking down."""
    import plotly.graph_objects as go

    fig = go.Figure()
    starts, ends = table_axes(bars)
    mids = {}
    for rec, a, b in zip(bars.itertuples(), starts, ends):
        fig.add_trace(
            go.Scatter(
                x=[a[0], b[0]],
                y=[a[1], b[1]],
                mode="lines",
                line=dict(
                    color=LAYER_COLORS.get(rec.layer, "black"),
                    width=4 if rec.layer == "upper" else 3,
                    dash="solid" if getattr(rec, "status", MEASURED) == MEASURED else "dot",
                ),
                name=f"bar {rec.bar_id} ({rec.layer} {rec.level})",
                showlegend=False,
            )
        )
        mids[rec.bar_id] = (a + b) / 2
    if spacings is not None:
        for s in spacings.itertuples():
            if s.bar_a in mids and s.bar_b in mids and np.isfinite(s.spacing_mm):
                m = (mids[s.bar_a] + mids[s.bar_b]) / 2
                fig.add_annotation(
                    x=m[0],
                    y=m[1],
                    text=f"{s.spacing_mm:.1f}",
                    showarrow=False,
                    font=dict(size=10, color=LAYER_COLORS.get(s.layer, "black")),
                )
    fig.update_layout(
        title=title,
        xaxis_title="x mm",
        yaxis_title="y mm",
        width=700,
        height=600,
        yaxis=dict(scaleanchor="x", autorange="reversed"),
        margin=dict(l=40, r=20, t=40, b=40),
    )
    return fig
