"""PointOutsideSphere's second-order terms (cpbc.constraints.point_outside_sphere): φ, ∇φ and
ẋᵀ∇²φ ẋ read from the per-step state alone (cpbc.kernels.barriers.point_sphere_motion),
against Pinocchio's own frame velocity and classical acceleration, on the thesis's planar
arm in absolute link angles and on the Panda."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from cpbc.constraints import ConstraintSet, LinearLimit, PointOutsideSphere
from cpbc.errors import CpbcError
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.loading import load_arm
from cpbc.resources import models_dir

_WORLD_ALIGNED = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _planar(offset: list[float] | None) -> PointOutsideSphere:
    model = RobotModel.from_mjcf(models_dir() / "planar_2link.xml",
                                 coordinates=LinearCoordinates.absolute_link_angles(2))
    return PointOutsideSphere(model, "end_point", [0, 2, 0], 0.5, offset)


def _panda(coordinates: LinearCoordinates) -> PointOutsideSphere:
    model = RobotModel(load_arm("panda").model, coordinates, name="panda")
    return PointOutsideSphere(model, "panda_hand_tcp", [0.4, 0.1, 0.5], 0.1,
                              [0.02, -0.03, 0.05])


def _pinocchio_curvature(c: PointOutsideSphere, x: np.ndarray, dx: np.ndarray
                         ) -> tuple[float, float]:
    """ẋᵀ∇²φ ẋ = 2‖ṗ‖² + 2 (p − c)·p̈₀ from Pinocchio's frame velocity and classical
    acceleration at q̈ = 0 (α × r + ω × (ω × r) for the offset r), on data of the test's own;
    and the size of its terms, 2‖ṗ‖² + 2‖p − c‖‖p̈₀‖, to measure a difference against."""
    pm, data = c.model.model, c.model.model.createData()
    q, dq = c.model.joint_coordinates(x), c.model.joint_coordinates(dx)
    pin.forwardKinematics(pm, data, q, dq, np.zeros_like(dq))
    pin.updateFramePlacements(pm, data)
    vel = pin.getFrameVelocity(pm, data, c.frame_id, _WORLD_ALIGNED)
    origin_acc = pin.getFrameClassicalAcceleration(pm, data, c.frame_id, _WORLD_ALIGNED).linear
    spin_dot = pin.getFrameAcceleration(pm, data, c.frame_id, _WORLD_ALIGNED).angular
    spin, placement = vel.angular, data.oMf[c.frame_id]
    r = np.zeros(3) if c.offset is None else placement.rotation @ c.offset
    p_dot = vel.linear + np.cross(spin, r)
    p_ddot = origin_acc + np.cross(spin_dot, r) + np.cross(spin, np.cross(spin, r))
    d = placement.translation + r - c.centre
    size = 2.0 * p_dot @ p_dot + 2.0 * np.linalg.norm(d) * np.linalg.norm(p_ddot)
    return 2.0 * float(p_dot @ p_dot) + 2.0 * float(d @ p_ddot), float(size)


def _states(n: int, count: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    return [(rng.uniform(-2.0, 2.0, n), rng.uniform(-1.5, 1.5, n)) for _ in range(count)]


def _assert_matches_the_pinocchio_path(c: PointOutsideSphere) -> None:
    n = c.model.n
    bent = 0
    for x, dx in _states(n, 8, seed=n):
        state = c.model.state(x, dx, kinematics=True, frames=c.frames)
        phi, grad, curv = c.motion_terms(state)
        value, gradient = c.evaluate(x)  # Pinocchio's frame Jacobian at x
        np.testing.assert_allclose(phi, value, rtol=1e-12)
        assert np.abs(grad - gradient).max() <= 1e-12 * np.abs(gradient).max()
        expected, size = _pinocchio_curvature(c, x, dx)
        assert abs(curv[0] - expected) <= 1e-12 * size, (curv[0], expected, size)
        assert c.curvature(x, dx)[0] == curv[0]  # one formula: curvature is motion_terms'
        bent += abs(expected) > 1e-2 * size
    assert bent >= 4  # the curvature is not trivially small against its terms


@pytest.mark.parametrize("offset", [None, [0.1, -0.05, 0.0]])
def test_planar_motion_terms_equal_pinocchio_in_absolute_link_angles(offset) -> None:
    _assert_matches_the_pinocchio_path(_planar(offset))


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_panda_motion_terms_equal_pinocchio_with_a_point_offset(coordinates) -> None:
    coords = (LinearCoordinates.identity(7) if coordinates == "joint"
              else LinearCoordinates.absolute_link_angles(7))
    _assert_matches_the_pinocchio_path(_panda(coords))


def test_motion_terms_make_no_pinocchio_pass() -> None:
    """The terms come from the state alone: the model's data, moved to another state after the
    state was built, is read by nothing and left as it was; the constraint keeps no data."""
    c = _panda(LinearCoordinates.absolute_link_angles(7))
    assert not any(isinstance(v, pin.Data) for v in vars(c).values())
    (x, dx), (x2, dx2) = _states(7, 2, seed=11)
    state = c.model.state(x, dx, kinematics=True, frames=c.frames)
    expected = c.motion_terms(state)
    pm, data = c.model.model, c.model.data
    pin.forwardKinematics(pm, data, x2, dx2, np.ones(7))
    pin.computeJointJacobians(pm, data, x2)
    pin.updateFramePlacements(pm, data)
    before = (data.oMf[c.frame_id].homogeneous.copy(), np.array(data.J),
              np.array([data.v[j].vector for j in range(pm.njoints)]),
              np.array([data.a[j].vector for j in range(pm.njoints)]))
    got = c.motion_terms(state)
    for e, g in zip(expected, got, strict=True):
        np.testing.assert_array_equal(e, g)
    after = (data.oMf[c.frame_id].homogeneous, np.array(data.J),
             np.array([data.v[j].vector for j in range(pm.njoints)]),
             np.array([data.a[j].vector for j in range(pm.njoints)]))
    for b, a in zip(before, after, strict=True):
        np.testing.assert_array_equal(b, a)


def test_a_state_without_what_the_terms_read_is_refused_naming_the_fix() -> None:
    c = _planar(None)
    x, dx = np.array([0.3, 0.9]), np.array([0.2, -0.1])
    with pytest.raises(CpbcError, match="kinematics=True"):
        c.motion_terms(c.model.state(x, dx, frames=c.frames))
    with pytest.raises(CpbcError, match="frame"):
        c.motion_terms(c.model.state(x, dx, kinematics=True))


def test_the_set_builds_the_joint_kinematics_only_for_the_motion_terms() -> None:
    """A law's state has no joint kinematics for a point (its barrier terms read the frame);
    a filter on φ̈ asks for them (``motion=True``), and only when a constraint reads them."""
    c = _planar(None)
    x, dx = np.array([0.3, 0.9]), np.array([0.2, -0.1])
    with_point = ConstraintSet(2, [c])
    assert with_point.state(c.model, x, dx).joint_jacobians is None
    assert with_point.state(c.model, x, dx, motion=True).joint_jacobians is not None
    limit = LinearLimit([[-1, 1]], [-3.0], [3.0], ["relative"])
    assert ConstraintSet(2, [limit]).state(c.model, x, dx, motion=True).joint_jacobians is None


def test_values_along_are_value_row_by_row_bit_for_bit(rng) -> None:
    """The margins along a prediction (one kinematics pass a row, the rest at once) are
    ``value`` at each row, to the bit, in absolute link angles, with an offset and without."""
    model = RobotModel.from_mjcf(models_dir() / "planar_2link.xml",
                                 coordinates=LinearCoordinates.absolute_link_angles(2))
    for offset in (None, [0.1, 0.0, 0.05]):
        c = PointOutsideSphere(model, "end_point", [0.0, 2.0, 0.0], 0.5, offset=offset)
        xs = rng.uniform(-1.0, 3.0, (9, 2))
        along = c.values_along(xs)
        assert along.shape == (9, 1)
        np.testing.assert_array_equal(along, np.array([c.value(x) for x in xs]))
