"""A declared model error (simulation.model_error, cpbc.controllers.safeguard.model_error): the
margins it can take in a period, the braking set's lower deceleration, and on the Panda with
its motors' rate limit a plant disturbed at the corners of the declared bound, kept only when
the guard knows the bound."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.constraints.linear_limit import joint_position_limit
from cpbc.constraints.rate_limit import joint_rate_limit
from cpbc.constraints.stopping import Braking
from cpbc.controllers.safeguard.error_floors import ErrorFloors
from cpbc.controllers.safeguard.model_error import (
    DeclaredError,
    friction_error,
    margin_losses,
    measurement_losses,
    mujoco_friction,
    reachable_accelerations,
)
from cpbc.model.coordinates import LinearCoordinates
from cpbc.model.robot_model import RobotModel
from cpbc.reliability.campaign import (
    RecordingPlant,
    campaign_setup,
    checked_run,
    kept_constraints,
)
from cpbc.reliability.verification import draw_state
from cpbc.resources import models_dir, scenarios_dir
from cpbc.run import main as run_main
from cpbc.scenario import build, load_scenario
from cpbc.simulation.disturbances import AccelerationDisturbance, PlantMismatch
from cpbc.verify import main as verify_main

ROOT = Path(__file__).resolve().parents[1]
RATE_CAMPAIGN = ROOT / "tools" / "campaigns" / "panda_sphere_rate.yaml"
ERROR = 5.0  # rad/s², every joint


def _declared(tmp_path: Path, error: float | None = ERROR) -> Path:
    text = RATE_CAMPAIGN.read_text()
    if error is not None:
        text = text.replace("simulation:\n",
                            f"simulation:\n  model_error: {{acceleration: {error}}}\n", 1)
    out = tmp_path / "panda_error.yaml"
    out.write_text(text)
    return out


@pytest.fixture(scope="module")
def planar_model() -> RobotModel:
    return RobotModel.from_mjcf(models_dir() / "planar_2link.xml")


def test_the_losses_are_the_first_order_reach_of_the_error(planar_model) -> None:
    """A joint limit's margin φ (its product form) loses c h² |∂φ/∂x_j| ā_j at the end and
    ⅛h² |∂φ/∂x_j| ā_j at mid-period; a rate ψ = ½v̄² − ½ẋ_j² loses h |ẋ_j| ā_j + ½h² ā_j²."""
    model = planar_model
    names = ["a", "b"]
    cons = ConstraintSet(2, (joint_position_limit([-1.0, -1.0], [1.0, 1.0], names),),
                         (joint_rate_limit([2.0, 2.0], names),))
    x, dx = np.array([0.1, -0.2]), np.array([0.5, -1.5])
    state = model.state(x, dx)
    bound, h, c = np.array([3.0, 7.0]), 0.002, 0.5
    end, mid = margin_losses(cons, state, bound, h, c)
    nc = cons.n_configuration
    assert nc == 2  # one margin a joint
    slope = np.abs(np.diag(cons.configuration[0].gradient(x)))
    assert slope == pytest.approx([0.2, 0.4])  # (upper − x) − (x − lower)
    assert end[:nc] == pytest.approx(c * h * h * slope * bound)
    assert mid == pytest.approx(0.125 * h * h * slope * bound)
    assert end[nc:] == pytest.approx(h * np.abs(dx) * bound + 0.5 * h * h * bound**2)


def test_the_braking_deceleration_is_lowered_by_the_errors_share_along_the_motion(
        planar_model) -> None:
    model = planar_model
    x, dx = np.array([0.1, -0.2]), np.array([0.6, -0.8])
    state = model.state(x, dx)
    bias = state.coriolis_force + state.gravity
    plain = Braking.of(model, 20.0).deceleration(state.inertia, bias, dx)
    bound = np.array([1.0, 2.0])
    lowered = Braking.of(model, 20.0, disturbance=bound).deceleration(state.inertia, bias, dx)
    assert lowered == pytest.approx(plain - (0.6 * 1.0 + 0.8 * 2.0))


@pytest.fixture(scope="module")
def disturbed_panda(tmp_path_factory):
    path = _declared(tmp_path_factory.mktemp("error"))
    setup = build(*load_scenario(str(path)))
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    return setup, entry


@pytest.mark.parametrize("seed", [34])
def test_a_plant_disturbed_inside_the_declared_error_is_kept_only_when_declared(
        disturbed_panda, seed) -> None:
    """A start a brake stops: disturbed at the corners of ±5 rad/s², the guard
    that knows the bound keeps every margin on MuJoCo's state; the one that does not lets a
    rate cross (its law cancels the model's acceleration at the bound; the error pushes)."""
    setup, entry = disturbed_panda
    period = 0.001
    kept = kept_constraints(setup, entry, period, setup.safeguard)
    s = draw_state(setup, seed)
    n = setup.model.n
    outcomes = {}
    for declared in (True, False):
        plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
        settings = replace(setup.loop_settings, duration=0.5, log_every=1,
                           model_error=np.full(n, ERROR) if declared else None,
                           disturbance=AccelerationDisturbance(np.full(n, ERROR), seed))
        check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                            safeguard=setup.safeguard)
        outcomes[declared] = check
    assert not outcomes[True].violated and outcomes[True].min_margin > 0.0
    assert outcomes[False].violated and outcomes[False].constraint.startswith("rate[")


