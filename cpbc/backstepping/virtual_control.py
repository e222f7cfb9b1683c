"""The first virtual control α2 of the barrier designs and its analytic derivative α̇2.

Shared by Theorem 3.6 (one constrained state) and Theorem 3.13 (two), whose first steps are
the same (3.12)/(3.34)/(3.111):

    z1 = ξ1 − α1(x)                                                   (3.8)
    α2 = −c1 z1 − f1(x, ξ1) + ∂α1/∂x·f(x, ξ1) − Γ(z1)·T(x, ξ1)/z1     (3.12)

T/z1 is the closed-form divided difference of :class:`~cpbc.backstepping.cascade.FirstStep`,
never a numerical division by z1. Along the nominal dynamics (disturbance ≡ 0)

    ż1 = ξ̇1 − ∂α1/∂x·f,    ξ̇1 = ξ2 + f1
    α̇2 = −c1 ż1 − ḟ1 + d/dt(∂α1/∂x·f) − Γ'(z1) ż1 (T/z1) − Γ(z1) d/dt(T/z1)

with each ġ = ∂g/∂x·f + ∂g/∂ξ1·ξ̇1 exact (the cascade supplies both parts).
"""

from __future__ import annotations

from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import Barrier
from cpbc.backstepping.cascade import FirstStep


@dataclass(frozen=True)
class VirtualControl:
    """α2 at (x, ξ1) and the pieces its derivative needs.

    Attributes:
        z1: ξ1 − α1(x).
        alpha2: α2 (3.12).
        gamma: Γ(z1).
        closed_loop_drift: ż1 − z2 = −c1 z1 − Γ(z1)·T/z1 (closed-loop (3.114)).
    """

    z1: float
    alpha2: float
    gamma: float
    closed_loop_drift: float
    _step: FirstStep
    _dgamma: float
    _c1: float

    def xi1_dot(self, xi2: float) -> float:
        """ξ̇1 = ξ2 + f1(x, ξ1) (for m = 1, pass v as ξ2)."""
        return xi2 + self._step.f1.value

    def rate(self, xi1_dot: float) -> float:
        """α̇2 along the nominal dynamics, given ξ̇1 = ξ2 + f1."""
        s = self._step
        z1_dot = xi1_dot - s.alpha1_flow.value
        return (
            -self._c1 * z1_dot
            - s.f1.rate(xi1_dot)
            + s.alpha1_flow.rate(xi1_dot)
            - self._dgamma * z1_dot * s.t_over_z.value
            - self.gamma * s.t_over_z.rate(xi1_dot)
        )


def virtual_control(step: FirstStep, barrier: Barrier, c1: float, xi1: float) -> VirtualControl:
    """α2 of (3.12) for the first step ``step`` at ξ1, with barrier term ``barrier`` on z1."""
    z1 = xi1 - step.alpha1
    gamma = barrier.gamma(z1)
    drift = -c1 * z1 - gamma * step.t_over_z.value
    alpha2 = drift - step.f1.value + step.alpha1_flow.value
    return VirtualControl(z1, alpha2, gamma, drift, step, barrier.dgamma(z1), c1)
