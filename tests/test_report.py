"""The acceptance report: the PDF's text equals the evaluation tables, text is escaped, weasyprint
loads nothing but the report's own assets, and ``rebar report`` handles a missing capture.

Results are built from the example captures' ground truth (``truth.json``) in the result.json
layout, with chosen numbers changed, so every verdict is known without running the inspection.
"""

from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path

import pandas as pd
import pypdf
import pytest

from rebarlib import RebarInputError, design_from_dict, load_design
from rebarlib.acceptance import design_top_cover_mm, evaluate
from rebarlib.cli import main
from rebarlib.report import build_report, render_html, report_context, safe_url_fetcher, templates_dir
from rebarlib.synth import result_from_truth as synth_result_from_truth

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
PAPER = EXAMPLES / "paper_slab"
COVER_OFF_MM = 4.6  # beyond 1.5 x the ±3 mm cover tolerance: flagged '#'
HIDE_EVERY = 5  # every 5th visible bar is reported hidden under crossing bars
EVIL = "<img src=file:///etc/passwd>"


def with_manifest(result: dict, capture: str) -> dict:
    """The result with the manifest `rebar inspect` stores: made from PAPER's capture and design."""
    from rebarlib._manifest import make_manifest

    return {**result, "manifest": make_manifest(PAPER / capture, PAPER / "design.toml", method="refined")}


def result_from_truth(capture_dir: Path, design, *, cover_offset_mm=0.0) -> dict:
    """A result.json dict holding the synthetic capture's ground truth (every 5th bar hidden)."""
    return synth_result_from_truth(capture_dir, design, hide_every=HIDE_EVERY, cover_offset_mm=cover_offset_mm)


def pdf_text(path) -> str:
    text = " ".join(p.extract_text() for p in pypdf.PdfReader(str(path)).pages)
    return re.sub(r"\s+", " ", text)


@pytest.fixture(scope="module")
def paper():
    design = load_design(PAPER)
    return design, {c: result_from_truth(PAPER / c, design) for c in ("A_400", "B_500")}


def test_pdf_text_equals_the_tables(paper, tmp_path):
    design, res = paper
    results = [res["A_400"], result_from_truth(PAPER / "B_500", design, cover_offset_mm=COVER_OFF_MM)]
    acc = evaluate(results, design)
    assert acc.verdict == "rejected"  # the cover of B is off by more than 1.5x
    cover_b = acc.checkpoints[(acc.checkpoints["item"] == "cover") & (acc.checkpoints["capture"] == "B_500")].iloc[0]
    assert (cover_b["status"], cover_b["flag"]) == ("beyond max", "#")
    out = build_report(PAPER, design, acc, out_path=tmp_path / "r.pdf")
    text = pdf_text(out)
    assert "Overall verdict: NOT ACCEPTED (rejected)" in text
    assert f"slab {design.slab_id}" in text and design.slab.get("drawing") in text
    assert "GB 50204-2015" in text
    for it in acc.items.itertuples():
        unit = "bars" if it.unit == "bars" else "mm"
        worst = f"{it.worst_deviation:+.0f} bars" if unit == "bars" else f"{it.worst_deviation:+.1f} mm"
        worst = worst.replace("+0.0 mm", "0.0 mm").replace("+0 bars", "0 bars")
        extra = ", ".join(
            t
            for t in (
                f"+{it.not_measured} n/m" if it.not_measured else "",
                f"+{it.excluded} hidden" if it.excluded else "",
            )
            if t
        )
        extra = f" ({extra})" if extra else ""
        row = f"{it.tolerance} {it.measured}{extra} {it.passed} {100 * it.pass_ratio:.0f} % {worst} {it.verdict}"
        assert row in text, f"summary row of {it.item} not in the PDF: {row!r}"
    # The flagged cover deviation is printed with its flag, as on a record sheet.
    assert f"B_500: {cover_b['deviation']:+.1f}#" in text
    # Exports next to the PDF hold every checkpoint.
    cp = pd.read_csv(tmp_path / "r_checkpoints.csv")
    assert len(cp) == len(acc.checkpoints)
    assert json.loads((tmp_path / "r_acceptance.json").read_text(encoding="utf-8"))["verdict"] == "rejected"


