"""The reliability campaigns' building blocks: states the arm can really be in, pushed to the
boundaries its law enforces, and what the recording plant counts."""

from __future__ import annotations

from functools import cache

import mujoco
import numpy as np

from cpbc.reliability.campaign import (
    RecordingPlant,
    campaign_setup,
    constrained,
    physically_possible,
    state_sampler,
)
from cpbc.scenario.build import ScenarioSetup


@cache
def _ur5() -> ScenarioSetup:
    return campaign_setup("ur5_bpbc")


def test_ur5_states_are_inside_the_joint_ranges_and_touch_nothing() -> None:
    setup = _ur5()
    model = setup.make_plant().model
    data = mujoco.MjData(model)
    law = constrained(setup)[0].controller
    sampler = state_sampler(setup, seed=3)
    assert sampler.constraints is law.constraints  # pushed towards the rate bounds, only
    for s in sampler.draw_many(25):
        lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
        assert np.all(s.position > lo) and np.all(s.position < hi)
        data.qpos[:] = s.position
        mujoco.mj_forward(model, data)
        assert data.ncon == 0
        assert np.all(setup.monitor.margins(s.position, s.velocity) > 0)
        assert np.all(law.constraints.margins(s.position, s.velocity) > 0)


def test_physically_possible_refuses_a_joint_beyond_its_range_and_a_collision() -> None:
    setup = _ur5()
    possible = physically_possible(setup)
    home = np.array(setup.target, dtype=float)
    assert possible(home)
    beyond = home.copy()
    beyond[2] = 3.5  # the elbow's range is ±π
    assert not possible(beyond)
    floor = home.copy()
    floor[1] = 0.9  # shoulder lifted down through the floor
    assert not possible(floor)


def test_recording_plant_counts_joint_stops() -> None:
    setup = _ur5()
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    q = np.array(setup.target, dtype=float)
    q[2] = np.pi - 1e-3
    dq = np.zeros(6)
    dq[2] = 2.0  # into the elbow's stop
    plant.reset(q, dq)
    plant.step(20)
    assert plant.joint_stops > 0
    assert len(plant.rows) == 21
    plant.reset(np.array(setup.target, dtype=float), np.zeros(6))
    assert plant.joint_stops == 0
