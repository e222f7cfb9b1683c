"""The joints' Coulomb friction levels F_c of the controller's model, checked once."""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ModelError


def coulomb_levels(levels: Array | None, n: int) -> Array:
    """Each joint's Coulomb friction level, shape (n,), finite and ≥ 0 (read-only)."""
    fc = np.zeros(n) if levels is None else np.array(levels, dtype=float)
    if fc.shape == ():
        fc = np.full(n, float(fc))
    if fc.shape != (n,) or not np.all(np.isfinite(fc)) or np.any(fc < 0):
        raise ModelError(f"coulomb_friction must be {n} finite levels ≥ 0 (or one), "
                         f"got {levels}", "coulomb_friction")
    fc.setflags(write=False)
    return fc