def test_html_draws_every_bar_and_writes_the_spacings(paper):
    design, res = paper
    acc = evaluate([res["A_400"]], design)
    html = render_html(report_context(PAPER, design, acc))
    assert html.count("data:image/jpeg;base64,") == 1
    # each sized bar's row gives its confidence; hidden ones none
    n_sized = sum(b["diameter_status"] == "measured" for b in res["A_400"]["bars"])
    assert n_sized and html.count("measured, confidence 0.97") == n_sized
    ctx = report_context(PAPER, design, acc)
    cap = ctx["captures"][0]
    drawn = {b["id"] for b in cap["image"]["bars"]}
    assert drawn == {str(b["bar_id"]) for b in res["A_400"]["bars"]}  # all visible bars are in view
    assert sum(b["hidden"] for b in cap["image"]["bars"]) == sum(b["hidden"] for b in res["A_400"]["bars"])
    labels = sorted(lab["text"] for lab in cap["plan"]["labels"])
    assert labels == sorted(f"{s['spacing_mm']:.0f}" for s in res["A_400"]["spacings"])
    # Plan coordinates are in the formwork plane: a spacing drawn equals the spacing measured.
    for lab, s in zip(cap["plan"]["labels"], res["A_400"]["spacings"]):
        gap = math.hypot(lab["x1"] - lab["x0"], lab["y1"] - lab["y0"])
        assert gap == pytest.approx(s["spacing_mm"], abs=1.0)


def test_text_from_design_files_is_escaped(paper, tmp_path):
    _, res = paper
    design = design_from_dict(
        {
            "slab": {"id": EVIL, "project": "<script>alert(1)</script>", "location": "a & b"},
            "design": {
                "cover_mm": 20,
                "layer_distance_mm": 85,
                "thickness_mm": 180,
                "lower": {"diameter_mm": 14, "spacing_mm": 200},
                "upper": {"diameter_mm": 12, "spacing_mm": 200},
            },
        }
    )
    r = dict(res["A_400"], capture=EVIL)
    acc = evaluate([r], design)
    html = render_html(report_context([r], design, acc))
    assert "<img src=file" not in html and "<script>" not in html
    assert "&lt;img src=file:///etc/passwd&gt;" in html and "a &amp; b" in html
    out = build_report([r], design, acc, out_path=tmp_path / "evil.pdf", exports=False)
    text = pdf_text(out)
    assert f"slab {EVIL}" in text and "<script>alert(1)</script>" in text


def test_url_fetcher_serves_only_data_uris_and_template_files(tmp_path):
    import weasyprint

    secret = tmp_path / "secret.css"
    secret.write_text("body { color: red }", encoding="utf-8")
    root = templates_dir()
    html = (
        f'<link rel="stylesheet" href="report.css"><link rel="stylesheet" href="{secret.as_uri()}">'
        '<link rel="stylesheet" href="../pyproject.toml">'
        '<img src="file:///etc/passwd"><img src="http://127.0.0.1:9/x.png">'
        '<img src="data:image/gif;base64,R0lGODlhAQABAAAAACwAAAAAAQABAAA=">'
    )
    refused = []
    weasyprint.HTML(
        string=html, base_url=str(root) + "/", url_fetcher=safe_url_fetcher(root, refused=refused)
    ).write_pdf()
    assert set(refused) == {
        secret.as_uri(),
        (root.parent / "pyproject.toml").as_uri(),
        "file:///etc/passwd",
        "http://127.0.0.1:9/x.png",
    }


def test_a_pdf_written_by_the_helper_process_is_the_same_file(paper, tmp_path):
    """``rebar report`` renders its PDF in a helper process that loaded WeasyPrint while the slab
    was judged: the same bytes as rendering here; the helper's failure is raised here, naming the
    file; a helper given nothing is ended."""
    import datetime

    from rebarlib._pdf_writer import PdfWriter

    design, res = paper
    acc = evaluate(list(res.values()), design)
    now = datetime.datetime(2026, 1, 2, 3, 4)
    here = build_report(PAPER, design, acc, out_path=tmp_path / "here.pdf", now=now, exports=False)
    with PdfWriter() as writer:
        helper = build_report(
            PAPER, design, acc, out_path=tmp_path / "helper.pdf", now=now, exports=False, pdf_writer=writer
        )
    assert helper.read_bytes() == here.read_bytes()
    with PdfWriter() as writer, pytest.raises(RuntimeError, match="nowhere"):
        writer.write("<p>a page</p>", tmp_path / "nowhere" / "x.pdf", templates_dir())
    assert not (tmp_path / "nowhere").exists()
    writer = PdfWriter()
    proc = writer._proc
    writer.close()
    assert proc.poll() is not None


