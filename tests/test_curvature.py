"""ẋᵀ∇²φ ẋ of the configuration constraints against second differences of φ along a straight
line x + tẋ (where ẍ = 0, so d²φ/dt² is the curvature alone), per sphere pair included."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.constraints.clearance import Clearance
from cpbc.constraints.point_outside_sphere import PointOutsideSphere
from cpbc.scenario import build, load_scenario


def _second_difference(values, x, dx, step=1e-4):
    return (values(x + step * dx) - 2 * values(x) + values(x - step * dx)) / step**2


@pytest.fixture(scope="module")
def panda():
    return build(*load_scenario("panda_cbf_qp"))


def _clearance(setup) -> Clearance:
    return next(c for c in setup.monitor.configuration if isinstance(c, Clearance))


def test_sphere_pairs_curvature_matches_second_differences(panda):
    c = _clearance(panda)
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(6):
        x = panda.model.joint_coordinates(rng.uniform(-1.0, 1.0, 7)) + np.array(
            [0, 0, 0, -2.0, 0, 2.0, 0])
        dx = rng.uniform(-1.5, 1.5, 7)
        _, grad, curv, moving = c.sphere_pairs(x, dx)
        fd = _second_difference(lambda z, v=dx: c.sphere_pairs(z, v)[0], x, dx)
        ahead, behind = c.sphere_pairs(x + 1e-6 * dx, dx)[0], c.sphere_pairs(x - 1e-6 * dx, dx)[0]
        slope = (ahead - behind) / 2e-6
        np.testing.assert_allclose(grad @ dx, slope, atol=1e-6)
        assert np.all(np.abs(curv - fd) <= 2e-4 * (1 + np.abs(fd))), np.max(np.abs(curv - fd))
        checked += int(np.sum(np.abs(curv) > 1e-3))
        assert moving.any()
    assert checked > 50  # the curvature is not trivially zero


def test_reported_clearance_curvature_is_the_closest_pairs(panda):
    c = _clearance(panda)
    x = np.array([0.1, 0.4, -0.2, -1.8, 0.3, 2.0, 0.5])
    dx = np.array([0.5, -0.4, 0.3, 0.6, -0.8, 0.2, 1.0])
    fd = _second_difference(c.value, x, dx, step=1e-5)
    assert np.all(np.abs(c.curvature(x, dx) - fd) <= 5e-3 * (1 + np.abs(fd)))


def test_point_outside_sphere_curvature(tmp_path):
    from tests.test_cbf_qp import ARM, _setup

    setup = _setup(ARM, tmp_path)
    c = next(k for k in setup.monitor.configuration if isinstance(k, PointOutsideSphere))
    for x, dx in (([0.3, -0.2], [1.0, -0.5]), ([1.1, 1.7], [-0.3, 0.8])):
        x, dx = np.array(x), np.array(dx)
        np.testing.assert_allclose(c.curvature(x, dx), _second_difference(c.value, x, dx),
                                   rtol=1e-5, atol=1e-6)


def test_panda_peer_keeps_one_row_per_near_sphere_pair(panda):
    from cpbc.peers import CBFQP

    law = next(e.controller for e in panda.controllers if isinstance(e.controller, CBFQP))
    c = _clearance(panda)
    from cpbc.reliability.verification import draw_state

    x = draw_state(panda, 2).position  # near the table
    dx = np.array([0.05, -0.04, 0.03, 0.06, -0.08, 0.02, 0.1])
    phi, _, _, moving = c.sphere_pairs(x, dx)
    near = int(np.sum(moving & (phi < c.influence)))
    a, lower, upper = law.rows(law.state(x, dx))
    assert near > 0 and len(a) == 7 + near + 7  # joint limits, sphere pairs, rate bounds
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0)
    tau = law.evaluate_state(law.state(x, dx)).torque
    assert np.all(a @ tau >= lower - 1e-7) and np.all(a @ tau <= upper + 1e-7)
    assert np.all(np.abs(tau) <= law.torque_limit + 1e-9)


def test_sphere_pairs_at_the_state_match_finite_differences(panda):
    """The per-pair rows the CBF-QP peer reads (``sphere_pairs_at``, the compiled kernel on
    the state's joint placements and Jacobians): φ_p against the clearance evaluated on its
    own, ∇φ_p against central differences of φ_p, and κ_p against central differences of
    ∇φ_p·ẋ along ẋ, at random Panda states near the table; and equal to the same kernel on a
    Pinocchio pass of the clearance's own (``sphere_pairs``) to 1e-12."""
    from cpbc.peers import CBFQP
    from cpbc.reliability.verification import draw_state

    law = next(e.controller for e in panda.controllers if isinstance(e.controller, CBFQP))
    c = _clearance(panda)
    rng = np.random.default_rng(4)
    h = 1e-6
    near = 0
    for seed in range(12):
        x = draw_state(panda, seed).position
        dx = rng.uniform(-1.0, 1.0, 7)
        phi, grad, curv, moving = c.sphere_pairs_at(law.state(x, dx))
        own = c.sphere_pairs(x, dx)
        for found, expect in zip((phi, grad, curv), own[:3], strict=True):
            np.testing.assert_allclose(found, expect, rtol=1e-12, atol=1e-12)
        assert np.array_equal(moving, own[3])
        outside = c.sphere_pairs(x, np.zeros(7))[0]
        np.testing.assert_allclose(phi, outside, rtol=0, atol=1e-15)
        step = np.eye(7) * h
        fd_grad = np.column_stack([(c.sphere_pairs(x + e, dx)[0] - c.sphere_pairs(x - e, dx)[0])
                                   / (2 * h) for e in step])
        smooth = np.all(np.abs(fd_grad - grad) < 1e-5, axis=1)  # away from region seams
        assert smooth.mean() > 0.95
        np.testing.assert_allclose(grad[smooth], fd_grad[smooth], atol=1e-7)
        ahead = c.sphere_pairs(x + h * dx, dx)[1] @ dx
        behind = c.sphere_pairs(x - h * dx, dx)[1] @ dx
        fd_curv = (ahead - behind) / (2 * h)
        np.testing.assert_allclose(curv[smooth], fd_curv[smooth],
                                   atol=1e-6 * (1 + np.abs(fd_curv[smooth]).max()))
        near += int(np.sum(moving & (phi < c.influence)))
    assert near > 20  # pairs the peer keeps as rows were among those checked


def test_peer_rows_read_the_state_only(panda, monkeypatch):
    """The CBF-QP peer's rows take no Pinocchio pass of their own: every Pinocchio function
    the constraints call counts zero calls while the rows are built from a state."""
    import pinocchio as pin

    from cpbc.peers import CBFQP
    from cpbc.reliability.verification import draw_state

    law = next(e.controller for e in panda.controllers if isinstance(e.controller, CBFQP))
    x = draw_state(panda, 2).position
    dx = np.array([0.05, -0.04, 0.03, 0.06, -0.08, 0.02, 0.1])
    state = law.state(x, dx)
    calls: list[str] = []
    for name in ("computeStaticRegressor", "computeJointJacobians", "forwardKinematics",
                 "computeJointJacobiansTimeVariation", "computeAllTerms", "crba",
                 "updateFramePlacements", "rnea", "nonLinearEffects",
                 "computeGeneralizedGravity", "computeCoriolisMatrix"):
        real = getattr(pin, name)
        monkeypatch.setattr(pin, name, lambda *a, _f=real, _n=name: calls.append(_n) or _f(*a))
    a, _, _ = law.rows(state)
    assert calls == []
    c = _clearance(panda)
    c.sphere_pairs(x, dx)  # the spy sees a pass of the clearance's own
    assert "computeJointJacobians" in calls
    phi = c.sphere_pairs(x, dx)[0]
    assert len(a) > 14 and np.sum(phi < c.influence) > 0  # sphere rows among them
