"""The CBF-QP peer's operational-space nominal (``cbf_qp`` with ``nominal: osc``,
cpbc.peers.osc): it decouples the task, it reaches a Panda goal on its own, the peer runs the
shipped task-space scenarios beside TS-CPBC, and a wrong ``nominal`` exits 2 naming it."""

from __future__ import annotations

import copy
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from cpbc.peers import CBFQP
from cpbc.reference import tracking
from cpbc.resources import scenarios_dir
from cpbc.results.task_metrics import reach_time, task_errors
from cpbc.run import main
from cpbc.scenario import Scenario, build
from cpbc.scenario.runner import run_one
from cpbc.simulation.loop import run_mujoco


def _shipped(name: str) -> dict[str, Any]:
    return yaml.safe_load((scenarios_dir() / f"{name}.yaml").read_text())


def _with_peer(spec: dict[str, Any], **extra: Any) -> dict[str, Any]:
    """The scenario with the peer beside its TS-CPBC, on the same task and posture gains."""
    d = copy.deepcopy(spec)
    law = next(c for c in d["controllers"] if c["type"].startswith("cpbc"))
    d["controllers"].append({"type": "cbf_qp", "name": "CBF-QP-OSC", "nominal": "osc",
                             "task": law["task"], "posture": law["posture"], **extra})
    return d


def _build(spec: dict[str, Any], tmp_path: Path):
    return build(Scenario.model_validate(spec), tmp_path / "s.yaml")


def _open_panda() -> dict[str, Any]:
    """panda_goal_pose without the ball and the table: the straight way is free."""
    d = _shipped("panda_goal_pose")
    d["obstacles"] = []
    d["constraints"] = [c for c in d["constraints"] if c["type"] != "clearance"]
    return d


@pytest.mark.parametrize("offset", [None, [0.0, 0.0, 0.105]])
def test_the_nominal_decouples_the_task_from_the_null_space(tmp_path, offset) -> None:
    """J ẍ + J̇ẋ = a_task with ẍ = D⁻¹ (τ_nom − C ẋ − g): the posture term, projected by Nᵀ,
    moves no task coordinate, and the J̇ẋ term (here by central differences of J along ẋ)
    is cancelled (checked at random moving states, rows of the axis goal: 3 + 2; with and
    without a TCP offset). Without J̇ẋ the task's acceleration was off by it: 0.27–2.3 (m/s²
    or rad/s², largest row) at these states."""
    d = _with_peer(_open_panda(), constraints=[])
    if offset is not None:
        d["goal"]["offset"] = offset
    setup = _build(d, tmp_path)
    peer = setup.controllers[-1].controller
    assert isinstance(peer, CBFQP) and peer.osc is not None
    rng = np.random.default_rng(4)
    for _ in range(5):
        x, dx = setup.target + rng.uniform(-0.3, 0.3, 7), rng.uniform(-1.0, 1.0, 7)
        state = peer.state(x, dx)
        j, _, accel = peer.osc._task(state)
        h = 1e-6
        drift = (peer.osc._task(peer.state(x + h * dx, dx))[0]
                 - peer.osc._task(peer.state(x - h * dx, dx))[0]) @ dx / (2 * h)
        np.testing.assert_allclose(peer.osc.drift(state), drift, atol=1e-6)
        tau = peer.osc.torque(state)
        moved = j @ np.linalg.solve(state.inertia, tau - state.coriolis_force - state.gravity)
        # up to the Tikhonov floor (1e-9 of the trace) in the inversion of Λ
        np.testing.assert_allclose(moved + drift, accel, atol=1e-6 * np.abs(accel).max())


def test_a_streamed_target_moves_the_peer_s_goal(tmp_path) -> None:
    # cpbc.reference's streamed target (set_target each step, teleoperation or a policy):
    # the tracker started the stream at a spring law's goal and refused a law without one,
    # the peer ("the law has no frame position spring to stream a target to").
    d = _with_peer(_open_panda(), constraints=[])
    d["controllers"] = d["controllers"][-1:]
    setup = _build(d, tmp_path)
    entry, goal = setup.controllers[0], setup.goal
    assert goal is not None
    law = tracking(entry.controller, 1e-3, run=setup.controller(entry))
    moved = goal.goal.position + np.array([0.0, 0.05, -0.03])
    law.set_target(moved)
    traj = run_mujoco(setup.make_plant(), law, setup.model.coordinates, goal.posture,
                      np.zeros(7), replace(setup.loop_settings, duration=2.5))
    peer = entry.controller
    assert isinstance(peer, CBFQP) and peer.osc is not None
    np.testing.assert_allclose(peer.osc.target.position, moved)
    errors = task_errors(setup.model, replace(goal.goal, position=moved), traj.position)
    assert errors[0, 0] > 0.05 and errors[-1, 0] < 1e-3, errors[[0, -1]]


