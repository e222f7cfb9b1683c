"""Compiled kernels: each formula of the hot path written once, over arrays, compiled by numba.

The constraint and law classes keep their Python methods as thin wrappers that call these
(the formulas live here, next to their thesis equation numbers): a subclass that overrides a
method replaces the kernel call with its own code, so nothing dispatches on type.

Every kernel is compiled ahead of first use for the one signature its wrapper calls it with
(``kernel``), in nopython mode only, and cached on disk by numba next to this package
(``cache=True``: numba's own cache, the only state kept between runs). ``python -m
cpbc.kernels --warm`` compiles them once (scripts/install.sh runs it), so a fresh process
compiles nothing; ``--check`` fails when any kernel is not compiled in nopython mode.
With ``NUMBA_DISABLE_JIT=1`` the same functions run as plain Python (the tests compare both).
numba's cache does not follow calls across modules: after editing a kernel that another
module's kernel calls (``barrier_set`` calls those of ``barriers``, ``clearance``, ``task``;
``laws`` those of ``barrier_set``, ``coordinate_maps``, ``law_terms``; ``sampled_guard``
those of ``barrier_set``, ``barriers``, ``clearance``, ``small_solves``),
delete the cache files (``*.nbi``, ``*.nbc`` under ``cpbc/kernels/__pycache__``) and warm again.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba

F = TypeVar("F", bound=Callable[..., Any])

# a float vector the kernel only reads, in a signature: it takes read-only arrays too
READ_ONLY = "Array(float64, 1, 'A', readonly=True)"
READ_ONLY_MATRIX = "Array(float64, 2, 'A', readonly=True)"


def kernel(signature: str, inline: bool = False) -> Callable[[F], F]:
    """numba's nopython compilation of one function for one signature, cached on disk;
    numpy's floating-point semantics (x/0 is ±inf or NaN, as the numpy code it replaces).

    ``inline``: a small kernel another kernel calls is written into its caller (numba's
    ``inline="always"``): a call between compiled functions passes each array as a struct
    and counts its references, about 10–50 ns a call, more than such a kernel's work. Kept
    for the small ones: each inlined copy is compiled again in every caller."""

    def wrap(fn: F) -> F:
        compiled = numba.njit(signature, cache=True, nogil=True, error_model="numpy",
                              inline="always" if inline else "never")(fn)
        return cast(F, compiled)

    return wrap
