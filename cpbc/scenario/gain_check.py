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
pump energy in.

**The arm.** The joints are coupled: near the target at rest, with gravity compensated, the
arm is D ẍ = u, and over one period (x̃, ẋ) ↦ A (x̃, ẋ) with

    A = [[I − (h²/2) D⁻¹K_P,  h I − (h²/2) D⁻¹K_D],
         [−h D⁻¹K_P,           I − h D⁻¹K_D     ]].

The held loop is stable iff the spectral radius of A is < 1 — for one coordinate this is the
condition above. The check evaluates it with D at the target and at every initial position
(the loop must be stable along the way), with the linear stiffness and damping of the law
near the target. Coupling matters: with the physical gains above, D⁻¹K_P and D⁻¹K_D share
eigenvectors, and a mode of eigenvalue λ of D⁻¹ diag(D) needs ω_n h < 4ζ and λ ζ ω_n h < 1,
with λ = 3.3 on the thesis's planar arm at q₂ = 0.8 (joint coordinates) and λ ≈ 100 on the
xArm 7 at its zero pose (two vertical axes aligned): the damping limit can be far tighter
than one joint alone suggests. The report names the coordinate that moves most in the
unstable mode, its effective inertia 1/(D⁻¹)_ii, and the longest control period at which
the gains are stable. The check ignores what the linearisation leaves out (the barrier terms
of the constrained laws, gravity held over a period, Coriolis terms, ∂g/∂q for laws without
gravity compensation).

**The integrator.** RK4 integrates D ẍ = u with u held exactly, as above. MuJoCo's Euler
(semi-implicit: v ← v + δ ẍ, then x ← x + δ v) over the k = h/δ physics steps of a period
gives ẋ_{k+1} = ẋ_k + h D⁻¹u and x̃_{k+1} = x̃_k + h ẋ_k + ½ h (h + δ) D⁻¹u: the h²/2 of the
first row of A becomes h(h + δ)/2. The implicit integrators treat velocity-dependent forces
implicitly and, with none in D ẍ = u, move the same way. With δ = h one coordinate is then
stable iff a + 2b < 4 (a, b as above): the bound on damping drops from k_d h < 2m
to k_d h < 2m − k_p h²/2. The check takes δ = the scenario's timestep for those
integrators and δ = 0 for RK4.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array


def physical_gains(omega_n: Array, zeta: Array, inertia_diag: Array) -> tuple[Array, Array]:
    """K_P = D_ii ω_n², K_D = 2 ζ ω_n D_ii, each of shape (n,)."""
    return inertia_diag * omega_n**2, 2.0 * zeta * omega_n * inertia_diag


def zoh_stable(kp: float, kd: float, inertia: float, period: float) -> bool:
    """Whether k_d h < 2m and k_p h < 2 k_d (the held PD loop of one coordinate)."""
    return kd * period < 2.0 * inertia and kp * period < 2.0 * kd


def _matrix(k: Array) -> Array:
    """A diagonal gain's matrix; a full stiffness or damping matrix (a task-space law's,
    J_vᵀK_pJ_v + K_n) as it is."""
    k = np.asarray(k, dtype=float)
    return np.diag(k) if k.ndim == 1 else k


def held_loop(kp: Array, kd: Array, inertia: Array, period: float,
              euler_step: float = 0.0) -> Array:
    """The map A of (x̃, ẋ) over one period (module docstring), shape (2n, 2n);
    ``euler_step`` is δ of an Euler-type physics integrator (0: exact, as RK4)."""
    n, h = len(kp), period
    stiff = np.linalg.solve(inertia, _matrix(kp))
    damp = np.linalg.solve(inertia, _matrix(kd))
    eye = np.eye(n)
    c = h * (h + euler_step) / 2
    return np.block([[eye - c * stiff, h * eye - c * damp],
                     [-h * stiff, eye - h * damp]])


def zoh_spectral_radius(kp: float, kd: float, inertia: float, period: float,
                        euler_step: float = 0.0) -> float:
    """Largest |eigenvalue| of one coordinate's held loop."""
    return spectral_radius(np.array([kp]), np.array([kd]), np.array([[inertia]]), period,
                           euler_step)


def spectral_radius(kp: Array, kd: Array, inertia: Array, period: float,
                    euler_step: float = 0.0) -> float:
    """Largest |eigenvalue| of the arm's held loop; < 1 iff stable."""
    loop = held_loop(kp, kd, inertia, period, euler_step)
    return float(np.max(np.abs(np.linalg.eigvals(loop))))


def longest_stable_period(kp: Array, kd: Array, inertia: Array, period: float,
                          euler_step: float = 0.0) -> float:
    """The longest h ≤ ``period`` at which the held loop is stable (bisection)."""
    lo, hi = 0.0, period
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if spectral_radius(kp, kd, inertia, mid, euler_step) < 1.0:
            lo = mid
        else:
            hi = mid
    return lo


