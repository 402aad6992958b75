"""The datum (formwork) plane is told from the lowest lattice by whether its points line up along
bar directions (decision 040). Ground truth: two lattices laid out here, with and without a plane
under them that has the bars' shadows cut out of it."""

import numpy as np

from rebarlib.scan._datum import find_datum

SPACING, R = 200.0, 7.0
OFFSETS = np.arange(-900.0, 901.0, SPACING)


def _bars(rng, height, along_x, sig_plan, sig_h=8.0, per_mm=2.0, shift=0.0):
    """Points on the upper half of bars of radius R with axes at ``height``, every SPACING, spread
    by ``sig_plan`` across and ``sig_h`` in height (range noise along slanting rays)."""
    out = []
    for o in OFFSETS + shift:
        n = int(per_mm * 2000)
        t, a = rng.uniform(-1000, 1000, n), rng.uniform(0, np.pi, n)
        across = o + R * np.cos(a) + rng.normal(0, sig_plan, n)
        up = height + R * np.sin(a) + rng.normal(0, sig_h, n)
        out.append(np.c_[t, across, up] if along_x else np.c_[across, t, up])
    return np.vstack(out)


def _mesh(rng):
    """Two lattices (axes at 7/21 mm and 92/104 mm) with nothing under them. The lower lattice's
    two levels merge into one height peak (8 mm of height noise) whose points, both directions
    together, line up 1.6 times over a typical angle's; the upper lattice's top level hides its
    bottom one (0.1 points per mm there), and alone lines up 8 times over: the lowest peak's
    excess is under a quarter of what lies above it, which the earlier rule read as a plane."""
    return np.vstack(
        [
            _bars(rng, 7.0, True, 6.0),
            _bars(rng, 21.0, False, 6.0),
            _bars(rng, 92.0, True, 2.0, per_mm=0.1, shift=100.0),
            _bars(rng, 104.0, False, 2.0, shift=100.0),
        ]
    )


def test_a_lattice_whose_levels_merge_is_not_taken_for_a_formwork():
    d = find_datum(_mesh(np.random.default_rng(0)), [0, 0, 1.0], rng=0)
    assert not d.found and "bars" in d.reason


def test_a_formwork_with_the_bars_shadows_is_found():
    rng = np.random.default_rng(1)
    mesh = _mesh(rng)
    xy = rng.uniform(-1000, 1000, (200_000, 2))
    # shadows: a stripe 30 mm wide beside each bar of the lowest level (15 % of the plane)
    shadow = np.any(np.abs(xy[:, 1, None] - (OFFSETS[None, :] + 20.0)) < 15.0, axis=1)
    plane = np.c_[xy[~shadow], rng.normal(-40.0, 3.0, (~shadow).sum())]
    d = find_datum(np.vstack([plane, mesh]), [0, 0, 1.0], rng=0)
    assert d.found and abs(d.plane.normal[2]) > 0.999
    assert 2.0 < d.noise_mm < 4.5
