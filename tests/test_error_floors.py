"""The floors the errors a guard holds raise (cpbc.controllers.safeguard.error_floors): the
slope bounds its first test raises them by lie above the gradients on real arms, the floors
they give lie above the exact ones, which ``refine`` restores, the friction's one-call kernel
gives the floors of the general path, and a guard on the FR3 holds the same torques either
way."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.linear_limit import LinearLimit, joint_position_limit
from cpbc.constraints.rate_limit import joint_rate_limit
from cpbc.controllers.cpbc import CPBC
from cpbc.controllers.safeguard import Safeguard, SafeguardSettings, guarded
from cpbc.controllers.safeguard.error_floors import ErrorFloors
from cpbc.controllers.safeguard.model_error import friction_error, margin_losses
from cpbc.hardware.motion import MotionSettings
from cpbc.hardware.robot_run import choose_controller, lockstep_for, on_robot, run_on_robot
from cpbc.model.coordinates import LinearCoordinates
from cpbc.model.input_bounds import InputBounds
from cpbc.model.robot_model import RobotModel
from cpbc.reliability.verification import draw_state
from cpbc.resources import models_dir
from cpbc.scenario import ScenarioSetup, build, load_scenario

ROOT = Path(__file__).resolve().parents[1]
FR3_REACH = ROOT / "tests" / "scenarios" / "fr3_reach_ball.yaml"
PANDA_SPHERES = ROOT / "tools" / "campaigns" / "panda_sphere_rate.yaml"


@pytest.fixture(scope="module")
def fr3() -> ScenarioSetup:
    return build(*load_scenario(str(FR3_REACH)))


def _guard(setup: ScenarioSetup) -> Safeguard:
    guard = on_robot(setup).controller(choose_controller(setup, "CPBC"))
    assert isinstance(guard, Safeguard)
    return guard


@pytest.mark.parametrize("path", [FR3_REACH, PANDA_SPHERES], ids=["fr3", "panda"])
def test_the_slope_bounds_lie_above_every_gradient_inside_the_constraints(path) -> None:
    """The joint limits' 2w|a| and the sphere constraints' reach bound |∇φ_i| entry by entry
    at states drawn as the campaigns draw them, near the boundaries too."""
    setup = build(*load_scenario(str(path)))
    law = choose_controller(setup, "CPBC").controller
    kept: ConstraintSet = law.constraints
    assert kept.gradients_bounded
    worst = 0.0
    for seed in range(60):
        drawn = draw_state(setup, seed)
        state = law.state(drawn.position, drawn.velocity)
        exact = np.abs(kept.configuration_gradients(state))
        bound = kept.configuration_gradient_bounds(state)
        assert np.all(exact <= bound + 1e-12), f"seed {seed}"
        worst = max(worst, float((exact / np.where(bound > 0, bound, 1.0)).max()))
    assert worst > 0.3  # the bounds are not vacuous: some gradient comes near its bound


def _step(guard: Safeguard, x: np.ndarray, dx: np.ndarray):
    state = guard.law.state(x, dx)
    out = guard.law.evaluate_state(state, margins=True)
    guard.box.begin(state)
    bias = state.coriolis_force + state.gravity + state.dissipation
    _, floor, mid = guard.sample_floors(state.x, out.margins)
    return state, bias, out.torque, floor, mid


def _exact_floors(guard: Safeguard, state, bias, floor, mid):
    """(S1)'s floors raised by the friction's losses at the gradients, from the public
    functions of model_error."""
    bounds = guard.box.reachable.bounds
    error = friction_error(guard.model, state, None, guard.period, torques=(bias, *bounds))
    end, middle = margin_losses(guard.guarded, state, error, guard.period, guard.travel)
    return floor + end, mid + middle


def test_the_first_tests_floors_lie_above_the_exact_ones_until_refined(fr3) -> None:
    guard = _guard(fr3)
    refined = 0
    for seed in range(40):
        drawn = draw_state(fr3, seed)
        state, bias, tau, floor, mid = _step(guard, drawn.position, drawn.velocity)
        exact, exact_mid = _exact_floors(guard, state, bias, floor, mid)
        refine = guard.errors.raise_floors(state, bias, tau, floor, mid)
        assert refine is not None  # the FR3's set has slope bounds: its floors are bounds
        assert np.all(floor >= exact) and np.all(mid >= exact_mid)
        refined += int(np.any(floor > exact))
        refine()
        np.testing.assert_allclose(floor, exact, rtol=1e-13, atol=0.0)
        np.testing.assert_allclose(mid, exact_mid, rtol=1e-13, atol=0.0)
    assert refined > 30  # the bounds raise the floors more than the gradients do


def test_the_friction_kernel_gives_the_floors_of_the_general_path(fr3) -> None:
    """Without slope bounds (rate limits only) the one call raises the floors by the
    gradients' losses, as friction_error and margin_losses do."""
    guard = _guard(fr3)
    rates_only = ConstraintSet(guard.guarded.n, (), guard.guarded.velocity)
    errors = ErrorFloors(rates_only, guard.model, guard.box, None, None, guard.period,
                         guard.travel, guard.cushion[guard.guarded.n_configuration:])
    nv = len(rates_only.names)
    for seed in range(20):
        drawn = draw_state(fr3, seed)
        state, bias, tau, floor, _ = _step(guard, drawn.position, drawn.velocity)
        floor, mid = floor[-nv:].copy(), np.empty(0)
        bounds = guard.box.reachable.bounds
        error = friction_error(guard.model, state, None, guard.period, torques=(bias, *bounds))
        end, _ = margin_losses(rates_only, state, error, guard.period, guard.travel)
        expected = floor + end
        assert errors.raise_floors(state, bias, tau, floor, mid) is None
        np.testing.assert_allclose(floor, expected, rtol=1e-13, atol=0.0)