@dataclass(frozen=True)
class UnstableLoop:
    """Gains whose held loop diverges or oscillates at the control period.

    Attributes:
        name: the coordinate that moves most in the unstable mode.
        index: its index.
        inertia: its effective inertia 1/(D⁻¹)_ii [kg·m²].
        kp, kd: its linear stiffness and damping.
        period: the control period h [s].
        radius: spectral radius of the held loop (≥ 1).
        longest_period: the longest period at which these gains are stable [s].
        stable_kd: for a coupled mode (each coordinate alone stable), the largest K_D of
            this coordinate, below ``kd``, at which the arm's held loop is stable; None when
            lowering it alone does not help.
    """

    name: str
    index: int
    inertia: float
    kp: float
    kd: float
    period: float
    radius: float
    longest_period: float
    stable_kd: float | None = None

    def gain_fix(self) -> str:
        """The way out in K_P and K_D (the gains as a user gives kp, kd)."""
        m, h, kp, kd = self.inertia, self.period, self.kp, self.kd
        if kd * h >= 2.0 * m:
            return f"K_D h ≥ 2 D_eff: lower kd below {2 * m / h:.4g}"
        if kp * h >= 2.0 * kd:
            return f"K_P h ≥ 2 K_D: raise kd above {kp * h / 2:.4g} or lower kp"
        if self.stable_kd is not None:
            return (f"a coupled mode: lower kd of '{self.name}' below {self.stable_kd:.4g} "
                    "(or omega_n, zeta)")
        return "a coupled mode: lower omega_n or zeta"

    def advice(self, fix: str | None = None) -> str:
        """What is wrong and the ways out, in numbers; ``fix``: the way out in the units the
        gains were written in (natural frequencies), instead of :meth:`gain_fix`."""
        m, h, kp, kd = self.inertia, self.period, self.kp, self.kd
        fix = self.gain_fix() if fix is None else fix
        return (f"the gains are unstable under the zero-order hold at control period "
                f"h = {h:.3g} s (spectral radius {self.radius:.4g} ≥ 1), mostly in coordinate "
                f"'{self.name}' (effective inertia {m:.3g}, K_P = {kp:.4g}, K_D = {kd:.4g}; "
                f"{fix}), or shorten simulation.control_period to below "
                f"{self.longest_period:.3g} s. One coordinate alone is stable iff "
                "K_D h < 2 D and K_P h < 2 K_D (ζ ω_n h < 1 and ω_n h < 4ζ)")


def unstable_loop(
    kp: Array, kd: Array, inertias: Sequence[Array], period: float, names: Sequence[str],
    euler_step: float = 0.0,
) -> UnstableLoop | None:
    """The first inertia D (of ``inertias``) at which the held loop is unstable, described;
    None when it is stable at every one."""
    n = len(kp)
    for inertia in inertias:
        values, vectors = np.linalg.eig(held_loop(kp, kd, inertia, period, euler_step))
        k = int(np.argmax(np.abs(values)))
        if abs(values[k]) < 1.0:
            continue
        i = int(np.argmax(np.abs(vectors[:n, k]) + np.abs(vectors[n:, k]) * period))
        m_eff = 1.0 / float(np.linalg.inv(inertia)[i, i])
        if np.ndim(kp) == 2:  # a task-space law: its diagonal, no single K_D to lower
            kp_i, kd_i = float(kp[i, i]), float(kd[i, i])
            return UnstableLoop(names[i], i, m_eff, kp_i, kd_i, period, float(abs(values[k])),
                                longest_stable_period(kp, kd, inertia, period, euler_step))
        return UnstableLoop(names[i], i, m_eff, float(kp[i]), float(kd[i]), period,
                            float(abs(values[k])),
                            longest_stable_period(kp, kd, inertia, period, euler_step),
                            _stable_kd(kp, kd, inertias, period, euler_step, i)
                            if zoh_stable(float(kp[i]), float(kd[i]), m_eff, period) else None)
    return None


def _stable_kd(kp: Array, kd: Array, inertias: Sequence[Array], period: float,
               euler_step: float, i: int) -> float | None:
    """The largest K_D of coordinate ``i`` (the others kept) below its own at which the held
    loop is stable at every inertia: scanned down from ``kd[i]`` to K_P h / 2 (below which
    the coordinate alone is unstable), then the edge found by bisection. None when no value
    on the way is stable."""
    def stable(value: float) -> bool:
        trial = np.array(kd, dtype=float)
        trial[i] = value
        return all(spectral_radius(kp, trial, d, period, euler_step) < 1.0 for d in inertias)

    grid = np.linspace(float(kd[i]), float(kp[i]) * period / 2.0, 66)[1:-1]
    hi = float(kd[i])  # unstable
    for lo in grid:
        if stable(lo):
            break
        hi = lo
    else:
        return None
    lo = float(lo)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo
