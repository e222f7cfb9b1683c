"""Potentials on the per-step state (cpbc.controllers.potentials): gradients against finite
differences, Theorem 6.9's V̇ with a task potential in every law that takes one, the
bounded-torque laws' bound with bounded task springs, the mandatory posture spring, and the
default potentials' torques unchanged to the bit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from lyapunov_rates import measured_rate, stated_rate

from cpbc.constraints import (
    ConstraintSet,
    KineticEnergyLimit,
    LinearLimit,
    PointOutsideSphere,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.controllers import (
    BPBC,
    CPBC,
    PD,
    BPBCKineticEnergy,
    Controller,
    CPBCKineticEnergy,
    Identity,
    PDGravity,
    Power,
    Tanh,
)
from cpbc.controllers.potentials import (
    FrameAxisSpring,
    FrameOrientationSpring,
    FramePositionLogCosh,
    FramePositionSpring,
    JointLogCoshSpring,
    JointSpring,
    Potential,
    total,
)
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.bounds import ModelBounds
from cpbc.model.frames import jacobian_bounds
from cpbc.model.loading import load_arm
from cpbc.resources import models_dir


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    """The Panda with joint friction, so that V̇ checks the f terms too."""
    arm = load_arm("panda")
    return RobotModel(arm.model, viscous_friction=np.linspace(0.2, 0.05, 7), name="panda")


@pytest.fixture(scope="module")
def planar() -> RobotModel:
    """The thesis's arm in absolute link angles: controller ≠ joint coordinates."""
    return RobotModel.from_mjcf(models_dir() / "planar_2link.xml",
                                coordinates=LinearCoordinates.absolute_link_angles(2))


PANDA_HOME = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
PANDA_GOAL_Q = np.array([0.6, 0.1, -0.2, -1.8, 0.1, 1.9, 0.5])


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def panda_potentials(model: RobotModel) -> dict[str, Potential]:
    """Every kind of potential on the Panda's hand, goals taken from a reachable pose."""
    goal = model.state(PANDA_GOAL_Q, np.zeros(7), frames=[model.frame_id("panda_hand")])
    hand = goal.frames[model.frame_id("panda_hand")]
    offset = [0.0, 0.0, 0.105]
    k_full = np.array([[300.0, 20.0, 0.0], [20.0, 200.0, 10.0], [0.0, 10.0, 250.0]])
    turned = hand.rotation @ _rotation(np.array([1.0, 2.0, 0.5]), 2.5)
    position = FramePositionSpring.named(model, "panda_hand", hand.position, k_full, offset)
    return {
        "joint": JointSpring(PANDA_HOME, [3.0, 5.0, 2.0, 4.0, 1.0, 2.0, 0.5]),
        "joint_log_cosh": JointLogCoshSpring(PANDA_HOME, 4.0, [2.0, 1.0, 3.0, 1.0, 2.0, 1, 5]),
        "position": position,
        "position_log_cosh": FramePositionLogCosh.named(model, "panda_hand", hand.position,
                                                        [80, 60, 70], [10, 8, 12], offset),
        "orientation": FrameOrientationSpring.named(model, "panda_hand", turned, 3.0),
        "axis": FrameAxisSpring.named(model, "panda_hand", [0, 0, 1], [0.2, 0.1, -1.0], 2.0),
        "sum": total(position, FrameAxisSpring.named(model, "panda_hand", [0, 0, 1],
                                                     [0, 0, -1], 2.0),
                     JointSpring(PANDA_HOME, 1.0)),
    }


def _gradient_matches(model: RobotModel, pot: Potential, x: np.ndarray, h: float = 1e-6
                      ) -> None:
    def value(y: np.ndarray) -> float:
        return pot.evaluate(model.state(y, np.zeros_like(y), frames=pot.frames))[0]

    u, grad = pot.evaluate(model.state(x, np.zeros_like(x), frames=pot.frames))
    assert u >= 0
    fd = np.array([(value(x + h * e) - value(x - h * e)) / (2 * h) for e in np.eye(x.size)])
    scale = float(np.linalg.norm(grad))
    assert scale > 0
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-6 * scale)


