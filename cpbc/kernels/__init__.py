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
numba keys a cached kernel on its own file only, so a kernel that calls into another module
(``laws`` into ``barrier_set``, ``law_terms``, ``coordinate_maps``, ``task``; ``barrier_set``
into ``barriers``, ``clearance``; ``sampled_guard`` into several; ``margin_losses`` into
``friction_error``, ``small_solves``) would be loaded stale after that module changed — and
compute with the old formula. Importing this package therefore
drops the cached kernels whenever any kernel source differs from the one they were compiled
from (``drop_stale_cache``).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from itertools import chain
from pathlib import Path
from typing import Any, TypeVar, cast

import numba

F = TypeVar("F", bound=Callable[..., Any])
STAMP = "kernel-sources.sha256"  # the digest of the sources the cached kernels come from


def drop_stale_cache(package: Path) -> bool:
    """Delete numba's cached kernels (``*.nbi``, ``*.nbc`` under ``package/__pycache__``)
    unless the digest of the package's sources equals the one stamped when they were
    cached, and stamp the current one; whether it deleted. Best effort: a folder that cannot
    be written is left as it is (numba then caches elsewhere, or not at all)."""
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in sorted(package.glob("*.py"))))
    cache, found = package / "__pycache__", digest.hexdigest()
    stamp = cache / STAMP
    try:
        if stamp.read_text(encoding="ascii") == found:
            return False
    except OSError:
        pass
    try:
        for old in chain(cache.glob("*.nbi"), cache.glob("*.nbc")):
            old.unlink()
        cache.mkdir(exist_ok=True)
        stamp.write_text(found, encoding="ascii")
    except OSError:
        return False
    return True


drop_stale_cache(Path(__file__).resolve().parent)

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


def inner(signature: str) -> Callable[[F], F]:
    """A small kernel that only other kernels call: written into each caller (numba's
    ``inline="always"``, compiled with the caller's options) and never compiled on its own,
    so importing the package loads nothing for it. ``signature`` records the types its
    callers pass; ``python -m cpbc.kernels --check`` counts it apart (its callers' nopython
    compilation covers it). A direct call from Python compiles it for the arguments given."""

    def wrap(fn: F) -> F:
        compiled = numba.njit(nogil=True, error_model="numpy", inline="always")(fn)
        compiled.inner_signature = signature  # type: ignore[attr-defined]
        return cast(F, compiled)

    return wrap
