"""A point of the robot kept outside a sphere (a circle for a planar arm): the thesis's obstacle."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from cpbc.arrays import Array, ArrayLike
from cpbc.constraints.constraint_kind import (
    Constraint,
    ConstraintEntrySpec,
    ConstraintInputs,
    ConstraintKind,
    SceneSphere,
)
from cpbc.constraints.constraint_types import ConfigurationConstraint
from cpbc.constraints.margins import CLEARANCE
from cpbc.constraints.packing import Packed
from cpbc.errors import CpbcError, ParameterError, ScenarioError
from cpbc.kernels.barriers import (
    POINT_CONSTANTS,
    pack_point_sphere,
    point_sphere_motion,
    point_sphere_terms,
)
from cpbc.model.frames import FrameKinematics
from cpbc.model.robot_model import ArmState, RobotModel
from cpbc.spec.fields import Positive, Vector


class PointOutsideSphere(ConfigurationConstraint):
    """φ(x) = ‖p(x) − c‖² − r² > 0, with ∇φ = 2 (p − c)ᵀ J_p(x).

    This is φ₁ of Section 6.4, where p is the end point of the 2-link arm, c = (0, 2) and
    r = 0.5. The squared distance keeps φ smooth everywhere.

    Args:
        model: the controller's robot model (for kinematics).
        frame: name of the frame that carries the point.
        centre: sphere centre in world coordinates, shape (3,) [m].
        radius: sphere radius [m], > 0.
        offset: the point in the frame's coordinates, shape (3,) [m].
        name: label of the constraint.
    """

    margin_type = CLEARANCE
    motion_kinematics = True  # its curvature reads the joint Jacobians (``motion_terms``)

    def margins(self, values: Array) -> Array:
        """φ = d² − r² as d − r [m]."""
        return values / (np.sqrt(np.maximum(values + self.radius**2, 0.0)) + self.radius)

    def __init__(
        self,
        model: RobotModel,
        frame: str,
        centre: ArrayLike,
        radius: float,
        offset: ArrayLike | None = None,
        name: str | None = None,
    ) -> None:
        if not (np.isfinite(radius) and radius > 0):
            raise ParameterError("radius", f"obstacle radius must be finite and > 0, got {radius}")
        centre = np.asarray(centre, dtype=float)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise ParameterError("centre", f"obstacle centre must be 3 finite numbers, got "
                                           f"{centre.tolist()}")
        self.model = model
        self.frame_id = model.frame_id(frame)
        self.frames = (self.frame_id,)
        self.centre = centre
        self.radius = float(radius)
        self._r2 = self.radius**2
        self.offset = None if offset is None else np.asarray(offset, dtype=float).reshape(3)
        self.names = (name or f"clearance[{frame}]",)
        # the coordinates that move the frame's link, and each coordinate's link: what the
        # curvature reads with the state's joint Jacobians
        # (cpbc.kernels.clearance_motion.sphere_motion)
        joint = model.model.frames[self.frame_id].parentJoint
        self._supports = model.joint_supports()[joint][None, :]
        self._coordinate_supports = model.coordinate_supports()
        self._packed = pack_point_sphere(centre, self.radius, self.offset, self.frame_id)
        self._constants = self._packed.floats[POINT_CONSTANTS][0]  # the kernel's

    def value(self, x: Array) -> Array:
        return self._squared_clearance(self.model.point_position(self.frame_id, x, self.offset))

    def values_along(self, xs: Array) -> Array:
        """φ at each row of xs, shape (N, 1): one kinematics pass a row, the rest at once."""
        model, frame, offset = self.model, self.frame_id, self.offset
        points = np.array([model.point_position(frame, x, offset) for x in xs])
        return self._squared_clearance(points.reshape(len(xs), 3))[:, None]

    def _squared_clearance(self, points: Array) -> Array:
        """‖p − c‖² − r² of each point (the last axis; the sum in order, as p·p sums it)."""
        d = points - self.centre
        return np.atleast_1d((d * d).sum(axis=-1) - self.radius**2)

    def gradient(self, x: Array) -> Array:
        return self.evaluate(x)[1]

    def evaluate(self, x: Array) -> tuple[Array, Array]:
        p, jac = self.model.point_kinematics(self.frame_id, x, self.offset)
        d = p - self.centre
        return np.array([d @ d - self._r2]), (2.0 * d @ jac)[None, :]

    def barrier_terms(self, state: ArmState, margins: bool = False
                      ) -> tuple[Array, Array, Array | None]:
        """φ, ∇φ/φ = 2 (p − c)ᵀ J_p / φ and φ again, from the frame's kinematics held by
        the state (``frames``) (cpbc.kernels.barriers.point_sphere_terms)."""
        kin = self._state_frame(state)
        phi, b = np.empty(1), np.empty(len(kin.jacobian[0]))
        point_sphere_terms(self._constants, kin.position, kin.rotation, kin.jacobian, phi, b)
        return phi, b, phi

    def packed(self) -> Packed | None:
        """The kernel's constants and frame, unless a subclass overrides ``barrier_terms``."""
        if type(self).barrier_terms is not PointOutsideSphere.barrier_terms:
            return None
        return self._packed

    def motion_terms(self, state: ArmState) -> tuple[Array, Array, Array]:
        """φ, ∇φ and ẋᵀ∇²φ ẋ = 2‖ṗ‖² + 2 (p − c)·p̈₀ from the frame's kinematics and the
        joint Jacobians the state holds (cpbc.kernels.barriers.point_sphere_motion): no
        Pinocchio pass of its own."""
        kin = self._state_frame(state)
        if state.joint_jacobians is None:
            raise CpbcError(f"{self.names[0]}'s curvature reads the state's joint Jacobians: "
                            "build the state with kinematics=True (the constraint set's "
                            "state(model, x, dx, motion=True), as the CBF-QP peer does)")
        phi, grad, curv = np.empty(1), np.empty((1, len(kin.jacobian[0]))), np.empty(1)
        point_sphere_motion(self._constants, kin.position, kin.rotation, kin.jacobian,
                            state.joint_jacobians, state.dq, self._supports,
                            self._coordinate_supports, phi, grad[0], curv)
        return phi, grad, curv

    def curvature(self, x: Array, dx: Array) -> Array:
        """ẋᵀ∇²φ ẋ at (x, ẋ) (``motion_terms``), from one Pinocchio pass there."""
        state = self.model.state(x, dx, kinematics=True, frames=self.frames)
        return self.motion_terms(state)[2]

    def _state_frame(self, state: ArmState) -> FrameKinematics:
        """The frame's placement and Jacobian, which the state holds for this constraint."""
        kin = state.frames.get(self.frame_id)
        if kin is None:
            raise CpbcError(f"{self.names[0]} reads frame {self.frame_id} from the state: "
                            "build it with the constraint set's frames (a law's state(x, dx))")
        return kin


