"""The CBF-QP peer (cpbc.peers.cbf_qp): its rows are the constraints' own, it keeps the torque
box, it runs beside the laws from a scenario, and bad input or a missing solver exits 2."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from cpbc.errors import ScenarioError
from cpbc.peers import CBFQP
from cpbc.run import main
from cpbc.scenario import Scenario, build

ARM: dict = {
    "name": "peer",
    "robot": {"model": "planar_2link", "coordinates": "absolute"},
    "simulation": {"duration": 2.0, "timestep": 0.001, "torque_limit": 3.0},
    "target": [1.0, 1.5],
    "cases": [{"name": "rest", "position": [0, 0]}],
    "constraints": [
        {"type": "point_outside_sphere", "name": "obstacle", "frame": "end_point",
         "centre": [0, 2], "radius": 0.5},
        {"type": "linear_limit", "name": "relative_angle", "coefficients": [[-1, 1]],
         "lower": ["-17*pi/18"], "upper": ["17*pi/18"]},
        {"type": "joint_rate_limit", "name": "link_rates", "bounds": [0.3, 0.2]},
    ],
    "controllers": [
        {"type": "cpbc", "name": "CPBC", "kp": 4, "kd": 20},
        {"type": "cbf_qp", "name": "QP", "kp": 4, "kd": 20, "gain": 10},
    ],
}


def _setup(spec: dict, tmp_path: Path):
    return build(Scenario.model_validate(spec), tmp_path / "s.yaml")


def _peer(setup) -> CBFQP:
    law = setup.controllers[1].controller
    assert isinstance(law, CBFQP)
    return law


def test_filter_meets_its_rows_and_box_and_passes_a_safe_nominal(tmp_path):
    setup = _setup(ARM, tmp_path)
    law = _peer(setup)
    rng = np.random.default_rng(3)
    changed = 0
    for _ in range(40):
        x = rng.uniform([-0.5, -0.5], [0.5, 0.5])
        dx = rng.uniform(-0.29, 0.29, 2) * np.array([1, 0.6])
        state = law.state(x, dx)
        tau = law.evaluate_state(state).torque
        a, lower, upper = law.rows(state)
        assert law.infeasible == 0
        assert np.all(a @ tau >= lower - 1e-7) and np.all(a @ tau <= upper + 1e-7)
        # the box is on the joint torques Tᵀτ (absolute link angles: T is not the identity)
        assert np.all(np.abs(setup.model.coordinates.matrix.T @ tau) <= 3.0 + 1e-7)
        nominal = law.nominal(state)
        nominal_ok = np.all(a @ nominal >= lower) and np.all(a @ nominal <= upper) and np.all(
            np.abs(setup.model.coordinates.matrix.T @ nominal) <= 3.0)
        if nominal_ok:  # a nominal that meets every row is passed through unchanged
            np.testing.assert_allclose(tau, nominal, atol=1e-8)
        else:
            changed += 1
    assert law.acted == changed > 0
    assert law.row_active_steps <= law.acted


def test_a_clip_to_the_box_alone_is_not_counted_as_the_rows_acting(tmp_path):
    """``acted`` counts every step whose torque differs from the PD nominal; the rows count
    apart only the steps at which the solution differs from the nominal clipped to the box."""
    spec = copy.deepcopy(ARM)
    spec["robot"]["coordinates"] = "joint"  # T = I: the box-only answer is a clip
    spec["constraints"] = [{"type": "joint_rate_limit", "name": "rates", "bounds": [5, 5]}]
    law = _peer(_setup(spec, tmp_path))
    far = law.state(np.array([-2.0, -2.0]), np.zeros(2))  # a large error: PD beyond the box
    tau = law.evaluate_state(far).torque
    assert np.max(np.abs(law.nominal(far))) > 3.0
    np.testing.assert_allclose(tau, np.clip(law.nominal(far), -3, 3), atol=1e-6)
    assert law.acted == 1 and law.row_active_steps == 0
    spec["constraints"][0]["bounds"] = [0.3, 0.2]
    law = _peer(_setup(spec, tmp_path))
    law.evaluate_state(law.state(np.array([0.0, 0.0]), np.array([0.0, 0.199])))
    assert law.acted == law.row_active_steps == 1  # near a rate bound, accelerated on: the row


def test_rate_rows_are_the_constraint_objects_bounds(tmp_path):
    law = _peer(_setup(ARM, tmp_path))
    x, dx = np.zeros(2), np.array([0.3 - 1e-3, 0.0])  # at its rate bound, heading out
    state = law.state(x, dx)
    tau = law.evaluate_state(state).torque
    acc = np.linalg.solve(state.inertia, tau - state.coriolis_force - state.gravity
                          - state.dissipation)
    # first order: d/dt (B − ẋ) ≥ −γ (B − ẋ), γ = 1/(2h)
    assert acc[0] <= law.rate_gain * 1e-3 + 1e-9
    assert law.rate_gain == pytest.approx(0.5 / 1e-3)


def test_scenario_runs_both_side_by_side(tmp_path):
    spec = copy.deepcopy(ARM)
    spec["simulation"]["duration"] = 0.3
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(spec))
    out = tmp_path / "out"
    assert main([str(path), "--out", str(out), "--quiet", "--no-plots"]) == 0
    import json
    runs = {r["controller"]: r for r in json.loads((out / "summary.json").read_text())}
    assert set(runs) == {"CPBC", "QP"}
    assert runs["QP"]["status"] != "constraint_violated"
    assert runs["QP"]["min_margins"]["rate[theta2]"] > 0


@pytest.mark.parametrize(("key", "value", "field"), [
    ("gain", -1, "controllers.1.cbf_qp.gain"),
    ("rate_gain", 0, "controllers.1.cbf_qp.rate_gain"),
    ("braking_share", 1.5, "controllers.1.cbf_qp.braking_share"),
    ("variant", "linear", "controllers.1.cbf_qp.variant"),
    ("constraints", ["nope"], "controllers[1].constraints"),
])
def test_bad_parameters_name_their_field(tmp_path, key, value, field):
    spec = copy.deepcopy(ARM)
    spec["controllers"][1][key] = value
    with pytest.raises((ScenarioError, ValueError)) as err:
        _setup(spec, tmp_path)
    assert field.split(".")[-1] in str(err.value)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(spec))
    assert main([str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert not (tmp_path / "o").exists()


def test_missing_solver_is_exit_2_naming_the_extra(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(ARM))
    code = ("import sys; sys.modules['daqp'] = None\n"  # as if cpbc[peers] were not installed
            "from cpbc.run import main\n"
            f"sys.exit(main([{str(path)!r}, '--out', {str(tmp_path / 'o')!r}, '--quiet']))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 2
    assert "cpbc[peers]" in done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "o").exists()


def test_the_library_never_imports_a_qp_solver():
    code = ("import sys, cpbc.run, cpbc.scenario, cpbc.controllers, cpbc.reliability.campaign\n"
            "assert 'daqp' not in sys.modules and 'quadprog' not in sys.modules")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def _closing_on_the_limit(tmp_path, variant: str):
    spec = copy.deepcopy(ARM)
    spec["simulation"]["torque_limit"] = 0.01  # no room to stop in
    spec["controllers"][1]["variant"] = variant
    law = _peer(_setup(spec, tmp_path))
    rel = 17 * np.pi / 18 - 0.01  # near the relative-angle limit, closing on it
    state = law.state(np.array([0.0, rel]), np.array([-0.1, 0.15]))
    return law, state, law.evaluate_state(state).torque


def test_exponential_variant_answers_an_infeasible_step_without_the_box(tmp_path):
    law, state, tau = _closing_on_the_limit(tmp_path, "exponential")
    assert law.infeasible == 1 and law.acted == 1
    a, lower, upper = law.rows(state)
    assert np.all(a @ tau >= lower - 1e-7) and np.all(a @ tau <= upper + 1e-7)
    assert np.max(np.abs(law.model.coordinates.matrix.T @ tau)) > 0.01  # the actuators clip it


def test_braking_variant_keeps_the_box_hard_and_counts_the_slack_step(tmp_path):
    law, _, tau = _closing_on_the_limit(tmp_path, "braking")
    assert law.infeasible == 1 and law.acted == 1
    joint = np.abs(law.model.coordinates.matrix.T @ tau)
    assert np.max(joint) <= 0.01 + 1e-9
    assert np.max(joint) > 0.01 * (1 - 1e-6)  # it brakes as hard as the box lets it


def test_cushion_and_rate_gain_follow_the_period(tmp_path):
    law = _peer(_setup(ARM, tmp_path))
    assert law.tuning.rate_cushion == pytest.approx(2e-3)
    slow = law.at_period(1e-2)
    assert slow.rate_gain == pytest.approx(50.0)
    assert 0.08 < slow.tuning.rate_cushion < 0.12


def _settle(tmp_path: Path, spec: dict, name: str) -> dict[str, dict]:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    out = tmp_path / name
    assert main([str(path), "--out", str(out), "--quiet", "--no-plots"]) == 0
    import json
    return {r["controller"]: r for r in json.loads((out / "summary.json").read_text())}


def test_shipped_panda_reach_both_ways_settles_within_a_tenth_of_the_qp(tmp_path):
    """The claim is the family's (scripts/settle_family.py, docs/reliability.md): over 40
    reaches around panda_cbf_qp's the guarded CPBC with α = 0.01 settles in a median 1.097× the
    CBF-QP's time (quartiles 1.085–1.113, range 1.028–1.152), not within 1.1× on every reach.
    This checks the two reaches the family
    starts from — the shipped one and its reversal — at 1.1×: measured 2.189 s against
    2.023 s (1.082×) and 2.207 s against 2.031 s (1.087×), 2026-11-25, while every
    constraint is kept. α = 0.2 takes 1.30× (its barrier's added inertia ρΠ = αL Σ Q/ψ slows
    it far from the rate bounds); it is not run here."""
    from cpbc.resources import scenarios_dir

    spec = yaml.safe_load((scenarios_dir() / "panda_cbf_qp.yaml").read_text())
    spec["controllers"] = [c for c in spec["controllers"] if c["name"] != "CPBC"]
    back = copy.deepcopy(spec)
    back["target"], back["cases"][0]["position"] = spec["cases"][0]["position"], spec["target"]
    for name, s in (("shipped", spec), ("reversed", back)):
        runs = _settle(tmp_path, s, name)
        law, qp = runs["CPBC-alpha0.01"], runs["CBF-QP"]
        assert law["status"] == qp["status"] == "converged"
        assert law["settle_time"] <= 1.1 * qp["settle_time"], name
        assert min(law["min_margins"].values()) > 0 and not law["crossed_constraints"]


def test_the_peer_state_carries_what_its_point_rows_read_and_the_law_state_does_not(tmp_path):
    """The obstacle's rows read the joint Jacobians (its curvature), so the peer's per-step
    state carries them; the CPBC law beside it reads the frame only and its state has none."""
    setup = _setup(ARM, tmp_path)
    law, peer = setup.controllers[0].controller, _peer(setup)
    x, dx = np.array([0.4, 1.1]), np.array([0.2, -0.1])
    assert peer.state(x, dx).joint_jacobians is not None
    assert law.state(x, dx).joint_jacobians is None
    a, _, _ = peer.rows(peer.state(x, dx))
    assert len(a) == 4  # the obstacle, the relative angle, the two rates (two-sided rows)