def test_a_guard_on_the_fr3_holds_the_same_torques_with_the_bounded_first_test(
        fr3, monkeypatch) -> None:
    """The lock-step FR3 reach past the ball (no time budget: a reproducible run) commands
    the same torques, bit for bit, whether the first test's floors come from the slope bounds
    or from the gradients."""
    def motion():
        run = run_on_robot(fr3, choose_controller(fr3, "CPBC"), lockstep_for(fr3),
                           MotionSettings(2.0, 10.0))
        return run.motion.commanded_torque

    bounded = motion()
    monkeypatch.setattr(ConstraintSet, "gradients_bounded", property(lambda self: False))
    exact = motion()
    np.testing.assert_array_equal(bounded, exact)


def test_in_absolute_link_angles_the_bounds_and_the_one_call_hold_too() -> None:
    """The thesis's planar arm in absolute link angles (a mapped torque, T ≠ I) with Coulomb
    friction, its relative-angle limit a = (−1, 1) and joint limits, a torque box and a rate
    limit: the limits' 2w|a| bound their slopes, the one call's floors lie above the exact
    ones, and ``refine`` gives the exact ones — no scenario ships an arm like this."""
    coords = LinearCoordinates.absolute_link_angles(2)
    model = RobotModel.from_mjcf(models_dir() / "planar_2link.xml", coordinates=coords,
                                 coulomb_friction=[0.5, 0.2])
    names = ["theta1", "theta2"]
    relative = LinearLimit([[-1, 1]], [-17 * np.pi / 18], [17 * np.pi / 18], ["relative"])
    limits = joint_position_limit([-0.5, -0.5], [3.5, 3.5], names)
    kept = ConstraintSet(2, [limits, relative], [joint_rate_limit([0.3, 0.2], names)])
    law = CPBC(model, np.array([np.pi, 2 * np.pi / 3]), kept, 4.0, 20.0)
    guard = guarded(law, InputBounds(0.001, np.array([20.0, 10.0]), 1000.0),
                    SafeguardSettings())
    assert isinstance(guard, Safeguard) and guard.guarded.gradients_bounded
    rng = np.random.default_rng(3)
    checked = 0
    while checked < 40:
        x, dx = rng.uniform(-0.4, 3.4, 2), rng.uniform(-0.25, 0.25, 2) * [0.3, 0.2]
        if not np.all(kept.margins(x, dx) > 0):
            continue
        state, bias, tau, floor, mid = _step(guard, x, dx)
        exact_slope = np.abs(kept.configuration_gradients(state))
        assert np.all(exact_slope <= kept.configuration_gradient_bounds(state) + 1e-12)
        exact, exact_mid = _exact_floors(guard, state, bias, floor, mid)
        refine = guard.errors.raise_floors(state, bias, tau, floor, mid)
        assert refine is not None
        assert np.all(floor >= exact) and np.all(mid >= exact_mid)
        refine()
        np.testing.assert_allclose(floor, exact, rtol=1e-13, atol=0.0)
        np.testing.assert_allclose(mid, exact_mid, rtol=1e-13, atol=0.0)
        checked += 1


def test_past_a_limit_only_the_guard_keeps_the_floors_are_the_exact_ones(fr3,
                                                                        monkeypatch) -> None:
    """At states beyond an extra limit (one only the guard keeps: its floor is its present
    margin, Safeguard.step_tests) the floors are made exact before they are copied: the guard
    holds the torques it holds when its first test's floors come from the gradients."""
    law = choose_controller(fr3, "CPBC").controller
    bounds = on_robot(fr3).loop_settings.bounds
    drawn = [draw_state(fr3, seed) for seed in range(60)]
    centre = float(np.mean([d.position[0] for d in drawn]))
    extra = LinearLimit(np.eye(7)[:1], [centre - 0.02], [centre + 0.02], ["extra_joint1"])
    states = [(d.position, d.velocity) for d in drawn if abs(d.position[0] - centre) > 0.02]
    assert len(states) > 50

    def torques() -> list[np.ndarray]:
        guard = Safeguard(law, bounds, SafeguardSettings(), also_keep=[extra])
        return [guard.torque(x, dx) for x, dx in states]

    bounded = torques()
    monkeypatch.setattr(ConstraintSet, "gradients_bounded", property(lambda self: False))
    for a, b in zip(bounded, torques(), strict=True):
        np.testing.assert_array_equal(a, b)
