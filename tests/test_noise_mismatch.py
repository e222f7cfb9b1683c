"""Measurement noise and model mismatch: seeded noise on what the controller sees only; a noisy
sample outside S is refused without ending the run while the arm itself stays inside; plant
overrides change MuJoCo and not the controller's model; the campaigns report, never crash."""

from __future__ import annotations

import copy
from dataclasses import replace

import mujoco
import numpy as np
import pytest
import yaml

from cpbc.constraints import ConstraintSet, joint_rate_limit
from cpbc.controllers import BPBC, Controller, Power
from cpbc.controllers.controller import Evaluation
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model import ArmState, RobotModel
from cpbc.model.input_bounds import InputBounds
from cpbc.reliability.campaign import campaign_setup
from cpbc.results.metrics import STATUSES
from cpbc.scenario import build, load_scenario
from cpbc.simulation import LoopSettings, MujocoPlant, PlantSettings, run_mujoco
from cpbc.simulation.disturbances import MeasurementNoise, PlantMismatch
from tools.reliability.bad_input import BASE
from tools.reliability.robustness import (
    MismatchLevel,
    mismatch_campaign,
    noise_beyond,
    noise_campaign,
    saturation_campaign,
    true_kinetic_energy,
)

RATES = [0.3, 0.2]


@pytest.fixture
def bpbc(absolute_model: RobotModel) -> BPBC:
    rates = ConstraintSet(2, velocity=[joint_rate_limit(RATES, ["t1", "t2"])])
    return BPBC(absolute_model, np.array([np.pi, np.pi]), rates, [2, 10], [4, 20], 1, 1,
                Power(0.2))


@pytest.fixture
def plant(planar_path) -> MujocoPlant:
    return MujocoPlant.from_file(planar_path, PlantSettings(0.001, "Euler"))


def run(plant: MujocoPlant, law: Controller, settings: LoopSettings, dx0=(0.0, 0.0)):
    return run_mujoco(plant, law, law.model.coordinates, np.zeros(2), np.array(dx0), settings)


def test_noise_is_seeded_and_seen_only_by_the_controller(bpbc: BPBC, plant) -> None:
    base = LoopSettings(0.3, InputBounds(0.001))
    clean = run(plant, bpbc, base)
    a = run(plant, bpbc, replace(base, noise=MeasurementNoise(1e-3, 1e-2, seed=4)))
    b = run(plant, bpbc, replace(base, noise=MeasurementNoise(1e-3, 1e-2, seed=4)))
    c = run(plant, bpbc, replace(base, noise=MeasurementNoise(1e-3, 1e-2, seed=5)))
    zero = run(plant, bpbc, replace(base, noise=MeasurementNoise(0.0, 0.0, seed=4)))
    np.testing.assert_array_equal(a.position, b.position)
    assert not np.array_equal(a.position, c.position)
    assert not np.array_equal(a.position, clean.position)
    np.testing.assert_array_equal(zero.position, clean.position)
    # the log holds the true state: its rates are smooth, not noise of σ = 0.01
    assert np.max(np.abs(np.diff(a.velocity, axis=0))) < 1e-3
    # V is that of the true state
    np.testing.assert_allclose(a.lyapunov[0], bpbc.lyapunov(np.zeros(2), np.zeros(2)))


def test_noise_sizes_are_checked() -> None:
    with pytest.raises(CpbcError, match=r"noise\.velocity"):
        MeasurementNoise(0.0, (0.1, 0.1, 0.1)).sigmas(2)
    with pytest.raises(CpbcError, match=r"noise\.position"):
        MeasurementNoise(-1.0, 0.0).sigmas(2)


def test_noisy_sample_outside_S_is_refused_and_the_run_goes_on(bpbc, plant) -> None:
    """Starting at 99.9 % of the rate bound with rate noise σ = 5 mrad/s, many samples are
    measured outside S; the arm is not, and the run completes."""
    settings = LoopSettings(1.0, InputBounds(0.001), noise=MeasurementNoise(0.0, 0.005, seed=1))
    traj = run(plant, bpbc, settings, dx0=(0.2997, 0.0))
    assert traj.outcome == "completed"
    assert traj.rejected_samples > 0
    assert np.all(np.abs(traj.velocity) < RATES)


