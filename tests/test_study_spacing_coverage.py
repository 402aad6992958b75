"""benchmarks/study_spacing_coverage.py: a measured spacing is scored against the truth of the
two true bars its bars are matched to, in the worst kind of its two bars, and its error is
counted against its stated uncertainty."""

import json
import sys

from benchmarks.study_spacing_coverage import main, rows_of, study


def _true(i, y, partner=None):
    return {
        "id": i,
        "layer": "lower",
        "axis_start_mm": [-300.0, y, 500.0],
        "axis_end_mm": [300.0, y, 500.0],
        "lap_partner": partner,
    }


def _bar(i, y, *, one=0.0, occluded=0.0, status="measured"):
    ends = {
        f"{e}_{k}_mm": v
        for e, p in (("start", [-250.0, y, 500.0]), ("end", [250.0, y, 500.0]))
        for k, v in zip("xyz", p)
    }
    return {
        "bar_id": i,
        "layer": "lower",
        "status": status,
        "one_sided_share": one,
        "occluded_fraction": occluded,
        **ends,
    }


def _spacing(a, b, value, u, status="measured"):
    return {"bar_a": a, "bar_b": b, "spacing_mm": value, "uncertainty_mm": u, "status": status}


TRUTH = {
    # bars at 0, 200, and a lap at 392 / 408 whose piece at 392 this capture sees alone
    "bars": [_true(10, 0.0), _true(11, 200.0), _true(12, 392.0, 13), _true(13, 408.0, 12)],
    "spacings": [{"bar_a": 10, "bar_b": 11, "spacing_mm": 200.0}, {"bar_a": 11, "bar_b": 12, "spacing_mm": 192.0}],
}
RESULT = {
    "bars": [
        _bar(0, 0.5),
        _bar(1, 200.2, one=0.8, occluded=0.6),
        _bar(2, 392.3),
        _bar(3, 600.0),  # no true bar within 20 mm: not matched
    ],
    "spacings": [
        _spacing(0, 1, 199.7, 0.5),  # error -0.3 mm: 0.6 u
        _spacing(1, 2, 194.1, 0.5),  # error +2.1 mm: 4.2 u
        _spacing(2, 3, 207.7, 0.5),  # bar 3 not matched: not scored
        _spacing(0, 2, None, None, status="not measured"),
    ],
}


def test_spacings_are_scored_in_the_worst_kind_of_their_bars():
    rows = rows_of(RESULT, TRUTH, "slab_000/C0")
    assert [(r["kind"], round(r["err"], 2), round(r["z"], 2)) for r in rows] == [
        ("one edge, under a nearer bar", -0.3, 0.6),
        ("lap", 2.1, 4.2),
    ]
    assert rows[1]["where"] == "slab_000/C0 bars 1-2"


def test_a_cache_is_read_and_the_table_printed(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "tabulate", None)  # not a dependency: the table is printed without it
    folder = tmp_path / "slab_000"
    (folder / "C0").mkdir(parents=True)
    (folder / "slab.json").write_text(json.dumps({"captures": ["C0"]}))
    (folder / "C0" / "truth.json").write_text(json.dumps(TRUTH))
    (folder / "result_C0.json").write_text(json.dumps(RESULT))
    df = study([tmp_path])
    assert len(df) == 2 and set(df.kind) == {"lap", "one edge, under a nearer bar"}
    assert main(["--cache", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "2 measured spacings matched" in out and "1 beyond 3 u" in out
    assert "slab_000/C0 bars 1-2: error +2.10 mm, u 0.50 mm (lap)" in out
    assert "| lap | 1 | 0.00 | 4.20 | 4.20 | 2.10 | 0.50 |" in out
