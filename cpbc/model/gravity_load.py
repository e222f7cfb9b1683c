"""Can the motors hold the arm up? Gravity against the joint torque limits.

At rest an arm needs the joint torques τ_q = Tᵀ g(x) just to stay where it is, so a joint j
with |τ_q,j| > L_j cannot hold the configuration at all: no controller can keep it there.

Holding is not enough for the safeguard. Its brake (cpbc.constraints.stopping.Braking) is
the uniform brake τ = b − A D ẋ/|ẋ|; near rest (C ẋ and f vanish) it applies
τ_q = Tᵀ (g − A D d) along the unit direction of motion d. Joint j can give it a
deceleration A in every direction d only if

    |Tᵀ g|_j + A ‖row_j(Tᵀ D)‖₂ ≤ L_j,

the worst d lining (Tᵀ D d)_j up against the gravity torque. The second term is the
*braking allowance*: the torque the braking set V needs on top of gravity, here at the
modest deceleration :data:`BRAKING_DECELERATION`. Where gravity leaves less room than that,
the brake slows the arm more weakly than it in some direction, and where it leaves none
(|τ_q,j| ≥ L_j) the braking set is empty there: the safeguard reports every step
infeasible and the arm sags through its constraints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.model.robot_model import RobotModel

#: The deceleration the braking allowance provides for, in every direction of motion
#: [rad/s² in the controller's coordinates].
BRAKING_DECELERATION = 1.0

#: Samples of the straight path from a start to the target, both ends included.
PATH_SAMPLES = 21


@dataclass(frozen=True)
class GravityLoad:
    """What gravity asks of one joint at one configuration.

    Attributes:
        joint: the joint's name.
        fraction: where the configuration lies on the straight path from the start (0) to
            the target (1).
        gravity: |τ_q,j|, the torque that holds the arm up [N·m].
        braking: the braking allowance on top of it [N·m].
        limit: L_j, the joint's torque limit [N·m].
    """

    joint: str
    fraction: float
    gravity: float
    braking: float
    limit: float

    @property
    def held(self) -> bool:
        """Whether the motor can hold the arm up here."""
        return self.gravity <= self.limit

    @property
    def brakes(self) -> bool:
        """Whether the motor has the braking allowance left over gravity."""
        return self.gravity + self.braking <= self.limit

    @property
    def share(self) -> float:
        """(gravity + braking allowance) / limit: above 1 the brake lacks room."""
        return (self.gravity + self.braking) / self.limit

    @property
    def where(self) -> str:
        if self.fraction <= 0.0:
            return "at the start"
        if self.fraction >= 1.0:
            return "at the target"
        return f"{self.fraction:.0%} of the way to the target"

    def describe(self) -> str:
        """One line: the joint, the torques, the limit, where."""
        need = ("more than its" if not self.held else
                f"and the brake {self.braking:.3g} N·m more (at {BRAKING_DECELERATION:g} "
                "rad/s²), over its")
        return (f"gravity on '{self.joint}' is {self.gravity:.4g} N·m {self.where}, {need} "
                f"torque limit {self.limit:.4g} N·m")


def joint_loads(model: RobotModel, x: Array, limit: Array | float,
                fraction: float = 0.0) -> list[GravityLoad]:
    """The load of every joint with a finite limit at the configuration x (controller
    coordinates); ``limit`` is one per joint, or one for all [N·m]."""
    limit = np.broadcast_to(np.asarray(limit, dtype=float), (model.n,))
    to_joint = model.coordinates.matrix.T  # τ_q = Tᵀ τ
    gravity = np.abs(to_joint @ model.gravity(x))
    braking = BRAKING_DECELERATION * np.linalg.norm(to_joint @ model.inertia(x), axis=1)
    names = model.joint_names
    return [GravityLoad(names[j], fraction, float(gravity[j]), float(braking[j]),
                        float(limit[j]))
            for j in range(model.n) if np.isfinite(limit[j])]


def unheld(model: RobotModel, x: Array, limit: Array,
           fraction: float = 1.0) -> GravityLoad | None:
    """The joint whose motor is furthest from holding the arm up at x (``fraction`` of the
    way to the target), or None when every motor holds it."""
    over = [load for load in joint_loads(model, x, limit, fraction) if not load.held]
    return max(over, key=lambda load: load.gravity / load.limit) if over else None


def _shares(model: RobotModel, x: Array, limit: Array) -> Array:
    """(gravity + braking allowance) / limit per joint, as :class:`GravityLoad.share`."""
    to_joint = model.coordinates.matrix.T
    gravity = np.abs(to_joint @ model.gravity(x))
    braking = BRAKING_DECELERATION * np.linalg.norm(to_joint @ model.inertia(x), axis=1)
    return (gravity + braking) / limit


def holdable_near(model: RobotModel, x0: Array, lower: Array, upper: Array, limit: Array,
                  share: float = 0.8) -> Array:
    """A configuration near ``x0``, inside [lower, upper], where every motor holds the arm
    with the braking allowance to spare (each share ≤ ``share``); ``x0`` itself when it is
    one already. Found by descending Σ max(0, share_j − ``share``)² from ``x0`` (bounded
    quasi-Newton): the arm lowered until its motors can carry it. The result may still be
    over: the caller checks it (:func:`joint_loads`).

    Args:
        model: the controller's model; x0, lower, upper in its coordinates (±inf: none).
        limit: the joint torque limits [N·m], inf where a joint has none.
    """
    limit = np.broadcast_to(np.asarray(limit, dtype=float), (model.n,))
    if np.all(_shares(model, x0, limit) <= share):
        return np.asarray(x0, dtype=float)
    from scipy.optimize import minimize  # only for an arm its motors cannot carry

    def excess(x: Array) -> float:
        return float(np.sum(np.maximum(_shares(model, x, limit) - share, 0.0) ** 2))

    bounds = [(lo if np.isfinite(lo) else None, hi if np.isfinite(hi) else None)
              for lo, hi in zip(lower, upper, strict=True)]
    return np.asarray(minimize(excess, x0, method="L-BFGS-B", bounds=bounds).x, dtype=float)


def heaviest_on_path(model: RobotModel, start: Array, target: Array, limit: Array,
                     samples: int = PATH_SAMPLES) -> GravityLoad | None:
    """Along the straight path from ``start`` to ``target`` (both included), the load that
    leaves the brake least room, or None when every motor has the braking allowance left
    everywhere."""
    worst: GravityLoad | None = None
    for fraction in np.linspace(0.0, 1.0, samples):
        x = start + fraction * (target - start)
        for load in joint_loads(model, x, limit, float(fraction)):
            if not load.brakes and (worst is None or load.share > worst.share):
                worst = load
    return worst
