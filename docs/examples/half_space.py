"""A new constraint kind written outside cpbc: a frame's point kept on one side of a plane,
n·p(x) < d — its class, its kernel and its scenario entry in this one module
(docs/new-constraint.md; tests/test_half_space_example.py runs it)."""

from typing import Literal

import numpy as np
from numba import njit
from pydantic import Field

from cpbc.constraints.constraint_kind import (
    ConstraintEntrySpec,
    ConstraintInputs,
    ConstraintKind,
)
from cpbc.constraints.constraint_types import ConfigurationConstraint
from cpbc.constraints.margins import CLEARANCE
from cpbc.model.robot_model import ArmState, RobotModel
from cpbc.spec.fields import Vector


@njit(nogil=True)
def half_space_terms(normal, depth, point, linear, phi, gradient):  # type: ignore[no-untyped-def]
    """φ = d − n·p into ``phi[0]`` and ∇φ/φ = −nᵀJ_p/φ into ``gradient`` (n,), from the
    point p (3,) and its Jacobian J_p (3, n)."""
    value = depth - (normal[0] * point[0] + normal[1] * point[1] + normal[2] * point[2])
    phi[0] = value
    for k in range(gradient.shape[0]):
        gradient[k] = -(normal[0] * linear[0, k] + normal[1] * linear[1, k]
                        + normal[2] * linear[2, k]) / value


class HalfSpace(ConfigurationConstraint):
    """φ(x) = d − n·p(x) > 0, p the origin of ``frame``, n a unit normal [m]."""

    margin_type = CLEARANCE  # φ is a distance in m

    def __init__(self, model: RobotModel, frame: str, normal: object, depth: float,
                 name: str = "half_space") -> None:
        n = np.asarray(normal, dtype=float).reshape(3)
        if not np.linalg.norm(n) > 0:
            raise ValueError(f"normal: needs a nonzero vector, got {n.tolist()}")
        self.model, self.frame_id = model, model.frame_id(frame)
        self.frames = (self.frame_id,)  # the per-step state holds its kinematics
        self.normal, self.depth, self.names = n / np.linalg.norm(n), float(depth), (name,)

    def value(self, x: np.ndarray) -> np.ndarray:
        return np.array([self.depth - self.normal @ self.model.point_position(self.frame_id, x)])

    def gradient(self, x: np.ndarray) -> np.ndarray:
        return -(self.normal @ self.model.point_jacobian(self.frame_id, x))[None, :]

    def barrier_terms(self, state: ArmState, margins: bool = False
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The law's terms from the frame the state holds, by the kernel."""
        frame = state.frames[self.frame_id]
        phi, b = np.empty(1), np.empty(frame.jacobian.shape[1])
        half_space_terms(self.normal, self.depth, frame.position, frame.jacobian[:3], phi, b)
        return phi, b, phi


class HalfSpaceSpec(ConstraintEntrySpec):
    type: Literal["half_space"] = Field(description="n·p < d for a frame's origin p")
    name: str = Field(default="half_space", description="unique name")
    frame: str = Field(description="the frame")
    normal: Vector = Field(description="the plane's normal n, pointing out of the side kept")
    depth: float = Field(description="d [m]")


def build(spec: HalfSpaceSpec, given: ConstraintInputs) -> HalfSpace:
    return HalfSpace(given.model, spec.frame, given.vector(spec.normal, 3, "normal"),
                     spec.depth, spec.name)


KINDS = (ConstraintKind(HalfSpaceSpec, build, HalfSpace,
                        {"half_space": {"frame": "end_point", "normal": [0, 1, 0],
                                        "depth": 1.9}}),)