class Pushing(Controller):
    """Enforces |ẋ| < 0.3, 0.2 by refusing states outside, but pushes joint 1 hard."""

    type_name = "pushing"

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        m = self.constraints.margins(state.x, state.dx)
        if np.any(m <= 0):
            i = int(np.argmin(m))
            raise ConstraintViolation(self.constraints.names[i], float(m[i]))
        return Evaluation(np.array([20.0, 0.0]), 0.0, m if margins else None)


def test_true_state_outside_S_ends_the_run_as_violated(absolute_model, plant) -> None:
    rates = ConstraintSet(2, velocity=[joint_rate_limit(RATES, ["t1", "t2"])])
    law = Pushing(absolute_model, np.zeros(2), rates)
    settings = LoopSettings(1.0, InputBounds(0.001),
                            noise=MeasurementNoise(0.0, 0.01, seed=2))
    traj = run(plant, law, settings)
    assert traj.outcome == "constraint_violated"
    assert traj.violated == "rate[t1]"
    assert 0 < traj.end_time < 1.0
    assert abs(traj.velocity[-1, 0]) >= RATES[0]  # the true rate crossed


# -- plant mismatch ---------------------------------------------------------------------------
def scenario_with_plant(tmp_path, plant_spec: dict):
    data = copy.deepcopy(BASE)
    data["robot"]["plant"] = plant_spec
    path = tmp_path / "mismatch.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return build(*load_scenario(path))


def test_plant_overrides_change_mujoco_and_not_the_controller(tmp_path) -> None:
    setup = scenario_with_plant(tmp_path, {
        "mass_scale": [1.2, 0.8], "inertia_scale": 1.1, "damping": [0.1, 0.2],
        "armature": 0.05, "frictionloss": 0.02,
    })
    nominal = campaign_setup("thesis_ch7").make_plant().model
    model = setup.make_plant().model
    np.testing.assert_allclose(model.body_mass[1:], [1.2, 0.8])
    np.testing.assert_allclose(model.body_inertia[1:], 1.1 * nominal.body_inertia[1:])
    np.testing.assert_allclose(model.dof_damping, [0.1, 0.2])
    np.testing.assert_allclose(model.dof_armature, [0.05, 0.05])
    np.testing.assert_allclose(model.dof_frictionloss, [0.02, 0.02])
    # The controller's model is the nominal arm: its D is not the plant's.
    q = np.array([0.3, 0.7])
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    m_plant = np.zeros((2, 2))
    mujoco.mj_fullM(model, data, m_plant)
    x = setup.model.coordinates.from_joint(q)
    m_model = setup.model.coordinates.matrix.T @ setup.model.inertia(x) @ (
        setup.model.coordinates.matrix)
    assert not np.allclose(m_plant, m_model, rtol=1e-3)


def test_random_mismatch_is_seeded_and_within_its_ranges() -> None:
    a = PlantMismatch.random(np.random.default_rng(3), 2, 2, 0.2, 0.2, 0.1, 0.05, 0.02)
    b = PlantMismatch.random(np.random.default_rng(3), 2, 2, 0.2, 0.2, 0.1, 0.05, 0.02)
    assert a == b
    assert all(0.8 <= v <= 1.2 for v in (*a.mass_scale, *a.inertia_scale))
    assert all(0 <= v <= 0.1 for v in a.damping)
    assert not a.is_nominal and PlantMismatch().is_nominal


def test_true_kinetic_energy_of_the_nominal_plant_is_the_model_s() -> None:
    setup = campaign_setup("planar_bpbc_ke")
    plant = setup.make_plant()
    rng = np.random.default_rng(0)
    xs, dxs = rng.uniform(-3, 3, (5, 2)), rng.uniform(-1, 1, (5, 2))
    t_inv = setup.model.coordinates.inverse
    ke = true_kinetic_energy(plant, xs @ t_inv.T, dxs @ t_inv.T)
    np.testing.assert_allclose(
        ke, [setup.model.kinetic_energy(x, dx) for x, dx in zip(xs, dxs, strict=True)],
        rtol=1e-10)


