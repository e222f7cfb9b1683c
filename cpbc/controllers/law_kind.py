"""What a law kind declares, beside its law, for the scenario's ``controllers:`` list.

A law module of this package (or of cpbc.peers) that a scenario may name ends with ``KINDS``,
a tuple of :class:`LawKind`: its pydantic spec (on the bases of cpbc.controllers.law_specs,
with the field descriptions the JSON Schema and the scenario reference are generated from),
its factory (spec → controller, errors naming the field), what the gain check needs of it
(:class:`Slopes`), a minimal example entry per type, which of its types take a goal. The
scenario layer finds those declarations by walking the packages (cpbc.scenario.schema.kinds);
nothing registers itself. Here too: what a factory is given (:class:`LawInputs`: its gains,
the scenario's constraints, the loop's period and torque limit, a goal).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.controllers.controller import Controller
from cpbc.controllers.law_specs import IdentityShapingSpec, PowerShapingSpec, ShapingSpec
from cpbc.controllers.shaping import Identity, Power, Shaping, Tanh
from cpbc.errors import ScenarioError
from cpbc.model import RobotModel
from cpbc.model.bounds import ModelBounds
from cpbc.model.input_bounds import InputBounds
from cpbc.spec.type_names import type_names

if TYPE_CHECKING:
    from pydantic import BaseModel

    from cpbc.taskspace.goal import FrameGoal

S = TypeVar("S", bound="BaseModel")


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
        bounds: the loop's control period h and the actuators' torque and torque-rate
            limits (cpbc.model.input_bounds).
        field: the entry's place in the scenario (``controllers[1]``), for errors.
        goal: a goal or reference scenario's frame goal (``target`` is then its posture),
            else None.
    """

    model: RobotModel
    target: Array
    gains: Mapping[str, object]
    constraints: Mapping[str, ConfigurationConstraint | VelocityConstraint]
    model_bounds: Callable[[], ModelBounds]
    bounds: InputBounds
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


@dataclass(frozen=True)
class LawKind(Generic[S]):
    """A law kind of the ``controllers:`` list.

    Attributes:
        spec: its YAML entry (a pydantic model with ``type: Literal[...]``, the gains, ``name``).
        build: the factory, spec → controller (ScenarioError naming the field).
        slopes: what the gain check needs: the slopes of its spring and damping near the
            target per unit of K_P and K_D (:class:`Slopes`; :func:`LINEAR` for a law linear
            in x̃ and ẋ, :func:`tanh_slopes` for a saturating one). No default: a law that
            does not say is refused.
        examples: per type name, the keys (beside ``type`` and the gains) of a minimal entry
            on the thesis's planar two-link arm whose constraints are ``limits`` (a
            joint_position_limit), ``rates`` (a joint_rate_limit) and ``energy`` (a
            kinetic_energy_limit) — what the contract test builds. No default.
        goal_types: those of its type names that take a scenario goal (task-space terms).
        start_problem: why the law cannot start from a case's state, if it can say so
            (law, x, ẋ, coordinate names, torque limit, held period) → message or None.
    """

    spec: type[S]
    build: Callable[[S, LawInputs], Controller]
    slopes: Callable[[S, int, str], Slopes]
    examples: Mapping[str, Mapping[str, Any]]
    goal_types: tuple[str, ...] = ()
    start_problem: Callable[
        [Controller, Array, Array, tuple[str, ...], Array | None, float | None], str | None
    ] | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return type_names(self.spec)
