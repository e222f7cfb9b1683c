"""Which constraint holds an arm off a target (cpbc.reference.holding): the one whose
log-barrier falls fastest along the pull, when it falls at STEEP or faster; on the Panda's
real constraint set (joint ranges, the ball's and the table's localised clearance)."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.constraints import ConstraintSet
from cpbc.reference.holding import STEEP, UNREACHABLE, holding_constraint
from cpbc.scenario import ScenarioSetup, build, load_scenario


@pytest.fixture(scope="module")
def setup() -> ScenarioSetup:
    return build(*load_scenario("panda_goal_pose"))


def _config(setup: ScenarioSetup) -> ConstraintSet:
    law = setup.controllers[1].controller
    return ConstraintSet(law.model.n, law.constraints.configuration)


def test_a_pull_into_a_joint_limit_names_it_and_a_pull_away_does_not(
        setup: ScenarioSetup) -> None:
    x = setup.goal.posture.copy()  # type: ignore[union-attr]
    x[6] = 2.85  # 0.047 rad inside joint 7's upper limit
    pull = np.zeros(7)
    pull[6] = 1.0
    assert holding_constraint(_config(setup), x, pull) == "position[panda_joint7]"
    assert holding_constraint(_config(setup), x, -pull) == UNREACHABLE
    assert holding_constraint(_config(setup), x, np.zeros(7)) == UNREACHABLE


def test_a_limit_far_along_the_pull_is_slack(setup: ScenarioSetup) -> None:
    # 1.5 rad from the limit, ln φ falls at 1/1.5 per radian: slower than STEEP
    x = setup.goal.posture.copy()  # type: ignore[union-attr]
    x[6] = 2.8973 - 1.5
    pull = np.zeros(7)
    pull[6] = 1.0
    assert 1.0 / 1.5 < STEEP
    assert holding_constraint(_config(setup), x, pull) == UNREACHABLE


def test_a_clearance_beyond_its_influence_is_slack(setup: ScenarioSetup) -> None:
    # the hand pulled toward the ball from where every pair is beyond the 0.1 m influence:
    # the clearance's barrier is flat there; close to the ball, it holds
    config = _config(setup)
    x = setup.goal.posture.copy()  # type: ignore[union-attr]
    names = config.names
    far = config.configuration_margins(x)
    ball_pairs = [i for i, n in enumerate(names) if n.endswith("|ball]")]
    assert min(far[i] for i in ball_pairs) > 0.1
    model = setup.model
    hand = model.frame_id("panda_hand")
    kin = model.state(x, np.zeros(7), frames=(hand,)).frames[hand]
    ball = np.array([0.5, 0.0, 0.3])
    pull = kin.linear.T @ (ball - kin.position)  # the hand toward the ball's centre
    assert not holding_constraint(config, x, pull).endswith("|ball]")
    near = x.copy()
    for _ in range(200):  # walk the hand toward the ball until a pair is within 2 cm
        kin = model.state(near, np.zeros(7), frames=(hand,)).frames[hand]
        near = near + 0.01 * kin.linear.T @ (ball - kin.position)
        if min(config.configuration_margins(near)[i] for i in ball_pairs) < 0.02:
            break
    assert 0.0 < min(config.configuration_margins(near)[i] for i in ball_pairs) < 0.02
    kin = model.state(near, np.zeros(7), frames=(hand,)).frames[hand]
    pull = kin.linear.T @ (ball - kin.position)
    assert holding_constraint(config, near, pull).endswith("|ball]")
