"""The geometry fits' fast median is numpy's median, to the bit."""

import numpy as np
import pytest

from rebarlib.geometry.fit import _median


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 10, 11, 1499, 1500])
def test_median_is_numpys(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        x = np.abs(rng.standard_t(3, n)) * rng.uniform(0.1, 10)
        assert _median(x) == float(np.median(x))
        assert _median(x.round(1)) == float(np.median(x.round(1)))  # ties


def test_median_nan_and_empty():
    assert np.isnan(_median(np.array([1.0, np.nan, 2.0])))
    assert np.isnan(_median(np.array([np.nan, 1.0])))
    with pytest.warns(RuntimeWarning):
        assert np.isnan(_median(np.array([])))
