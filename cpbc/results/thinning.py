"""Thinning a long logged signal for drawing without losing any of its extremes."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from cpbc.constraints.constraint_types import Array

BUCKETS = 1500  # time buckets of a thinned curve in the figures (two samples each)
#: Sample indices into a logged signal.
Index = NDArray[np.intp]


def envelope(y: Array, buckets: int = BUCKETS) -> Index:
    """Indices of the samples of ``y`` a thinned curve keeps, in time order.

    The first and last samples and, in each of ``buckets`` equal runs of samples, the
    smallest and the largest (NaN samples are never preferred). All samples when short.
    """
    n = len(y)
    if n <= 2 * buckets:
        return np.arange(n)
    b = -(-n // buckets)
    padded = np.full(b * (-(-n // b)), np.nan)
    padded[:n] = y
    rows = padded.reshape(-1, b)
    offset = np.arange(rows.shape[0]) * b
    lo = np.argmin(np.where(np.isnan(rows), np.inf, rows), axis=1) + offset
    hi = np.argmax(np.where(np.isnan(rows), -np.inf, rows), axis=1) + offset
    idx = np.unique(np.concatenate([[0, n - 1], lo, hi]))
    return idx[idx < n]
