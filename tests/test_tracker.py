"""A streamed target (cpbc.reference.tracker): nothing a policy sends breaks the tracker. Bad
input raises a ValueError naming it and leaves the previous target in force; a jump of any
size is paced by the governor; a target the constraints hold the arm off is reported by
``blocked_by``; a joint target is followed. Real Panda model, scenario and MuJoCo plant."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from cpbc.controllers.packed_law import PacksItsLaw
from cpbc.errors import ParameterError
from cpbc.reference import GovernorSettings, ReferenceTracker, tracking
from cpbc.scenario import ScenarioSetup, build, load_scenario
from cpbc.simulation.plant import MujocoPlant

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


@pytest.fixture(scope="module")
def setup() -> ScenarioSetup:
    return build(*load_scenario("panda_goal_pose"))


def _tracker(setup: ScenarioSetup, **kwargs: object) -> ReferenceTracker:
    entry = setup.controllers[1]  # task-space CPBC in its safeguard
    return tracking(entry.controller, 1e-3, run=setup.controller(entry), **kwargs)  # type: ignore[arg-type]


def _plant(setup: ScenarioSetup) -> MujocoPlant:
    assert setup.goal is not None
    plant = setup.make_plant()
    plant.reset(setup.goal.posture, np.zeros(7))
    return plant


def _run(law: ReferenceTracker, plant: MujocoPlant, steps: int) -> np.ndarray:
    """The user's own loop: the tracker's torque held for one 1 ms MuJoCo step."""
    tau = np.zeros(7)
    for _ in range(steps):
        tau = law.torque(plant.data.qpos, plant.data.qvel)
        assert np.all(np.isfinite(tau))
        plant.apply(tau)
        plant.step(1)
    return tau


def _hand(setup: ScenarioSetup, law: ReferenceTracker, x: np.ndarray) -> np.ndarray:
    return setup.model.point_position(law.frame, x, law.offset)


@pytest.mark.parametrize(("position", "velocity", "field", "says"), [
    ([np.nan, 0.0, 0.0], None, "position", "finite"),
    ([0.5, np.inf, 0.3], None, "position", "finite"),
    ([0.5], None, "position", "shape (1,)"),
    ([0.5, 0.0, 0.3, 0.0], None, "position", "shape (4,)"),
    ("near the ball", None, "position", "3 finite numbers"),
    ([0.5, 0.0, 0.3], [0.0, np.nan, 0.0], "velocity", "finite"),
    ([0.5, 0.0, 0.3], [1.0, 0.0], "velocity", "shape (2,)"),
])
def test_a_bad_target_is_refused_and_the_previous_one_stays(
        setup: ScenarioSetup, position: object, velocity: object, field: str, says: str
        ) -> None:
    law = _tracker(setup)
    good = law.requested + np.array([0.0, 0.0, 0.05])
    law.set_target(good, [0.01, 0.0, 0.0])
    with pytest.raises(ValueError, match=re.escape(says)) as err:
        law.set_target(position, velocity)  # type: ignore[arg-type]
    assert isinstance(err.value, ParameterError) and err.value.parameter == field
    assert str(err.value).startswith(f"{field} must be")
    assert "frame 'panda_hand'" in str(err.value)  # in the user's terms
    np.testing.assert_array_equal(law.requested, good)
    np.testing.assert_array_equal(law.requested_velocity, [0.01, 0.0, 0.0])


def test_after_a_refused_nan_the_torque_stays_finite_and_tracking_goes_on(
        setup: ScenarioSetup) -> None:
    # before: one NaN target turned every later torque to NaN, for good
    law, plant = _tracker(setup), _plant(setup)
    good = law.requested + np.array([0.0, 0.0, 0.05])
    law.set_target(good)
    _run(law, plant, 50)
    with pytest.raises(ValueError):
        law.set_target([np.nan, np.nan, np.nan])
    _run(law, plant, 1450)
    assert np.all(np.isfinite(law.moving.position))
    assert np.linalg.norm(_hand(setup, law, plant.data.qpos) - good) < 0.01


@pytest.mark.parametrize("period", [0.0, -1e-3, np.nan, np.inf, "1 ms"])
def test_a_period_that_is_not_a_positive_time_is_refused(setup: ScenarioSetup,
                                                         period: object) -> None:
    entry = setup.controllers[1]
    with pytest.raises(ValueError, match="period must be the control period") as err:
        tracking(entry.controller, period, run=setup.controller(entry))  # type: ignore[arg-type]
    assert isinstance(err.value, ParameterError) and err.value.parameter == "period"


@pytest.mark.parametrize(("x", "dx", "field"), [
    (np.zeros(6), np.zeros(7), "x"),
    (np.zeros(7), np.zeros(8), "dx"),
    ([0.0] * 7, np.zeros(7), None),  # a list of the right length is read
    (np.full(7, np.nan), np.zeros(7), "x"),
    (np.zeros(7), np.array([0, 0, np.inf, 0, 0, 0, 0]), "dx"),
])
def test_a_wrong_state_names_itself_not_pinocchio(setup: ScenarioSetup, x: object,
                                                  dx: object, field: str | None) -> None:
    law = _tracker(setup)
    start = setup.goal.posture  # type: ignore[union-attr]
    if field is None:
        assert np.all(np.isfinite(law.torque(start + np.asarray(x), np.zeros(7))))
        return
    with pytest.raises(ValueError, match=rf"^{field} must be 7 finite numbers") as err:
        law.torque(x, dx)  # type: ignore[arg-type]
    assert "pinocchio" not in str(err.value).lower()


def test_a_second_tracker_on_one_law_steers_it(setup: ScenarioSetup) -> None:
    # before: the second tracking() failed with "no frame position spring"
    first = _tracker(setup)
    second = _tracker(setup)
    np.testing.assert_allclose(second.requested, first.requested)
    plant = _plant(setup)
    goal = second.requested + np.array([0.0, 0.0, 0.05])
    second.set_target(goal)
    _run(second, plant, 1500)
    assert np.linalg.norm(_hand(setup, second, plant.data.qpos) - goal) < 0.01


def test_a_law_without_a_frame_spring_is_refused_by_name(setup: ScenarioSetup) -> None:
    joint = build(*load_scenario("panda_cpbc_sphere"))
    with pytest.raises(ValueError, match=r"^law: a cpbc law without a frame position spring"):
        tracking(joint.controllers[-1].controller, 1e-3)


def test_a_jump_of_any_size_moves_the_applied_point_at_the_governor_pace(
        setup: ScenarioSetup) -> None:
    settings = GovernorSettings(max_speed=0.5)
    law, plant = _tracker(setup, settings=settings), _plant(setup)
    start = law.moving.position.copy()
    law.set_target(start + np.array([1e6, 0.0, 0.0]))
    before = law.moving.position.copy()
    for _ in range(200):
        _run(law, plant, 1)
        step = np.linalg.norm(law.moving.position - before)
        assert step <= 0.5 * 1e-3 * (1 + 1e-12)
        before = law.moving.position.copy()
    assert 0.0 < np.linalg.norm(law.moving.position - start) <= 0.1 + 1e-9


def test_a_fed_forward_velocity_is_capped_at_the_pace(setup: ScenarioSetup) -> None:
    law, plant = _tracker(setup), _plant(setup)
    law.set_target(law.requested, [1e9, 0.0, 0.0])
    _run(law, plant, 1)
    assert np.linalg.norm(law.moving.velocity) <= law.settings.max_speed * (1 + 1e-12)


@pytest.mark.parametrize(("target", "held_by"), [
    ([0.5, 0.0, 0.3], "clearance[panda_hand|ball]"),  # the ball's centre
    ([0.45, 0.35, -0.2], "clearance[panda_leftfinger|table]"),  # under the table
    ([2.0, 0.0, 0.5], "unreachable"),  # 2 m out: beyond the arm's reach
])
def test_a_target_the_arm_is_held_off_is_approached_and_reported(
        setup: ScenarioSetup, target: list[float], held_by: str) -> None:
    law, plant = _tracker(setup), _plant(setup)
    law.set_target(target)
    _run(law, plant, 300)
    assert law.blocked_by is None  # on its way
    _run(law, plant, 2700)
    x = plant.data.qpos.copy()
    setup.controllers[1].controller.constraints.check_admissible(x, plant.data.qvel, "end")
    assert np.linalg.norm(_hand(setup, law, x) - target) > 0.1
    assert law.blocked_by == held_by
    law.set_target(setup.goal.goal.position)
    _run(law, plant, 2000)
    assert law.blocked_by is None
    assert np.linalg.norm(_hand(setup, law, plant.data.qpos) - law.requested) < 0.01


def test_a_joint_target_is_followed(setup: ScenarioSetup) -> None:
    # joints 1 and 7 turn about vertical axes here: the law's gripper-down axis spring
    # agrees with the target (another joint target would pull against it)
    law, plant = _tracker(setup), _plant(setup)
    goal = setup.goal.posture + np.array([0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.4])  # type: ignore[union-attr]
    law.set_joint_target(goal)
    np.testing.assert_allclose(law.requested, _hand(setup, law, goal))
    _run(law, plant, 1000)
    assert law.blocked_by is None  # joint 7 still turning toward it (ω_n 2 rad/s)
    _run(law, plant, 4000)
    assert np.max(np.abs(plant.data.qpos - goal)) < 0.01
    assert law.blocked_by is None
    with pytest.raises(ValueError, match=r"^joints must be 7 finite numbers"):
        law.set_joint_target(goal[:3])
    np.testing.assert_array_equal(law.requested_posture, goal)


def test_a_joint_target_past_a_limit_is_reported(setup: ScenarioSetup) -> None:
    law, plant = _tracker(setup), _plant(setup)
    start = setup.goal.posture.copy()  # type: ignore[union-attr]
    start[6] = 2.3  # turned about the gripper's (vertical) axis
    plant.reset(start, np.zeros(7))
    goal = start.copy()
    goal[6] = 3.5  # joint 7's upper limit is 2.8973 rad
    law.set_joint_target(goal)  # the applied posture sets out from the law's x_n (j7 ≈ 0)
    _run(law, plant, 7000)  # j7 rings against its barrier at 4-6 s, then rests
    assert 2.5 < plant.data.qpos[6] < 2.8973
    assert law.blocked_by == "position[panda_joint7]"


@pytest.mark.parametrize("huge", [1e300, -1e200, 1e15])
def test_a_huge_but_finite_target_leaves_the_torque_finite(setup: ScenarioSetup,
                                                           huge: float) -> None:
    law, plant = _tracker(setup), _plant(setup)
    law.set_target([huge, 0.0, huge], [huge, huge, 0.0])
    _run(law, plant, 200)  # asserts a finite torque at every step
    law.set_joint_target(np.full(7, huge), np.full(7, -huge))
    _run(law, plant, 200)
    assert np.all(np.isfinite(law.moving.position)) and np.all(np.isfinite(law.moving.posture))
    law.set_target(setup.goal.goal.position)  # type: ignore[union-attr]
    _run(law, plant, 2500)
    assert np.linalg.norm(_hand(setup, law, plant.data.qpos) - law.requested) < 0.01


def _rotation_about_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _hand_rotation(setup: ScenarioSetup, x: np.ndarray) -> np.ndarray:
    hand = setup.model.frame_id("panda_hand")
    return setup.model.state(x, np.zeros(7), frames=(hand,)).frames[hand].rotation.copy()


def test_a_pose_is_followed_by_the_laws_axis_spring(setup: ScenarioSetup) -> None:
    # the law's gripper-down axis spring turns the tool axis to R_r a_b (its yaw free); the
    # posture spring, still toward x_n, leaves 13 mrad and 2 mm (a compromise)
    law, plant = _tracker(setup), _plant(setup)
    start = _hand_rotation(setup, plant.data.qpos)
    aim = _rotation_about_x(0.4) @ start
    goal = law.requested + np.array([0.0, 0.0, 0.03])
    law.set_pose(goal, aim)
    _run(law, plant, 3000)
    axis = _hand_rotation(setup, plant.data.qpos)[:, 2]
    assert np.arccos(min(1.0, float(axis @ aim[:, 2]))) < 0.02
    assert np.linalg.norm(_hand(setup, law, plant.data.qpos) - goal) < 0.005
    assert law.moving.rotation is not None
    np.testing.assert_allclose(law.moving.rotation, aim, atol=1e-12)


def test_a_pose_turns_no_faster_than_the_governor_allows(setup: ScenarioSetup) -> None:
    from cpbc.reference.rotations import angle_between

    law, plant = _tracker(setup, settings=GovernorSettings(max_angular_speed=0.5)), \
        _plant(setup)
    start = _hand_rotation(setup, plant.data.qpos)
    law.set_pose(law.requested, _rotation_about_x(2.5) @ start)
    assert law.moving.rotation is not None
    before = law.moving.rotation.copy()
    for _ in range(300):
        _run(law, plant, 1)
        # 0.5 rad/s × 1 ms, to the angle's own rounding (from a quaternion's square roots)
        assert angle_between(before, law.moving.rotation) <= 0.5e-3 + 1e-8
        before = law.moving.rotation.copy()
    assert angle_between(start, law.moving.rotation) > 0.0


@pytest.mark.parametrize(("rotation", "says"), [
    (np.eye(3) * 2.0, "not a rotation"),
    (np.diag([1.0, 1.0, -1.0]), "not a rotation"),  # a reflection
    ([1.0, 0.0, 0.0], "shape (3,)"),
    ([np.nan, 0.0, 0.0, 1.0], "finite"),
    ([2.0, 0.0, 0.0, 0.0], "norm 2"),
])
def test_a_bad_orientation_is_refused_and_the_previous_pose_stays(
        setup: ScenarioSetup, rotation: object, says: str) -> None:
    law = _tracker(setup)
    good = law.requested + np.array([0.0, 0.0, 0.02])
    law.set_pose(good, [1.0, 0.0, 0.0, 0.0])  # a unit quaternion: the world's axes
    with pytest.raises(ValueError, match=re.escape(says)) as err:
        law.set_pose(good + 0.1, rotation)  # type: ignore[arg-type]
    assert isinstance(err.value, ParameterError) and err.value.parameter == "rotation"
    np.testing.assert_array_equal(law.requested, good)
    np.testing.assert_array_equal(law.requested_rotation, np.eye(3))


def test_a_pose_for_a_law_without_an_orientation_spring_is_refused(
        tmp_path: Path) -> None:
    text = (SCENARIOS / "panda_goal_pose.yaml").read_text()
    text = text.replace("  orientation:\n    axis: {tool: [0, 0, 1], world: [0, 0, -1]}\n", "")
    text = text.replace(", rotation_omega_n: 24", "")
    path = tmp_path / "panda_goal_point.yaml"
    path.write_text(text)
    point = build(*load_scenario(path))
    law = _tracker(point)
    with pytest.raises(ValueError, match=r"^rotation: the law has no orientation or axis"):
        law.set_pose(law.requested, np.eye(3))
    assert law.moving.rotation is None and law.requested_rotation is None


def test_a_pose_stream_keeps_the_compiled_step(setup: ScenarioSetup) -> None:
    # the streamed orientation (and its feed-forward) are rows of the law's kernel tables,
    # read again before each step: the first pose does not send the law to its general path
    law, plant = _tracker(setup), _plant(setup)
    inner = law.law
    assert isinstance(inner, PacksItsLaw) and inner.packed_law().terms is not None
    start = _hand_rotation(setup, plant.data.qpos)
    law.set_pose(law.requested, _rotation_about_x(0.2) @ start, angular_velocity=[0.1, 0, 0])
    _run(law, plant, 50)
    packed = inner.packed_law()
    assert packed.terms is not None and packed.produce is not None
    assert law.moving.axes is not None and law.moving.rotation is not None
    np.testing.assert_allclose(law.moving.axes[1], law.moving.rotation @ [0.0, 0.0, 1.0])


def _turning_lag(setup: ScenarioSetup, feed_forward: bool) -> float:
    """A pose turning about the world x axis at 0.3 rad/s, streamed at 50 Hz with or without
    its angular velocity: the mean angle [rad] between the hand's axis and the streamed
    one's, from 1 to 3 s."""
    law, plant = _tracker(setup), _plant(setup)
    start, rate = _hand_rotation(setup, plant.data.qpos), 0.3
    lags = []
    for k in range(3000):
        if k % 20 == 0:
            law.set_pose(law.requested, _rotation_about_x(rate * k * 1e-3) @ start,
                         angular_velocity=[rate, 0.0, 0.0] if feed_forward else None)
        _run(law, plant, 1)
        aim = _rotation_about_x(rate * (k + 1) * 1e-3) @ start
        axis = _hand_rotation(setup, plant.data.qpos)[:, 2]
        lags.append(np.arccos(min(1.0, float(axis @ aim[:, 2]))))
    return float(np.mean(lags[1000:]))


def test_an_angular_feed_forward_cuts_the_lag_of_a_turning_pose(setup: ScenarioSetup) -> None:
    # 47 mrad behind without, 31 mrad with ω_r fed forward to the task damping
    without, with_ = _turning_lag(setup, False), _turning_lag(setup, True)
    assert with_ < 0.8 * without, (with_, without)


def test_a_bad_angular_velocity_is_refused_and_the_previous_pose_stays(
        setup: ScenarioSetup) -> None:
    law = _tracker(setup)
    good = law.requested + np.array([0.0, 0.0, 0.02])
    law.set_pose(good, np.eye(3), angular_velocity=[0.1, 0.0, 0.0])
    for bad in ([np.nan, 0.0, 0.0], [0.1, 0.2], "spin"):
        with pytest.raises(ValueError, match="angular_velocity") as err:
            law.set_pose(good + 0.1, _rotation_about_x(0.3), angular_velocity=bad)
        assert isinstance(err.value, ParameterError)
        assert err.value.parameter == "angular_velocity"
        np.testing.assert_array_equal(law.requested, good)
        np.testing.assert_array_equal(law.requested_rotation, np.eye(3))
        np.testing.assert_array_equal(law.requested_angular_velocity, [0.1, 0.0, 0.0])
