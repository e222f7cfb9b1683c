"""References (cpbc.reference): paths and their tangents, the CSV reader's refusals, the
moving target leaving a law unchanged while it holds still, the governor's block / rejoin,
and its per-step cost."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cpbc.controllers import CPBC, PDGravity, Power, TaskDamping
from cpbc.controllers.potentials import FrameAxisSpring, FramePositionSpring, JointSpring, total
from cpbc.errors import ParameterError
from cpbc.model import RobotModel
from cpbc.model.loading import load_arm
from cpbc.reference.csv_path import read_csv_path
from cpbc.reference.governor import GovernorSettings, PathGovernor
from cpbc.reference.paths import Circle, Lissajous, Waypoints
from cpbc.reference.paths import Path as RefPath
from cpbc.reference.target import MovingTarget, steer

HOME = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
GOAL = np.array([0.45, 0.35, 0.35])


def _tangent_matches(path: RefPath) -> None:
    s = np.linspace(0.013, path.duration - 0.013, 57)
    h = 1e-6
    p_hi, _ = path.sample(s + h)
    p_lo, _ = path.sample(s - h)
    _, dp = path.sample(s)
    assert np.allclose((p_hi - p_lo) / (2 * h), dp, atol=1e-5)


@pytest.mark.parametrize("interpolation", ["linear", "cubic", "min_jerk"])
def test_waypoints_pass_their_points_with_their_tangent(interpolation: str) -> None:
    pts = np.array([[0.4, 0.0, 0.4], [0.4, 0.1, 0.3], [0.3, 0.3, 0.35]])
    path = Waypoints(np.array([0.0, 1.0, 2.5]), pts, interpolation)
    assert np.allclose(path.sample(np.array([0.0, 1.0, 2.5]))[0], pts)
    _tangent_matches(path)
    if interpolation != "linear":  # at rest at both ends
        assert np.allclose(path.sample(np.array([0.0, 2.5]))[1], 0.0)


def test_circle_and_lissajous_speed_and_tangent() -> None:
    circle = Circle(np.array([0.3, 0.1, 0.4]), 0.15, np.array([0, 0, 1.0]), 0.25, laps=2)
    assert circle.duration == pytest.approx(2 * 2 * np.pi * 0.15 / 0.25)
    _, dp = circle.sample(np.linspace(0, circle.duration, 9)[1:-1])
    assert np.allclose(np.linalg.norm(dp, axis=1), 0.25)
    _tangent_matches(circle)
    eight = Lissajous(np.array([0.4, 0, 0.4]), np.array([0.1, 0.1, 0]), np.array([1, 2, 0.0]), 4.0)
    _tangent_matches(eight)
    assert np.allclose(circle.sample(np.array([99.0]))[1], 0.0)  # held after the end


@pytest.mark.parametrize("text, says", [
    ("a,b,c,d\n0,0,0,0\n1,0,0,0\n", "header"),
    ("t,x,y,z\n0,0,0,0\n", "at least 2"),
    ("t,x,y,z\n0,0,0,0\n0,1,0,0\n", "increase strictly"),
    ("t,x,y,z\n0,0,0,0\n1,0,zero,0\n", "line 3"),
    ("t,x,y,z\n0,0,0\n", "columns"),
    ("t,x,y,z\n0,0,0,0\n1,nan,0,0\n", "non-finite"),
])
def test_csv_refusals_name_the_field(tmp_path: Path, text: str, says: str) -> None:
    f = tmp_path / "ref.csv"
    f.write_text(text)
    with pytest.raises(ParameterError, match=says) as info:
        read_csv_path(f)
    assert info.value.parameter == "reference.path.csv"
    with pytest.raises(ParameterError, match="cannot be read"):
        read_csv_path(tmp_path / "missing.csv")


def test_csv_reads_a_polyline(tmp_path: Path) -> None:
    f = tmp_path / "ref.csv"
    f.write_text("t,x,y,z\n0,0.4,0,0.4\n1,0.4,0.2,0.4\n")
    path = read_csv_path(f)
    assert path.duration == 1.0
    assert np.allclose(path.sample(np.array([0.5]))[0], [[0.4, 0.1, 0.4]])


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    return RobotModel(load_arm("panda").model, name="panda")


@pytest.mark.parametrize("kind", ["pd_gravity", "cpbc"])
def test_a_still_target_leaves_the_law_unchanged(panda: RobotModel, kind: str) -> None:
    """Steered to a MovingTarget at the law's own goal, posture and zero feed-forward, the law
    gives the same τ and V as built (so its V̇ identity is the fixed-goal one)."""
    fid = panda.frame_id("panda_hand")

    def law() -> PDGravity | CPBC:
        task = total(FramePositionSpring(fid, GOAL, 200.0),
                     FrameAxisSpring.named(panda, "panda_hand", [0, 0, 1], [0, 0, -1], 2.0),
                     JointSpring(HOME, 2.0))
        damp = TaskDamping(fid, 20.0)
        if kind == "pd_gravity":
            return PDGravity(panda, HOME, 20.0, 1.0, potential=task, task_damping=damp)
        from cpbc.constraints import ConstraintSet, joint_rate_limit

        rates = joint_rate_limit(np.full(7, 2.0), list(panda.joint_names))
        return CPBC(panda, HOME, ConstraintSet(7, [], [rates]), 20.0, 1.0, Power(0.2),
                    potential=task, task_damping=damp)

    fixed, moving = law(), law()
    target = MovingTarget(GOAL, HOME)
    steer(moving, target)
    rng = np.random.default_rng(1)
    for _ in range(5):
        x, dx = HOME + 0.2 * rng.standard_normal(7), 0.3 * rng.standard_normal(7)
        assert np.allclose(fixed.evaluate(x, dx)[0], moving.evaluate(x, dx)[0])
        assert fixed.evaluate(x, dx)[1] == pytest.approx(moving.evaluate(x, dx)[1])
    target.set(GOAL + 0.05, np.array([0.1, 0.0, 0.0]))
    assert not np.allclose(fixed.torque(HOME, np.zeros(7)), moving.torque(HOME, np.zeros(7)))


def _run(gov: PathGovernor, steps: int, vbar: float = 0.0) -> list[float]:
    return [gov.advance(k * gov.h, vbar, 0.25) for k in range(steps)]


def test_the_governor_blocks_within_one_period_and_names_the_constraint() -> None:
    h = 0.001
    gov = PathGovernor(GovernorSettings(), 3.0, h, ((0.4105, 1.7, "pan_limit"),))
    s = _run(gov, 2000)
    assert gov.blocks and gov.blocks[0].constraint == "pan_limit"
    assert abs(gov.blocks[0].time - 0.4105) <= h
    assert max(s) < 0.4105 and s[-1] == max(s)  # stop: never onto the stretch


def test_rejoin_waits_out_the_stretch_then_catches_up() -> None:
    h = 0.001
    settings = GovernorSettings(on_infeasible="rejoin", catch_up=1.5)
    gov = PathGovernor(settings, 3.0, h, ((0.4, 1.0, "pan_limit"),), (0.1,))
    s = _run(gov, 3100)
    assert gov.blocks[0].constraint == "pan_limit" and gov.s == pytest.approx(3.0)
    assert not any(0.4 <= v < 1.0 for v in s)
    assert gov.steps_blocked * h == pytest.approx(0.6, abs=0.01)


def test_the_budget_slows_and_stops_the_reference() -> None:
    gov = PathGovernor(GovernorSettings(budget=1.0, gain=20.0), 3.0, 0.001, ())
    assert _run(gov, 100, vbar=1.0)[-1] == 0.0  # at the budget: no progress
    gov = PathGovernor(GovernorSettings(budget=1.0, gain=20.0), 3.0, 0.001, ())
    s = _run(gov, 1000, vbar=0.98)  # ṡ = 20·0.02 = 0.4
    assert s[-1] == pytest.approx(0.4, rel=0.01) and gov.steps_slowed == 1000


def test_a_rejoin_blend_is_checked_admissible(panda: RobotModel) -> None:
    from cpbc.constraints import ConstraintSet, joint_position_limit
    from cpbc.reference.plan import blend_admissible

    names = list(panda.joint_names)
    limits = joint_position_limit(np.full(7, -2.8), np.full(7, 2.8), names)
    config = ConstraintSet(7, [limits])
    a, b = HOME.copy(), HOME.copy()
    b[0] = 1.0
    assert blend_admissible(config, a, b, 0.01)  # a box is convex: the blend stays inside
    b[0] = 2.799  # the end itself closer than δ to the bound (φ = (x − l)(u − x))
    assert not blend_admissible(config, a, b, 0.05)


def _general(law):  # type: ignore[no-untyped-def]
    """The same law (its terms, the same target) as a subclass whose ``_law`` only calls
    the base class's: the same formulas, taken method by method (the general path)."""

    class General(type(law)):  # type: ignore[misc]
        def _law(self, *args, **kwargs):  # type: ignore[no-untyped-def]
            return super()._law(*args, **kwargs)

    general = General.__new__(General)
    general.__dict__.update(law.__dict__)
    general._packed_law = None
    assert general.packed_law().terms is None
    return general


