"""The slab's acceptance report (PDF or HTML) from the inspection results and the acceptance.

The report only reads: numbers come from the results, verdicts from :mod:`rebarlib.acceptance`.
What is computed here is presentation (pixel and plan coordinates of the bars to draw them).
HTML comes from jinja2 templates in the repository's ``templates/`` folder (autoescaped: text
from design files and captures is printed as text); weasyprint renders it with a URL fetcher
that refuses everything but ``data:`` URIs made here and the template folder's own files.
"""

from __future__ import annotations

import base64
import datetime as _dt
import math
import statistics
from pathlib import Path

from . import _pdf_writer
from ._capture import read_intrinsics
from ._checks import RebarInputError
from ._design import Design
from ._report_figures import BAR_COLOURS, LAYER_COLOURS, _image_data_uri, _image_overlay, _plan_view, over
from ._results import table_records
from ._status import ACCEPTED, NOT_CHECKED, REJECTED, SLAB_INCOMPLETE
from .acceptance import Acceptance
from ._report_rows import (
    _checkpoint_rows,
    _css_class,
    _design_context,
    _fmt,
    _item_rows,
    _max_factor_text,
    _measurement_rows,
    _not_measured_rows,
    _pct,
    _signed,
    _size,
    _spacing_status,
    _uncertainty_rows,
)

__all__ = [
    "build_report",
    "report_context",
    "render_html",
    "templates_dir",
    "write_exports",
    "safe_url_fetcher",
    "find_captures",
    "BAR_COLOURS",
]

_BAR_KEYS = (
    "bar_id",
    "layer",
    "level",
    "plan_angle_deg",
    "visible_length_mm",
    "n_points",
    "width_median_mm",
    "width_spread_mm",
    "nominal_mm",
    "confidence",
    "design_diameter_mm",
    "diameter_status",
    "diameter_reason",
    "one_sided_share",
)
VERDICT_TEXT = {
    ACCEPTED: "ACCEPTED",
    REJECTED: "NOT ACCEPTED (rejected)",
    SLAB_INCOMPLETE: "NOT ACCEPTED (incomplete: not everything could be judged)",
}
#: Longest text a design file's field (slab id, location, project, ...) is printed with; a longer
#: one is cut there with an ellipsis (the exports keep it whole). A 14 000-character id once made
#: the PDF take minutes to lay out; 200 characters fill three lines of the identification table.
FIELD_MAX_CHARS = 200


def templates_dir() -> Path:
    """The report templates: ``rebarlib/templates/`` when installed as package data, else the
    repository's ``templates/`` next to the ``rebarlib`` package (source checkout, editable install).

    Raises
    ------
    RebarInputError
        When neither folder holds ``report.html.j2`` (e.g. a wheel built without the templates).

    Examples
    --------
    >>> sorted(p.name for p in templates_dir().iterdir())
    ['overlay.svg.j2', 'plan.svg.j2', 'report.css', 'report.html.j2']
    """
    package = Path(__file__).resolve().parent
    candidates = (package / "templates", package.parent / "templates")
    for path in candidates:
        if (path / "report.html.j2").is_file():
            return path
    raise RebarInputError(
        f"report templates not found: no report.html.j2 in {candidates[0]} or {candidates[1]} "
        "(the report needs rebarlib's templates/ folder: use a source checkout, or a build that "
        "ships templates/ as package data)"
    )


# --------------------------------------------------------------------------------------------
# Safety: what weasyprint may load
# --------------------------------------------------------------------------------------------


def safe_url_fetcher(allowed_dir=None, *, refused=None):
    """A weasyprint URL fetcher that serves only ``data:`` URIs and files inside ``allowed_dir``
    (default: the templates folder).

    Every other URL (http, ftp, any other local path) is refused with ``ValueError``, which
    weasyprint turns into a missing resource. Refused URLs are appended to ``refused`` (a list)
    when one is given, so callers and tests can see what a document tried to load.
    """
    return _pdf_writer.safe_url_fetcher(allowed_dir or templates_dir(), refused=refused)


# --------------------------------------------------------------------------------------------
# Slab folders
# --------------------------------------------------------------------------------------------


def find_captures(slab_dir) -> list:
    """Capture folders of a slab folder (sub-folders holding a ``camera.json``), sorted by name.

    Examples
    --------
    >>> from pathlib import Path
    >>> [p.name for p in find_captures(Path(__file__).parent.parent / "examples" / "paper_slab")]
    ['A_400', 'B_500', 'C_600', 'D_500']
    """
    slab = Path(slab_dir)
    if not slab.is_dir():
        raise RebarInputError(f"{slab}: slab folder not found (expected design.toml and capture folders)")
    return sorted(p for p in slab.iterdir() if p.is_dir() and (p / "camera.json").is_file())


