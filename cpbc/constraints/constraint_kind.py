"""What a constraint kind declares, beside its class, for the scenario's ``constraints:`` list.

A constraint module of this package that a scenario may name ends with ``KINDS``, a tuple of
:class:`ConstraintKind`: its pydantic spec (the YAML entry, with the field descriptions the
JSON Schema and the scenario reference are generated from), its factory (spec → constraint,
errors naming the field), the class it builds (whose ``margin_type`` says how the results
report it, cpbc.constraints.margins) and a minimal example entry per type, which the
contract test (tests/test_registry.py) builds. The scenario layer finds those declarations by
walking this package (cpbc.scenario.schema.kinds); nothing registers itself.

Here too: the base of every spec (:class:`ConstraintEntrySpec`) and what a factory is given
(:class:`ConstraintInputs`: the robot, its coordinate names, the scene and the entry's field,
with the checks every kind shares).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, Literal, TypeVar

import numpy as np
from pydantic import BaseModel, Field

from cpbc.arrays import Array
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.constraints.geometry import Obstacle
from cpbc.errors import ScenarioError
from cpbc.model import RobotModel
from cpbc.spec.fields import Strict
from cpbc.spec.type_names import type_names
from cpbc.spec.values import model_limits, vector

if TYPE_CHECKING:  # the loaders import MuJoCo: only for the types
    from cpbc.model.collision_geoms import CollisionGeom
    from cpbc.model.loading import LoadedArm

Constraint = ConfigurationConstraint | VelocityConstraint
FromModel = Literal["from_model"]  # a limit read from the robot's URDF/MJCF
S = TypeVar("S", bound=BaseModel)


class ConstraintEntrySpec(Strict):
    """What every ``constraints:`` entry has: its ``type`` and its unique ``name``. Each
    constraint kind narrows ``type`` to its name, gives ``name`` its default and adds its own
    keys."""

    type: str = Field(description="the constraint")
    name: str = Field(description=(
        "unique name, used by controllers' constraints lists and in the summary"))


@dataclass(frozen=True)
class SceneSphere:
    """A sphere a constraint entry places in the MuJoCo scene and the viewer (the thesis's
    obstacle, say): ``collides`` makes it a physical body."""

    name: str
    centre: Array
    radius: float
    collides: bool


@dataclass(frozen=True)
class ConstraintInputs:
    """A constraint entry's robot and scene.

    Attributes:
        model: the controller's robot model.
        names: its coordinate names.
        field: the entry's place in the scenario (``constraints[2]``), for errors.
        arm: the URDF arm (None for an MJCF model), for covers from collision meshes and
            its position-dependent velocity limits.
        obstacles: the scenario's obstacles by name.
        collision: reads an MJCF robot's collision geoms (cpbc.model.collision_geoms), for
            covers, when called; None for a URDF arm (its collision meshes are on ``arm``).
        joint_range: the joint range the scenario keeps (its joint position limits inside
            the model's ranges), lower and upper per joint, or None: the model's.
    """

    model: RobotModel
    names: tuple[str, ...]
    field: str
    arm: LoadedArm | None = None
    obstacles: Mapping[str, Obstacle] | None = None
    collision: Callable[[], tuple[CollisionGeom, ...]] | None = None
    joint_range: tuple[Array, Array] | None = None

    def at(self, key: str) -> str:
        """The field of one of the entry's keys."""
        return f"{self.field}.{key}"

    def joints(self, joints: list[str] | None) -> list[int] | None:
        """The indices of the entry's ``joints`` (None: all)."""
        if joints is None:
            return None
        missing = [j for j in joints if j not in self.names]
        if missing:
            raise ScenarioError(self.at("joints"), f"unknown coordinates {missing}; the robot "
                                f"has {list(self.names)}")
        return [self.names.index(j) for j in joints]

    def rows(self, coefficients: list[list[float]]) -> Array:
        """The entry's ``coefficients`` as rows of n numbers."""
        rows = np.asarray(coefficients, dtype=float)
        if rows.ndim != 2 or rows.shape[1] != self.model.n:
            raise ScenarioError(self.at("coefficients"), f"needs rows of {self.model.n} "
                                f"coefficients, got shape {rows.shape}")
        return rows

    def vector(self, value: list[float], k: int, key: str) -> Array:
        """One of the entry's vectors, of k numbers."""
        return vector(value, k, self.at(key))

    def limit(self, value: list[float] | str, kind: str, side: int, idx: list[int] | None,
              key: str) -> Array:
        """A limit vector as given, or ``from_model`` (side 0 lower, 1 upper) on joints idx."""
        k = self.model.n if idx is None else len(idx)
        if isinstance(value, str):
            limits = model_limits(self.model, kind, self.at(key), idx)[side]
            return limits if idx is None else limits[idx]
        return self.vector(value, k, key)


    def rate_bounds(self, value: list[float] | str, scale: float, idx: list[int] | None,
                    key: str) -> Array:
        """Joint rate bounds B_i as given (or ``from_model``: the model's velocity limits),
        times ``scale``. For an arm whose velocity limits depend on the joint's position
        (the fr3), ``from_model`` is also at most the largest constant bound inside them
        over the scenario's joint range, and bounds past that are refused."""
        bounds = scale * self.limit(value, "velocity", 1, idx, key)
        limits = None if self.arm is None else self.arm.velocity_limits
        if limits is None:
            return bounds
        lo, hi = self.joint_range or model_limits(self.model, "position", self.at(key))
        allowed = limits.constant_bound(lo, hi)
        chosen = list(range(self.model.n)) if idx is None else idx
        if isinstance(value, str):
            bounds = np.minimum(bounds, scale * allowed[chosen])
        for j, i in enumerate(chosen):
            if bounds[j] <= 0 or bounds[j] > allowed[i] * (1 + 1e-12):
                # the range on which half the peak velocity is allowed, as a hint
                room_lo, room_hi = limits.range_for(0.5 * limits.peak)
                found = (f"allows no speed toward the ends of the joint range [{lo[i]:.4g}, "
                         f"{hi[i]:.4g}]:" if allowed[i] <= 0 else
                         f"allows {allowed[i]:.4g} rad/s on the joint range [{lo[i]:.4g}, "
                         f"{hi[i]:.4g}], the bound is {bounds[j]:.4g}: give at most that, or")
                raise ScenarioError(self.at(key), (
                    f"{self.names[i]}: the robot's position-dependent velocity limit "
                    f"(libfranka's rate_limiting.h) {found} narrow the joint_position_limit "
                    f"(within [{room_lo[i]:.4g}, {room_hi[i]:.4g}] it allows "
                    f"{0.5 * limits.peak[i]:.4g} rad/s)"))
        return bounds


def row_labels(name: str, k: int) -> list[str]:
    """The names of a k-row entry's constraints: its name, or name[i] per row."""
    return [name] if k == 1 else [f"{name}[{i}]" for i in range(k)]


@dataclass(frozen=True)
class ConstraintKind(Generic[S]):
    """A constraint kind of the ``constraints:`` list.

    Attributes:
        spec: its YAML entry (a pydantic model with ``type: Literal[...]`` and ``name``).
        build: the factory, spec → constraint object (ScenarioError naming the field).
        constraint: the class ``build`` returns; it declares the margins' type and unit.
        examples: per type name, the keys (beside ``type`` and ``name``) of a minimal entry
            on the thesis's planar two-link arm (the ``planar_2link`` model, coordinates
            ``theta1``, ``theta2``, links ``link1``, ``link2``, frame ``end_point``) — what
            the contract test builds. No default: a kind without one is refused.
        scene: the sphere the entry places in the MuJoCo scene and the viewer, if any.
    """

    spec: type[S]
    build: Callable[[S, ConstraintInputs], Constraint]
    constraint: type[ConfigurationConstraint] | type[VelocityConstraint]
    examples: Mapping[str, Mapping[str, Any]]
    scene: Callable[[S, Constraint], SceneSphere] | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return type_names(self.spec)
