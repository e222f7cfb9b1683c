"""The reliability campaigns' building blocks: states the arm can really be in, pushed to the
boundaries its law enforces, and what the recording plant counts."""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import mujoco
import numpy as np

from cpbc.constraints import ConstraintSet, LinearLimit
from cpbc.reliability.campaign import (
    RecordingPlant,
    campaign_setup,
    checked_run,
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


def test_recording_plant_notes_the_first_joint_stop() -> None:
    setup = _ur5()
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    q = np.array(setup.target, dtype=float)
    q[2] = np.pi - 1e-3
    dq = np.zeros(6)
    dq[2] = 2.0  # into the elbow's stop
    plant.reset(q, dq)
    plant.step(20)
    assert plant.first_touch is not None and 0 <= plant.first_touch < 20
    assert plant.touched == "joint stop elbow_joint"
    assert len(plant.rows) == 21
    plant.reset(np.array(setup.target, dtype=float), np.zeros(6))
    assert plant.first_touch is None and plant.touched is None


def test_recording_plant_names_the_obstacle_it_touched() -> None:
    setup = _ur5()
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    q = np.array(setup.target, dtype=float)
    q[1] = -0.8  # clear of the floor, swinging down at it
    assert physically_possible(setup)(q)
    dq = np.zeros(6)
    dq[1] = 3.0
    plant.reset(q, dq)
    plant.step(400)
    assert plant.first_touch is not None and plant.first_touch > 0
    assert plant.touched == "floor"


def _first_law(setup: ScenarioSetup, constrained_law: bool):
    return next(e for e in setup.controllers
                if (not e.controller.constraints.empty) == constrained_law)


def test_a_joint_stop_met_before_any_violation_is_a_touch() -> None:
    """The UR5's BPBC bounds rates only; driven into the elbow's stop, whatever breaks
    after is the stop's doing, not the law's sampling."""
    setup = _ur5()
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    q = np.array(setup.target, dtype=float)
    q[2] = np.pi - 2e-3
    dq = np.zeros(6)
    dq[2] = 0.9  # inside the 0.945 rad/s bound, heading into the stop
    settings = replace(setup.loop_settings, duration=0.05)
    check = checked_run(plant, setup, _first_law(setup, True), q, dq, settings)
    assert plant.first_touch is not None
    assert check.touched and check.touch == "joint stop elbow_joint"


def test_a_stop_met_only_after_the_limit_is_crossed_is_not_a_touch() -> None:
    """The Panda's position limits are its URDF ranges: a run that crosses one meets the stop
    only at or after the crossing, and that counts as the violation it is."""
    setup = campaign_setup("panda_cpbc_sphere")
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    limits = ConstraintSet(7, [c for c in setup.monitor.configuration
                               if isinstance(c, LinearLimit)])
    model = plant.model
    q = np.array(setup.target, dtype=float)
    q[3] = model.jnt_range[3, 1] - 1e-4
    dq = np.zeros(7)
    dq[3] = 1.0
    settings = replace(setup.loop_settings, duration=0.02)
    check = checked_run(plant, setup, _first_law(setup, False), q, dq, settings, limits)
    assert check.violated and check.constraint == "position[panda_joint4]"
    assert plant.first_touch is not None and not check.touched and check.touch is None