def test_the_osc_nominal_alone_reaches_a_panda_goal(tmp_path) -> None:
    d = _with_peer(_open_panda(), constraints=[])  # no rows: the nominal and the torque box
    d["controllers"] = d["controllers"][-1:]
    d["simulation"]["duration"] = 5.0  # the null space comes to rest after the task
    setup = _build(d, tmp_path)
    s = run_one(setup, setup.cases[0], setup.controllers[0], "mujoco").summary
    assert s.status == "reached", s.status
    assert s.task_error_final is not None and s.reach_time is not None
    assert s.task_error_final["position"] <= 1e-3 and s.task_error_final["angle"] <= 0.01
    assert s.reach_time < 2.5


@pytest.mark.parametrize(("name", "duration"), [
    ("panda_goal_pose", 1.5), ("ur5_circle", 1.0), ("panda_pick_place_window", 1.0)])
def test_the_peer_runs_the_shipped_task_space_scenarios(tmp_path, name, duration) -> None:
    d = _with_peer(_shipped(name))
    d["simulation"]["duration"] = duration
    setup = _build(d, tmp_path)
    entry = setup.controllers[-1]
    run = run_one(setup, setup.cases[0], entry, "mujoco")
    s = run.summary
    assert not s.crossed_constraints and s.status != "constraint_violated", s.status
    assert all(m > 0 for m in s.min_margins.values())
    errors = s.task_error_max
    assert errors is not None and np.isfinite(errors["position"])
    if name != "panda_goal_pose":  # a reference: the governor moved the applied point
        assert run.reference is not None and run.reference["path_time"][-1] > 0.5


def _exit(tmp_path: Path, spec: dict[str, Any], capsys) -> str:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(spec))
    assert main([str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert not (tmp_path / "out").exists()
    return capsys.readouterr().err


@pytest.mark.parametrize(("edit", "word"), [
    (lambda d: d["controllers"][-1].update(nominal="khatib"), "nominal"),
    (lambda d: d["controllers"][-1].update(nominal="pd_gravity"), "nominal: osc"),
])
def test_a_wrong_nominal_exits_2_naming_the_field(tmp_path, capsys, edit, word) -> None:
    d = _with_peer(_shipped("panda_goal_pose"))
    edit(d)
    err = _exit(tmp_path, d, capsys)
    assert "controllers[2].nominal" in err and word in err


def test_osc_without_a_goal_exits_2_naming_the_nominal(tmp_path, capsys) -> None:
    d = yaml.safe_load((scenarios_dir() / "panda_cbf_qp.yaml").read_text())
    d["controllers"][-1]["nominal"] = "osc"
    err = _exit(tmp_path, d, capsys)
    assert "controllers[2].nominal" in err and "goal:" in err


UR5_GOAL: dict[str, Any] = {
    "frame": "tool0", "position": [0.45, 0.30, 0.28],
    "orientation": {"axis": {"tool": [0, 0, 1], "world": [0, 0, -1]}},
    "tolerance": {"position": 0.001, "angle": 0.01}}


def test_reach_time_within_1_2x_joint_cpbc_on_the_ik_posture(tmp_path) -> None:
    """The issue's target on a UR5 goal (scripts/reach_ratio.py measures more): the hand
    within 1 mm / 0.01 rad for good, TS-CPBC against joint CPBC whose target is the IK
    posture at the task's ω_n, ζ (same constraints, shaping, torque box and safeguard).
    Before the task gains counted the held rotation's inertia and the posture terms'
    task-space images it was 1.37×."""
    base = _shipped("ur5_circle")
    d = {k: base[k] for k in ("robot", "simulation", "cases", "obstacles", "constraints")}
    d["simulation"]["duration"] = 2.0
    law = {"type": "cpbc", "name": "TS-CPBC", "shaping": {"type": "power", "alpha": 0.2},
           "constraints": ["joint_limits", "joint_rates"]}
    task = _build({**d, "name": "g", "goal": UR5_GOAL, "controllers": [
        {**law, "task": {"omega_n": 12, "zeta": 1, "rotation_omega_n": 24},
         "posture": {"omega_n": 2, "zeta": 1}}]}, tmp_path)
    assert task.goal is not None
    joint = _build({**d, "name": "j", "target": task.goal.posture.tolist(), "controllers": [
        {**law, "name": "CPBC", "omega_n": 12, "zeta": 1}]}, tmp_path)
    times = []
    for setup in (task, joint):
        traj = run_one(setup, setup.cases[0], setup.controllers[0], "mujoco").trajectory
        errors = task_errors(task.model, task.goal.goal, traj.position)
        times.append(reach_time(traj.time, np.all(errors <= [1e-3, 0.01], axis=1)))
    assert times[0] is not None and times[1] is not None, times
    assert times[0] <= 1.2 * times[1], times