def _capture_info(folder: Path | None) -> dict:
    """Colour image path, intrinsics and metadata of a capture folder (nothing measured)."""
    if folder is None or not folder.is_dir():
        return {}
    info = {}
    try:
        info["intrinsics"], meta = read_intrinsics(folder / "camera.json")
        info["meta"] = meta
    except RebarInputError:
        return {}
    for name in ("color.jpg", "color.png"):
        if (folder / name).is_file():
            info["color"] = folder / name
            break
    return info


# --------------------------------------------------------------------------------------------
# Drawing geometry (presentation only)
# --------------------------------------------------------------------------------------------

# --------------------------------------------------------------------------------------------
# Context and rendering
# --------------------------------------------------------------------------------------------


def _no_image_text(result: dict, has_folder: bool) -> str:
    """Why a capture's section shows no colour image (a scanned cloud has none: its plan view does)."""
    if (result.get("extras") or {}).get("cloud") is not None:
        return "a scanned point cloud has no colour image; the plan view below shows its bars"
    return (
        "colour image or camera.json unreadable"
        if has_folder
        else "no capture folder with a colour image and camera.json"
    )


def _capture_folders(source) -> tuple[Path | None, dict]:
    if isinstance(source, (str, Path)):
        slab = Path(source)
        return slab, {p.name: p for p in find_captures(slab)}
    return None, {}


def _camera_basis(r: dict) -> str:
    """How the camera's systematic errors entered a result's uncertainties: "calibrated on ..."
    or "factory calibration, device profile ..." (``rebarlib.uncertainty``)."""
    extras = r.get("extras") or {}
    cal = extras.get("calibration")
    if cal:
        return cal.get("summary") or f"calibrated ({cal.get('file', 'calibration file')})"
    inp = (extras.get("uncertainty") or {}).get("inputs")
    if not inp:
        return "not recorded (the result has no uncertainty budget: the uncertainties are the fits' alone)"
    text = f"factory calibration, device profile {inp.get('name')}"
    return text + (" (no profile matched the device: conservative default)" if inp.get("default_profile") else "")


def _decision_context(acceptance: Acceptance) -> dict:
    """The decision rule and what it implied on this slab, in words for the methods section."""
    d = acceptance.decision_summary()
    pct = lambda x: f"{100 * x:.1f} %"  # noqa: E731
    d["text"] = (
        f"{d['within_not_proven']} checkpoint(s) within tolerance but not proven (the interval "
        f"± U reaches over a limit), {d['beyond_not_proven']} beyond but not proven. Over the "
        f"{d['checkpoints_with_u']} checkpoints with an uncertainty, the expected number of false "
        f"accepts is {d['expected_false_accepts']:.2f} (largest single chance "
        f"{pct(d['max_false_accept'])}) and of false rejects {d['expected_false_rejects']:.2f} "
        f"(largest {pct(d['max_false_reject'])}), for a normal error of standard deviation U / k."
    )
    return d