def test_a_steered_law_packs_and_reads_the_moving_target(panda: RobotModel) -> None:
    """A law steered to a MovingTarget keeps its one kernel call: its goal, feed-forward,
    posture and posture feed-forward are packed rows refreshed from the target before each
    step (Packed.live). As the target moves, τ and V equal the law's general path (method by
    method) to 1e-12, and change with each of the four."""
    fid = panda.frame_id("panda_hand")
    from cpbc.constraints import ConstraintSet, joint_rate_limit

    rates = joint_rate_limit(np.full(7, 2.0), list(panda.joint_names))
    task = total(FramePositionSpring(fid, GOAL, 200.0),
                 FrameAxisSpring.named(panda, "panda_hand", [0, 0, 1], [0, 0, -1], 2.0),
                 JointSpring(HOME, 2.0))
    law = CPBC(panda, HOME, ConstraintSet(7, [], [rates]), 20.0, 1.0, Power(0.2),
               potential=task, task_damping=TaskDamping(fid, 20.0))
    target = MovingTarget(GOAL, HOME)
    steer(law, target)
    assert law.packed_law().terms is not None and len(law.packed_law().live) == 4

    general = _general(law)
    rng = np.random.default_rng(4)
    x, dx = HOME + 0.1 * rng.standard_normal(7), 0.3 * rng.standard_normal(7)
    seen = [law.evaluate(x, dx)[0]]
    moves = [dict(position=GOAL + 0.03), dict(position=GOAL, velocity=np.array([0.1, 0, 0])),
             dict(position=GOAL, posture=HOME + 0.1),
             dict(position=GOAL, posture=HOME, posture_velocity=np.full(7, 0.2))]
    for move in moves:
        target.set(**move)
        tau, value = law.evaluate(x, dx)
        slow = general.evaluate_state(general.state(x, dx))
        np.testing.assert_allclose(tau, slow.torque, rtol=1e-12, atol=1e-12)
        assert value == pytest.approx(slow.lyapunov, rel=1e-12)
        np.testing.assert_allclose(law.evaluate_state(law.state(x, dx)).torque, tau,
                                   rtol=1e-12, atol=1e-12)
        assert not np.allclose(tau, seen[-1], rtol=1e-9, atol=1e-9), move
        seen.append(tau)


