"""Gains in physical terms (ω_n, ζ) and the zero-order-hold stability check, against MuJoCo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from cpbc.errors import ScenarioError
from cpbc.scenario import ScenarioSetup, build, load_scenario
from cpbc.scenario.gain_check import (
    longest_stable_period,
    physical_gains,
    spectral_radius,
    unstable_loop,
    zoh_spectral_radius,
    zoh_stable,
)
from cpbc.scenario.runner import run_one

HOME = [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]


def _setup(tmp_path: Path, data: dict) -> ScenarioSetup:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return build(*load_scenario(path))


def _scenario(robot: str, controller: dict, period: float, duration: float,
              check: bool = True, integrator: str = "RK4", timestep: float = 0.001) -> dict:
    if robot == "panda":
        target = HOME
        start = [q + 0.05 for q in HOME]
    else:
        target, start = [0.5, 0.8], [0.45, 0.85]
    return {
        "name": "gains", "robot": {"model": robot},
        "simulation": {"duration": duration, "timestep": timestep, "control_period": period,
                       "safeguard": False, "check_gains": check, "integrator": integrator},
        "target": target, "cases": [{"name": "near", "position": start}],
        "controllers": [{"type": "pd_gravity", "name": "PDg", **controller}],
    }


def test_the_condition_is_the_spectral_radius(rng: np.random.Generator) -> None:
    """k_d h < 2m and k_p h < 2k_d  ⇔  both eigenvalues of the held loop inside |z| < 1."""
    checked = 0
    for _ in range(4000):
        m, h = rng.uniform(0.01, 5), rng.uniform(1e-4, 0.05)
        kp, kd = 10 ** rng.uniform(-1, 6), 10 ** rng.uniform(-2, 4)
        rho = zoh_spectral_radius(kp, kd, m, h)
        if abs(rho - 1) < 1e-6:
            continue  # on the boundary: floating point decides
        assert zoh_stable(kp, kd, m, h) == (rho < 1), (kp, kd, m, h, rho)
        checked += 1
    assert checked > 3900


def test_euler_with_one_step_per_period(rng: np.random.Generator) -> None:
    """δ = h: stable iff k_p h²/m + 2 k_d h/m < 4 (module docstring)."""
    for _ in range(2000):
        m, h = rng.uniform(0.01, 5), rng.uniform(1e-4, 0.05)
        kp, kd = 10 ** rng.uniform(-1, 6), 10 ** rng.uniform(-2, 4)
        a, b = kp * h * h / m, kd * h / m
        rho = zoh_spectral_radius(kp, kd, m, h, euler_step=h)
        if abs(rho - 1) > 1e-6:
            assert (a + 2 * b < 4) == (rho < 1), (a, b, rho)


def test_physical_gains_scale_with_the_inertia_at_the_target(tmp_path: Path) -> None:
    data = _scenario("planar_2link", {"omega_n": [3.0, 5.0], "zeta": 0.7}, 0.001, 0.01)
    setup = _setup(tmp_path, data)
    d = np.diag(setup.model.inertia(setup.target))
    law = setup.controllers[0].controller
    np.testing.assert_allclose(law.kp, d * [9.0, 25.0])
    np.testing.assert_allclose(law.kd, 2 * 0.7 * np.array([3.0, 5.0]) * d)
    assert physical_gains(np.array([2.0]), np.array([1.0]), np.array([0.5]))[1] == 2.0


def test_bpbc_physical_gains_account_for_xi_and_gamma(tmp_path: Path) -> None:
    data = _scenario("planar_2link", {}, 0.001, 0.01)
    data["constraints"] = [{"type": "joint_rate_limit", "bounds": [1, 1]}]
    data["controllers"] = [{"type": "bpbc", "omega_n": 2.0, "zeta": 1.0, "xi": 4, "gamma": 2}]
    setup = _setup(tmp_path, data)
    d = np.diag(setup.model.inertia(setup.target))
    law = setup.controllers[0].controller
    np.testing.assert_allclose(law.kp * 4, d * 4.0)  # slope K_P ξ = D_ii ω²
    np.testing.assert_allclose(law.kd * 2, d * 4.0)  # slope K_D γ = 2 ζ ω D_ii


def _grew(setup: ScenarioSetup) -> tuple[str, float, float]:
    """Status, initial error and the largest error over the last quarter of a MuJoCo run."""
    r = run_one(setup, setup.cases[0], setup.controllers[0], "mujoco")
    traj = r.trajectory
    err = np.max(np.abs(traj.position - setup.target), axis=1)
    tail = err[len(err) * 3 // 4:]
    return r.summary.status, float(err[0]), float(np.max(tail)) if tail.size else np.inf


# (robot, gains, control period): the check's verdict is asserted, then MuJoCo's
CASES = [
    ("planar_2link", {"omega_n": 50, "zeta": 0.25}, 0.01, True),
    ("planar_2link", {"omega_n": 20, "zeta": 0.7}, 0.01, True),
    ("planar_2link", {"omega_n": 50, "zeta": 0.7}, 0.01, False),  # coupled: λ ζ ω h > 1
    ("planar_2link", {"omega_n": 50, "zeta": 0.08}, 0.01, False),  # ω h = 0.5 > 4ζ
    ("planar_2link", {"omega_n": 50, "zeta": 3.0}, 0.01, False),  # ζ ω h = 1.5 > 1
    ("planar_2link", {"kp": 20000, "kd": 20}, 0.005, False),  # K_P h = 100 > 2 K_D
    ("panda", {"omega_n": 40, "zeta": 0.8}, 0.001, True),
    ("panda", {"omega_n": 40, "zeta": 0.8}, 0.005, False),  # coupled: λ up to 12 here
    ("panda", {"omega_n": 40, "zeta": 0.04}, 0.005, False),
    ("panda", {"omega_n": 40, "zeta": 6.0}, 0.005, False),
]


# (integrator, control period = timestep): the same gains, exact under RK4, not under Euler
INTEGRATORS = [("RK4", True), ("Euler", False)]


@pytest.mark.parametrize(("integrator", "stable"), INTEGRATORS)
def test_the_check_knows_the_integrator(tmp_path: Path, integrator: str, stable: bool) -> None:
    gains = {"omega_n": 40, "zeta": 0.7}  # ρ = 0.85 (RK4), 1.13 (Euler) at h = δ = 10 ms
    data = _scenario("planar_2link", gains, 0.01, 1.0, integrator=integrator, timestep=0.01)
    _the_check_predicts_what_mujoco_does(tmp_path, data, stable)


@pytest.mark.parametrize(("robot", "gains", "period", "stable"), CASES,
                         ids=[f"{c[0]}-{'-'.join(map(str, c[1].values()))}-{c[2]}" for c in CASES])
def test_the_check_predicts_what_mujoco_does(
    tmp_path: Path, robot: str, gains: dict, period: float, stable: bool
) -> None:
    _the_check_predicts_what_mujoco_does(tmp_path, _scenario(robot, gains, period, 1.0), stable)


def _the_check_predicts_what_mujoco_does(tmp_path: Path, data: dict, stable: bool) -> None:
    if stable:
        setup = _setup(tmp_path, data)  # accepted
        status, first, last = _grew(setup)
        assert status != "diverged" and last < 0.2 * first, (status, first, last)
        return
    with pytest.raises(ScenarioError, match="zero-order hold") as info:
        _setup(tmp_path, data)
    assert info.value.field == "controllers[0]"
    assert "coordinate '" in str(info.value) and "control_period" in str(info.value)
    data["simulation"]["check_gains"] = False
    setup = _setup(tmp_path, data)
    status, first, last = _grew(setup)
    assert status == "diverged" or last > first, (status, first, last)


def test_the_report_names_the_coordinate_and_the_period_that_works() -> None:
    inertia = np.diag([1.0, 1.0])
    bad = unstable_loop(np.array([10.0, 10.0]), np.array([1.0, 500.0]), [inertia], 0.01,
                        ["shoulder", "elbow"])
    assert bad is not None and bad.name == "elbow"
    assert "lower kd below 200" in bad.advice()
    assert bad.longest_period == pytest.approx(2 / 500, rel=1e-6)  # K_D h < 2m
    assert unstable_loop(np.array([10.0, 10.0]), np.array([1.0, 5.0]), [inertia], 0.01,
                         ["a", "b"]) is None


def test_coupling_tightens_the_damping_limit() -> None:
    """On the planar arm (q2 = 0.8) gains stable for each joint alone are not for the arm."""
    d = np.array([[3.5 + np.cos(0.8), 1.25 + 0.5 * np.cos(0.8)],
                  [1.25 + 0.5 * np.cos(0.8), 1.25]])
    kp, kd = physical_gains(np.full(2, 50.0), np.full(2, 0.7), np.diag(d))
    assert all(zoh_stable(kp[i], kd[i], d[i, i], 0.01) for i in range(2))
    assert spectral_radius(kp, kd, d, 0.01) > 1
    h = longest_stable_period(kp, kd, d, 0.01)
    assert spectral_radius(kp, kd, d, 0.99 * h) < 1 < spectral_radius(kp, kd, d, 1.01 * h)


def test_a_coupled_mode_is_reported_with_the_damping_that_is_stable() -> None:
    d = np.array([[3.5 + np.cos(0.8), 1.25 + 0.5 * np.cos(0.8)],
                  [1.25 + 0.5 * np.cos(0.8), 1.25]])
    kp, kd = physical_gains(np.full(2, 50.0), np.full(2, 0.7), np.diag(d))
    bad = unstable_loop(kp, kd, [d], 0.01, ["shoulder", "elbow"])
    assert bad is not None and bad.stable_kd is not None
    assert f"lower kd of '{bad.name}' below {bad.stable_kd:.4g}" in bad.advice()
    lowered = kd.copy()
    lowered[bad.index] = 0.99 * bad.stable_kd
    assert spectral_radius(kp, lowered, d, 0.01) < 1
    lowered[bad.index] = 1.01 * bad.stable_kd
    assert spectral_radius(kp, lowered, d, 0.01) > 1


def _named_value(message: str, name: str) -> float:
    """The value the refusal names for ``name`` ("lower NAME[ (default v)] to X or less")."""
    tail = message.split(f"lower {name}", 1)[1]
    return float(tail.split(" to ", 1)[1].split(" or less", 1)[0])


def test_gains_written_as_omega_n_are_answered_in_omega_n(tmp_path: Path) -> None:
    """The Panda with omega_n = 40 at 5 ms: the refusal names the omega_n to lower to, not a
    K_D; the loop is stable just below that value and refused just above it."""
    data = _scenario("panda", {"omega_n": 40, "zeta": 0.8}, 0.005, 1.0)
    with pytest.raises(ScenarioError) as info:
        _setup(tmp_path, data)
    message = str(info.value)
    assert "lower kd" not in message and "lower omega_n to " in message, message
    edge = _named_value(message, "omega_n")
    assert 1.0 < edge < 40.0
    data["controllers"][0]["omega_n"] = 0.999 * edge
    _setup(tmp_path, data)  # accepted
    data["controllers"][0]["omega_n"] = 1.01 * edge
    with pytest.raises(ScenarioError, match="zero-order hold"):
        _setup(tmp_path, data)


def test_task_gains_are_answered_in_the_frequency_that_helps(tmp_path: Path) -> None:
    """panda_goal_pose's task-space CPBC with task: {omega_n: 6} at 100 Hz: the unstable mode
    is the joint damping of the posture spring the entry left at its default, so the
    refusal names posture.omega_n (and its default), and the value it names is the edge."""
    from cpbc.resources import scenarios_dir

    data = yaml.safe_load((scenarios_dir() / "panda_goal_pose.yaml").read_text())
    data["simulation"].update(control_period=0.01, duration=0.1)
    data["controllers"] = [{"type": "cpbc", "name": "TS-CPBC", "task": {"omega_n": 6},
                            "shaping": {"type": "power", "alpha": 0.2}}]
    with pytest.raises(ScenarioError) as info:
        _setup(tmp_path, data)
    message = str(info.value)
    assert "lower kd" not in message and "lower posture.omega_n (default 2) to" in message
    edge = _named_value(message, "posture.omega_n (default 2)")
    data["controllers"][0]["posture"] = {"omega_n": 0.995 * edge}
    _setup(tmp_path, data)  # accepted
    data["controllers"][0]["posture"] = {"omega_n": 1.01 * edge}
    with pytest.raises(ScenarioError, match="zero-order hold"):
        _setup(tmp_path, data)
