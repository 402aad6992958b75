"""The advice for a bar left between two sizes: a capture from closer, aimed at it
(rebarlib/diameter/closer.py, docs/decisions/038)."""

from __future__ import annotations

import math

import pytest

from rebarlib._camera import GEMINI2
from rebarlib.diameter.barsizes import ENVELOPE_SIGMA_MM, WIDTH_SIGMA_DOF, bar_system
from rebarlib.diameter.closer import CloserParams, closer_advice, needed_ratio

SYSTEM = "GB1499.2"


def _posterior(width, sigma, size_index):
    """The size's posterior written out by hand: every size equally likely, the width's error
    Student's t (10 degrees of freedom) with scale hypot(σ, the table's envelope σ)."""
    env = bar_system(SYSTEM).envelope_mm
    s = math.hypot(sigma, ENVELOPE_SIGMA_MM)
    nu = WIDTH_SIGMA_DOF
    like = [(1 + ((width - e) / s) ** 2 / nu) ** (-(nu + 1) / 2) for e in env]
    return like[size_index] / sum(like)


def _by_hand(width, sigma, size_index, env, min_confidence=0.8):
    """The largest r with the scaled reading clear, by a plain scan in steps of 1e-4."""
    e = width - env
    r = 1.0
    while r > 0 and _posterior(env + e * r, sigma * r, size_index) < min_confidence:
        r -= 1e-4
    return r


def test_a_width_on_an_envelope_needs_the_sigma_that_clears_its_neighbours():
    # 18.4 mm is Φ16's envelope; its neighbours 16.2 (Φ14) and 20.5 (Φ18). By hand (see the
    # decision page): σ 0.984 mm gives scale 0.995 mm, the neighbours' likelihood ratios 0.112
    # and 0.132, the sizes beyond 0.005: posterior 0.80
    r = needed_ratio(18.4, 1.0, min_confidence=0.8, system=SYSTEM)
    assert r == pytest.approx(0.984, abs=0.002)
    assert _posterior(18.4, r, 5) == pytest.approx(0.8, abs=0.002)


@pytest.mark.parametrize("width, sigma", [(17.66, 1.436), (17.16, 1.008), (15.32, 0.981), (19.36, 0.606)])
def test_needed_ratio_matches_the_hand_computation(width, sigma):
    env = bar_system(SYSTEM).envelope_mm
    i = min(range(len(env)), key=lambda k: abs(width - env[k]))
    assert needed_ratio(width, sigma, min_confidence=0.8, system=SYSTEM) == pytest.approx(
        _by_hand(width, sigma, i, env[i]), abs=2e-3
    )


def test_needed_ratio_outside_the_table_and_already_clear():
    assert math.isnan(needed_ratio(80.0, 0.5, min_confidence=0.8, system=SYSTEM))
    assert math.isnan(needed_ratio(16.0, math.nan, min_confidence=0.8, system=SYSTEM))
    assert needed_ratio(16.2, 0.1, min_confidence=0.8, system=SYSTEM) == 1.0


def _row(reason, width=17.66, sigma=1.436):
    return {"diameter_reason": reason, "width_used_mm": width, "width_sigma_mm": sigma}


AMBIGUOUS = (
    "ambiguous: width 17.7 mm (mask) lies between Φ14 (16.2 mm) and Φ16 (18.4 mm), nearer Φ16 "
    "(confidence 0.51): check it by hand"
)


def test_advice_wording_distance_and_side():
    # the bar's seen middle 759 mm deep, to the left of the image's centre: r 0.619 -> 469.9 mm,
    # rounded down to 460
    p0, p1 = (-300.0, -20.0, 759.0), (-200.0, 20.0, 759.0)
    text = closer_advice(_row(AMBIGUOUS), p0, p1, GEMINI2, min_confidence=0.8, system=SYSTEM, deformed=True)
    assert text == (
        "; a capture with the camera about 460 mm or less from the bar (this one: 759 mm), aimed at its middle "
        "(towards the image's left edge), would tell Φ14 from Φ16 (envelopes 2.2 mm apart) at this capture's "
        "error in pixels (mark it with an aim.json naming this capture and bar, docs/formats.md)"
    )
    # a bar in the image's middle needs no aiming
    mid = closer_advice(
        _row(AMBIGUOUS), (-20, 0, 759), (20, 0, 759), GEMINI2, min_confidence=0.8, system=SYSTEM, deformed=True
    )
    assert "near the image's middle already" in mid


