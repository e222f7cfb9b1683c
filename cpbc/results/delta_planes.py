"""Float arrays as the byte planes of their successive differences: the viewer page's coding.

A signal sampled at 1 kHz changes little from one sample to the next, but deflate cannot see
it: consecutive floats share their leading bytes, four or eight bytes apart. :func:`encode`
stores an array as the differences of successive samples' bit patterns (along its first
axis, wrapping as unsigned integers), split into byte planes: plane k holds byte k of every
difference. The sign, exponent and leading mantissa planes are then nearly constant and
deflate to almost nothing; :func:`decode` gives back the same bits, NaN and -0.0 included.

The page's arrays travel this way (cpbc.viewer.page_data, decoded by viewer/view.js). Run
logs are HDF5 files now (cpbc.results.hdf5_log); cpbc before them wrote each run's log as a
``trajectory.npz`` of such coded members, which :func:`load_earlier_log` still reads, so that
older run folders replay.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Any array a log holds: float signals, names, an outcome string.
Stored = NDArray[Any]

#: The suffix of a coded member: ``NAME.deltas`` holds the float array ``NAME``.
CODED = ".deltas"


def encode(a: NDArray[np.floating[Any]]) -> NDArray[np.uint8]:
    """The byte planes, shape ``(itemsize, *a.shape)``, of ``a``'s successive differences."""
    a = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<"))
    bits = a.view(f"<u{a.itemsize}")
    deltas = np.diff(bits, axis=0, prepend=np.zeros_like(bits[:1]))
    planes = deltas.view(np.uint8).reshape(*a.shape, a.itemsize)
    return np.ascontiguousarray(np.moveaxis(planes, -1, 0))


def decode(planes: NDArray[np.uint8]) -> NDArray[np.floating[Any]]:
    """The float array whose :func:`encode` is ``planes``."""
    size = planes.shape[0]
    deltas = np.ascontiguousarray(np.moveaxis(planes, 0, -1)).view(f"<u{size}")[..., 0]
    return np.cumsum(deltas, axis=0, dtype=deltas.dtype).view(f"<f{size}")


def load_earlier_log(path: Path | str) -> dict[str, Stored]:
    """Every array of a ``trajectory.npz`` that earlier versions of cpbc wrote, decoded, by
    name (a member ``NAME.deltas`` is the coded float array ``NAME``; plain members, as the
    earliest versions wrote, read as ``numpy.load`` reads them)."""
    with np.load(path, allow_pickle=False) as z:
        return {(k[: -len(CODED)] if k.endswith(CODED) else k):
                (decode(z[k]) if k.endswith(CODED) else z[k]) for k in z.files}
