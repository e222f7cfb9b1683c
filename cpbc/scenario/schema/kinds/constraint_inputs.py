"""What a constraint kind's factory is given: the robot, its coordinate names, the scene,
and the entry's field, with the checks every kind shares (joint names, rows, limits)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.geometry import Obstacle
from cpbc.errors import ScenarioError
from cpbc.model import RobotModel
from cpbc.model.loading import LoadedArm
from cpbc.scenario.values import model_limits, vector


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
        arm: the URDF arm (None for an MJCF model), for covers from collision meshes.
        obstacles: the scenario's obstacles by name.
    """

    model: RobotModel
    names: tuple[str, ...]
    field: str
    arm: LoadedArm | None = None
    obstacles: Mapping[str, Obstacle] | None = None

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


def row_labels(name: str, k: int) -> list[str]:
    """The names of a k-row entry's constraints: its name, or name[i] per row."""
    return [name] if k == 1 else [f"{name}[{i}]" for i in range(k)]
