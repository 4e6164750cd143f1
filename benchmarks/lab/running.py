"""Running means and medians of a record, in O(n) and O(n × window) whatever the window.

:func:`running_median` is scipy.ndimage's ``median_filter(x, size, mode="nearest")``,
compiled: importing scipy.ndimage took a quarter of a second of every ``lab fit``'s start.
:func:`running_mean` is ``np.convolve(y, ones(width) / width, mode)`` by cumulative sums: the
convolution costs n × width, and a window of a hundredth of a 75,000-sample record took
5 ms a call."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["running_mean", "running_median"]


def running_mean(y, width: int, mode: str = "valid") -> np.ndarray:
    """The mean of each window of ``width`` samples: ``mode`` "valid" (the windows within
    the record, n − width + 1 of them) or "same" (one centred on each sample, ``width`` odd,
    the record padded with zeros beyond its ends, as ``np.convolve`` pads). Equal to the
    convolution to rounding (the sums' rounding, ~1e-16 of the record's largest |y| times
    its length)."""
    y = np.asarray(y, dtype=float)
    if mode == "same":
        if width % 2 == 0:
            raise ValueError(f"width must be odd for mode 'same', got {width}")
        y = np.concatenate([np.zeros(width // 2), y, np.zeros(width // 2)])
    elif mode != "valid":
        raise ValueError(f"mode must be 'valid' or 'same', got {mode!r}")
    if not 1 <= width <= len(y):
        raise ValueError(f"width must be from 1 to the record's {len(y)} samples, got {width}")
    sums = np.concatenate(([0.0], np.cumsum(y)))
    return (sums[width:] - sums[:-width]) / width


def running_median(x, size: int) -> np.ndarray:
    """The median of each sample's window of ``size`` (odd, at least 1) samples centred on it,
    the record extended beyond its ends by its first and last sample. ``x``: finite numbers.
    ValueError for an even or non-positive ``size``."""
    if size < 1 or size % 2 == 0:
        raise ValueError(f"size must be an odd number of samples, at least 1, got {size}")
    x = np.ascontiguousarray(x, dtype=float)
    if len(x) == 0:
        return x.copy()
    return _running_median(x, size)


@njit(cache=True)
def _running_median(x, size):
    n, half = x.shape[0], size // 2
    window = np.empty(size)                 # the window's values, sorted
    for j in range(size):
        window[j] = x[min(max(j - half, 0), n - 1)]
    window.sort()
    out = np.empty(n)
    out[0] = window[half]
    for i in range(1, n):
        gone = x[min(max(i - 1 - half, 0), n - 1)]
        new = x[min(i + half, n - 1)]
        k = np.searchsorted(window, gone)   # its place (one of equal values: the same value)
        # the gap at k moves to where `new` belongs, the values between shifted by one
        while k > 0 and window[k - 1] > new:
            window[k] = window[k - 1]
            k -= 1
        while k < size - 1 and window[k + 1] < new:
            window[k] = window[k + 1]
            k += 1
        window[k] = new
        out[i] = window[half]
    return out