def test_small_mismatch_campaign_reports_every_controller() -> None:
    setup = campaign_setup("planar_bpbc_ke")
    setup.loop_settings = replace(setup.loop_settings, duration=2.0)
    records = mismatch_campaign(setup, "planar_bpbc_ke", [MismatchLevel("inertia", 0.2, 0.2)],
                                draws=1, seed=0)
    names = {(r["controller"], r["case"], r["safeguard"]) for r in records}
    assert ("PD", "rest", True) in names
    assert ("BPBC-KE", "rest", False) in names and ("BPBC-KE", "rest", True) in names
    for r in records:
        assert r["status"] in STATUSES
        assert np.isfinite(r["true_min_margin"])
    pd = next(r for r in records if r["controller"] == "PD")
    assert pd["true_violation"] and pd["ke_peak_over_limit"] > 1  # PD ignores the bound


def test_noise_and_saturation_campaigns_report_status_not_crashes() -> None:
    setup = campaign_setup("thesis_ch7")
    setup.loop_settings = replace(setup.loop_settings, duration=0.5)
    noisy = noise_campaign(setup, "thesis_ch7", [("high", 1e-2, 5e-2)], seed=0)
    limited = saturation_campaign(setup, "thesis_ch7", [0.2])
    assert len(noisy) == 4 and len(limited) == 8
    for r in (*noisy, *limited):
        assert r["status"] in STATUSES, r
        assert r["finite"]
    assert any(r["saturated_steps"] > 0 for r in limited)


def test_the_mismatch_campaign_runs_each_constrained_law_also_with_the_error_declared() -> None:
    setup = campaign_setup("planar_bpbc_ke")
    setup.loop_settings = replace(setup.loop_settings, duration=1.0)
    level = MismatchLevel("inertia", 0.2, 0.2, damping=0.05)
    assert level.declared() == {"inertia": 0.2, "damping": 0.05}
    built = []

    def declared(at: MismatchLevel):
        built.append(at)
        knows = campaign_setup("planar_bpbc_ke", model_error=at.declared())
        knows.loop_settings = replace(knows.loop_settings, duration=1.0)
        return knows

    records = mismatch_campaign(setup, "planar_bpbc_ke", [level], draws=1, seed=0,
                                declared=declared)
    assert built == [level]
    marked = {(r["controller"], r["safeguard"], r["declared"]) for r in records}
    assert ("BPBC-KE", True, True) in marked and ("BPBC-KE", True, False) in marked
    assert not any(r["declared"] for r in records if r["controller"] == "PD")


def test_the_noise_draws_beyond_the_declared_bound_are_those_of_the_loops_generator() -> None:
    assert noise_beyond(3, 2, 50, 0.0, (0.1, 0.2)) == 200  # every draw is beyond 0 σ
    assert noise_beyond(3, 2, 50, 0.0, (0.1, 0.0)) == 100  # a noiseless rate draws none
    rng = np.random.default_rng(3)
    draws = rng.standard_normal((50, 2, 2))  # n positions then n rates, each instant
    assert noise_beyond(3, 2, 50, 1.0, (0.1, 0.2)) == int(np.sum(np.abs(draws) > 1.0))


def test_a_declared_rate_error_as_large_as_the_rate_bound_leaves_no_room() -> None:
    setup = campaign_setup("thesis_ch7")
    setup.loop_settings = replace(setup.loop_settings, duration=0.3)
    runs = noise_campaign(setup, "thesis_ch7", [("high", 1e-2, 5e-2), ("low", 1e-4, 1e-3)],
                          seed=0, declared_sigmas=4.0)
    declared = [r for r in runs if r["declared"]]
    assert {r["controller"] for r in declared} == {"BPBC"}  # the constrained law only
    room = {r["level"]: r["declarable"] for r in declared}
    assert room == {"high": False, "low": True}  # 4 × 0.05 rad/s is thesis_ch7's rate bound
    assert all(isinstance(r["beyond"], int) for r in declared)
