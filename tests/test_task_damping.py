"""Task-space damping (cpbc.controllers.task_damping): each law's V̇ identity with K_D ẋ
replaced by K_D ẋ + F, ẋᵀF ≥ 0 without feed-forward, the bounded form's bound inside BPBC's
torque bound, and the refusal of unbounded task damping by the bounded-torque laws."""

from __future__ import annotations

import math

import numpy as np
import pytest
from lyapunov_rates import measured_rate, stated_rate

from cpbc.constraints import (
    ConstraintSet,
    KineticEnergyLimit,
    PointOutsideSphere,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.controllers import (
    BPBC,
    CPBC,
    BPBCKineticEnergy,
    Controller,
    CPBCKineticEnergy,
    PDGravity,
    Power,
    TaskDamping,
    TaskTanhDamping,
)
from cpbc.controllers.potentials import (
    FrameAxisSpring,
    FramePositionLogCosh,
    FramePositionSpring,
    JointLogCoshSpring,
    JointSpring,
    total,
)
from cpbc.errors import CpbcError
from cpbc.model import RobotModel
from cpbc.model.bounds import ModelBounds
from cpbc.model.loading import load_arm

HOME = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
GOAL = np.array([0.45, 0.35, 0.35])
HAND = "panda_hand"


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    arm = load_arm("panda")
    return RobotModel(arm.model, viscous_friction=np.linspace(0.2, 0.05, 7), name="panda")


def _laws(model: RobotModel) -> list[tuple[str, Controller]]:
    arm = load_arm("panda")
    names = list(model.joint_names)
    limits = joint_position_limit(arm.position_lower, arm.position_upper, names)
    rates = joint_rate_limit(0.5 * arm.velocity_limit, names)
    ball = PointOutsideSphere(model, HAND, [0.5, -0.4, 0.2], 0.1)
    ke = KineticEnergyLimit(model, 3.0)
    kp, kd = 20.0, np.linspace(2.0, 0.3, 7)
    bounds = ModelBounds(1.0, 1.0, 1.0)
    axis = FrameAxisSpring.named(model, HAND, [0, 0, 1], [0, 0, -1], 2.0)
    task = total(FramePositionSpring.named(model, HAND, GOAL, 200.0), axis,
                 JointSpring(HOME, 2.0))
    bounded = total(FramePositionLogCosh.named(model, HAND, GOAL, 60.0, 8.0), axis,
                    JointLogCoshSpring(HOME, 2.0, 1.0))
    fid = model.frame_id(HAND)
    linear = TaskDamping(fid, np.array([[30.0, 5.0, 0.0], [5.0, 20.0, 0.0], [0.0, 0.0, 25.0]]))
    tanh = TaskTanhDamping.named(model, HAND, [15.0, 10.0, 12.0], [2.0, 3.0, 1.5])
    return [
        ("pd_gravity", PDGravity(model, HOME, kp, kd, potential=task, task_damping=linear)),
        ("cpbc", CPBC(model, HOME, ConstraintSet(7, [limits, ball], [rates]), kp, kd,
                      Power(0.3), potential=task, task_damping=linear)),
        ("cpbc_ke", CPBCKineticEnergy(model, HOME, ConstraintSet(7, [limits, ball], [ke]), kp,
                                      kd, Power(0.5), potential=task, task_damping=linear)),
        ("bpbc", BPBC(model, HOME, ConstraintSet(7, [], [rates]), kp, kd, 2.0, 3.0, Power(0.2),
                      bounds, potential=bounded, task_damping=tanh)),
        ("bpbc_ke", BPBCKineticEnergy(model, HOME, ConstraintSet(7, [], [ke]), kp, kd, 2.0, 3.0,
                                      None, bounds, potential=bounded, task_damping=tanh)),
    ]




@pytest.mark.parametrize("index", range(5))
def test_lyapunov_rate_with_task_damping_matches_theorem(panda: RobotModel, index: int) -> None:
    name, law = _laws(panda)[index]
    rng = np.random.default_rng(40 + index)
    checked = 0
    for _ in range(100):
        x = HOME + rng.uniform(-0.5, 0.5, 7)
        dx = rng.uniform(-0.4, 0.4, 7)
        if not np.all(law.constraints.margins(x, dx, law.state(x, dx)) > 0):
            continue
        assert law.task_damping is not None
        want = stated_rate(name, law, x, dx)
        assert want < 0
        assert measured_rate(law, panda, x, dx) == pytest.approx(want, rel=1e-4, abs=1e-7), name
        checked += 1
        if checked == 3:
            break
    assert checked == 3


def test_task_damping_changes_the_torque_by_exactly_its_force(panda: RobotModel) -> None:
    """CPBC-KE without C or D⁻¹: τ − τ(no task damping) = −F/(1 + ρ/ψ); F = J_vᵀD_xJ_vẋ."""
    _, law = _laws(panda)[2]
    assert isinstance(law, CPBCKineticEnergy) and law.task_damping is not None
    bare = CPBCKineticEnergy(panda, HOME, law.constraints, law.kp, law.kd, law.shaping,
                             potential=law.potential)
    x, dx = HOME + 0.1, np.full(7, 0.2)
    state = law.state(x, dx)
    jv = state.frames[panda.frame_id(HAND)].linear
    force = jv.T @ law.task_damping.gain @ jv @ dx  # type: ignore[attr-defined]
    diff = law.torque(x, dx) - bare.torque(x, dx)
    assert np.allclose(diff / np.linalg.norm(diff), -force / np.linalg.norm(force))


def test_feedforward_slot_is_zero_for_a_fixed_goal_and_tracks_a_moving_point(
        panda: RobotModel) -> None:
    fid = panda.frame_id(HAND)
    fixed = TaskDamping(fid, 10.0)
    assert np.all(fixed.feedforward == 0)
    x, dx = HOME, np.full(7, 0.1)
    state = panda.state(x, dx, frames=[fid])
    v = state.frames[fid].linear @ dx
    moving = TaskDamping(fid, 10.0, feedforward=v)
    assert np.allclose(moving.force(state, dx), 0.0, atol=1e-12)


@pytest.mark.parametrize("offset", [None, [0.01, -0.02, 0.1]])
def test_bounded_task_terms_equal_their_numpy_formulas(panda: RobotModel, offset) -> None:  # type: ignore[no-untyped-def]
    """The ln cosh position spring and the tanh task damping (their kernels, in
    cpbc.kernels.law_terms and cpbc.kernels.task) against the numpy code they replaced, on
    the point of FrameKinematics.point: U, ∂U/∂x = J_pᵀ K tanh(Ξe) and
    F = J_pᵀ D_x tanh(Γ_x (J_p ẋ − ṗ_ff)) to 1e-12, in and past saturation."""
    spring = FramePositionLogCosh.named(panda, HAND, GOAL, [50.0, 60.0, 70.0], [5.0, 8.0, 3.0],
                                        offset)
    named = TaskTanhDamping.named(panda, HAND, [15.0, 10.0, 12.0], [2.0, 3.0, 1.5], offset)
    tanh = TaskTanhDamping(named.frame, named.gain, named.gamma, named.reach, named.offset,
                           np.array([0.1, -0.2, 0.05]))
    weight = spring.stiffness / spring.xi
    rng = np.random.default_rng(11)
    for _ in range(50):
        x, dx = rng.uniform(-2.0, 2.0, 7), rng.normal(scale=2.0, size=7)
        state = panda.state(x, dx, frames=[spring.frame])
        p, jv = state.frames[spring.frame].point(spring.offset)
        y = spring.xi * (p - spring.goal)
        value = float(np.sum(weight * (np.logaddexp(y, -y) - math.log(2.0))))
        u, grad = spring.evaluate(state)
        assert u == pytest.approx(value, rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(grad, jv.T @ (spring.stiffness * np.tanh(y)), rtol=1e-12,
                                   atol=1e-12)
        want = jv.T @ (tanh.gain * np.tanh(tanh.gamma * (jv @ dx - tanh.feedforward)))
        np.testing.assert_allclose(tanh.force(state, dx), want, rtol=1e-12, atol=1e-12)


def test_bounded_task_damping_enters_the_torque_bound_and_linear_is_refused(
        panda: RobotModel) -> None:
    _, law = _laws(panda)[3]
    assert isinstance(law, BPBC) and isinstance(law.task_damping, TaskTanhDamping)
    plain = BPBC(panda, HOME, law.constraints, law.kp, law.kd, 2.0, 3.0, Power(0.2),
                 law.model_bounds, potential=law.potential)
    extra = law.task_damping.force_bound
    assert law.torque_bound_norm == pytest.approx(plain.torque_bound_norm + extra)
    rng = np.random.default_rng(3)
    for _ in range(50):
        x = rng.uniform(-3, 3, 7)
        dx = rng.uniform(-50, 50, 7)
        state = panda.state(x, dx, frames=[panda.frame_id(HAND)])
        assert np.linalg.norm(law.task_damping.force(state, dx)) <= extra
    with pytest.raises(CpbcError, match="bounded task damping"):
        BPBC(panda, HOME, law.constraints, law.kp, law.kd, 2.0, 3.0, Power(0.2),
             law.model_bounds, potential=law.potential,
             task_damping=TaskDamping(panda.frame_id(HAND), 10.0))
