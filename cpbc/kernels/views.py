"""Views of one flat array as a row-major table, inside the kernels: a kernel keeps its
tables, and its per-step work arrays, in one array each and reads them through these (an
allocation costs numba about 20 ns, a strided view nothing); and a kernel's argument that
numba does not reference-count (``borrowed``)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeVar

import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numpy.typing import NDArray

from cpbc.arrays import Array
from cpbc.kernels import inner

Ints = NDArray[np.int64]  # the index tables
Bools = NDArray[np.bool_]  # marks, one per margin
F = TypeVar("F")


@inner("int64[:, :](int64[::1], int64, int64, int64)")
def int_rows(flat: Ints, start: int, rows: int, columns: int) -> Ints:
    """flat[start : start + rows·columns] as a (rows, columns) view, row-major (numba's
    reshape calls out to C, about 16 ns; a strided view costs nothing)."""
    return np.lib.stride_tricks.as_strided(flat[start:], shape=(rows, columns),
                                           strides=(columns * flat.itemsize, flat.itemsize))


@inner("float64[:, :](float64[::1], int64, int64, int64)")
def float_rows(flat: Array, start: int, rows: int, columns: int) -> Array:
    """``int_rows`` of a float array."""
    return np.lib.stride_tricks.as_strided(flat[start:], shape=(rows, columns),
                                           strides=(columns * flat.itemsize, flat.itemsize))


@intrinsic
def _uncounted(typingctx: Any, array: Any) -> Any:
    """``array`` without numba's owner record (its meminfo): ``borrowed``, compiled."""
    if not isinstance(array, types.Array):
        return None

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        given = context.make_array(signature.args[0])(context, builder, args[0])
        found = context.make_array(signature.return_type)(context, builder)
        cgutils.copy_struct(found, given)
        found.meminfo = cgutils.get_null_value(found.meminfo.type)
        found.parent = cgutils.get_null_value(found.parent.type)
        return found._getvalue()

    return array(array), codegen


def _itself(array: F) -> F:
    """``borrowed`` run as plain Python (NUMBA_DISABLE_JIT=1): the array itself."""
    return array


# ``array`` itself, its reference count left alone: the same data, shape and strides without
# numba's owner record, so that neither it nor a view of it is counted when made, passed or
# dropped — numba counts them with an atomic add, about 5 ns each, some 150 in a law's step
# (the step's time went 5.2 → 4.4 µs on the planar arm). Only for a kernel's own arguments,
# which its caller holds for the whole call: never for an array the kernel allocates (numba
# frees it at its last use), and never returned.
if TYPE_CHECKING:
    def borrowed(array: F) -> F:
        """(typed as it behaves)"""
else:
    borrowed = _itself if numba.config.DISABLE_JIT else _uncounted
