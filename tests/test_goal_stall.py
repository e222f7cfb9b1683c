"""Goal runs that end away from their goal (cpbc.results.task_metrics): a barrier that
holds the arm with margin to spare is named, not called a local minimum; an arm creeping
along a barrier the safeguard keeps reads ``stalled``, not ``not_settled``."""

from __future__ import annotations

from collections.abc import Callable

from cpbc.results.metrics import RunSummary
from cpbc.scenario import ScenarioSetup
from cpbc.scenario.runner import run_one


def _run(load_dict: Callable[[dict], ScenarioSetup], scenario: dict) -> RunSummary:
    setup = load_dict(scenario)
    return run_one(setup, setup.cases[0], setup.controllers[0], "mujoco").summary


def test_a_goal_under_the_ball_is_held_by_the_ball_s_clearance(load_dict, ur10_under_ball
                                                                ) -> None:
    # The law rests 126 mm and 1.1 rad off, its wrist 61 mm from the ball's clearance
    # (0.86 of its start margin). Its springs do not balance each other there (net
    # ∂U/∂x 42 against 46 in the parts): the barrier holds it. It read local_minimum.
    s = _run(load_dict, ur10_under_ball(20.0))
    assert s.status == "stalled", s.status
    kind = s.stall_kind or ""
    assert kind.startswith("barrier:clearance[") and kind.endswith("|ball]"), kind


def test_an_arm_creeping_along_a_kept_clearance_is_stalled(load_dict, ur10_under_ball) -> None:
    # The law enforces the ranges only; the safeguard keeps the ball's clearance. The wrist
    # rides it (7e-5 of its 0.039 start margin) in stick-slip — braked to rest, pushed on —
    # at up to 0.06 rad/s, the hand 245 mm off and not closing in. Judged against the
    # posture (2 % of joint progress) it read not_settled at 20 s, and at 40 s.
    s = _run(load_dict, ur10_under_ball(20.0, constraints=["ranges"]))
    assert s.status == "stalled", s.status
    assert s.stall_kind == "barrier:clearance[wrist_3_link|ball]", s.stall_kind


def test_a_kinova_goal_held_off_by_the_shaped_barrier_names_its_joint(
        load_dict, kinova_behind_base) -> None:
    # Kinova Jaco2 from the upright start to a goal behind the base, power shaping α = 0.2:
    # the law rests 110 mm off, where α U ∇ln φ of joint 3's range (0.24 rad from its stop,
    # 16 % of its start margin) gives 0.92 N·m against the task springs' 1.11. It read
    # local_minimum.
    scenario = kinova_behind_base(6.0, shaping={"type": "power", "alpha": 0.2})
    s = _run(load_dict, scenario)
    assert s.status == "stalled", s.status
    assert s.stall_kind == "barrier:position[j2s6s200_joint_3]", s.stall_kind
    assert s.task_error_final is not None and s.task_error_final["position"] > 0.1
