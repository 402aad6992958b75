"""The smoothed height and offset histograms of the scan stage, at every width of noise."""

import numpy as np

from rebarlib.scan import split_lattices
from rebarlib.scan._util import _smoothed_hist


def test_a_smoothed_histogram_keeps_one_count_per_bin_when_the_kernel_is_wider_than_the_span():
    # 10 heights 1 mm apart smoothed with σ 5 mm: the kernel (43 taps) is longer than the
    # histogram (9 bins); the smoothed counts must still be one per bin
    centres, smoothed, counts = _smoothed_hist(np.arange(10.0), 1.0, 5.0)
    assert len(centres) == len(smoothed) == len(counts) == 9
    assert np.isclose(smoothed.sum(), counts.sum(), rtol=0.6)  # the tails beyond the span are lost
    assert np.argmax(smoothed) in (3, 4, 5)  # centred on the middle of a flat histogram


def test_a_smoothed_histogram_is_centred_as_before_on_a_wide_span():
    x = np.random.default_rng(1).normal(0, 30, 5000)
    for sd in (2.0, 5.0, 10.0):
        centres, smoothed, counts = _smoothed_hist(x, 1.0, sd)
        k = max(sd, 0.5)
        ker = np.exp(-0.5 * (np.arange(-int(4 * k) - 1, int(4 * k) + 2) / k) ** 2)
        assert np.array_equal(smoothed, np.convolve(counts.astype(float), ker / ker.sum(), mode="same"))


def test_two_layers_under_noise_wider_than_their_span_give_no_split_rather_than_an_error():
    # two lattices 35 mm apart, each ±5 mm, read with a noise of 15 mm (it raised IndexError)
    rng = np.random.default_rng(0)
    heights = np.r_[rng.normal(40, 5, 2000), rng.normal(75, 5, 2000)]
    out = split_lattices(heights, noise_mm=15)
    assert out is None or np.isfinite(out)