@pytest.mark.parametrize("kind", ["joint", "joint_log_cosh", "position", "position_log_cosh",
                                  "orientation", "axis", "sum"])
def test_panda_gradients_equal_finite_differences(panda: RobotModel, kind: str) -> None:
    pot = panda_potentials(panda)[kind]
    rng = np.random.default_rng(1)
    for _ in range(3):
        _gradient_matches(panda, pot, PANDA_HOME + rng.uniform(-0.8, 0.8, 7))


def test_planar_gradients_in_absolute_angles_equal_finite_differences(planar: RobotModel
                                                                       ) -> None:
    """x = T q ≠ q: the frame Jacobians are taken with respect to x."""
    rng = np.random.default_rng(2)
    pots = [
        FramePositionSpring.named(planar, "end_point", [-1.5, 0.8, 0.0], 3.0, [0.1, 0.2, 0]),
        FramePositionLogCosh.named(planar, "end_point", [-1.5, 0.8, 0.0], 3.0, 2.0),
        FrameOrientationSpring.named(planar, "link2", _rotation(np.array([0, 0, 1.0]), 2.0),
                                     1.5),
        FrameAxisSpring.named(planar, "link2", [1, 0, 0], [0, 1, 0], 2.0),
    ]
    for pot in pots:
        for _ in range(3):
            _gradient_matches(planar, pot, rng.uniform(-np.pi, np.pi, 2))


def test_jacobian_bounds_hold_at_random_configurations(panda: RobotModel, planar: RobotModel
                                                       ) -> None:
    rng = np.random.default_rng(3)
    for model, frame, offset in [(panda, "panda_hand", np.array([0, 0, 0.105])),
                                 (planar, "end_point", None)]:
        fid = model.frame_id(frame)
        lin, ang = jacobian_bounds(model.model, model.coordinates.inverse, fid, offset)
        worst = np.zeros(2)
        for _ in range(200):
            x = rng.uniform(-np.pi, np.pi, model.n)
            kin = model.state(x, np.zeros(model.n), frames=[fid]).frames[fid]
            _, jv = kin.point(offset)
            worst = np.maximum(worst, [np.linalg.norm(jv, 2), np.linalg.norm(kin.angular, 2)])
        assert np.all(worst <= [lin, ang])
        assert np.all(worst > 0.4 * np.array([lin, ang]))  # and not absurdly loose


# -- V̇ along the model's exact dynamics with a task potential -------------------------------
def _task(model: RobotModel, bounded: bool) -> Potential:
    pots = panda_potentials(model)
    if bounded:
        return total(pots["position_log_cosh"], pots["orientation"],
                     JointLogCoshSpring(PANDA_HOME, 2.0, 1.0))
    return total(pots["position"], pots["orientation"], JointSpring(PANDA_HOME, 2.0))


def panda_task_laws(model: RobotModel) -> list[tuple[str, Controller]]:
    arm = load_arm("panda")
    names = list(model.joint_names)
    limits = joint_position_limit(arm.position_lower, arm.position_upper, names)
    rates = joint_rate_limit(0.5 * arm.velocity_limit, names)
    ball = PointOutsideSphere(model, "panda_hand", [0.5, -0.4, 0.2], 0.1)
    ke = KineticEnergyLimit(model, 3.0)
    kp, kd = 20.0, np.linspace(4.0, 0.5, 7)
    bounds = ModelBounds(1.0, 1.0, 1.0)  # the laws' torques do not read them
    task, bounded = _task(model, False), _task(model, True)
    return [
        ("pd_gravity", PDGravity(model, PANDA_HOME, kp, kd, potential=task)),
        ("cpbc", CPBC(model, PANDA_HOME, ConstraintSet(7, [limits, ball], [rates]), kp, kd,
                      Power(0.3), potential=task)),
        ("cpbc_tanh", CPBC(model, PANDA_HOME, ConstraintSet(7, [ball], [rates, ke]), kp, kd,
                           Tanh(0.7), potential=task)),
        ("cpbc_ke", CPBCKineticEnergy(model, PANDA_HOME, ConstraintSet(7, [limits, ball], [ke]),
                                      kp, kd, Power(0.5), potential=task)),
        ("bpbc", BPBC(model, PANDA_HOME, ConstraintSet(7, [], [rates]), kp, kd, 2.0, 3.0,
                      Power(0.2), bounds, potential=bounded)),
        ("bpbc_ke", BPBCKineticEnergy(model, PANDA_HOME, ConstraintSet(7, [], [ke]), kp, kd, 2.0,
                                      3.0, Identity(), bounds, potential=bounded)),
    ]




