"""Running medians and means (:mod:`benchmarks.lab.running`) against what they replace:
scipy.ndimage's ``median_filter(mode="nearest")`` (equal to the last bit on walks, quantised
and constant records, short and long) and ``np.convolve`` with a box (equal to rounding)."""

import numpy as np
import pytest
from scipy.ndimage import median_filter

from benchmarks.lab.running import running_mean, running_median


@pytest.mark.parametrize("n", [1, 2, 5, 9, 10, 100, 20_000])
@pytest.mark.parametrize("size", [1, 3, 9, 51, 205])
def test_it_is_scipys_median_filter(n, size):
    rng = np.random.default_rng(n * 1000 + size)
    for x in (np.cumsum(rng.standard_normal(n)),            # a walk
              np.round(3.0 * rng.standard_normal(n)),       # quantised: many ties
              np.ones(n),                                   # all equal
              np.linspace(0.0, 1.0, n)):                    # monotone: its own samples
        assert np.array_equal(running_median(x, size),
                              median_filter(x, size=size, mode="nearest"))


@pytest.mark.parametrize("size", [0, -1, 2, 50])
def test_an_even_or_empty_window_is_refused(size):
    with pytest.raises(ValueError, match=f"got {size}"):
        running_median(np.arange(10.0), size)


def test_an_empty_record_gives_an_empty_median():
    assert running_median(np.empty(0), 9).shape == (0,)


@pytest.mark.parametrize("n,width", [(1, 1), (5, 5), (10, 3), (1000, 11), (75_220, 753)])
@pytest.mark.parametrize("mode", ["valid", "same"])
def test_the_running_mean_is_numpys_box_convolution(n, width, mode):
    y = 0.5 + 1e-3 * np.cumsum(np.random.default_rng(n).standard_normal(n))
    expected = np.convolve(y, np.ones(width) / width, mode=mode)
    got = running_mean(y, width, mode)
    # the cumulative sums' rounding: ~1e-16 of |y| (0.5) per sample summed
    assert got.shape == expected.shape
    assert np.abs(got - expected).max() <= 1e-16 * n + 1e-15


@pytest.mark.parametrize("width,mode,match", [(0, "valid", "width"), (11, "valid", "width"),
                                              (4, "same", "odd"), (3, "full", "mode")])
def test_a_running_mean_of_a_bad_window_is_refused(width, mode, match):
    with pytest.raises(ValueError, match=match):
        running_mean(np.arange(10.0), width, mode)