def test_no_promise_nearer_than_the_caps():
    # 323 mm deep, r 0.62: it would need about 200 mm, nearer than the view's coverage of a
    # 200 mm design (2 x 200 mm over the short side, 800 px at f 616.4: 308 mm)
    class Design:
        def lattice(self, layer):
            return self

        def level(self, level):
            return type("S", (), {"spacing_mm": 200.0})()

    def advise(**kw):  # the ambiguous bar seen 323 mm away, across the image's middle
        return closer_advice(
            _row(AMBIGUOUS),
            (-20, 0, 323),
            (20, 0, 323),
            GEMINI2,
            min_confidence=0.8,
            system=SYSTEM,
            deformed=True,
            **kw,
        )

    text = advise(design=Design())
    assert text.startswith("; no capture from closer is advised: it would need the camera within about 200 mm")
    assert "nearer than 308 mm" in text
    # and the camera's near range alone
    near = advise(prm=CloserParams(near_mm=250.0))
    assert "nearer than 250 mm" in near


@pytest.mark.parametrize(
    "reason",
    [
        "mask width 13.8 mm and point-cloud width 15.9 mm disagree",
        "possible wrong size: the mask width 17.4 mm gives Φ16 (confidence 0.90), but the axis was fitted ...",
        "ribs resolved: the rib crests (18.3 mm) give Φ16, the core between them (13.0 mm) Φ12: check it by hand",
        "too few clean cross-sections (4 of 46; most lost in shadow)",
        "hidden: 100% of its cross-sections lie wholly or partly under nearer bars",
    ],
)
def test_systematic_readings_get_no_promise(reason):
    assert closer_advice(_row(reason), (0, 0, 700), (50, 0, 700), GEMINI2, min_confidence=0.8, system=SYSTEM) == ""


def test_a_bar_cut_by_the_border_is_told_to_be_aimed_at():
    text = closer_advice(
        _row("too few clean cross-sections (4 of 46; most lost at the image border)", math.nan, math.nan),
        (300, 300, 801),
        (440, 320, 801),
        GEMINI2,
        min_confidence=0.8,
        system=SYSTEM,
    )
    assert text == (
        "; a capture aimed at its middle (towards the image's bottom edge), from about 650 mm or less "
        "(this one: 801 mm), would show it away from the border (mark it with an aim.json naming this capture "
        "and bar, docs/formats.md)"
    )


def test_no_capture_is_advised_from_farther_than_the_capture_guide():
    """A bar 1.2 m away (at the far border of a tilted view) is not told to be captured from about
    740 mm (r 0.619 of its distance) nor from its own distance, but from the guide's greatest
    height, 650 mm (docs/capturing.md; decision 041): from 800-1000 mm most bars are ambiguous."""
    amb = closer_advice(
        _row(AMBIGUOUS), (-300, -20, 1200), (-200, 20, 1200), GEMINI2, min_confidence=0.8, system=SYSTEM
    )
    assert "camera about 650 mm or less from the bar (this one: 1200 mm)" in amb
    border = _row("too few clean cross-sections (4 of 46; most lost at the image border)", math.nan, math.nan)
    text = closer_advice(border, (300, 300, 1029), (440, 320, 1029), GEMINI2, min_confidence=0.8, system=SYSTEM)
    assert "from about 650 mm or less (this one: 1029 mm)" in text
    # where the guide allows more, the bar's own distance stays the bound
    wide = CloserParams(far_mm=2000.0)
    far = closer_advice(
        border, (300, 300, 1029), (440, 320, 1029), GEMINI2, min_confidence=0.8, system=SYSTEM, prm=wide
    )
    assert "from about 1020 mm or less" in far
