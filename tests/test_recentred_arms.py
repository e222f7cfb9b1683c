"""The ``recentred`` law (Cases 2–3, eqs. 6.53–6.65) on real 6- and 7-joint arms.

On the UR3 the law commands 100+ N·m at rest far from its bounds. These tests pin down that
this is the law and not the code (the gradient, centring and signs against the thesis's own
product form), what the law does (every joint gets the error energy of all of them), and
that the scenario builder refuses the set-ups where it cannot work, with numbers.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

from cpbc.constraints import ConstraintSet
from cpbc.constraints.linear_limit import joint_position_limit
from cpbc.constraints.rate_limit import joint_rate_limit
from cpbc.controllers import RecentredBarrier
from cpbc.errors import ScenarioError
from cpbc.model import RobotModel
from cpbc.model.loading import LoadedArm, load_arm
from cpbc.scenario import ScenarioSetup, build, load_scenario
from cpbc.scenario.gain_check import physical_gains

# a target and starts of the kind a user picks for the UR3 (the UR5 scenario's), far from
# every bound of its ±2π (elbow ±π) ranges
TARGET = [1.2, -1.2, 1.3, -1.7, -1.57, 0.6]
REST = [-1.0, -1.9, 1.9, -1.6, -1.57, 0.0]
FAR = [-2.0, -2.5, 2.5, 1.0, 1.0, -1.0]


@cache
def _arm(name: str) -> tuple[LoadedArm, RobotModel]:
    arm = load_arm(name)
    return arm, RobotModel(arm.model, name=name)


def _law(name: str, target: np.ndarray | None = None, rates: bool = False
         ) -> tuple[LoadedArm, RobotModel, RecentredBarrier]:
    """The law on the arm's own ranges, ω_n = 10, ζ = 1 gains at the target (mid-range
    unless given), with half the arm's rate limits when ``rates``."""
    arm, model = _arm(name)
    lo, hi = arm.position_lower, arm.position_upper
    x_d = 0.5 * (lo + hi) if target is None else np.asarray(target, float)
    kp, kd = physical_gains(np.full(model.n, 10.0), np.ones(model.n),
                            np.diag(model.inertia(x_d)))
    limits = joint_position_limit(lo, hi, arm.joint_names)
    velocity = [joint_rate_limit(0.5 * arm.velocity_limit, arm.joint_names)] if rates else []
    return arm, model, RecentredBarrier(model, x_d, ConstraintSet(model.n, [limits], velocity),
                                        kp, kd)


def _thesis_gradient(law: RecentredBarrier, arm: LoadedArm, x: np.ndarray) -> np.ndarray:
    """(6.55) as printed: ∇f = [Φ K q + ½ qᵀK q P_φ q] / Φ², φ_i = ½(X_i² − q_i²), with
    q measured from the centre of each range, X its half-width, and the thesis's K_P the
    code's K_P times Π X_i²/2 (the code normalises each factor to 1 at the centre)."""
    centre = 0.5 * (arm.position_lower + arm.position_upper)
    half = 0.5 * (arm.position_upper - arm.position_lower)
    q = x - centre
    phi_i = 0.5 * (half**2 - q**2)
    phi = np.prod(phi_i)
    k = law.kp * np.prod(half**2 / 2)
    p_phi = np.array([np.prod(np.delete(phi_i, s)) for s in range(len(q))])
    return (phi * k * q + 0.5 * (q @ (k * q)) * p_phi * q) / phi**2


@pytest.mark.parametrize("name", ["ur3", "xarm7"])
def test_gradient_is_the_derivative_of_f_and_the_thesis_form(name: str) -> None:
    """The code's ∇f is the derivative of its own f (central differences) and the thesis's
    product form (6.55) with the centring of asymmetric ranges: no slip in the gradient."""
    arm, model, law = _law(name)
    rng = np.random.default_rng(3)
    for _ in range(10):
        x = law.centre + rng.uniform(-0.9, 0.9, model.n) * law.half_width
        _, grad = law._barrier_potential(x)
        h = 1e-6
        fd = np.array([(law._barrier_potential(x + h * e)[0]
                        - law._barrier_potential(x - h * e)[0]) / (2 * h)
                       for e in np.eye(model.n)])
        np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-6 * np.abs(grad).max())
        np.testing.assert_allclose(grad, _thesis_gradient(law, arm, x), rtol=1e-10)
        own, shared, phi = law.force_parts(x)
        np.testing.assert_allclose(own + shared, grad, rtol=1e-12)
        assert phi == pytest.approx(np.prod(1 - ((x - law.centre) / law.half_width) ** 2))


