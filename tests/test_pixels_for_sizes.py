"""The capture-wide advice for bars left unsized by their widths where the camera's pixels put two
neighbouring sizes too close (rebarlib/diameter/closer.py ``pixels_for_sizes``, the inspection's
note, the sheet's note; docs/decisions/063)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pandas as pd
import pytest

from rebarlib._camera import GEMINI2, Intrinsics
from rebarlib._inspect import _note_pixels_for_sizes
from rebarlib.acceptance import _pixels_notes
from rebarlib.data import paper_design
from rebarlib.diameter.closer import CloserParams, envelope_gap_mm, pixels_for_sizes

SYSTEM = "GB1499.2"
#: a D435 in its 848 x 480 mode: f 422.7 px
D435_848 = Intrinsics(fx=422.675, fy=422.675, cx=423.5, cy=239.5, width=848, height=480)
AMBIGUOUS = "ambiguous: width 15.1 mm (mask) lies between Φ12 (13.9 mm) and Φ14 (16.2 mm), nearer Φ14 (confidence 0.53)"
DISAGREE = "mask width 16.4 mm and point-cloud width 18.6 mm disagree"


def _bars(*rows):
    """A bar table: (bar id, design size, status, reason, depth of the seen middle)."""
    return pd.DataFrame(
        [
            {
                "bar_id": i,
                "design_diameter_mm": d,
                "diameter_status": st,
                "diameter_reason": why,
                "start_z_mm": z - 10.0,
                "end_z_mm": z + 10.0,
            }
            for i, d, st, why, z in rows
        ]
    )


def test_envelope_gap_is_the_nearer_neighbour():
    # GB 1499.2 envelopes: Φ12 13.9, Φ14 16.2, Φ16 18.4, Φ18 20.5 mm
    assert envelope_gap_mm(14, system=SYSTEM) == pytest.approx(2.2)
    assert envelope_gap_mm(16, system=SYSTEM) == pytest.approx(2.1)
    assert envelope_gap_mm(6, system=SYSTEM) == pytest.approx(9.3 - 7.0)  # the smallest size: one neighbour
    assert math.isnan(envelope_gap_mm(13, system=SYSTEM))  # not a size of the table
    assert envelope_gap_mm(12, system=SYSTEM, deformed=False) == pytest.approx(2.0)  # nominal sizes


def test_a_bar_farther_than_its_pixels_allow_gets_the_distance_by_hand():
    # Φ14 (gap 2.2 mm) 640 mm away at f 616.395: 2.119 px < 2.5; needed 616.395 x 2.2 / 2.5 =
    # 542.4 mm -> 540 (down to 5 mm)
    adv = pixels_for_sizes(
        _bars((3, 14.0, "not measured", AMBIGUOUS, 640.0), (4, 14.0, "measured", "", 640.0)),
        GEMINI2,
        system=SYSTEM,
        design=paper_design(),
    )
    assert adv["bar_ids"] == [3]
    assert adv["gap_px"] == [pytest.approx(616.395 * 2.2 / 640, abs=0.005)] * 2
    assert adv["needed_mm"] == 540.0
    # the nearest a capture stands: 2 x 200 mm over the short side (800 px at 616.395 px): 308.2 mm
    assert adv["nearest_mm"] == pytest.approx(2 * 200 * 616.395 / 800, abs=0.05)
    assert adv["reachable"] is True
    assert adv["note"] == (
        "bar sizes: 1 bar(s) left unsized by their widths (between two sizes, or the widths disagreeing) lies "
        "640 mm from the camera, where its focal length (616 px) puts a size's rib envelope and its neighbour's "
        "(2.2 mm apart) 2.1 px apart; bars were sized reliably from 2.5 px apart (docs/capturing.md): a capture "
        "from about 540 mm or nearer to it gives that"
    )


def test_no_advice_where_the_pixels_suffice_or_the_reason_is_not_the_width():
    design = paper_design()
    # 500 mm: 616.395 x 2.2 / 500 = 2.71 px, enough
    assert pixels_for_sizes(_bars((1, 14.0, "not measured", AMBIGUOUS, 500.0)), GEMINI2, system=SYSTEM) is None
    # far, but unsized for reasons more pixels do not settle, or sized, or hidden
    others = _bars(
        (1, 14.0, "not measured", "too few clean cross-sections (4 of 46; most lost in shadow)", 900.0),
        (2, 14.0, "not measured", "possible wrong size: the mask width 17.4 mm gives Φ16 ...", 900.0),
        (3, 14.0, "hidden", "hidden: 100% of its cross-sections lie wholly or partly under nearer bars", 900.0),
        (4, 14.0, "measured", "", 900.0),
    )
    assert pixels_for_sizes(others, GEMINI2, system=SYSTEM, design=design) is None
    # a table without the columns (a result of the paper's method, no diameters) gives none
    assert pixels_for_sizes(pd.DataFrame({"bar_id": [1]}), GEMINI2, system=SYSTEM) is None
    # the gap is a parameter: at 2.0 px the 640 mm bar above (2.12 px) is enough
    amb = _bars((3, 14.0, "not measured", AMBIGUOUS, 640.0))
    assert pixels_for_sizes(amb, GEMINI2, system=SYSTEM, prm=CloserParams(min_gap_px=2.0)) is None


def test_a_camera_that_cannot_stand_near_enough_is_told_the_pixels_it_needs():
    # D435 at 848 x 480, a design of 250 mm spacings: the view keeps two of them from
    # 2 x 250 x 422.675 / 480 = 440.3 mm; a Φ16 bar (gap 2.1 mm) needs 422.675 x 2.1 / 2.5 = 355.1 mm
    design = paper_design(lower={"diameter_mm": 16, "spacing_mm": 250})
    bars = _bars((7, 16.0, "not measured", DISAGREE, 560.0), (8, 16.0, "not measured", AMBIGUOUS, 610.0))
    adv = pixels_for_sizes(bars, D435_848, system=SYSTEM, design=design)
    assert adv["bar_ids"] == [7, 8]
    assert adv["reachable"] is False
    assert adv["nearest_mm"] == pytest.approx(440.3, abs=0.05)
    assert adv["needed_mm"] == 355.0
    assert adv["focal_needed_px"] == round(2.5 * adv["nearest_mm"] / 2.1)
    assert "nearer than a capture of this slab can stand (440 mm" in adv["note"]
    assert "560–610 mm from the camera" in adv["note"] and "1.5–1.6 px apart" in adv["note"]
    # with 200 mm spacings it can stand at 352.2 mm, and 355 mm is advised
    # a bar of the same capture unsized by its width with enough pixels: not the pixels alone
    mixed = pd.concat([bars, _bars((9, 16.0, "not measured", AMBIGUOUS, 300.0))], ignore_index=True)
    adv = pixels_for_sizes(mixed, D435_848, system=SYSTEM, design=design)
    assert adv["bar_ids"] == [7, 8] and adv["unsized_with_enough_px"] == 1
    assert "though 1 other bar(s) of this capture, with 2.5 px or more, were left unsized" in adv["note"]
    near = pixels_for_sizes(
        bars, D435_848, system=SYSTEM, design=paper_design(lower={"diameter_mm": 16, "spacing_mm": 200})
    )
    assert near["reachable"] is True and near["needed_mm"] == 355.0


def test_the_inspection_notes_it_and_keeps_its_figures():
    bars = _bars((3, 14.0, "not measured", AMBIGUOUS, 640.0))
    res = SimpleNamespace(bars=bars, notes=[], extras={})
    _note_pixels_for_sizes(res, SimpleNamespace(intrinsics=GEMINI2), paper_design())
    assert res.notes[0].startswith("bar sizes: 1 bar(s) left unsized by their widths")
    assert res.extras["pixels_for_sizes"]["bar_ids"] == [3] and "note" not in res.extras["pixels_for_sizes"]
    quiet = SimpleNamespace(bars=_bars((3, 14.0, "measured", "", 640.0)), notes=[], extras={})
    _note_pixels_for_sizes(quiet, SimpleNamespace(intrinsics=GEMINI2), paper_design())
    assert quiet.notes == [] and quiet.extras == {}


def _cp(*rows):
    """Bar-size checkpoints: (capture, bar id, status)."""
    return pd.DataFrame(
        [{"item": "bar_size_lower_bottom", "capture": c, "what": f"bar {b}", "status": st} for c, b, st in rows]
    )


def test_the_sheet_counts_only_the_bars_it_still_leaves_unsized():
    adv = {"bar_ids": [3, 5], "min_gap_px": 2.5, "needed_mm": 540.0, "reachable": True, "focal_needed_px": 300.0}
    res = [{"capture": "C0", "extras": {"pixels_for_sizes": adv}}, {"capture": "C1", "extras": {}}]
    # bar 5 was sized in another capture (excluded here): one bar left
    notes = _pixels_notes(res, _cp(("C0", 3, "not measured"), ("C0", 5, "excluded"), ("C1", 3, "within")))
    assert notes == [
        "1 bar(s) left unsized (C0) lie where the camera's pixels put two neighbouring sizes' rib envelopes under "
        "2.5 px apart: from about 540 mm or nearer to the bars a capture puts them 2.5 px apart (each capture's "
        "notes say which bars)."
    ]
    # none left: no note
    assert _pixels_notes(res, _cp(("C0", 3, "within"), ("C0", 5, "excluded"))) == []
    # a capture that cannot stand near enough names the focal length
    far = {**adv, "reachable": False, "focal_needed_px": 524.0}
    notes = _pixels_notes([{"capture": "C2", "extras": {"pixels_for_sizes": far}}], _cp(("C2", 3, "not measured")))
    assert notes[0].endswith(
        "under 2.5 px apart: the camera cannot stand near enough, and a focal length of about 524 px or more is "
        "needed (each capture's notes say which bars)."
    )


def test_bars_one_capture_cannot_hold_are_grouped():
    # GEMINI2 from 540 mm sees 540 x 1280 / 616.4 = 1121 mm by 700.8 mm; less the design's 200 mm
    # spacing: cells of 921 x 500.8 mm. Bars 1 and 2 (middles 300 mm apart) share one, bar 3
    # (1200 mm to the side) another
    bars = _bars(*((i, 14.0, "not measured", AMBIGUOUS, 640.0) for i in (1, 2, 3)))
    bars["start_x_mm"] = bars["end_x_mm"] = [0.0, 300.0, 1200.0]
    bars["start_y_mm"] = bars["end_y_mm"] = [0.0, 0.0, 0.0]
    adv = pixels_for_sizes(bars, GEMINI2, system=SYSTEM, design=paper_design())
    assert adv["groups"] == [[1, 2], [3]]
    assert adv["note"].endswith(
        "a capture from about 540 mm or nearer to them gives that (2 such captures cover them: bars 1, 2; 3)"
    )
    # without the middles (a table without the x, y columns): one group
    one = pixels_for_sizes(bars.drop(columns=["start_x_mm", "end_x_mm"]), GEMINI2, system=SYSTEM, design=paper_design())
    assert one["groups"] == [[1, 2, 3]] and "such captures" not in one["note"]


def test_the_sheet_reads_a_note_without_its_gap_at_the_default():
    adv = {"bar_ids": [3], "needed_mm": 500.0, "reachable": True}  # (a result written by hand)
    notes = _pixels_notes([{"capture": "C0", "extras": {"pixels_for_sizes": adv}}], _cp(("C0", 3, "not measured")))
    assert "under 2.5 px apart: from about 500 mm or nearer" in notes[0]