# -- the scenario's ``type: point_outside_sphere`` -------------------------------------------
class PointOutsideSphereSpec(ConstraintEntrySpec):
    type: Literal["point_outside_sphere"] = Field(
        description=(
            "‖p − c‖² − r² > 0 for a frame's point p (the thesis's end-point obstacle)"))
    name: str = Field(
        default="obstacle", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    frame: str = Field(description="the model frame carrying the point")
    offset: Vector | None = Field(
        default=None, description=(
            "the point in the frame [m]; the frame's origin when omitted"))
    centre: Vector = Field(description="the sphere's centre in the world [m]")
    radius: Positive = Field(description="the sphere's radius [m]")
    # the thesis's obstacle is not a physical body
    collides: bool = Field(
        default=False, description=(
            "make the sphere a physical body in MuJoCo (the thesis's obstacle is not)"))


def build(spec: PointOutsideSphereSpec, given: ConstraintInputs) -> PointOutsideSphere:
    centre = np.zeros(3)
    if len(spec.centre) not in (2, 3):
        raise ScenarioError(given.at("centre"), "needs 2 (planar) or 3 coordinates")
    centre[: len(spec.centre)] = spec.centre
    offset = None if spec.offset is None else given.vector(spec.offset, 3, "offset")
    return PointOutsideSphere(given.model, spec.frame, centre, spec.radius, offset, spec.name)


def scene(spec: PointOutsideSphereSpec, built: Constraint) -> SceneSphere:
    assert isinstance(built, PointOutsideSphere)
    return SceneSphere(spec.name, built.centre, spec.radius, spec.collides)


KINDS = (ConstraintKind(PointOutsideSphereSpec, build, PointOutsideSphere,
                        {"point_outside_sphere": {"frame": "end_point", "centre": [0, 2],
                                                  "radius": 0.5}}, scene),)
