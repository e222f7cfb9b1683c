"""The MuJoCo closed loop and the continuous-time reference backend."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.constraints import ConstraintSet, joint_rate_limit
from cpbc.controllers import BPBC, PD, Controller, Power
from cpbc.controllers.controller import Evaluation
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model import ArmState, LinearCoordinates, RobotModel
from cpbc.model.input_bounds import InputBounds
from cpbc.resources import models_dir
from cpbc.simulation import (
    LoopSettings,
    MujocoPlant,
    PlantSettings,
    run_mujoco,
    run_reference,
    substeps_per_control,
)

PATH = models_dir() / "planar_2link.xml"
ABSOLUTE = LinearCoordinates.absolute_link_angles(2)


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return RobotModel.from_mjcf(PATH, coordinates=ABSOLUTE)


@pytest.fixture(scope="module")
def bpbc(model: RobotModel) -> BPBC:
    rates = ConstraintSet(2, velocity=[joint_rate_limit([0.3, 0.2], ["t1", "t2"])])
    return BPBC(model, np.array([np.pi, np.pi]), rates, [2, 10], [4, 20], 1, 1, Power(0.2))


def plant(integrator: str = "RK4", timestep: float = 0.001) -> MujocoPlant:
    return MujocoPlant.from_file(PATH, PlantSettings(timestep, integrator))


def test_mujoco_and_reference_agree(model: RobotModel, bpbc: BPBC) -> None:
    settings = LoopSettings(3.0, InputBounds(0.001))
    x0, dx0 = np.zeros(2), np.array([-0.2, -0.1])
    mj = run_mujoco(plant(), bpbc, ABSOLUTE, x0, dx0, settings)
    ref = run_reference(RobotModel.from_mjcf(PATH, coordinates=ABSOLUTE), bpbc, x0, dx0,
                        settings)
    assert mj.outcome == ref.outcome == "completed"
    assert mj.time.shape == ref.time.shape
    # 1 kHz zero-order hold against continuous control: close, not identical.
    np.testing.assert_allclose(mj.position, ref.position, atol=2e-4)
    np.testing.assert_allclose(mj.velocity, ref.velocity, atol=2e-4)
    assert np.max(np.abs(mj.position - ref.position)) > 0  # two different integrations


def test_lyapunov_is_logged_and_does_not_increase(bpbc: BPBC) -> None:
    traj = run_mujoco(plant(), bpbc, ABSOLUTE, np.zeros(2), np.zeros(2),
                      LoopSettings(2.0, InputBounds(0.001)))
    assert traj.lyapunov.shape == traj.time.shape
    np.testing.assert_allclose(traj.lyapunov[0], bpbc.lyapunov(np.zeros(2), np.zeros(2)))
    assert np.max(np.diff(traj.lyapunov)) <= 1e-9 * traj.lyapunov[0]


def test_joint_torque_is_transpose_map_of_controller_torque(bpbc: BPBC) -> None:
    traj = run_mujoco(plant(), bpbc, ABSOLUTE, np.zeros(2), np.zeros(2),
                      LoopSettings(0.2, InputBounds(0.001)))
    np.testing.assert_allclose(traj.joint_torque, traj.torque @ ABSOLUTE.matrix)


def test_torque_limit_saturates_and_is_counted(model: RobotModel) -> None:
    pd = PD(model, np.array([np.pi, np.pi]), [2, 10], [4, 20])
    limit = np.array([5.0, 5.0])
    traj = run_mujoco(plant(), pd, ABSOLUTE, np.zeros(2), np.zeros(2),
                      LoopSettings(1.0, InputBounds(0.001, limit)))
    assert traj.saturated_steps > 0
    assert np.max(np.abs(traj.joint_torque)) <= 5.0 + 1e-12
    assert np.max(np.abs(traj.torque @ ABSOLUTE.matrix)) > 5.0  # what was asked for


def test_control_period_must_be_whole_multiple_of_timestep() -> None:
    assert substeps_per_control(0.004, 0.001) == 4
    with pytest.raises(CpbcError, match="whole multiple"):
        substeps_per_control(0.0025, 0.001)


def test_zero_order_hold_holds_torque_between_control_instants(model: RobotModel) -> None:
    pd = PD(model, np.array([1.0, 1.0]), 5, 1)
    traj = run_mujoco(plant("Euler"), pd, ABSOLUTE, np.zeros(2), np.zeros(2),
                      LoopSettings(0.1, InputBounds(0.01)))
    assert len(traj.time) == 11
    assert traj.control_steps == 11


class Exploding(Controller):
    type_name = "exploding"

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        return Evaluation(np.full(2, np.nan) if state.x[0] > 0.05 else np.array([50.0, 0.0]),
                          0.0)


class Refusing(Controller):
    type_name = "refusing"

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        if state.x[0] > 0.05:
            raise ConstraintViolation("wall", 0.05 - float(state.x[0]))
        return Evaluation(np.array([50.0, 0.0]), 0.0)


def test_nan_torque_ends_run_as_diverged(model: RobotModel) -> None:
    traj = run_mujoco(plant(), Exploding(model, np.zeros(2)), ABSOLUTE, np.zeros(2),
                      np.zeros(2), LoopSettings(2.0, InputBounds(0.001)))
    assert traj.outcome == "diverged"
    assert 0 < traj.end_time < 2.0
    assert np.all(np.isfinite(traj.position))


def test_constraint_crossing_ends_run_with_time_and_name(model: RobotModel) -> None:
    traj = run_mujoco(plant(), Refusing(model, np.zeros(2)), ABSOLUTE, np.zeros(2),
                      np.zeros(2), LoopSettings(2.0, InputBounds(0.001)))
    assert traj.outcome == "constraint_violated"
    assert traj.violated == "wall"
    assert 0 < traj.end_time < 2.0
    assert traj.position[-1, 0] > 0.05


def test_log_decimation_keeps_every_kth_sample_and_the_last(bpbc: BPBC) -> None:
    traj = run_mujoco(plant(), bpbc, ABSOLUTE, np.zeros(2), np.zeros(2),
                      LoopSettings(1.0, InputBounds(0.001), log_every=10))
    assert traj.control_steps == 1001
    assert len(traj.time) == 101
    assert traj.time[-1] == pytest.approx(1.0)


def test_plant_rejects_unknown_integrator() -> None:
    with pytest.raises(CpbcError, match="integrator"):
        PlantSettings(0.001, "Verlet")


class Violent(Controller):
    """Finite but absurd torque: MuJoCo's state blows up and MuJoCo resets it."""

    type_name = "violent"

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        return Evaluation(np.array([1e12, -1e12]), 0.0)