def test_torque_at_rest_is_the_re_centred_gradient_difference() -> None:
    """At rest (6.57) is τ = g − ∇f(x) + ∇f(x_d) (signs, and x_d apart from the centre),
    and at the target it is exactly gravity."""
    arm, model, law = _law("ur3", np.array(TARGET))
    x = np.array(REST)
    state = model.state(x, np.zeros(model.n))
    tau = law.evaluate_state(state).torque
    expected = (state.gravity - _thesis_gradient(law, arm, x)
                + _thesis_gradient(law, arm, np.array(TARGET)))
    np.testing.assert_allclose(tau, expected, rtol=1e-10)
    at_target = model.state(np.array(TARGET), np.zeros(model.n))
    np.testing.assert_allclose(law.evaluate_state(at_target).torque, at_target.gravity,
                               atol=1e-9)


def test_every_joint_gets_the_error_energy_of_all_of_them() -> None:
    """The property behind the 100+ N·m: target mid-range, start δ off on every joint.
    Near the centre the law is K_P x̃ (within 5 % on the shoulders at δ = 0.1); at δ = 1 the
    wrists, whose own gain is 10²–10³ times below the shoulders', get several N·m, almost
    all of it the shared term E z_i/((w_i² − z_i²)Φ); at δ = 1.5 the elbow's torque passes
    the UR3's 150 N·m effort limit."""
    arm, model, law = _law("ur3")
    rest = np.zeros(model.n)

    def at(delta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """τ − g, K_P x̃ and the shared part of ∇f, δ below the centre on every joint."""
        x = law.centre - delta
        state = model.state(x, rest)
        _, shared, _ = law.force_parts(x)
        return law.evaluate_state(state).torque - state.gravity, law.kp * delta, shared

    near, pd, _ = at(0.1)
    np.testing.assert_allclose(near[:3], pd[:3], rtol=0.05)
    far, pd, shared = at(1.0)
    wrists = slice(3, 6)
    assert np.all(far[wrists] > 5.0)
    assert np.all(far[wrists] > 7.0 * pd[wrists])
    assert np.all(-shared[wrists] > 0.8 * far[wrists])
    x = law.centre - 1.5
    elbow = law.evaluate_state(model.state(x, rest)).torque[2]
    assert abs(elbow) > arm.effort_limit[2] > 8 * law.kp[2] * 1.5


def _write(tmp_path: Path, simulation: dict, cases: list[list[float]], omega: float = 10.0
           ) -> Path:
    scenario = {
        "name": "ur3_recentred",
        "robot": {"model": "ur3"},
        "simulation": {"duration": 1.0, "timestep": 0.001, **simulation},
        "target": TARGET,
        "cases": [{"name": f"case{i}", "position": c} for i, c in enumerate(cases)],
        "constraints": [
            {"type": "joint_rate_limit", "name": "joint_rates", "bounds": "from_model",
             "scale": 0.5},
            {"type": "joint_position_limit", "name": "joint_limits", "lower": "from_model",
             "upper": "from_model"},
        ],
        "controllers": [{"type": "recentred", "name": "RC", "omega_n": omega, "zeta": 1.0}],
    }
    path = tmp_path / "ur3_recentred.yaml"
    path.write_text(yaml.safe_dump(scenario))
    return path


def _build(path: Path) -> ScenarioSetup:
    return build(*load_scenario(path))


def test_refused_where_it_commands_more_than_the_torque_limit(tmp_path: Path) -> None:
    """The far start needs 1287 N·m on the elbow against its 150 N·m: refused, naming the
    controller, the case, the joint and the parts; the kp factor the message advises fits
    (just inside it builds, just outside it is refused)."""
    sim = {"torque_limit": "from_model"}
    with pytest.raises(ScenarioError) as err:
        _build(_write(tmp_path, sim, [REST, FAR]))
    assert err.value.field == "controllers[0]"
    text = str(err.value)
    for part in ("case 'case1'", "'elbow_joint'", "× its torque limit 150 N·m",
                 "error energy of all joints"):
        assert part in text
    factor = float(text.split("(omega_n ")[1].split(" ×")[0])
    _build(_write(tmp_path, sim, [REST, FAR], omega=10.0 * factor * 0.99))
    with pytest.raises(ScenarioError, match="torque limit"):
        _build(_write(tmp_path, sim, [REST, FAR], omega=10.0 * factor * 1.01))
    _build(_write(tmp_path, {"torque_limit": "none"}, [REST, FAR]))  # no limit, guarded: runs


def test_bare_law_refused_where_its_first_period_breaks_a_rate(tmp_path: Path) -> None:
    """Without the safeguard, from REST the held τ takes wrist 3 past its rate bound in the
    first 1 ms: refused. MuJoCo agrees: one held period of that τ on the plant leaves the
    wrist's rate outside its bound. The same start with the safeguard on is not refused."""
    with pytest.raises(ScenarioError, match=r"breaks rate\[wrist_3_joint\] within its first"):
        _build(_write(tmp_path, {"safeguard": False}, [REST]))
    setup = _build(_write(tmp_path, {}, [REST]))
    arm, model, law = _law("ur3", np.array(TARGET), rates=True)
    tau = law.evaluate_state(model.state(np.array(REST), np.zeros(6))).torque
    np.testing.assert_allclose(
        tau, setup.controllers[0].controller.evaluate_state(
            model.state(np.array(REST), np.zeros(6))).torque, rtol=1e-9)
    mj = arm.mujoco_model()
    mj.opt.timestep = 1e-4
    data = mujoco.MjData(mj)
    data.qpos[:] = REST
    data.qfrc_applied[:] = tau
    for _ in range(10):  # one 1 ms control period, the torque held
        mujoco.mj_step(mj, data)
    assert abs(data.qvel[5]) > 0.5 * arm.velocity_limit[5]


def test_on_the_xarm7_the_refusal_follows_the_start() -> None:
    """The refusal is of starts, not of arms: on the 7-joint xArm (Case 2, target
    mid-range) the law 0.1 rad off on every joint fits the effort limits; 0.5 rad off it
    needs 2.1 × them (PD + g with the same gains: 1.5 ×)."""
    arm, model, law = _law("xarm7")
    near = model.state(law.target - 0.1, np.zeros(model.n))
    assert law.start_problem(near, arm.joint_names, arm.effort_limit) is None
    far = model.state(law.target - 0.5, np.zeros(model.n))
    problem = law.start_problem(far, arm.joint_names, arm.effort_limit)
    assert problem is not None
    assert "2.09 × its torque limit 50 N·m" in problem


def test_rate_bounds_multiply_the_potential_force_by_psi() -> None:
    """Case 3 (6.63) as printed: at rest τ − g = Ψ(x, 0)(∇f(x_d) − ∇f(x)) with the thesis's
    unnormalised Ψ = Π ½B_j². At half the xArm7's rate limits that is 4.3: the law is 4.3 ×
    stiffer than K_P says (and K_D is not scaled)."""
    arm, model, plain = _law("xarm7")
    _, _, rated = _law("xarm7", rates=True)
    state = model.state(plain.target - 0.1, np.zeros(model.n))
    psi = float(np.prod(0.5 * (0.5 * arm.velocity_limit) ** 2))
    assert psi == pytest.approx(4.3, abs=0.05)
    np.testing.assert_allclose(rated.evaluate_state(state).torque - state.gravity,
                               psi * (plain.evaluate_state(state).torque - state.gravity),
                               rtol=1e-10)
