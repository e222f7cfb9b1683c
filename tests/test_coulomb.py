"""The joints' Coulomb friction (cpbc.model.coulomb): the levels as checked, and how the
plant's dry friction takes its sign (DryFriction) — its rule against MuJoCo's own
``frictionloss`` on the UR5 of the rate campaign, and the force error it bounds."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from cpbc.errors import ModelError
from cpbc.model.coulomb import MUJOCO_FRICTION, DryFriction, coulomb_levels
from cpbc.scenario import build, load_scenario

UR5_RATE = Path(__file__).resolve().parents[1] / "tools" / "campaigns" / "ur5_bpbc_rate.yaml"
LEVELS = np.array([2.0, 0.5])
EPS = 0.05


def test_levels_are_one_per_joint_finite_and_not_negative() -> None:
    np.testing.assert_array_equal(coulomb_levels(np.array(0.5), 3), [0.5, 0.5, 0.5])
    with pytest.raises(ModelError, match="coulomb_friction"):
        coulomb_levels(np.array([1.0, -1.0]), 2)


def test_a_sliding_joint_errs_by_the_smooth_models_shortfall_only() -> None:
    """Fast and decelerating gently: the plant's friction is F sign(q̇), the smooth one
    F tanh(|q̇|/ε): they differ by F (1 − tanh(s/ε)) at the least speed s."""
    low = np.array([0.3, 0.4])
    e = MUJOCO_FRICTION.force_error(LEVELS, EPS, low, low + 0.1, np.array([1.0, 2.0]))
    np.testing.assert_allclose(e, LEVELS * (1.0 - np.tanh(low / EPS)))
    assert np.all(e < 0.01 * LEVELS)


def test_a_joint_braked_to_rest_within_the_build_up_may_be_pulled_along_its_motion() -> None:
    """0.3 rad/s decelerating at 100 rad/s²: it would rest within MuJoCo's 9.5 ms, so its
    friction may already oppose the deceleration: up to F (1 + tanh(S/ε)), near 2F."""
    speed = np.array([0.3, 0.3])
    e = MUJOCO_FRICTION.force_error(LEVELS, EPS, speed, speed, np.array([100.0, 100.0]))
    np.testing.assert_allclose(e, LEVELS * (1.0 + np.tanh(speed / EPS)))
    # an ideal Coulomb friction opposes any nonzero rate whatever the deceleration
    ideal = DryFriction(build_up=0.0, creep=0.0)
    e = ideal.force_error(LEVELS, EPS, speed, speed, np.array([100.0, 100.0]))
    assert np.all(e < 0.01 * LEVELS)
    # at rest it may be anything in [−F, F] against the smooth model's 0
    rest = np.zeros(2)
    np.testing.assert_allclose(ideal.force_error(LEVELS, EPS, rest, rest, rest), LEVELS)


def _plant_samples(count: int, seed: int):
    """The UR5 campaign plant's friction force at random states and torques (MuJoCo's
    qfrc_constraint: only the frictionloss rows act, no contact, no joint stop), with the
    acceleration it ends with and (D⁻¹)_jj."""
    setup = build(*load_scenario(str(UR5_RATE)))
    plant = setup.make_plant().model
    data = mujoco.MjData(plant)
    rng = np.random.default_rng(seed)
    q0 = np.array([-1.0, -1.9, 1.9, -1.6, -1.57, 0.0])
    for _ in range(count):
        data.qpos[:] = q0 + rng.uniform(-0.3, 0.3, 6)
        data.qvel[:] = rng.choice([-1.0, 1.0], 6) * rng.uniform(0.0, 0.5, 6)
        data.qfrc_applied[:] = rng.uniform(-20.0, 20.0, 6)
        mujoco.mj_forward(plant, data)
        if data.ncon:
            continue
        yield plant, data.qvel.copy(), data.qacc.copy(), -data.qfrc_constraint.copy()


def test_mujocos_frictionloss_is_f_sign_of_the_rate_wherever_the_rule_says_it_slides() -> None:
    """MuJoCo's friction: exactly F_j sign(q̇_j) wherever the joint slides by the rule
    |q̇_j| ≥ T_f α_j + v_c (α_j its deceleration in the step); and where a joint decelerates
    harder than its rate over T_f, the friction pulls with the motion at times, farther
    from the smooth model than F: the second branch is needed."""
    slid, along = 0, 0
    for plant, dq, ddq, force in _plant_samples(400, 36):
        levels = plant.dof_frictionloss
        alpha = np.maximum(-np.sign(dq) * ddq, 0.0)
        slides = np.abs(dq) >= MUJOCO_FRICTION.build_up * alpha + MUJOCO_FRICTION.creep
        np.testing.assert_allclose(force[slides], (levels * np.sign(dq))[slides], atol=1e-6)
        slid += int(slides.sum())
        smooth = levels * np.tanh(dq / EPS)
        beyond = np.abs(force - smooth) > levels * (1.0 + 1e-6)
        assert not np.any(beyond & slides)
        assert np.all(np.abs(force - smooth)
                      <= MUJOCO_FRICTION.force_error(levels, EPS, np.abs(dq), np.abs(dq), alpha)
                      + 1e-9)
        along += int(beyond.sum())
    assert slid > 500 and along > 0
    assert math.isclose(MUJOCO_FRICTION.build_up, 0.0095)