def report_context(source, design: Design, acceptance: Acceptance, *, now=None) -> dict:
    """Everything the template prints, as plain values (numbers already judged by ``acceptance``).

    ``source``: the slab folder (images and camera files are read from its capture folders), or
    the list of results that were judged (the report then has no images).
    """
    from . import __version__

    if not isinstance(acceptance, Acceptance):
        raise RebarInputError(
            f"acceptance: expected an Acceptance from rebarlib.acceptance.evaluate, got {type(acceptance).__name__}"
        )
    slab_dir, folders = _capture_folders(source)
    results = list(acceptance.results)
    if not isinstance(source, (str, Path)) and source is not None:
        # Results passed directly: find capture folders they name, if any.
        for r in results:
            src = (r.get("extras") or {}).get("source") or r.get("source")
            if src and Path(src).is_dir():
                folders[r["capture"]] = Path(src)
    now = now or _dt.datetime.now()
    design = _limited(design)
    slab = dict(design.slab)
    tol = acceptance.tolerances
    cp = acceptance.checkpoints
    status_of = _spacing_status(cp)
    captures, devices, dates = [], set(), set()
    for r in results:
        info = _capture_info(folders.get(str(r["capture"])))
        meta = info.get("meta", {})
        if meta.get("device"):
            devices.add(str(meta["device"]))
        if meta.get("captured_at"):
            dates.add(str(meta["captured_at"]))
        captures.append(_capture_context(r, info, folders, acceptance, status_of, design))
    items, rules = _item_rows(acceptance)
    checkpoints = table_records(cp, digits=None)
    for c in checkpoints:
        nd = 0 if c["unit"] == "bars" else 1
        c["design_text"] = _fmt(c["design_value"], nd)
        c["measured_text"] = _fmt(c["measured_value"], nd)
        c["deviation_text"] = _signed(c["deviation"], nd)
    checkpoint_rows = _checkpoint_rows(items, checkpoints, design.bar_system)
    record = str(slab.get("record", "")) or f"{design.slab_id}-{now:%Y%m%d}"
    return {
        "title": f"Rebar inspection record — slab {design.slab_id}",
        "record": record,
        "record_generated": not slab.get("record"),
        "project": slab.get("project", ""),
        "slab_id": design.slab_id,
        "element": design.element,
        "location": design.location,
        "drawing": slab.get("drawing", ""),
        "contractor": slab.get("contractor", ""),
        "lot": str(slab.get("lot", "")),
        "standard": tol.standard,
        "edition": tol.edition,
        "preset": tol.name,
        "preset_title": tol.title,
        "overrides": list(tol.overrides),
        "design_source": design.source,
        "capture_dates": ", ".join(sorted(dates)) or "not recorded in the capture files",
        "devices": ", ".join(sorted(devices)) or "not recorded",
        "software": f"rebarlib {__version__}",
        "report_date": f"{now:%Y-%m-%d %H:%M}",
        "n_captures": len(results),
        "missing_captures": [{"capture": c, "reason": r} for c, r in acceptance.missing_captures],
        "design": _design_context(design),
        "verdict": acceptance.verdict,
        "verdict_text": VERDICT_TEXT.get(acceptance.verdict, acceptance.verdict),
        "rules": rules,
        "max_factor_text": _max_factor_text(tol),
        "reasons": list(acceptance.reasons),
        "notes": list(acceptance.notes),
        "items": items,
        "checkpoints": checkpoints,
        "checkpoint_rows": checkpoint_rows,
        "captures": captures,
        "uncertainty": _uncertainty_rows(cp),
        "not_measured": _not_measured_rows(checkpoints),
        "decision": _decision_context(acceptance),
        "methods": sorted({str(r.get("method", "")) for r in results if r.get("method")}),
        "colours": BAR_COLOURS,
        "layer_colours": LAYER_COLOURS,
    }


def _mask_lean_mm(bars: list) -> float:
    """The lean the diameter stage took off this capture's mask widths (median over its bars that
    have one, mm at each bar), or 0: none taken off, or a result from before it was recorded."""
    leans = [b["mask_lean_mm"] for b in bars if isinstance(b.get("mask_lean_mm"), (int, float)) and b["mask_lean_mm"]]
    leans = [v for v in leans if math.isfinite(v)]
    return float(statistics.median(leans)) if leans else 0.0


def _capture_context(
    r: dict, info: dict, folders: dict, acceptance: Acceptance, status_of: dict, design: Design
) -> dict:
    """One capture's section: its image with the bars drawn on it, its plan view, its bars with
    their verdicts, its measurements and how the camera was placed and calibrated."""
    name = str(r["capture"])
    meta = info.get("meta", {})
    bars = [dict(b) for b in (r.get("bars") or [])]
    spacings = [{**s, "capture": name} for s in (r.get("spacings") or [])]
    bv = acceptance.bars[acceptance.bars["capture"] == name]
    verdicts = {str(k): v for k, v in zip(bv["bar_id"], bv["verdict"])}
    image = None
    if info.get("color") is not None and info.get("intrinsics") is not None:
        uri, _ = _image_data_uri(info["color"])
        K = info["intrinsics"]
        image = {
            "uri": uri,
            "width": K.width,
            "height": K.height,
            "bars": _image_overlay(bars, verdicts, K),
            "font": K.width / 60,
            "stroke": K.width / 320,
        }
    for b in bars:
        b["verdict"] = verdicts.get(str(b.get("bar_id")), NOT_CHECKED)
        for key in _BAR_KEYS:  # the template prints every column; absent = not in the result
            b.setdefault(key, None)
    cam = r.get("camera") or {}
    return {
        "name": name,
        "method": r.get("method", ""),
        "image": image,
        "image_missing": "" if image else _no_image_text(r, name in folders),
        "plan": _plan_view(
            bars,
            spacings,
            status_of,
            r.get("formwork") or {},
            design,
            positions=r.get("positions") or [],
            boundary=(r.get("extras") or {}).get("mesh_boundary"),
        ),
        "bars": bars,
        "measurements": _measurement_rows(r),
        "notes": list(r.get("notes") or []),
        "height": _fmt(cam.get("height_mm"), 0, "mm"),
        "tilt": _fmt(cam.get("tilt_deg"), 1) + ("°" if cam.get("tilt_deg") is not None else ""),
        "device": meta.get("device", "not recorded"),
        "captured_at": meta.get("captured_at", "not recorded"),
        "camera_basis": _camera_basis(r),
        "has_diameter": any("nominal_mm" in b or "diameter_status" in b for b in bars),
        "mask_lean_mm": _mask_lean_mm(bars),
    }