@pytest.mark.parametrize("index", range(6))
def test_lyapunov_rate_with_a_task_potential_matches_theorem(panda: RobotModel, index: int
                                                             ) -> None:
    name, law = panda_task_laws(panda)[index]
    rng = np.random.default_rng(20 + index)
    checked = 0
    for _ in range(100):
        x = PANDA_HOME + rng.uniform(-0.5, 0.5, 7)
        dx = rng.uniform(-0.4, 0.4, 7)
        if not np.all(law.constraints.margins(x, dx, law.state(x, dx)) > 0):
            continue
        want = stated_rate(name, law, x, dx)
        assert want <= 0
        assert measured_rate(law, panda, x, dx) == pytest.approx(want, rel=1e-4, abs=1e-7), name
        checked += 1
        if checked == 4:
            break
    assert checked == 4


# -- the bounded-torque laws' bound with bounded task springs --------------------------------
@pytest.mark.parametrize("kind", ["bpbc", "bpbc_ke"])
def test_bounded_task_springs_keep_the_torque_bound(tilted: RobotModel, kind: str) -> None:
    tip = tilted.frame_id("tip")
    task = total(
        FramePositionLogCosh.named(tilted, "tip", [1.2, 0.0, -0.9], [40.0, 1.0, 30.0], 4.0),
        FrameAxisSpring.named(tilted, "tip", [1, 0, 0], [0, 0, -1], 6.0),
        JointLogCoshSpring(np.array([0.4, -0.3]), [3.0, 2.0], 1.0),
    )
    kd = np.array([5.0, 3.0])
    if kind == "bpbc":
        law: BPBC | BPBCKineticEnergy = BPBC(
            tilted, np.array([0.4, -0.3]), ConstraintSet(2, [], [joint_rate_limit(
                [1.5, 2.0], ["j1", "j2"])]), 1.0, kd, 1.0, 3.0, Power(0.2), potential=task)
    else:
        law = BPBCKineticEnergy(tilted, np.array([0.4, -0.3]), ConstraintSet(
            2, [], [KineticEnergyLimit(tilted, 2.0)]), 1.0, kd, 1.0, 3.0, Identity(),
            potential=task)
    # (7.32)/(7.40) with λmax(K_P) replaced by the springs' gradient bound:
    # J̄_v ‖diag K‖ + 2 … k J̄_ω + (‖diag K_n‖ or, as the thesis states it, λmax(K_n))
    reach_v, reach_w = jacobian_bounds(tilted.model, tilted.coordinates.inverse, tip)
    frame_part = reach_v * math.hypot(40.0, 1.0, 30.0) + reach_w * 6.0
    zb = law.model_bounds
    rate = math.hypot(1.5, 2.0)
    tail = zb.gravity + (zb.coriolis * rate**2 + zb.friction * rate if kind == "bpbc" else 0)
    assert law.torque_bound_norm == pytest.approx(
        tail + frame_part + math.hypot(3.0, 2.0) + math.hypot(5.0, 3.0), rel=1e-12)
    assert law.torque_bound == pytest.approx(tail + frame_part + 3.0 + 5.0, rel=1e-12)
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(2000):
        try:
            tau = law.torque(rng.uniform(-np.pi, np.pi, 2), rng.uniform(-2.0, 2.0, 2))
        except ConstraintViolation:
            continue
        worst = max(worst, float(np.linalg.norm(tau)))
    assert 0 < worst <= law.torque_bound_norm