def test_mujoco_reset_after_blow_up_is_reported_as_divergence(
    model: RobotModel, tmp_path, monkeypatch
) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT into the working directory
    traj = run_mujoco(plant(), Violent(model, np.zeros(2)), ABSOLUTE, np.zeros(2), np.zeros(2),
                      LoopSettings(1.0, InputBounds(0.001)))
    assert traj.outcome == "diverged"
    assert traj.end_time < 0.01


def test_plant_reports_instability_until_reset() -> None:
    p = plant("Euler")
    p.reset(np.zeros(2), np.zeros(2))
    p.step(3)
    assert not p.unstable()
    p.apply(np.array([1e12, 0.0]))  # MuJoCo refuses a control this large (bad ctrl)
    p.step(1)
    assert p.unstable()
    p.reset(np.zeros(2), np.zeros(2))
    assert not p.unstable()
    p.data.qvel[:] = [np.nan, 0.0]  # and resets a NaN state (bad qvel)
    p.step(1)
    assert p.unstable()


class _Watched(Controller):
    """A law defined only inside its constraints' set, naming (as the constrained laws do)
    the worst margin, and the first constraint at a state that is not finite."""

    def __init__(self, law: Controller, constraints: ConstraintSet) -> None:
        self.law, self.constraints, self.model = law, constraints, law.model

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        m = self.constraints.margins(state.x, state.dx)
        if not np.all(m > 0):
            i = int(np.argmin(np.nan_to_num(m, nan=-np.inf)))
            raise ConstraintViolation(self.constraints.names[i], float(m[i]))
        return self.law.evaluate_state(state, margins)


def test_reference_names_the_constraint_the_trajectory_crossed(model: RobotModel) -> None:
    rates = ConstraintSet(2, velocity=[joint_rate_limit([50.0, 0.3], ["first", "second"])])
    law = _Watched(PD(model, np.array([1.0, 1.5]), [4, 4], [2, 2]), rates)
    traj = run_reference(model, law, np.zeros(2), np.zeros(2), LoopSettings(2.0, InputBounds(0.01)))
    assert traj.outcome == "constraint_violated"
    assert traj.violated == "rate[second]"  # a rejected stage, from NaN, named the first


def test_violated_run_logs_the_torque_held_until_the_crossing(model: RobotModel) -> None:
    rates = ConstraintSet(2, velocity=[joint_rate_limit([50.0, 0.3], ["first", "second"])])
    law = _Watched(PD(model, np.array([1.0, 1.5]), [4, 4], [2, 2]), rates)
    traj = run_mujoco(plant(), law, ABSOLUTE, np.zeros(2), np.zeros(2),
                      LoopSettings(2.0, InputBounds(0.01)))
    assert traj.outcome == "constraint_violated"
    assert np.all(np.isfinite(traj.torque)) and np.all(np.isfinite(traj.joint_torque))
    np.testing.assert_array_equal(traj.torque[-1], traj.torque[-2])  # zero-order hold
    np.testing.assert_array_equal(traj.joint_torque[-1], traj.joint_torque[-2])
    assert np.isnan(traj.lyapunov[-1])  # V is undefined outside S
