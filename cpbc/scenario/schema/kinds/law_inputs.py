"""What a law kind's factory is given (its gains, the scenario's constraints, the loop), and
what the gain check asks of each law kind (:class:`Slopes`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints import ConfigurationConstraint, ConstraintSet, VelocityConstraint
from cpbc.controllers import Identity, Power, Tanh
from cpbc.controllers.shaping import Shaping
from cpbc.errors import ScenarioError
from cpbc.model import RobotModel
from cpbc.model.bounds import ModelBounds
from cpbc.scenario.schema.controller_specs import (
    IdentityShapingSpec,
    PowerShapingSpec,
    ShapingSpec,
)
from cpbc.simulation import LoopSettings
from cpbc.taskspace.goal import FrameGoal


def gain_vector(value: float | list[float], n: int, field: str) -> Array:
    """A gain given as one number or one per coordinate, as n numbers."""
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise ScenarioError(field, f"needs 1 or {n} entries (one per coordinate), got {a.size}")
    return a


@dataclass(frozen=True)
class Slopes:
    """What the gain check (cpbc.scenario.gain_check) needs of a law: the slopes near the target
    of its spring and damping per unit of K_P and K_D, shape (n,) each. Its linear stiffness
    is K_P·spring and its damping K_D·damping; gains given as ω_n, ζ are divided by them.
    ``saturates``: the spring and damping saturate (tanh), and so do a goal's task terms."""

    spring: Array
    damping: Array
    saturates: bool


def LINEAR(spec: Any, n: int, field: str) -> Slopes:
    """A law linear in x̃ and ẋ near the target (−K_P x̃ − K_D ẋ): slopes K_P, K_D."""
    return Slopes(np.ones(n), np.ones(n), saturates=False)


def tanh_slopes(spec: Any, n: int, field: str) -> Slopes:
    """A law with the spring K_P tanh(Ξx̃) and the damping K_D tanh(Γẋ) (the spec's ``xi``
    and ``gamma``): slopes K_P Ξ, K_D Γ."""
    return Slopes(gain_vector(spec.xi, n, f"{field}.xi"),
                  gain_vector(spec.gamma, n, f"{field}.gamma"), saturates=True)


def shaping(spec: ShapingSpec | None) -> Shaping:
    """The barrier's shaping s of a ``shaping:`` entry (identity when omitted)."""
    if spec is None or isinstance(spec, IdentityShapingSpec):
        return Identity()
    if isinstance(spec, PowerShapingSpec):
        return Power(spec.alpha)
    return Tanh(spec.sigma)


@dataclass(frozen=True)
class LawInputs:
    """A controller entry's robot, gains, constraints and loop.

    Attributes:
        model: the controller's robot model.
        target: the joint target (a goal's posture).
        gains: the law's keyword arguments kp, kd — with a goal also potential and
            task_damping (cpbc.scenario.goal_build.law_terms).
        constraints: every scenario constraint by name.
        model_bounds: the model's bounds (estimated once, when a law first asks).
        loop: the loop's settings (control period, torque limit).
        field: the entry's place in the scenario (``controllers[1]``), for errors.
        goal: a goal or reference scenario's frame goal (``target`` is then its posture),
            else None.
    """

    model: RobotModel
    target: Array
    gains: Mapping[str, object]
    constraints: Mapping[str, ConfigurationConstraint | VelocityConstraint]
    model_bounds: Callable[[], ModelBounds]
    loop: LoopSettings
    field: str
    goal: FrameGoal | None = None

    def constraint_set(self, chosen: list[str] | None) -> ConstraintSet:
        """The scenario constraints an entry names (all when None)."""
        names = list(self.constraints) if chosen is None else chosen
        unknown = [c for c in names if c not in self.constraints]
        if unknown:
            raise ScenarioError(f"{self.field}.constraints", f"unknown constraint names "
                                f"{unknown}; the scenario defines {list(self.constraints)}")
        objs = [self.constraints[c] for c in names]
        return ConstraintSet(
            self.model.n,
            [o for o in objs if isinstance(o, ConfigurationConstraint)],
            [o for o in objs if isinstance(o, VelocityConstraint)],
        )
