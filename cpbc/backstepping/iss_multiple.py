"""Several constrained states with an ISS-cLf: the design of §4.2, Theorem 4.4.

For a :class:`~cpbc.backstepping.strict_feedback.StrictFeedback` system (4.1) whose x-subsystem
is ISS with respect to z1 = ξ1 − α1(x) (Assumption 4.1) and whose f_1 … f_{m−1} are bounded with
bounded derivatives (Assumption 4.2), the coordinates (4.8) are the successive time derivatives
of z1 along the nominal flow,

    z1 = ξ1 − α1(x),   z_{i+1} = ż_i,   ż_m = u + L_m  with  L_m = f_m + ḟ_{m−1} + … − α1^{(m)}

and the law (4.9) u = −Σ c_i z_i − L_m makes ż = A z, A the companion matrix (4.14). This is
the law of Theorem 3.8 (:class:`~cpbc.backstepping.iss_clf.IssClfLaw`); what Chapter 4 adds is
a bound on *every* state. For |z_i(0)| ≤ Z_i (4.10):

    |z_i(t)| ≤ b_i = sup_t Σ_j |(e^{At})_ij| Z_j                      (4.16)–(4.18)
    |ξ_i(t)| ≤ b_i + sup |ξ_i − z_i|,   ξ_i − z_i = −f_{i−1} − … + α1^{(i−1)}    (4.19)

(the last line of (4.19) prints f_m and d^mα1; with (4.8) the remainder of ξ_m stops at order
m−1). The sup of the remainder of ξ_i runs over all x and |ξ_j| ≤ X_j for j < i (the bounds
already found), so the bounds are computed in order. The constraint |ξ_i| ≤ Ξ_i holds only by
tuning: there is no barrier.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.backstepping.barrier_terms import positive
from cpbc.backstepping.iss_clf import IssCascade, IssClfLaw, companion
from cpbc.backstepping.jets import Coef, Jet, as_jet
from cpbc.backstepping.linear_reach import box_reach
from cpbc.backstepping.strict_feedback import StrictFeedback, nominal_jets
from cpbc.backstepping.worst_case import Sup, grid_sup


class StrictFeedbackIss(IssCascade):
    """A :class:`StrictFeedback` system in the coordinates (4.8), for :class:`IssClfLaw`.

    Args:
        system: the system; its α1 must make the x-subsystem ISS w.r.t. z1 (Assumption 4.1).
    """

    def __init__(self, system: StrictFeedback) -> None:
        self.system = system
        self.m = system.m
        x = system.x_samples()
        a1 = system.alpha1([x[:, j] for j in range(system.n)])
        self.delta = float(np.max(np.abs(np.asarray(a1, dtype=float))))

    def _z1(self, x: Sequence[Coef], xi: Sequence[Coef]) -> Jet:
        xj, yj = nominal_jets(self.system, x, xi, self.m)
        return yj[0] - as_jet(self.system.alpha1(xj), self.m)

    def z_coordinates(self, x: Sequence[Coef], xi: Sequence[Coef]) -> tuple[Coef, ...]:
        """(z1, ż1, …, z1^{(m−1)}) along the nominal flow (4.8)."""
        z1 = self._z1(x, xi)
        return tuple(z1.derivative(k) for k in range(self.m))

    def drift(self, x: Sequence[Coef], xi: Sequence[Coef]) -> Coef:
        """L_m = z1^{(m)} with u = 0 (ż_m = u + L_m, (4.13))."""
        return self._z1(x, xi).derivative(self.m)

    def remainders(self, x: Sequence[Coef], xi: Sequence[Coef]) -> tuple[Coef, ...]:
        """(ξ_i − z_i)_i; the i-th reads x and ξ_1 … ξ_{i−1} only."""
        z = self.z_coordinates(x, xi)
        return tuple(xi[i] - z[i] for i in range(self.m))

    def state_from_coordinates(self, x: Sequence[Coef], z: Sequence[Coef]) -> tuple[Coef, ...]:
        """The ξ with coordinates z at x: ξ_i = z_i + (ξ_i − z_i)(x, ξ1 … ξ_{i−1})."""
        xi: list[Coef] = [0.0 * zi for zi in z]
        for i in range(self.m):
            xi[i] = z[i] + self.remainders(x, xi)[i]
        return tuple(xi)


@dataclass(frozen=True)
class IssBounds:
    """The bounds of Theorem 4.4 for a box of initial errors.

    Attributes:
        box: Z_i of (4.10).
        error_bounds: b_i (4.18).
        remainders: sup |ξ_i − z_i| found, with where (worst-case search).
        state_bounds: X_i = b_i + sup |ξ_i − z_i| (4.19).
    """

    box: tuple[float, ...]
    error_bounds: tuple[float, ...]
    remainders: tuple[Sup, ...]
    state_bounds: tuple[float, ...]


def iss_bounds(law: IssClfLaw, box: Sequence[float], points: int = 21) -> IssBounds:
    """(4.18) and (4.19) for ``law`` (built on a :class:`StrictFeedbackIss`) and the box."""
    cas = law.cascade
    if not isinstance(cas, StrictFeedbackIss):
        raise TypeError("iss_bounds needs an IssClfLaw on a StrictFeedbackIss")
    z_box = tuple(positive(f"Z{i + 1}", v) for i, v in enumerate(box))
    b = box_reach(companion(law.c), z_box)
    sys = cas.system
    sups: list[Sup] = []
    xs: list[float] = []
    for i in range(cas.m):
        def rem(xcols: list[np.ndarray], v: list[np.ndarray], i: int = i) -> np.ndarray:
            xi = [*v, *[0.0 * xcols[0]] * (cas.m - len(v))]
            return np.asarray(cas.remainders(xcols, xi)[i])

        sup = grid_sup(rem, sys.x_samples(), xs, points=points)
        sups.append(sup)
        xs.append(float(b[i]) + sup.value)
    return IssBounds(z_box, tuple(float(v) for v in b), tuple(sups), tuple(xs))