# -- refusals ---------------------------------------------------------------------------------
def test_a_task_potential_without_posture_spring_is_refused(panda: RobotModel) -> None:
    pots = panda_potentials(panda)
    bare = total(pots["position_log_cosh"], pots["axis"])
    rates = ConstraintSet(7, [], [joint_rate_limit(np.ones(7), list(panda.joint_names))])
    ke = ConstraintSet(7, [], [KineticEnergyLimit(panda, 3.0)])
    bounds = ModelBounds(1.0, 1.0, 1.0)
    makers = [
        lambda p: PD(panda, PANDA_HOME, 1, 1, potential=p),
        lambda p: PDGravity(panda, PANDA_HOME, 1, 1, potential=p),
        lambda p: CPBC(panda, PANDA_HOME, rates, 1, 1, potential=p),
        lambda p: CPBCKineticEnergy(panda, PANDA_HOME, ke, 1, 1, potential=p),
        lambda p: BPBC(panda, PANDA_HOME, rates, 1, 1, model_bounds=bounds, potential=p),
        lambda p: BPBCKineticEnergy(panda, PANDA_HOME, ke, 1, 1, model_bounds=bounds,
                                    potential=p),
    ]
    for make in makers:
        with pytest.raises(CpbcError, match="no posture spring"):
            make(bare)
        with pytest.raises(CpbcError, match="no posture spring"):
            make(pots["position"])
    with pytest.raises(CpbcError, match="bounded gradient"):
        BPBC(panda, PANDA_HOME, rates, 1, 1, model_bounds=bounds, potential=_task(panda, False))


def test_a_state_without_the_potentials_frame_is_refused(panda: RobotModel) -> None:
    pot = panda_potentials(panda)["position"]
    with pytest.raises(CpbcError, match="holds no kinematics of frame"):
        pot.evaluate(panda.state(PANDA_HOME, np.zeros(7), kinematics=True))
    law = CPBC(panda, PANDA_HOME, ConstraintSet(7), 1.0, 1.0, potential=_task(panda, False))
    assert set(law.state(PANDA_HOME, np.zeros(7)).frames) == {panda.frame_id("panda_hand")}


# -- default potentials: the torques of before, to the bit -----------------------------------
# τ and V of each law, computed by the code before potentials were state-based (the laws'
# own joint springs), at three states each.
BEFORE = {
    "pd": [([7.500000000000002, -9.4], 3.9536736391472767), ([29.0, -19.5], 20.404575704129154),
           ([-19.0, 15.7], 11.877469045531372)],
    "pd_gravity": [([-9.65242905566038, -12.398992306663104], 3.9536736391472767),
                   ([13.393309772749614, -22.623517075640777], 20.404575704129154),
                   ([-29.809047225462134, 12.576482924359219], 11.877469045531372)],
    "cpbc": [([-17.547321037062012, -7.733517103310675], 2.197150073880831),
             ([-13.792006064279287, -6.594092219306456], 10.980622360941304),
             ([-37.61812618139412, -8.498971343859758], 12.877623918040518)],
    "cpbc_tanh": [([-11.55896530978211, -10.451464084975852], 3.9759706409558024),
                  ([13.371380475628516, -22.600343214013282], 20.404609707228172),
                  ([-23.71146545460558, -7.038362331485757], 25.9502931918071)],
    "cpbc_ke": [([-16.770137447408253, -10.038921640368821], 1.5770795136364542),
                ([-12.646816741899364, -11.083430035341069], 7.485782623177906),
                ([-32.01082826273222, -4.991220810038367], 14.553235029943362)],
    "bpbc": [([-11.917410383564718, -6.614198077612073], 6.007274653610049),
             ([-7.626328938330223, -3.4108909236121123], 24.9125772364513),
             ([-20.12622899861588, -1.846544954175507], 15.752725275655523)],
    "bpbc_ke": [([-14.479605781059215, -5.904484946074982], 3.6879259762565635),
                ([-13.625820033268353, -4.440241340875813], 15.443507262315972),
                ([-13.422468936869691, -1.4665250944340809], 9.597174548779078)],
    "cpbc_planar": [([0.140095463934331, 0.04938462070937374], 42.75030945776758),
                    ([0.805554643903638, 0.08305460737713244], 8.689236253756413),
                    ([0.2179755981704327, 0.013905115966028161], 85.9541703699729)],
}
TILTED_STATES = [(np.array([0.1, 0.2]), np.array([0.3, -0.2])),
                 (np.array([-0.5, 0.6]), np.array([-0.4, 0.5])),
                 (np.array([1.0, -1.1]), np.array([0.2, 0.1]))]
