"""The potential that beats the joints' Coulomb friction (cpbc.controllers.potentials
.friction): its formula, and in MuJoCo a Panda with an FR3's rotor inertia and friction and
a heavy wrist reaching a joint goal within 5 mrad with it and stalling short without it,
every constraint kept on the plant's state."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from cpbc.controllers.potentials import Configuration, PotentialSum
from cpbc.controllers.potentials.friction import friction_compensation
from cpbc.errors import ScenarioError
from cpbc.results.summary_table import joint_dynamics_note, run_notes
from cpbc.scenario.runner import run_one

TARGET = [0.179, 0.172, 0.497, -2.085, -0.103, 2.233, 0.785]
START = [-0.179, 0.372, -0.297, -1.885, 0.103, 2.033, 0.585]
# an FR3's joints 1–4 and rotor inertia, a wrist with 1–2 N·m of dry friction
COULOMB = [1.137, 1.137, 1.137, 1.137, 2.0, 1.5, 1.0]
ARMATURE = [0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074]
REACH: dict = {
    "name": "friction_reach",
    "robot": {"model": "panda", "armature": ARMATURE,
              "friction": {"coulomb": COULOMB, "viscous": 0.21}},
    # 8 s: the wrist, whose shaped spring pulls less than its dry friction while the base
    # joints are far off, moves last and settles at 6.4 s (MuJoCo's frictionloss built up as
    # it does where the MJCF declares the armature, cpbc.model.joint_dynamics.on_mujoco)
    "simulation": {"duration": 8.0, "timestep": 0.001, "control_period": 0.001,
                   "integrator": "implicitfast", "torque_limit": "from_model",
                   "position_tolerance": 0.005},
    "target": TARGET,
    "cases": [{"name": "rest", "position": START}],
    "constraints": [
        {"type": "joint_position_limit", "name": "limits", "lower": "from_model",
         "upper": "from_model"},
        {"type": "joint_rate_limit", "name": "rates", "bounds": "from_model", "scale": 0.5},
    ],
    "controllers": [{"type": "cpbc", "name": "CPBC", "kp": [60, 60, 60, 60, 20, 20, 20],
                     "kd": [12, 12, 12, 12, 3, 3, 3],
                     "shaping": {"type": "power", "alpha": 0.2}}],
}


def test_the_term_is_a_ln_cosh_spring_bounded_by_the_coulomb_level() -> None:
    target, levels = np.array([0.3, -0.2, 0.1]), np.array([1.2, 0.0, 0.5])
    term = friction_compensation(target, levels, 0.002)
    assert term is not None
    for step in ([0.0, 0.0, 0.0], [0.001, -0.5, 0.3], [-2.0, 0.1, -0.0005]):
        x = target + np.array(step)
        value, grad = term.evaluate(Configuration(x))
        np.testing.assert_allclose(grad, levels * np.tanh((x - target) / 0.002), atol=1e-9)
        assert np.all(np.abs(grad) <= levels + 1e-9)
        assert value >= 0.0
    assert term.evaluate(Configuration(target))[0] == pytest.approx(0.0, abs=1e-15)
    assert term.gradient_bound is not None
    assert term.gradient_bound.stated == pytest.approx(1.2)
    assert friction_compensation(target, np.zeros(3)) is None


def _run(load_dict, compensate: bool):
    data = copy.deepcopy(REACH)
    data["robot"]["friction"]["compensate"] = compensate
    setup = load_dict(data)
    entry, case = setup.controllers[0], setup.cases[0]
    return setup, entry, run_one(setup, case, entry, "mujoco")


def test_a_heavy_wrist_reaches_the_goal_with_the_compensation_and_stalls_without(
        load_dict) -> None:
    """0 → 5 mrad: the bare law stalls where its spring pulls less than the dry friction
    (wrist: 20 N·m/rad against 1–2 N·m); with the compensation in the potential every joint
    ends within 5 mrad. Both keep the joint limits and rates on MuJoCo's state (the
    guarantee does not depend on the friction's level), and the summary says what was used."""
    setup, entry, with_term = _run(load_dict, True)
    assert entry.friction_compensation == pytest.approx(0.001)
    assert isinstance(getattr(entry.controller, "potential", None), PotentialSum)
    _, bare_entry, bare = _run(load_dict, False)
    assert bare_entry.friction_compensation is None
    target = np.array(TARGET)
    reached = np.abs(with_term.trajectory.position[-1] - target)
    stalled = np.abs(bare.trajectory.position[-1] - target)
    assert reached.max() <= 0.005, reached
    assert stalled.max() > 0.005, stalled
    for run in (with_term, bare):
        summary = run.summary
        assert summary.violated_constraint is None
        assert min(summary.min_margins.values()) > 0.0, summary.min_margins
        rates = np.abs(run.trajectory.velocity).max(axis=0)
        assert np.all(rates <= 0.5 * setup.model.model.velocityLimit), rates
    assert with_term.summary.status == "converged"
    assert with_term.summary.armature == ARMATURE
    assert with_term.summary.friction == {"coulomb": COULOMB, "viscous": [0.21] * 7,
                                          "smoothing": 0.05, "compensation": 0.001}
    assert bare.summary.friction is not None
    assert bare.summary.friction["compensation"] is None
    # the table's notes say what the model had
    assert ("model with Coulomb friction ≤ 2 N·m (compensated), viscous ≤ 0.21 N·m·s/rad, "
            "armature ≤ 0.195 kg·m²") in run_notes(with_term.summary)
    assert "Coulomb friction ≤ 2 N·m (not compensated)" in run_notes(bare.summary)


def test_a_model_without_friction_or_armature_adds_no_note() -> None:
    assert joint_dynamics_note({"coulomb": [0.0] * 7, "viscous": [0.0] * 7,
                                "compensation": None}, [0.0] * 7) == ""
    assert joint_dynamics_note(None, None) == ""


def test_the_held_loop_check_sees_the_term_stiffness(load_dict) -> None:
    """At the target the term is a spring of F̂_c/ε_c (2000 N·m/rad on joint 5): a wrist
    damping of 0.5 N·m·s/rad is too little for it held over 1 ms with RK4 (k h < 2 k_d
    fails), though enough for the law's own spring; the check refuses the compensated law,
    naming it. (MuJoCo's semi-implicit Euler steps, as in the reach above, tolerate it:
    a + 2b < 4 in cpbc.scenario.gain_check's terms.)"""
    data = copy.deepcopy(REACH)
    data["simulation"]["integrator"] = "RK4"
    data["controllers"][0]["kd"] = [12, 12, 12, 12, 0.5, 0.5, 0.5]
    with pytest.raises(ScenarioError) as info:
        load_dict(data)
    assert info.value.field == "controllers[0]"
    data["robot"]["friction"]["compensate"] = False
    load_dict(data)
