"""What the proofs leave out: measurement noise and a plant that differs from the model.

* :class:`MeasurementNoise` — seeded Gaussian noise on the position and rate the controller
  sees (controller coordinates). The plant and the log keep the true state.
* :class:`PlantMismatch` — edits of the MuJoCo plant only (masses and inertias scaled per
  body, joint damping, armature, dry friction), so that the controller's Pinocchio model and
  the physics differ.
* :class:`AccelerationDisturbance` — a plant inside a declared model error: the MuJoCo arm
  plus an acceleration disturbance |d_j| ≤ ā_j, as ``python -m cpbc.verify --disturb`` draws
  one (the declared error of ``simulation.model_error``,
  cpbc.controllers.safeguard.model_error). Each control period the disturbance takes a
  corner of the box, d = ā ⊙ s with random signs s_j = ±1 (seeded): the largest error the
  declaration allows, in every direction over a run. It enters as the generalised force
  M(q) d added to the command (M the plant's own mass matrix, rotor inertia included, from
  the physics step before: it lags the state by one step, a relative error of order h in d),
  so the plant's acceleration moves by d from what it would be — whatever the plant's own
  difference from the controller's model adds on top.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.errors import CpbcError


def _per_entry(
    value: float | tuple[float, ...] | Array, k: int, what: str, positive: bool) -> Array:
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = np.full(k, float(a))
    if a.shape != (k,):
        raise CpbcError(f"{what} needs 1 or {k} entries, got {a.size}")
    ok = a > 0 if positive else a >= 0
    if not np.all(np.isfinite(a)) or not np.all(ok):
        sign = "> 0" if positive else "≥ 0"
        raise CpbcError(f"{what} must be finite and {sign}, got {a.tolist()}")
    return a


@dataclass(frozen=True)
class MeasurementNoise:
    """x_meas = x + σ_x ε, ẋ_meas = ẋ + σ_ẋ ε', ε, ε' ~ N(0, I), drawn from a seeded generator.

    Attributes:
        position: σ_x [rad], a number or one per coordinate, ≥ 0.
        velocity: σ_ẋ [rad/s], a number or one per coordinate, ≥ 0.
        seed: seed of the generator (the same seed draws the same noise).
    """

    position: float | tuple[float, ...] = 0.0
    velocity: float | tuple[float, ...] = 0.0
    seed: int = 0

    def sigmas(self, n: int) -> tuple[Array, Array]:
        """σ_x and σ_ẋ as (n,) arrays."""
        return (
            _per_entry(self.position, n, "noise.position", positive=False),
            _per_entry(self.velocity, n, "noise.velocity", positive=False),
        )

    @property
    def active(self) -> bool:
        return bool(np.any(np.asarray(self.position)) or np.any(np.asarray(self.velocity)))


def rate_into_set(
    constraints: ConstraintSet, x: Array, dx: Array, fraction: float = 1e-3
) -> Array | None:
    """ẋ scaled by the largest c ≤ 1 that leaves every velocity margin ≥ ``fraction`` of its
    value at rest, or None if a configuration margin at x is ≤ 0 (then no rate helps).

    Each ψ_j = Ω_j(x) − ½ẋᵀQ_j(x)ẋ is quadratic in ẋ, so ψ_j(cẋ) = Ω_j − c²(Ω_j − ψ_j(ẋ))
    and c follows in closed form.
    """
    k = sum(len(c.names) for c in constraints.configuration)
    now = constraints.margins(x, dx)
    if not np.all(now[:k] > 0):
        return None
    rest = constraints.margins(x, np.zeros_like(dx))[k:]
    used = rest - now[k:]  # ½ẋᵀQẋ ≥ 0
    with np.errstate(divide="ignore", invalid="ignore"):
        c2 = np.where(used > 0, (1.0 - fraction) * rest / used, np.inf)
    return dx * min(1.0, float(np.sqrt(np.min(c2, initial=np.inf))))


@dataclass(frozen=True)
class PlantMismatch:
    """How the MuJoCo plant differs from the controller's model.

    Attributes:
        mass_scale: factor on each body's mass (a number, or one per body below the world,
            in MuJoCo's body order).
        inertia_scale: factor on each body's rotational inertia about its centre of mass.
        damping: joint viscous damping added to the plant [N·m·s/rad], number or per joint.
        armature: rotor inertia added to each joint [kg·m²], number or per joint.
        frictionloss: dry (Coulomb) friction of each joint [N·m], number or per joint.
    """

    mass_scale: float | tuple[float, ...] = 1.0
    inertia_scale: float | tuple[float, ...] = 1.0
    damping: float | tuple[float, ...] = 0.0
    armature: float | tuple[float, ...] = 0.0
    frictionloss: float | tuple[float, ...] = 0.0

    @property
    def is_nominal(self) -> bool:
        return bool(
            np.all(np.asarray(self.mass_scale) == 1.0)
            and np.all(np.asarray(self.inertia_scale) == 1.0)
            and not np.any(np.asarray(self.damping))
            and not np.any(np.asarray(self.armature))
            and not np.any(np.asarray(self.frictionloss))
        )

    def check(self, nbody: int, ndof: int) -> None:
        """Raise CpbcError naming the entry if a value does not fit the model."""
        self._arrays(nbody, ndof)

    def _arrays(self, nbody: int, ndof: int) -> tuple[Array, Array, Array, Array, Array]:
        return (
            _per_entry(self.mass_scale, nbody, "mass_scale", positive=True),
            _per_entry(self.inertia_scale, nbody, "inertia_scale", positive=True),
            _per_entry(self.damping, ndof, "damping", positive=False),
            _per_entry(self.armature, ndof, "armature", positive=False),
            _per_entry(self.frictionloss, ndof, "frictionloss", positive=False),
        )

    def apply(self, model: mujoco.MjModel) -> None:
        """Edit a compiled MjModel in place (bodies 1..nbody−1; every dof)."""
        mass, inertia, damping, armature, friction = self._arrays(model.nbody - 1, model.nv)
        model.body_mass[1:] *= mass
        model.body_inertia[1:] *= inertia[:, None]
        model.dof_damping[:] += damping
        model.dof_armature[:] += armature
        model.dof_frictionloss[:] += friction
        mujoco.mj_setConst(model, mujoco.MjData(model))  # derived quantities of the new inertia

    @classmethod
    def random(
        cls,
        rng: np.random.Generator,
        nbody: int,
        ndof: int,
        mass: float = 0.2,
        inertia: float = 0.2,
        damping: float = 0.0,
        armature: float = 0.0,
        frictionloss: float = 0.0,
    ) -> PlantMismatch:
        """Masses and inertias scaled by factors uniform in [1 − mass, 1 + mass] (resp.
        inertia) per body; damping, armature and dry friction uniform in [0, value] per
        joint."""
        return cls(
            tuple(rng.uniform(1 - mass, 1 + mass, nbody).tolist()),
            tuple(rng.uniform(1 - inertia, 1 + inertia, nbody).tolist()),
            tuple(rng.uniform(0, damping, ndof).tolist()),
            tuple(rng.uniform(0, armature, ndof).tolist()),
            tuple(rng.uniform(0, frictionloss, ndof).tolist()),
        )


@dataclass(frozen=True)
class AccelerationDisturbance:
    """An acceleration disturbance within ``bound`` [joint coordinates, per joint], its signs
    drawn anew each control period from ``seed``."""

    bound: Array
    seed: int = 0

    def __post_init__(self) -> None:
        _per_entry(self.bound, len(self.bound), "disturbance bound", positive=False)

    def drawn(self) -> Disturber:
        """A fresh run's draws."""
        return Disturber(np.asarray(self.bound, dtype=float), np.random.default_rng(self.seed))


class Disturber:
    """One run's disturbance: the generalised force of the next control period."""

    def __init__(self, bound: Array, rng: np.random.Generator) -> None:
        self.bound, self.rng = bound, rng
        self._force = np.empty(len(bound))

    def force(self, model: mujoco.MjModel, data: mujoco.MjData) -> Array:
        """M(q) d for a fresh corner d of the box (the module docstring,
        :class:`AccelerationDisturbance`)."""
        d = self.bound * self.rng.choice((-1.0, 1.0), size=len(self.bound))
        mujoco.mj_mulM(model, data, self._force, d)
        return self._force