PLANAR_STATES = [(np.array([0.3, 0.5]), np.array([0.1, -0.05])),
                 (np.array([2.0, 2.5]), np.array([-0.2, 0.1])),
                 (np.array([-1.0, 0.2]), np.array([0.0, 0.15]))]


def default_laws(tilted: RobotModel, planar: RobotModel, explicit: bool
                 ) -> dict[str, Controller]:
    """The laws with their default potentials, or (``explicit``) the same joint springs
    passed as potentials."""
    target, kp, kd = np.array([0.4, -0.3]), np.array([30.0, 20.0]), np.array([5.0, 3.0])
    quad = {"potential": JointSpring(target, kp)} if explicit else {}
    lc = {"potential": JointLogCoshSpring(target, kp, 2.0)} if explicit else {}
    rates = joint_rate_limit([1.5, 2.0], ["j1", "j2"])
    limits = joint_position_limit([-1.2, -2.0], [1.5, 1.0], ["j1", "j2"])
    sphere = PointOutsideSphere(tilted, "tip", [1.2, 0.0, -1.2], 0.3)
    ke = KineticEnergyLimit(tilted, 2.0)
    mb = ModelBounds(1.0, 1.0, 1.0)
    t_planar = np.array([np.pi, 2 * np.pi / 3])
    obstacle = PointOutsideSphere(planar, "end_point", [0, 2, 0], 0.5, name="obstacle")
    rel = LinearLimit([[-1, 1]], [-17 * np.pi / 18], [17 * np.pi / 18], ["relative"])
    planar_quad = {"potential": JointSpring(t_planar, 4.0)} if explicit else {}
    return {
        "pd": PD(tilted, target, kp, kd, **quad),
        "pd_gravity": PDGravity(tilted, target, kp, kd, **quad),
        "cpbc": CPBC(tilted, target, ConstraintSet(2, [limits, sphere], [rates]), kp, kd,
                     Power(0.3), **quad),
        "cpbc_tanh": CPBC(tilted, target, ConstraintSet(2, [sphere], [rates, ke]), kp, kd,
                          Tanh(0.7), **quad),
        "cpbc_ke": CPBCKineticEnergy(tilted, target, ConstraintSet(2, [limits, sphere], [ke]),
                                     kp, kd, Power(0.5), **quad),
        "bpbc": BPBC(tilted, target, ConstraintSet(2, [], [rates]), kp, kd, 2.0, 3.0,
                     Power(0.2), mb, **lc),
        "bpbc_ke": BPBCKineticEnergy(tilted, target, ConstraintSet(2, [], [ke]), kp, kd, 2.0,
                                     3.0, Identity(), mb, **lc),
        "cpbc_planar": CPBC(planar, t_planar, ConstraintSet(2, [obstacle, rel], [
            joint_rate_limit([0.3, 0.2], ["t1", "t2"])]), 4, 20, Power(0.2), **planar_quad),
    }


@pytest.mark.parametrize("explicit", [False, True])
def test_default_potentials_give_the_torques_of_before(tilted: RobotModel, planar: RobotModel,
                                                       explicit: bool) -> None:
    for name, law in default_laws(tilted, planar, explicit).items():
        states = PLANAR_STATES if name.endswith("planar") else TILTED_STATES
        for (x, dx), (tau, value) in zip(states, BEFORE[name], strict=True):
            # to rounding: the compiled law kernels (cpbc.kernels) order the arithmetic
            # differently from the array code these values were recorded with
            got, v = law.evaluate(x, dx)
            np.testing.assert_allclose(got, tau, rtol=1e-12, atol=1e-12, err_msg=name)
            assert v == pytest.approx(value, rel=1e-12, abs=1e-12), name
            np.testing.assert_allclose(law.evaluate_state(law.state(x, dx)).torque, tau,
                                       rtol=1e-12, atol=1e-12, err_msg=name)
