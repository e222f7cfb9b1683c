"""How far a stable linear system ż = A z reaches from a box of initial conditions.

For |z_j(0)| ≤ Z_j, component i of z(t) = e^{At} z(0) is linear in z(0), so its largest value
over the box is attained at a vertex and equals Σ_j |(e^{At})_ij| Z_j. The reach

    R_i = sup_{t ≥ 0} Σ_j |(e^{At})_ij| Z_j   (≥ Z_i, the value at t = 0)

is the constant b_i of (3.50)/(4.16)–(4.18) ("computed explicitly from (4.16)"), exact rather
than an overbound. Computed on a fine time grid by repeated multiplication with e^{AΔt}, then
refined around the grid maximum; valid for any Hurwitz A (also a defective one).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.linalg import expm
from scipy.optimize import minimize_scalar

from cpbc.arrays import Array
from cpbc.backstepping.design_errors import DesignError


def box_reach(a: Array, box: Sequence[float], samples: int = 20000) -> Array:
    """(R_1, …, R_m) for ż = A z and |z_j(0)| ≤ box_j; :class:`DesignError` unless A is Hurwitz."""
    a = np.asarray(a, dtype=float)
    z = np.asarray(box, dtype=float)
    eig = np.linalg.eigvals(a)
    if np.any(eig.real >= 0.0):
        raise DesignError("A", float(np.max(eig.real)), "the z-loop must be Hurwitz")
    slow, fast = float(np.min(-eig.real)), float(np.max(np.abs(eig)))
    horizon = 40.0 / slow
    dt = min(horizon / samples, 0.05 / fast)
    step = expm(a * dt)
    phi = np.eye(len(z))
    best = np.abs(phi) @ z
    when = np.zeros(len(z))
    t = 0.0
    while t < horizon:
        phi = phi @ step
        t += dt
        now = np.abs(phi) @ z
        better = now > best
        best[better], when[better] = now[better], t
    for i in range(len(z)):
        if when[i] > 0.0:
            res = minimize_scalar(
                lambda s, i=i: -float(np.abs(expm(a * s)[i]) @ z),
                bounds=(max(when[i] - dt, 0.0), when[i] + dt), method="bounded",
                options={"xatol": 1e-12 * max(1.0, when[i])},
            )
            best[i] = max(best[i], -float(res.fun))
    return best
