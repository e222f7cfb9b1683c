"""The stopping test under bounded torque: a state it calls lost is lost whatever torque in
the box is held, and one it calls savable is saved by the torque it assumes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from cpbc.constraints import ConstraintSet, joint_position_limit
from cpbc.constraints.stopping import stopping_margins
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


def test_a_scenario_case_that_cannot_be_stopped_is_refused(tmp_path, capsys) -> None:
    """The Panda 0.1 mm short of joint 4's upper stop, approaching it at 1 rad/s (inside the
    rate bound): no torque within the URDF's 87 N·m stops that in time. The CLI says so,
    names the field and exits 2 without writing anything."""
    from cpbc.resources import scenarios_dir
    from cpbc.run import main

    text = (scenarios_dir() / "panda_cpbc_sphere.yaml").read_text()
    start = "    position: [-0.179, 0.172, -0.497, -2.085, 0.103, 2.233, 0.785]\n"
    assert start in text
    near = "    position: [-0.179, 0.172, -0.497, -0.0699, 0.103, 2.233, 0.785]\n"
    lost = text.replace(start, near + "    velocity: [0, 0, 0, 1.0, 0, 0, 0]\n")
    path = tmp_path / "lost.yaml"
    path.write_text(lost.replace("duration: 5.0", "duration: 0.01"))
    out = tmp_path / "out"
    assert main([str(path), "--out", str(out), "--quiet", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "cases[0].velocity" in err and "cannot be stopped" in err
    assert "position[panda_joint4]" in err and not out.exists()
