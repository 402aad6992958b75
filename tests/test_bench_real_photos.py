"""The real-photo benchmark's run options, on hand-built images: the mean over scales and the
straightness filter (benchmarks/bench_real_photos.py)."""

import numpy as np

from benchmarks.bench_real_photos import _multi_scale, _straight_parts


class _Dark:
    """A stand-in model: the probability of a pixel is 1 where the photo is dark."""

    calls = []

    def predict_proba(self, rgb, **kw):
        self.calls.append(rgb.shape[:2])
        return (rgb.mean(axis=2) < 100).astype(np.float32)


def test_multi_scale_runs_each_factor_and_returns_the_photo_size():
    rgb = np.full((80, 120, 3), 200, np.uint8)
    rgb[30:50, :] = 20  # a dark bar 20 px wide across the photo
    m = _Dark()
    m.calls = []
    p = _multi_scale(m, rgb, [1.0, 0.5])
    assert m.calls == [(80, 120), (40, 60)]
    assert p.shape == (80, 120)
    assert p[40].min() == 1.0 and p[5].max() == 0.0  # the bar's middle and far from it agree at both scales


def test_straight_parts_keep_a_long_bar_and_drop_a_blob_and_a_short_stub():
    mask = np.zeros((200, 200), bool)
    mask[100:106, 10:190] = True  # a bar 180 px long
    mask[20:40, 20:40] = True  # a 20 px blob
    mask[150:170, 150:153] = True  # a stub 20 px long
    kept = _straight_parts(mask, 41)
    assert kept[100:106, 10:190].all()
    assert not kept[20:40, 20:40].any()
    assert not kept[150:170, 150:153].any()


def test_hysteresis_keeps_weak_pixels_only_where_they_touch_a_strong_one():
    from benchmarks.bench_real_photos import _hysteresis

    p = np.zeros((5, 9))
    p[2, 0:4] = [0.9, 0.4, 0.35, 0.3]  # a strong seed and the weaker pixels running from it
    p[2, 6:9] = 0.4  # as weak, touching no seed
    got = _hysteresis(p, 0.3, 0.5)
    assert got[2].astype(int).tolist() == [1, 1, 1, 0, 0, 0, 0, 0, 0]


def test_normalisations_keep_the_photo_s_shape_and_type():
    from benchmarks.bench_real_photos import _normalised

    rgb = (np.random.default_rng(0).random((20, 30, 3)) * 200).astype(np.uint8)
    for how in ("none", "grayworld", "stretch", "clahe", "gamma0.8"):
        out = _normalised(rgb, how)
        assert out.shape == rgb.shape and out.dtype == np.uint8
    assert (_normalised(rgb, "stretch").max(), _normalised(rgb, "stretch").min()) == (255, 0)
    g = _normalised(rgb, "grayworld").reshape(-1, 3).mean(axis=0)
    assert np.ptp(g) < 1.0  # the channels' means made equal
