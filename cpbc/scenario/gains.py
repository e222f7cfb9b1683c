"""Gains in physical terms, and the stability of a PD loop under a zero-order hold.

**Physical gains.** A natural frequency ω_n,i [rad/s] and damping ratio ζ_i per coordinate
give, with the arm's inertia at the target D(x_d),

    K_P,i = D_ii(x_d) ω_n,i²,        K_D,i = 2 ζ_i ω_n,i D_ii(x_d),

so that coordinate i, seen alone with the others still, behaves near the target like
D_ii x̃̈ + K_D,i ẋ + K_P,i x̃ = 0: a second-order system of frequency ω_n,i and damping ζ_i.
For the bounded laws (BPBC), whose stiffness and damping near the target are K_P Ξ and
K_D Γ (∂U/∂x̃ = K_P tanh(Ξ x̃), K_D tanh(Γ ẋ)), K_P and K_D are divided by ξ_i and γ_i.

**Zero-order hold.** The loop samples the state every h seconds and holds the torque. For one
coordinate of inertia m under the held PD torque u_k = −k_p x̃_k − k_d ẋ_k (gravity
compensated), the motion over a period is exact:

    x̃_{k+1} = x̃_k + h ẋ_k + h²/(2m) u_k,      ẋ_{k+1} = ẋ_k + (h/m) u_k.

With a = k_p h²/m, b = k_d h/m and y = h ẋ the map is [[1 − a/2, 1 − b/2], [−a, 1 − b]],
of trace 2 − a/2 − b and determinant 1 − b + a/2. By the Jury test it is stable (both
eigenvalues inside the unit circle) **if and only if**

    0 < a < 2b < 4,   i.e.   k_d h < 2m   and   k_p h < 2 k_d.

In physical terms: ζ ω_n h < 1 and ω_n h < 4ζ. Too much damping for the period makes the
rate flip sign every sample and grow; too little (for the stiffness) lets the held torque
pump energy in. The check applies the condition to each coordinate with m = D_ii — the
diagonal of D at the target and at every initial position, taking the smallest (the
stiffest case) — and with the linear stiffness and damping of the law near the target. It
is exact for a decoupled arm; for a coupled D it screens the gains coordinate by coordinate
(the barrier terms of the constrained laws come on top of it). It holds for a plant that
integrates the held torque exactly (MuJoCo's RK4 does for this model); it says nothing of the
physics integrator's own step.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.constraints.base import Array


def physical_gains(omega_n: Array, zeta: Array, inertia_diag: Array) -> tuple[Array, Array]:
    """K_P = D_ii ω_n², K_D = 2 ζ ω_n D_ii, each of shape (n,)."""
    return inertia_diag * omega_n**2, 2.0 * zeta * omega_n * inertia_diag


@dataclass(frozen=True)
class UnstableCoordinate:
    """A coordinate whose held PD loop diverges or oscillates at the control period.

    Attributes:
        index: the coordinate's index.
        name: its name.
        inertia: m = D_ii used [kg·m²].
        kp, kd: its linear stiffness and damping.
        period: the control period h [s].
    """

    index: int
    name: str
    inertia: float
    kp: float
    kd: float
    period: float

    @property
    def too_damped(self) -> bool:
        """k_d h ≥ 2m: the rate overshoots its own correction every sample."""
        return self.kd * self.period >= 2.0 * self.inertia

    def advice(self) -> str:
        """What is wrong and the ways out, in numbers."""
        m, h, kp, kd = self.inertia, self.period, self.kp, self.kd
        longest = min(2.0 * m / kd, 2.0 * kd / kp)
        if self.too_damped:
            why = (f"K_D h = {kd * h:.3g} ≥ 2 D_ii = {2 * m:.3g}: lower kd below "
                   f"{2 * m / h:.4g}")
        else:
            why = (f"K_P h = {kp * h:.3g} ≥ 2 K_D = {2 * kd:.3g}: raise kd above "
                   f"{kp * h / 2:.4g} or lower kp below {2 * kd / h:.4g}")
        return (f"coordinate '{self.name}' (D_ii = {m:.3g}, K_P = {kp:.4g}, K_D = {kd:.4g}) is "
                f"unstable under the zero-order hold at h = {h:.3g} s ({why}), or shorten "
                f"simulation.control_period below {longest:.3g} s; stable iff K_D h < 2 D_ii "
                "and K_P h < 2 K_D (in physical terms ζ ω_n h < 1 and ω_n h < 4ζ)")


def zoh_stable(kp: float, kd: float, inertia: float, period: float) -> bool:
    """Whether k_d h < 2m and k_p h < 2 k_d (the held PD loop of one coordinate)."""
    return kd * period < 2.0 * inertia and kp * period < 2.0 * kd


def zoh_spectral_radius(kp: float, kd: float, inertia: float, period: float) -> float:
    """Largest |eigenvalue| of the one-coordinate map of the module docstring."""
    a, b = kp * period**2 / inertia, kd * period / inertia
    step = np.array([[1 - a / 2, 1 - b / 2], [-a, 1 - b]])
    return float(np.max(np.abs(np.linalg.eigvals(step))))


def unstable_coordinates(
    kp: Array, kd: Array, inertia_diag: Array, period: float, names: Sequence[str]
) -> list[UnstableCoordinate]:
    """Coordinates whose held loop fails :func:`zoh_stable`, in order."""
    return [
        UnstableCoordinate(i, names[i], float(inertia_diag[i]), float(kp[i]), float(kd[i]),
                           period)
        for i in range(len(kp))
        if not zoh_stable(float(kp[i]), float(kd[i]), float(inertia_diag[i]), period)
    ]