def _env():
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        autoescape=True,
        trim_blocks=True,
        lstrip_blocks=True,
        undefined=jinja2.StrictUndefined,
    )
    env.filters.update(fmt=_fmt, signed=_signed, pct=_pct, cls=_css_class, size=_size, over=over)
    return env


def _svg_uri(svg: str) -> str:
    return "data:image/svg+xml;base64," + base64.b64encode(svg.encode("utf-8")).decode("ascii")


def limit_text(text, n: int = FIELD_MAX_CHARS) -> str:
    """``text`` cut to ``n`` characters, the last an ellipsis, where it is longer.

    Examples
    --------
    >>> limit_text("S-101"), limit_text("x" * 300, 10)
    ('S-101', 'xxxxxxxxx…')
    """
    text = str(text)
    return text if len(text) <= n else text[: n - 1] + "…"


def _limited(design: Design) -> Design:
    """The design with every text field from its file cut to :data:`FIELD_MAX_CHARS`."""
    from dataclasses import replace

    slab = {k: limit_text(v) if isinstance(v, str) else v for k, v in design.slab.items()}
    return replace(
        design,
        slab_id=limit_text(design.slab_id),
        element=limit_text(design.element),
        location=limit_text(design.location),
        slab=slab,
    )


def render_html(context: dict) -> str:
    """The report as one self-contained HTML page (CSS inlined, images as data URIs).

    The drawings are SVG documents of their own (templates ``overlay.svg.j2``, ``plan.svg.j2``)
    embedded as data URIs: inline, their hundreds of elements would each go through the HTML
    style cascade, which doubled the PDF's layout time.
    """
    env = _env()
    overlay, plan = env.get_template("overlay.svg.j2"), env.get_template("plan.svg.j2")
    captures = []
    for c in context["captures"]:
        c = dict(c)
        if c.get("image"):
            c["image"] = {**c["image"], "overlay_uri": _svg_uri(overlay.render(image=c["image"]))}
        if c.get("plan"):
            p = c["plan"]
            # Page content is 184 mm wide; at most 80 mm high keeps image and plan on one page.
            c["plan"] = {**p, "uri": _svg_uri(plan.render(plan=p)), "display_mm": min(184.0, 80.0 * p["w"] / p["h"])}
        captures.append(c)
    return env.get_template("report.html.j2").render(**{**context, "captures": captures})


def write_exports(acceptance: Acceptance, out_path) -> list:
    """Machine-readable copies next to the report: ``<stem>_checkpoints.csv`` (every checkpoint)
    and ``<stem>_acceptance.json`` (verdict, items, checkpoints, tolerances)."""
    out = Path(out_path)
    csv_path = out.with_name(out.stem + "_checkpoints.csv")
    json_path = out.with_name(out.stem + "_acceptance.json")
    acceptance.checkpoints.to_csv(csv_path, index=False)
    json_path.write_text(acceptance.to_json(), encoding="utf-8")
    return [csv_path, json_path]


def build_report(
    slab_dir_or_results,
    design: Design,
    acceptance: Acceptance,
    *,
    out_path,
    format: str = "pdf",
    exports: bool = True,
    now=None,
    pdf_writer=None,
) -> Path:
    """Write the slab's acceptance report.

    Parameters
    ----------
    slab_dir_or_results : path of the slab folder (capture folders give the images), or the
        list of results (no images unless a result names its capture folder in ``extras.source``)
    design : Design
    acceptance : Acceptance from :func:`rebarlib.acceptance.evaluate` on those results
    out_path : where the PDF (or HTML) goes
    format : "pdf" or "html"
    exports : also write ``<stem>_checkpoints.csv`` and ``<stem>_acceptance.json`` next to it
    pdf_writer : a ``PdfWriter`` (``rebarlib._pdf_writer``) started earlier (``rebar report``
        starts one before it judges the slab, so that WeasyPrint loads meanwhile); default: the
        PDF is rendered in this process

    Returns
    -------
    Path of the report.
    """
    if format not in ("pdf", "html"):
        raise RebarInputError(f"format: expected 'pdf' or 'html', got {format!r}")
    out = Path(out_path)
    if not out.parent.is_dir():
        raise RebarInputError(f"out_path: folder {out.parent} does not exist")
    html = render_html(report_context(slab_dir_or_results, design, acceptance, now=now))
    if format == "html":
        out.write_text(html, encoding="utf-8")
    elif pdf_writer is not None:
        pdf_writer.write(html, out, templates_dir())
    else:
        _pdf_writer.write_pdf(html, out, templates_dir())
    if exports:
        write_exports(acceptance, out)
    return out
