"""The stopping test under bounded torque: a state it calls lost is lost whatever torque in
the box is held, and one it calls savable is saved by the torque it assumes."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from cpbc.constraints import ConstraintSet, joint_position_limit
from cpbc.constraints.stopping import Braking, stopping_margins, stopping_terms
from cpbc.model import RobotModel

LIMIT = np.array([4.0, 2.0])


def _limits(model: RobotModel) -> ConstraintSet:
    return ConstraintSet(2, [joint_position_limit(np.array([-3.0, -1.0]),
                                                  np.array([3.0, 1.0]), ["q1", "q2"])])


def _lowest_margin(model: RobotModel, cons: ConstraintSet, x: np.ndarray, dx: np.ndarray,
                   tau_q: np.ndarray, seconds: float = 3.0, dt: float = 1e-4) -> float:
    """min φ over a held torque until joint 2 turns back (semi-implicit Euler, the model)."""
    low = np.inf
    x, dx = x.copy(), dx.copy()
    for _ in range(int(seconds / dt)):
        dx = dx + dt * model.forward_dynamics(x, dx, tau_q)
        x = x + dt * dx
        low = min(low, float(cons.configuration_margins(x).min()))
        if dx[1] <= 0.0:
            break
    return low


def _formula(cons: ConstraintSet, model: RobotModel, x: np.ndarray, dx: np.ndarray,
             limit: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """s, v, a of the module docstring, written out with numpy, constraint by constraint."""
    state = model.state(x, dx)
    bias = state.coriolis_force + state.gravity + state.dissipation
    s, v, a = [], [], []
    for c in cons.configuration:
        phi, grads, curvature = c.motion_terms(cons.state(model, x, dx, motion=True))
        for i in range(len(phi)):
            y = np.linalg.solve(state.inertia, grads[i])
            w = model.coordinates.inverse @ y
            reach = sum(abs(wj) * lj for wj, lj in zip(w, limit, strict=True) if wj != 0.0)
            a.append(reach - y @ bias + curvature[i])
            v.append(-grads[i] @ dx)
            lost = v[-1] ** 2 / (2 * a[-1]) if a[-1] > 0 else np.inf
            s.append(phi[i] - lost if v[-1] > 0 else phi[i])
    return np.array(s), np.array(v), np.array(a)


@pytest.mark.parametrize("coordinates", ["joint_model", "absolute_model"])
def test_the_compiled_test_is_the_formula(coordinates: str, request: pytest.FixtureRequest,
                                          rng: np.random.Generator) -> None:
    """stopping_terms (one compiled call, cpbc.kernels.stopping_test) against the module
    docstring's formula at random states, in joint and in absolute coordinates (T ≠ I), with
    one joint unlimited (L = ∞ adds only where it moves φ), and a box too weak to stop a
    joint against gravity (a ≤ 0: lost, s = −∞)."""
    model: RobotModel = request.getfixturevalue(coordinates)
    cons = _limits(model)
    lost = 0
    for limit in (LIMIT, np.array([np.inf, 2.0]), np.array([4.0, 1e-3])):
        for _ in range(20):
            x, dx = rng.uniform(-0.9, 0.9, 2), rng.uniform(-3.0, 3.0, 2)
            state = model.state(x, dx)
            bias = state.coriolis_force + state.gravity + state.dissipation
            s, v, a, _ = stopping_terms(cons, model, state, bias, limit)
            want = _formula(cons, model, x, dx, limit)
            for got, expected in zip((s, v, a), want, strict=True):
                np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
            lost += int(np.isneginf(s).sum())
    assert lost > 0  # the weak box met a ≤ 0 on an approach


def test_margins_and_curvature_of_a_joint_limit(joint_model: RobotModel) -> None:
    cons = _limits(joint_model)
    x, dx = np.array([0.0, 0.9]), np.array([0.0, 0.5])
    s, v, a = stopping_margins(cons, joint_model, x, dx, LIMIT)
    phi = cons.configuration_margins(x)
    assert s.shape == v.shape == a.shape == (2,)
    assert v[1] == pytest.approx(-(-2 * 0.9) * 0.5)  # φ̇ = (l + u − 2x)ẋ
    assert s[1] == pytest.approx(phi[1] - v[1] ** 2 / (2 * a[1]))
    assert s[0] == phi[0]  # not approaching joint 1's limits
    s_rest, _, _ = stopping_margins(cons, joint_model, x, np.zeros(2), LIMIT)
    np.testing.assert_array_equal(s_rest, phi)


@pytest.mark.parametrize("speed", [1.2, 2.0, 3.0])
def test_a_lost_state_is_lost_under_every_corner_of_the_box(joint_model: RobotModel,
                                                            speed: float) -> None:
    """Close to joint 2's upper limit and approaching fast: the test says lost, and no held
    corner torque of the box (the extreme ones) keeps φ > 0."""
    cons = _limits(joint_model)
    x, dx = np.array([0.0, 0.93]), np.array([0.0, speed])
    s, _, _ = stopping_margins(cons, joint_model, x, dx, LIMIT)
    assert s[1] < 0
    for signs in itertools.product((-1.0, 1.0), repeat=2):
        assert _lowest_margin(joint_model, cons, x, dx, np.array(signs) * LIMIT) <= 0


def test_a_savable_state_is_saved_by_the_torque_the_test_assumes(joint_model: RobotModel
                                                                 ) -> None:
    cons = _limits(joint_model)
    x, dx = np.array([0.0, 0.6]), np.array([0.0, 0.6])
    s, _, _ = stopping_margins(cons, joint_model, x, dx, LIMIT)
    assert s[1] > 0.3 * cons.configuration_margins(x)[1]
    state = joint_model.state(x, dx)
    grad = cons.configuration[0].gradient(x)[1]
    w = np.linalg.solve(state.inertia, grad)
    best = np.sign(w) * LIMIT  # the largest φ̈ any torque of the box gives
    assert _lowest_margin(joint_model, cons, x, dx, best) > 0


def _case(tmp_path: Path, q4: float, velocity: str, duration: float) -> Path:
    """panda_cpbc_sphere started with joint 4 at ``q4`` and the given velocity."""
    from cpbc.resources import scenarios_dir

    text = (scenarios_dir() / "panda_cpbc_sphere.yaml").read_text()
    start = "    position: [-0.179, 0.172, -0.497, -2.085, 0.103, 2.233, 0.785]\n"
    assert start in text
    near = f"    position: [-0.179, 0.172, -0.497, {q4}, 0.103, 2.233, 0.785]\n"
    case = text.replace(start, near + f"    velocity: {velocity}\n")
    path = tmp_path / "case.yaml"
    path.write_text(case.replace("duration: 5.0", f"duration: {duration}"))
    return path


def _refusal(tmp_path: Path, capsys: pytest.CaptureFixture[str], q4: float,
             velocity: str) -> str:
    """The CLI's answer to panda_cpbc_sphere started with joint 4 at ``q4`` and the given
    velocity: exit 2, nothing written; the message."""
    from cpbc.run import main

    out = tmp_path / "out"
    assert main([str(_case(tmp_path, q4, velocity, 0.01)), "--out", str(out), "--quiet",
                 "--no-plots"]) == 2
    assert not out.exists()
    return capsys.readouterr().err


def test_a_scenario_case_that_cannot_be_stopped_is_refused(tmp_path, capsys) -> None:
    """The Panda 0.1 mm short of joint 4's upper stop, approaching it at 1 rad/s (inside the
    rate bound): no torque within the URDF's 87 N·m stops that in time. The CLI says so,
    names the field and exits 2 without writing anything."""
    err = _refusal(tmp_path, capsys, -0.0699, "[0, 0, 0, 1.0, 0, 0, 0]")
    assert "cases[0].velocity" in err and "cannot be stopped inside the constraints" in err
    assert "no torque within the limits can stop it" in err
    assert "position[panda_joint4]" in err


def test_a_case_outside_v_that_a_rescue_brake_stops_runs_and_crosses_nothing(
        tmp_path, capsys) -> None:
    """0.01 rad short of joint 4's stop at 0.6 rad/s while the shoulder (joint 2) swings at
    1 rad/s: the brake that slows every joint together must also stop the heavy shoulder and
    would not stop joint 4 in time (the start is outside V), but a brake that lets each joint
    decelerate as the box allows does. Such a start was refused; it runs now, the CLI says
    it starts outside V, and nothing is crossed."""
    import json

    from cpbc.run import main

    out = tmp_path / "out"
    path = _case(tmp_path, -0.0798, "[0, 1.0, 0, 0.6, 0, 0, 0]", 0.4)
    assert main([str(path), "--out", str(out), "--quiet", "--no-plots"]) == 0
    err = capsys.readouterr().err
    assert "starts outside the safeguard's braking set V" in err
    assert "position[panda_joint4]" in err
    runs = {r["controller"]: r for r in json.loads((out / "summary.json").read_text())}
    cpbc = runs["CPBC"]
    assert cpbc["status"] != "constraint_violated"
    assert min(v for k, v in cpbc["min_margins"].items() if k.startswith("position")) > 0
    assert cpbc["rescues"] > 0  # the guard's own brake could not: its rescue held one


# -- the braking set -------------------------------------------------------------------------
def _panda_states(count: int, seed: int) -> tuple[RobotModel, np.ndarray, list]:
    from cpbc.reliability.campaign import campaign_setup, sample_states

    setup = campaign_setup("panda_cpbc_sphere")
    limit = setup.loop_settings.bounds.torque
    assert limit is not None
    return setup.model, limit, sample_states(setup, count, seed)


def test_the_uniform_brake_at_its_deceleration_sits_on_the_torque_box() -> None:
    """τ = b − A D ẋ/|ẋ| touches the box |τ| ≤ L (one joint at its limit, none beyond),
    and asks for ẍ = −A ẋ/|ẋ|."""
    model, limit, states = _panda_states(12, seed=5)
    braking = Braking.of(model, limit)
    for s in states:
        st = model.state(s.position, s.velocity)
        bias = st.coriolis_force + st.gravity + st.dissipation
        a = braking.deceleration(st.inertia, bias, s.velocity)
        unit = s.velocity / np.linalg.norm(s.velocity)
        tau = bias - a * st.inertia @ unit
        assert np.max(np.abs(tau) / limit) == pytest.approx(1.0, abs=1e-9)
        acc = np.linalg.solve(st.inertia, tau - bias)
        np.testing.assert_allclose(acc, -a * unit, atol=1e-9 * a)
    assert braking.deceleration(st.inertia, bias, np.zeros(7)) == np.inf


def test_the_full_brake_stops_the_arm_short_of_the_stopping_point() -> None:
    """The uniform brake at the full deceleration A of each instant (A re-evaluated as D,
    g and C ẋ change along the stop, not frozen) stops the Panda within the travel
    |ẋ|²/(2θA₀) that σ counts on: θ = 0.8 covers how much A falls on the way."""
    model, limit, states = _panda_states(12, seed=5)
    braking = Braking.of(model, limit)
    dt = 2e-4
    for s in states:
        x, dx = s.position.copy(), s.velocity.copy()
        st = model.state(x, dx)
        k = braking.per_speed(st.inertia, st.coriolis_force + st.gravity, dx)
        stop = x + k * np.linalg.norm(dx) * dx
        for _ in range(20000):
            st = model.state(x, dx)
            bias = st.coriolis_force + st.gravity + st.dissipation
            a = braking.deceleration(st.inertia, bias, dx)
            speed = np.linalg.norm(dx)
            if a * dt >= speed:
                break
            dx = dx - (dt * a / speed) * dx  # ẍ = −A ẋ/|ẋ|: along the segment ahead of ẋ
            x = x + dt * dx
        direction = s.velocity / np.linalg.norm(s.velocity)
        assert (x - s.position) @ direction <= (stop - s.position) @ direction