@pytest.mark.parametrize("orientation", ["axis", "rotation"])
def test_a_steered_orientation_packs_and_reads_the_moving_target(panda: RobotModel,
                                                                 orientation: str) -> None:
    """A law whose axis (or orientation) spring is steered to a streamed orientation keeps
    its one kernel call: R_d (or [a_b; R_d a_b]) and the angular feed-forward ω_ff are packed
    rows refreshed from the target before each step. As the target turns and ω_ff changes,
    τ and V equal the general path's to 1e-12, and change with each."""
    from cpbc.constraints import ConstraintSet
    from cpbc.controllers.potentials import FrameOrientationSpring

    fid = panda.frame_id("panda_hand")
    down = np.diag([1.0, -1.0, -1.0])
    spring = (FrameAxisSpring.named(panda, "panda_hand", [0, 0, 1], [0, 0, -1], 2.0)
              if orientation == "axis" else FrameOrientationSpring(fid, down, 2.0, 1.0))
    task = total(FramePositionSpring(fid, GOAL, 200.0), spring, JointSpring(HOME, 2.0))
    law = CPBC(panda, HOME, ConstraintSet(7), 20.0, 1.0, Power(0.2), potential=task,
               task_damping=TaskDamping(fid, 20.0, angular=5.0))
    target = MovingTarget(GOAL, HOME)
    target.orient(down, np.array([0.0, 0.0, 1.0]) if orientation == "axis" else None)
    steer(law, target)
    assert law.packed_law().terms is not None

    general = _general(law)
    rng = np.random.default_rng(5)
    x, dx = HOME + 0.1 * rng.standard_normal(7), 0.3 * rng.standard_normal(7)
    seen = [law.evaluate(x, dx)[0]]
    c, s = np.cos(0.3), np.sin(0.3)
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    for turn, spin in ((tilt @ down, None), (tilt @ down, np.array([0.2, -0.1, 0.3]))):
        target.turn(turn)
        target.set(GOAL, angular_velocity=spin)
        tau, value = law.evaluate(x, dx)
        slow = general.evaluate_state(general.state(x, dx))
        np.testing.assert_allclose(tau, slow.torque, rtol=1e-12, atol=1e-12)
        assert value == pytest.approx(slow.lyapunov, rel=1e-12)
        assert not np.allclose(tau, seen[-1], rtol=1e-9, atol=1e-9), (turn, spin)
        seen.append(tau)


@pytest.mark.parametrize("name", ["bpbc", "bpbc_ke"])
def test_a_steered_bounded_law_packs_and_reads_the_moving_target(name: str) -> None:
    """The bounded-torque laws' task terms (ln cosh position spring, ln cosh posture spring,
    tanh task damping), steered: packed, and equal to their general path as the target's
    position, feed-forward and posture move."""
    from bounded_goal import bounded_goal_laws

    laws, states = bounded_goal_laws(3)
    law = laws[name]
    posture = np.array(law.target, dtype=float)
    goal = law.potential.parts[0].goal.copy()  # type: ignore[attr-defined]
    target = MovingTarget(goal, posture)
    steer(law, target)
    assert law.packed_law().terms is not None and len(law.packed_law().live) == 3

    general = _general(law)
    for move in (dict(position=goal + 0.02), dict(position=goal, velocity=np.full(3, 0.05)),
                 dict(position=goal, posture=posture + 0.05)):
        target.set(**move)
        for x, dx in states:
            tau, value = law.evaluate(x, dx)
            slow = general.evaluate_state(general.state(x, dx))
            np.testing.assert_allclose(tau, slow.torque, rtol=1e-12, atol=1e-12)
            assert value == pytest.approx(slow.lyapunov, rel=1e-12)