def test_verify_disturbs_only_a_scenario_that_declares_an_error(tmp_path, capsys) -> None:
    undeclared = _declared(tmp_path, None)
    assert verify_main([str(undeclared), "--states", "1", "--rates", "1000", "--disturb"]) == 2
    err = capsys.readouterr().err
    assert "--disturb" in err and "simulation.model_error" in err and "Traceback" not in err


def test_verify_states_the_declared_error_and_the_disturbance(tmp_path, capsys) -> None:
    path = _declared(tmp_path)
    assert verify_main([str(path), "--seeds", "34", "--rates", "1000", "--horizon", "0.1",
                        "--disturb", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    campaign = doc["campaigns"][0] if "campaigns" in doc else doc
    assert campaign["conditions"]["model_error"] == [ERROR] * 7
    assert campaign["plan"]["disturb"] is True


def test_the_smooth_coulomb_friction_error_exceeds_its_level_only_where_a_joint_may_turn(
        planar_model) -> None:
    """At rest the plant's friction may be anything in [−F, F] against the smooth model's 0:
    |D⁻¹| F. At 2 and 3 rad/s, braked or driven by no more than a few rad/s², each joint
    slides over the period: the error is the smooth model's shortfall F (1 − tanh), nearly
    0, held at F; where any torque may be held (no box) no joint is taken to slide and the
    friction may pull with the motion: |D⁻¹| 2F."""
    levels = np.array([0.5, 0.2])
    model = RobotModel.from_mjcf(models_dir() / "planar_2link.xml", coulomb_friction=levels)
    x, h = np.array([0.1, -0.2]), 0.001
    rest = model.state(x, np.zeros(2))
    inv = np.abs(np.linalg.inv(rest.inertia))
    assert friction_error(model, rest) == pytest.approx(inv @ levels)
    moving = model.state(x, np.array([2.0, -3.0]))
    inv = np.abs(np.linalg.inv(moving.inertia))
    gentle = (np.array([-1.0, 1.0]), np.full(2, 2.0))  # centre, radius [rad/s²]
    assert friction_error(model, moving, gentle, h) == pytest.approx(inv @ levels)
    assert friction_error(model, moving, None, h) == pytest.approx(inv @ (2.0 * levels))
    assert friction_error(planar_model, rest) is None


def _friction_error_reference(model: RobotModel, state, centre, radius, period: float,
                              creep: float = 0.15) -> tuple[np.ndarray, np.ndarray]:
    """The friction's error bound of the module docstring in numpy, product by product, and
    which joints it takes to slide."""
    levels, eps = model.coulomb_friction, model.friction_smoothing
    t_inv = model.coordinates.inverse
    inv = np.linalg.inv(state.inertia)
    to_accel, joint_inv = inv @ t_inv.T, t_inv @ inv @ t_inv.T
    coarse = np.abs(joint_inv) @ (2.0 * levels)
    dq = t_inv @ state.dx
    c, r = t_inv @ centre, np.abs(t_inv) @ radius
    low = np.abs(dq) - period * (np.abs(c) + r + coarse)
    high = np.abs(dq) + period * (np.abs(c) + r + coarse)
    # the joint's own friction as it would be if it slid: F (1 − tanh(s/ε)) off the model's
    own = np.abs(np.diag(joint_inv)) * levels * (1.0 + np.tanh(np.maximum(low, 0.0) / eps))
    alpha = np.maximum(-np.sign(dq) * c + r, 0.0) + coarse - own
    slides = low >= 0.95 * 0.02 / 2.0 * alpha + creep  # MuJoCo's T_f and the creep v_c
    e = np.where(slides, levels * (1.0 - np.tanh(np.maximum(low, 0.0) / eps)),
                 levels * (1.0 + np.tanh(high / eps)))
    return np.abs(to_accel) @ np.maximum(e, levels), slides


def test_a_joint_the_bound_takes_to_slide_slides_in_mujoco() -> None:
    """The slide test asked of the torques a step may hold (1 N·m around gravity, a
    1000 N·m/s limit at 1 kHz) against MuJoCo's own friction on the xArm7 with 2 N·m on its
    light wrist (tools/campaigns/xarm7_wrist_friction.yaml): wherever the bound takes a joint
    to slide, the plant's friction is F_j sign(q̇_j) for every torque of the box; and with
    the joint's own friction taken as it would be if it slid (not the coarse 2F), the wrist
    is taken to slide at working speeds."""
    setup = build(*load_scenario(str(ROOT / "tools" / "campaigns" /
                                     "xarm7_wrist_friction.yaml")))
    model = setup.model
    plant = setup.make_plant().model
    data = mujoco.MjData(plant)
    creep = mujoco_friction(model).creep
    assert creep == pytest.approx(0.208, abs=0.001)
    rng = np.random.default_rng(36)
    lower, upper = plant.jnt_range[:, 0], plant.jnt_range[:, 1]
    slid = 0
    for _ in range(300):
        q = rng.uniform(lower + 0.3, upper - 0.3)
        dq = rng.choice([-1.0, 1.0], 7) * rng.uniform(0.0, 2.5, 7)
        state = model.state(q, dq)
        bias = state.coriolis_force + state.gravity + state.dissipation
        held = state.gravity + rng.uniform(-3.0, 3.0, 7)
        accel = reachable_accelerations(model, state, bias, held - 1.0, held + 1.0)
        _, slides = _friction_error_reference(model, state, *accel, 0.0, creep)
        for tau in (held - 1.0, held + 1.0, held + rng.uniform(-1.0, 1.0, 7)):
            data.qpos[:], data.qvel[:], data.qfrc_applied[:] = q, dq, tau
            mujoco.mj_forward(plant, data)
            if data.ncon:
                continue
            force = -data.qfrc_constraint  # the frictionloss rows only: no contact, no stop
            np.testing.assert_allclose(force[slides], (plant.dof_frictionloss * np.sign(dq))[
                slides], atol=1e-6)
        slid += int(slides[4:].sum())
    # 178 of the 900 wrist samples (from 0.45 rad/s); the coarse 2F of its own took none
    assert slid > 100


@pytest.mark.parametrize("coordinates", [None, LinearCoordinates.absolute_link_angles(2)])
def test_the_friction_error_is_its_formula_in_either_coordinates(coordinates, rng) -> None:
    """The compiled bound (cpbc.kernels.friction_error) is the docstring's formula, worked in
    numpy here: at rest, sliding and turning joints, bounded by a torque box and not; asked
    with the box's torques it is the bound at the box's reachable accelerations."""
    kwargs = {} if coordinates is None else {"coordinates": coordinates}
    model = RobotModel.from_mjcf(models_dir() / "planar_2link.xml",
                                 coulomb_friction=[0.5, 0.2], **kwargs)
    for _ in range(200):
        dx = rng.normal(size=2) * rng.choice([0.0, 0.05, 1.0, 4.0])
        state = model.state(rng.uniform(-1.0, 1.0, 2), dx)
        bias = state.coriolis_force + state.gravity + state.dissipation
        lower = -rng.uniform(1.0, 20.0, 2)
        upper = lower + rng.uniform(0.5, 30.0, 2)
        h = float(rng.choice([0.0, 0.001, 0.002]))
        accel = reachable_accelerations(model, state, bias, lower, upper)
        inv = np.linalg.inv(state.inertia)
        np.testing.assert_allclose(accel[0], inv @ (model.coordinates.inverse.T @ (
            0.5 * (lower + upper))) - inv @ bias, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(accel[1], np.abs(inv @ model.coordinates.inverse.T) @ (
            0.5 * (upper - lower)), rtol=1e-12)
        bound = friction_error(model, state, accel, h)
        assert bound is not None
        np.testing.assert_allclose(bound, _friction_error_reference(model, state, *accel, h)[0],
                                   rtol=1e-12)
        np.testing.assert_array_equal(
            friction_error(model, state, None, h, torques=(bias, lower, upper)), bound)
        # any torque: no joint slides; over a period any speed (2F), at an instant 1 + tanh
        levels, t_inv = model.coulomb_friction, model.coordinates.inverse
        e = 2.0 * levels if h else levels * (1.0 + np.tanh(
            np.abs(t_inv @ dx) / model.friction_smoothing))
        anything = friction_error(model, state, None, h)
        assert anything is not None
        np.testing.assert_allclose(anything, np.abs(inv @ t_inv.T) @ e, rtol=1e-12)


def test_a_kinetic_energy_limit_loses_its_weighted_reach(planar_model) -> None:
    """ψ = Ω − ½ẋᵀDẋ loses h |Dẋ|·ā + ½h² āᵀ|D|ā at the end of a period (Π = D)."""
    cons = ConstraintSet(2, (), (KineticEnergyLimit(planar_model, 2.0),))
    x, dx = np.array([0.3, -0.4]), np.array([0.8, -1.1])
    state = planar_model.state(x, dx, coriolis=True)
    bound, h = np.array([2.0, 5.0]), 0.001
    end, mid = margin_losses(cons, state, bound, h, 0.5)
    d = state.inertia
    assert mid.shape == (0,)
    assert end == pytest.approx([h * np.abs(d @ dx) @ bound + 0.5 * h * h * bound @ np.abs(d)
                                 @ bound], rel=1e-12)


FR3_CAMPAIGN = ROOT / "tools" / "campaigns" / "fr3_sphere_rate.yaml"


@pytest.mark.parametrize("seed", [74, 119])
def test_the_fr3s_friction_error_held_keeps_a_rate_the_smooth_model_alone_lets_cross(
        monkeypatch, seed) -> None:
    """FR3 with franky-sim's friction, 1000 N·m/s, 1 kHz, from starts a brake stops:
    as joints' rates pass through zero the plant's dry friction leaves the model's smooth one
    by up to F_c; the guard that holds that error keeps every margin, the guard that takes
    the model as exact lets a rate cross."""
    setup = build(*load_scenario(str(FR3_CAMPAIGN)))
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    base = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    kept = kept_constraints(setup, entry, 0.001, setup.safeguard)
    s = draw_state(setup, seed)
    settings = replace(setup.loop_settings, duration=0.5, log_every=1)

    def run():
        return checked_run(base, setup, entry, s.position, s.velocity, settings, kept,
                           safeguard=setup.safeguard)

    held = run()
    assert not held.violated and held.min_margin > 0.0
    # the floors (S1)'s alone: the model's smooth friction taken as exact
    monkeypatch.setattr(ErrorFloors, "raise_floors", lambda self, *args: None)
    exact = run()
    assert exact.violated and exact.constraint.startswith("rate[")


# -- a declared inertia, joint and measurement error (model_error.DeclaredError) --------------
def _drawn_errors(model: RobotModel, bound, level: dict, plants: int, states: int,
                  seed: int, target: np.ndarray, make_plant) -> tuple[np.ndarray, np.ndarray]:
    """|a − â| on plants drawn inside ``level`` (PlantMismatch.random) and the bound ā at the
    same states and model accelerations, row by row."""
    rng = np.random.default_rng(seed)
    errors, bounds = [], []
    for _ in range(plants):
        plant = make_plant()
        PlantMismatch.random(rng, plant.nbody - 1, plant.nv, **level).apply(plant)
        data = mujoco.MjData(plant)
        for _ in range(states):
            x = target + rng.uniform(-0.5, 0.5, model.n)
            dx = rng.uniform(-1.0, 1.0, model.n)
            state = model.state(x, dx)
            bias = state.coriolis_force + state.gravity + state.dissipation
            accel = rng.uniform(-20.0, 20.0, model.n)
            data.qpos[:], data.qvel[:] = x, dx
            data.qfrc_applied[:] = bias + state.inertia @ accel
            mujoco.mj_forward(plant, data)
            assert data.nefc == 0  # no contact, no joint stop: the dynamics alone
            errors.append(np.abs(data.qacc - accel))
            bounds.append(bound.bound(state, accel))
    return np.array(errors), np.array(bounds)


def _planar_plant() -> mujoco.MjModel:
    model = mujoco.MjModel.from_xml_path(str(models_dir() / "planar_2link.xml"))
    model.jnt_limited[:] = 0  # the dynamics only
    return model


@pytest.mark.parametrize("level", [
    {"mass": 0.2, "inertia": 0.2},
    {"mass": 0.2, "inertia": 0.2, "damping": 0.05, "armature": 0.02},
])
def test_plants_drawn_inside_a_declared_inertia_error_stay_inside_its_bound(
        planar_model, level) -> None:
    """Masses and inertias ±20 % per link (and up to the added damping and rotor inertia):
    MuJoCo's acceleration under the same torque never leaves the model's by more than ā;
    a bound for a quarter of the error is exceeded by the same plants (the test can fail)."""
    declared = DeclaredError(
        inertia=0.2, armature=None if "armature" not in level else np.full(2, 0.02),
        damping=None if "damping" not in level else np.full(2, 0.05))
    bound = declared.acceleration_bound(planar_model)
    target = np.array([0.3, -0.4])
    errors, bounds = _drawn_errors(planar_model, bound, level, 8, 40, 7, target, _planar_plant)
    assert np.all(errors <= bounds)
    assert np.max(errors / bounds) > 0.2  # the bound is not loose beyond use
    quarter = DeclaredError(inertia=0.05).acceleration_bound(planar_model)
    errors, too_small = _drawn_errors(planar_model, quarter, {"mass": 0.2, "inertia": 0.2},
                                      8, 40, 7, target, _planar_plant)
    assert np.any(errors > too_small)


def test_the_pandas_links_drawn_inside_the_declared_error_stay_inside_its_bound() -> None:
    setup = campaign_setup("panda_cpbc_sphere")  # no friction, no rotor inertia
    model = setup.model
    bound = DeclaredError(inertia=0.2).acceleration_bound(model)

    def plant() -> mujoco.MjModel:
        m = setup.make_plant().model
        m.jnt_limited[:] = 0
        m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        return m

    errors, bounds = _drawn_errors(model, bound, {"mass": 0.2, "inertia": 0.2}, 4, 25, 3,
                                   setup.target, plant)
    assert np.all(errors <= bounds)


def test_the_arms_energy_stays_within_1_plus_e_of_the_models_and_the_laws_keep_less(
        tmp_path) -> None:
    """½ẋᵀDẋ ≤ (1 + e) ½ẋᵀD̂ẋ on plants drawn inside ±e, so a scenario that declares e builds
    its laws with Ω/(1 + e) and keeps Ω in its monitor."""
    model = RobotModel.from_mjcf(models_dir() / "planar_2link.xml")
    rng = np.random.default_rng(5)
    for _ in range(20):
        plant = _planar_plant()
        PlantMismatch.random(rng, plant.nbody - 1, plant.nv, 0.2, 0.2).apply(plant)
        data = mujoco.MjData(plant)
        x, dx = rng.uniform(-2, 2, 2), rng.uniform(-2, 2, 2)
        data.qpos[:] = x
        mujoco.mj_forward(plant, data)
        full = np.zeros((2, 2))
        mujoco.mj_fullM(plant, data, full)
        assert dx @ full @ dx <= 1.2 * dx @ model.inertia(x) @ dx
    setup = campaign_setup("planar_cpbc_ke", model_error={"inertia": 0.25})
    (ke,) = setup.monitor.velocity
    law = next(e for e in setup.controllers if e.name == "CPBC-KE").controller
    (kept,) = law.constraints.velocity
    assert isinstance(ke, KineticEnergyLimit) and isinstance(kept, KineticEnergyLimit)
    assert kept.names == ke.names and kept.limit == pytest.approx(ke.limit / 1.25)


def test_a_measurement_error_can_hide_the_first_order_reach_of_each_margin(planar_model) -> None:
    names = ["a", "b"]
    cons = ConstraintSet(2, (joint_position_limit([-1.0, -1.0], [1.0, 1.0], names),),
                         (joint_rate_limit([2.0, 2.0], names),))
    x, dx = np.array([0.1, -0.2]), np.array([0.5, -1.5])
    state = planar_model.state(x, dx)
    p, v, h = np.array([0.01, 0.02]), np.array([0.1, 0.3]), 0.002
    end, mid = measurement_losses(cons, state, DeclaredError(position=p, velocity=v), h)
    slope = np.abs(np.diag(cons.configuration[0].gradient(x)))
    assert end[:2] == pytest.approx(slope * (p + h * v))
    assert mid == pytest.approx(slope * (p + 0.5 * h * v))
    assert end[2:] == pytest.approx(np.abs(dx) * v + 0.5 * v**2)
    # ... and a true rate that far from the measured one is off by at most that much
    true_dx = dx - np.sign(dx) * v
    measured = cons.margins(x, dx)[2:]
    assert np.all(cons.margins(x, true_dx)[2:] >= measured - end[2:] - 1e-12)


def test_a_plant_inside_the_declared_inertia_error_is_kept_only_when_declared() -> None:
    """The Panda past a ball, its links' masses and inertias drawn within ±20 % (the
    robustness campaign's first plant): the guard that takes the model as exact lets a wrist
    rate cross (the law cancels the model's acceleration at the bound, the error pushes);
    the scenario that declares inertia: 0.2 keeps every margin on MuJoCo's state."""
    checks = {}
    declarations: tuple[dict[str, object] | None, ...] = (None, {"inertia": 0.2})
    for declared in declarations:
        setup = campaign_setup("panda_cpbc_sphere", integrator=None, model_error=declared)
        entry = next(e for e in setup.controllers if e.name == "CPBC")
        plant = setup.make_plant().model
        PlantMismatch.random(np.random.default_rng(2007), plant.nbody - 1, plant.nv, 0.2,
                             0.2).apply(plant)
        case = setup.cases[0]
        settings = replace(setup.loop_settings, duration=2.0, log_every=10)
        checks[declared is not None] = checked_run(
            RecordingPlant(plant, setup.plant_settings), setup, entry, case.position,
            case.velocity, settings, safeguard=setup.safeguard)
    assert checks[False].violated and str(checks[False].constraint).startswith("rate[")
    assert not checks[True].violated and checks[True].min_margin > 0.0


@pytest.mark.parametrize("error, field", [
    ({"inertia": 1.0}, "simulation.model_error.inertia"),
    ({"inertia": -0.1}, "simulation.model_error.inertia"),
    ({"velocity": [0.1, 0.2, 0.3]}, "simulation.model_error.velocity"),
    ({"damping": "lots"}, "simulation.model_error.damping"),
    ({}, "simulation.model_error"),
])
def test_a_bad_declared_error_exits_2_naming_its_field(tmp_path, capsys, error, field) -> None:
    data = yaml.safe_load((scenarios_dir() / "thesis_ch7.yaml").read_text())
    data["simulation"]["model_error"] = error
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    assert run_main([str(path), "--out", str(out), "--quiet", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert field in err and "Traceback" not in err
    assert not out.exists()