def test_a_capture_s_mask_lean_is_said_under_its_bars(paper):
    """Where the diameter stage took a lean off a capture's mask widths (``mask_lean_mm``), the
    capture's section says how much and which way; a capture without one says nothing."""
    design, res = paper
    a = copy.deepcopy(res["A_400"])
    for b, lean in zip(a["bars"], (0.31, 0.29, 0.33, 0.30)):
        b["mask_lean_mm"] = lean
    html = render_html(report_context(PAPER, design, evaluate([a, res["B_500"]], design)))
    assert html.count("The colour mask read every bar of this capture") == 1
    assert "this capture 0.30 mm wide" in html
    a["bars"][0]["mask_lean_mm"] = a["bars"][1]["mask_lean_mm"] = -0.2
    a["bars"][2]["mask_lean_mm"] = a["bars"][3]["mask_lean_mm"] = -0.2
    html = render_html(report_context(PAPER, design, evaluate([a], design)))
    assert "this capture 0.20 mm narrow" in html


def test_cli_report_with_a_missing_capture(paper, tmp_path, capsys):
    design, res = paper
    results = tmp_path / "results"
    for name, r in res.items():  # C_600 and D_500 have no result
        (results / name).mkdir(parents=True)
        (results / name / "result.json").write_text(json.dumps(with_manifest(r, name)), encoding="utf-8")
    out = tmp_path / "report" / "S-101.pdf"
    assert main(["report", str(PAPER), "--results", str(results), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "INCOMPLETE" in printed and str(out) in printed
    saved = json.loads((tmp_path / "report" / "S-101_acceptance.json").read_text(encoding="utf-8"))
    assert saved["verdict"] == "incomplete"
    assert [m["capture"] for m in saved["missing_captures"]] == ["C_600", "D_500"]
    text = pdf_text(out)
    assert "NOT ACCEPTED (incomplete" in text and "capture C_600: no result" in text
    assert main(["report", str(PAPER), "--results", str(tmp_path / "nowhere"), "--out", str(out)]) == 2


def test_design_top_cover_used_by_the_report_is_over_the_ribs(paper):
    design, res = paper
    acc = evaluate([res["A_400"]], design)
    row = acc.items.set_index("item").loc["top_cover"]
    assert row["design_value"] == design_top_cover_mm(design) < design.top_cover_mm
    assert row["verdict"] == "pass"  # the truth's top of the bars includes the ribs


def test_cli_html_with_another_standard(paper, tmp_path):
    _, res = paper
    (tmp_path / "res" / "A_400").mkdir(parents=True)
    (tmp_path / "res" / "A_400" / "result.json").write_text(
        json.dumps(with_manifest(res["A_400"], "A_400")), encoding="utf-8"
    )
    out = tmp_path / "r.html"
    assert (
        main(
            [
                "report",
                str(PAPER),
                "--results",
                str(tmp_path / "res"),
                "--out",
                str(out),
                "--standard",
                "ACI117-318",
                "--no-exports",
            ]
        )
        == 0
    )
    html = out.read_text(encoding="utf-8")
    assert "ACI 318-19 / ACI 117-10" in html and "±76 mm" in html
    assert not (tmp_path / "r_checkpoints.csv").exists()
    assert (
        main(["report", str(PAPER), "--results", str(tmp_path / "res"), "--out", str(out), "--standard", "BS8110"]) == 2
    )


def test_cli_report_under_another_decision_rule(paper, tmp_path, capsys):
    _, res = paper
    (tmp_path / "res" / "A_400").mkdir(parents=True)
    (tmp_path / "res" / "A_400" / "result.json").write_text(
        json.dumps(with_manifest(res["A_400"], "A_400")), encoding="utf-8"
    )
    out = tmp_path / "r.html"
    args = ["report", str(PAPER), "--results", str(tmp_path / "res"), "--out", str(out), "--no-exports"]
    assert main(args + ["--decision-rule", "Proven", "--force"]) == 0
    html = out.read_text(encoding="utf-8")
    assert "rejection only where proven" in html  # the report names the rule it judged under
    assert main(args + ["--decision-rule", "lenient", "--force"]) == 2
    assert "--decision-rule: decision_rule: expected one of" in capsys.readouterr().err
    assert main(args + ["--force"]) == 0
    assert "simple acceptance (ILAC-G8 w = 0)" in out.read_text(encoding="utf-8")


def test_missing_templates_fail_with_a_clear_error(monkeypatch, tmp_path):
    import rebarlib.report as report

    monkeypatch.setattr(report, "__file__", str(tmp_path / "rebarlib" / "report.py"))
    with pytest.raises(RebarInputError, match="report templates not found"):
        report.templates_dir()


def test_unmeasured_item_is_reported_with_its_reason(paper):
    design, res = paper
    r = json.loads(json.dumps(res["A_400"]))
    r["measurements"]["layer_distance"] = {
        "value_mm": None,
        "uncertainty_mm": None,
        "n_points": 0,
        "status": "not measured",
        "reason": "upper lattice not found",
    }
    acc = evaluate([r], design)
    assert acc.verdict == "incomplete"
    ctx = report_context([r], design, acc)
    row = next(it for it in ctx["items"] if it["item"] == "layer_distance")
    assert (row["verdict"], row["ratio_text"], row["worst_text"]) == ("not measured", "–", "–")
    assert [n["reason"] for n in ctx["not_measured"]] == ["upper lattice not found"]
    html = render_html(ctx)
    assert "NOT ACCEPTED (incomplete" in html and "upper lattice not found" in html
    assert ctx["captures"][0]["image"] is None  # results without a slab folder: no image, said so
    assert "No image:" in html


def test_cli_inspects_captures_itself_without_results(paper, tmp_path, monkeypatch, capsys):
    import sys
    import types

    design, _ = paper
    calls = []

    def fake_inspect(capture, design_, *, method):
        calls.append((capture.name, method))
        if capture.name == "D_500":
            raise RebarInputError("depth image empty")
        return result_from_truth(PAPER / capture.name, design_)

    monkeypatch.setitem(sys.modules, "rebarlib._inspect", types.SimpleNamespace(inspect=fake_inspect))
    out = tmp_path / "r.html"
    assert main(["report", str(PAPER), "--out", str(out), "--method", "paper"]) == 0
    assert calls == [(c, "paper") for c in ("A_400", "B_500", "C_600", "D_500")]
    saved = json.loads((tmp_path / "r_acceptance.json").read_text(encoding="utf-8"))
    assert saved["missing_captures"] == [{"capture": "D_500", "reason": "inspection failed: depth image empty"}]
    monkeypatch.setitem(sys.modules, "rebarlib._inspect", None)  # the stage is not installed
    assert main(["report", str(PAPER), "--out", str(out), "--force"]) == 2  # (the report exists)
    assert "--results" in capsys.readouterr().err


def test_bar_row_does_not_repeat_its_status_and_a_partly_checked_bar_is_not_passed(paper):
    design, res = paper
    r = json.loads(json.dumps(res["A_400"]))
    hid = next(b for b in r["bars"] if b["hidden"])
    hid["diameter_reason"] = "hidden: 90% of its cross-sections lie wholly or partly under nearer bars"
    # a bar whose spacings are within tolerance but whose size could not be measured
    spaced = {str(s["bar_a"]) for s in r["spacings"]} | {str(s["bar_b"]) for s in r["spacings"]}
    nm = next(b for b in r["bars"] if not b["hidden"] and str(b["bar_id"]) in spaced)
    nm.update(
        nominal_mm=None,
        confidence=0.6,
        diameter_status="not measured",
        diameter_reason="ambiguous: width 15.2 mm (mask) lies between Φ12 and Φ14",
    )
    acc = evaluate([r], design)
    ctx = report_context([r], design, acc)
    rows = {str(b["bar_id"]): b for b in ctx["captures"][0]["bars"]}
    assert rows[str(nm["bar_id"])]["verdict"] == "incomplete"
    html = render_html(ctx)
    assert "hidden: 90% of its cross-sections" in html and "hidden: hidden" not in html
    assert "not measured: ambiguous: width 15.2 mm" in html


def test_a_width_from_one_edge_is_said_so_in_the_bar_table(paper):
    # A bar sized mostly from one edge and its axis (one_sided_share >= 0.5: the other edge at the
    # image border or under a nearer bar) has a width that hangs on the axis: its row says so.
    # Bars sized between two edges, and results without the column, get no such note.
    design, res = paper
    r = copy.deepcopy(res["A_400"])
    sized = [b for b in r["bars"] if b["diameter_status"] == "measured"]
    for b, share in zip(sized, (1.0, 0.5, 0.3)):
        b["one_sided_share"] = share
    html = render_html(report_context(PAPER, design, evaluate([r], design)))
    assert html.count("from one edge and the axis") == 2
    plain = render_html(report_context(PAPER, design, evaluate([res["A_400"]], design)))
    assert "from one edge" not in plain
