"""Constraint layer: values against independent formulas (the thesis's φ₁, φ₂ and Ψ of
Section 6.4 among them), gradients against finite differences, the closed-form barrier
terms against the generic base-class formula, and the admissible set S."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import state_at

from cpbc.constraints import (
    BarrierTerms,
    ConfigurationConstraint,
    ConstraintSet,
    KineticEnergyLimit,
    LinearLimit,
    PointOutsideSphere,
    RateLimit,
    VelocityConstraint,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.errors import (
    ConstraintViolation,
    CpbcError,
    InadmissibleStateError,
    ModelError,
    ParameterError,
)
from cpbc.model import RobotModel

REL = 17 * math.pi / 18  # the relative-joint limit of Section 6.4
X_OBS = np.array([0.0, 2.0, 0.0])
R_OBS = 0.5
B = np.array([0.3, 0.2])  # link rate bounds of Sections 6.4 and 7.3
OFFSET = np.array([0.3, -0.2, 0.1])
N_SAMPLES = 15


def thesis_phi1(th: np.ndarray) -> float:
    """φ₁ of Section 6.4: the end point outside the circle of radius 0.5 at (0, 2)."""
    return (
        (math.cos(th[0]) + math.cos(th[1]) - X_OBS[0]) ** 2
        + (math.sin(th[0]) + math.sin(th[1]) - X_OBS[1]) ** 2
        - R_OBS**2
    )


def thesis_grad_phi1(th: np.ndarray) -> np.ndarray:
    ex = math.cos(th[0]) + math.cos(th[1]) - X_OBS[0]
    ey = math.sin(th[0]) + math.sin(th[1]) - X_OBS[1]
    return np.array(
        [
            2 * ex * -math.sin(th[0]) + 2 * ey * math.cos(th[0]),
            2 * ex * -math.sin(th[1]) + 2 * ey * math.cos(th[1]),
        ]
    )


def thesis_phi2(th: np.ndarray) -> float:
    """φ₂ of Section 6.4: (17π/18)² − (θ2 − θ1)²."""
    return REL**2 - (th[1] - th[0]) ** 2


def thesis_inertia(th: np.ndarray) -> np.ndarray:
    """D of eq. 6.69 (m = 1, l = 1, l_c = 0.5, I = 1)."""
    d12 = 0.5 * math.cos(th[1] - th[0])
    return np.array([[2.25, d12], [d12, 1.25]])


def states(rng: np.random.Generator, n: int = N_SAMPLES, scale: float = 0.15):
    """Admissible-looking states: angles from the thesis's range, small rates."""
    for _ in range(n):
        yield rng.uniform(-2.5, 2.5, 2), rng.uniform(-scale, scale, 2)


def obstacle(model: RobotModel, offset: np.ndarray | None = None) -> PointOutsideSphere:
    return PointOutsideSphere(model, "end_point", X_OBS, R_OBS, offset=offset, name="obstacle")


def relative_limit() -> LinearLimit:
    return LinearLimit([[-1.0, 1.0]], [-REL], [REL], ["relative_angle"])


def assert_generic_configuration_terms(c: ConfigurationConstraint, x: np.ndarray) -> None:
    """The subclass's closed-form barrier terms equal the base class's generic formula."""
    st = state_at(x, model=getattr(c, "model", None), frames=c.frames)
    phi, b, value = c.barrier_terms(st, margins=True)
    phi_ref, b_ref, _ = ConfigurationConstraint.barrier_terms(c, st)
    np.testing.assert_array_equal(value, phi)
    np.testing.assert_allclose(phi, phi_ref, rtol=1e-13, atol=0)
    np.testing.assert_allclose(b, b_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(phi, c.value(x), rtol=1e-13, atol=0)
    # and the generic formula itself is Σ ∇φ_i/φ_i
    np.testing.assert_allclose(b_ref, (c.gradient(x) / c.value(x)[:, None]).sum(axis=0))


def assert_generic_velocity_terms(c: VelocityConstraint, x, dx, dyn) -> None:
    st = state_at(x, dx) if dyn is None else dyn
    psi, pi, b = c.barrier_terms(st)
    psi_ref, pi_ref, b_ref = VelocityConstraint.barrier_terms(c, st)
    np.testing.assert_allclose(psi, psi_ref, rtol=1e-13, atol=0)
    np.testing.assert_allclose(pi, pi_ref, rtol=1e-12, atol=1e-12)
    if b is None:
        np.testing.assert_array_equal(b_ref, np.zeros_like(x))
    else:
        np.testing.assert_allclose(b, b_ref, rtol=1e-10, atol=1e-12)
    # Π = Σ Q_j/ψ_j, written out by hand
    manual = sum(q / p for q, p in zip(c.weights(x, dyn), c.value(x, dx, dyn), strict=True))
    np.testing.assert_allclose(pi, manual, rtol=1e-12, atol=1e-12)


# == LinearLimit / joint_position_limit ==========================================================
def test_linear_limit_value_is_the_product_of_the_two_margins(rng):
    rows = np.array([[1.0, 0.0], [0.5, -2.0], [-1.0, 1.0]])
    lower, upper = np.array([-1.0, -3.0, -0.5]), np.array([2.0, 1.0, 0.7])
    c = LinearLimit(rows, lower, upper, ["a", "b", "c"])
    for _ in range(N_SAMPLES):
        x = rng.uniform(-2, 2, 2)
        y = rows @ x
        centre, half = (lower + upper) / 2, (upper - lower) / 2
        np.testing.assert_allclose(c.value(x), (y - lower) * (upper - y), rtol=1e-13)
        np.testing.assert_allclose(c.value(x), half**2 - (y - centre) ** 2, atol=1e-13)
    np.testing.assert_allclose(c.centre, [0.5, -1.0, 0.1])
    np.testing.assert_allclose(c.half_width, [1.5, 2.0, 0.6])


def test_linear_limit_gradient_and_barrier_terms(rng, central_difference):
    c = LinearLimit([[1.0, 0.0], [0.5, -2.0], [-1.0, 1.0]], [-1, -3, -0.5], [2, 1, 0.7],
                    ["a", "b", "c"])
    for _ in range(N_SAMPLES):
        x = rng.uniform(-2, 2, 2)
        np.testing.assert_allclose(c.gradient(x), central_difference(c.value, x), atol=1e-8)
        phi, grad = c.evaluate(x)
        np.testing.assert_array_equal(phi, c.value(x))
        np.testing.assert_array_equal(grad, c.gradient(x))
        assert_generic_configuration_terms(c, x)


def test_thesis_relative_joint_limit_phi2(rng, central_difference):
    c = relative_limit()
    assert c.names == ("relative_angle",)
    for th, _ in states(rng):
        assert c.value(th)[0] == pytest.approx(thesis_phi2(th), rel=1e-13, abs=1e-13)
        d = th[1] - th[0]
        np.testing.assert_allclose(c.gradient(th), [[2 * d, -2 * d]], atol=1e-13)
        np.testing.assert_allclose(c.gradient(th), central_difference(c.value, th), atol=1e-8)
        assert_generic_configuration_terms(c, th)
    assert c.value(np.array([0.0, REL]))[0] == pytest.approx(0.0, abs=1e-12)
    assert c.value(np.array([-0.1, REL]))[0] < 0


def test_joint_position_limit_selects_joints_and_names_them(joint_model, rng):
    c = joint_position_limit([-0.5], [1.5], joint_model.joint_names, joints=[1])
    assert c.names == ("position[joint2]",)
    np.testing.assert_array_equal(c.rows, [[0.0, 1.0]])
    x = np.array([3.0, 0.2])  # joint 1 is out of range but not limited
    assert c.value(x)[0] == pytest.approx((0.2 + 0.5) * (1.5 - 0.2))
    both = joint_position_limit([-1.0, -2.0], [1.0, 0.5], joint_model.joint_names)
    assert both.names == ("position[joint1]", "position[joint2]")
    for _ in range(5):
        x = rng.uniform(-1, 0.5, 2)
        np.testing.assert_allclose(both.value(x), (x - [-1, -2]) * ([1, 0.5] - x))
        assert_generic_configuration_terms(both, x)


def test_barrier_terms_give_the_margins_when_asked(rng):
    c = LinearLimit([[1.0, 0.0], [-1.0, 1.0]], [-1, -2], [2, 2], ["a", "b"])
    x = rng.uniform(-0.5, 0.5, 2)
    phi, b, value = c.barrier_terms(state_at(x), margins=True)
    phi_b, b_b, _ = ConfigurationConstraint.barrier_terms(c, state_at(x))
    np.testing.assert_array_equal(phi, phi_b)
    np.testing.assert_allclose(b, b_b, rtol=1e-13)
    np.testing.assert_array_equal(value, c.value(x))


def test_linear_limit_values_along_equals_value(rng):
    c = LinearLimit([[1.0, 0.0], [-1.0, 1.0]], [-1, -2], [2, 2], ["a", "b"])
    xs = rng.uniform(-1, 1, (7, 2))
    np.testing.assert_allclose(c.values_along(xs), np.array([c.value(x) for x in xs]))


def test_linear_limit_arrays_are_read_only():
    c = relative_limit()
    for a in (c.rows, c.lower, c.upper, c.centre, c.half_width):
        with pytest.raises(ValueError):
            a[0] = 0.0


@pytest.mark.parametrize(
    ("lower", "upper", "match", "named"),
    [
        ([1.0], [1.0], "lower < upper", "upper"),
        ([2.0], [1.0], "lower < upper", "upper"),
        ([np.nan], [1.0], "finite", "lower"),
        ([-np.inf], [1.0], "finite", "lower"),
        ([0.0], [np.inf], "finite", "upper"),
        ([0.0, 0.0], [1.0, 1.0], "agree", "lower"),
        ([0.0], [1.0, 2.0], "agree", "upper"),
    ],
)
def test_linear_limit_rejects_bad_bounds(lower, upper, match, named):
    """A ValueError naming the argument at fault (ParameterError)."""
    with pytest.raises(ParameterError, match=match) as caught:
        LinearLimit([[1.0, 0.0]], lower, upper, ["a"])
    assert isinstance(caught.value, ValueError) and caught.value.parameter == named


def test_linear_limit_rejects_wrong_number_of_names():
    with pytest.raises(ParameterError, match="agree") as caught:
        LinearLimit([[1.0, 0.0], [0.0, 1.0]], [0, 0], [1, 1], ["only_one"])
    assert caught.value.parameter == "names"


@pytest.mark.parametrize("bounds", [[-1.0, 1.0], [np.nan, 1.0], [0.0, 1.0], [np.inf, 1.0], [1.0]])
def test_rate_limit_rejects_bad_bounds(bounds):
    with pytest.raises(ParameterError, match="rate limit") as caught:
        joint_rate_limit(bounds, ["a", "b"]) if len(bounds) == 2 else RateLimit(
            np.eye(2), bounds, ["a", "b"])
    assert caught.value.parameter == "bounds"


def test_a_set_refuses_a_limit_of_another_arm():
    """A limit with rows of 2 coordinates in a set of 3 (it was taken, and its margins and
    gradients were of the wrong width for the law that read them)."""
    with pytest.raises(ParameterError, match="rows of 2 coordinates; the set's arm has 3"):
        ConstraintSet(3, [joint_position_limit([0.0, 0.0], [1.0, 1.0], ["a", "b"])])
    with pytest.raises(ParameterError, match="rows of 2 coordinates; the set's arm has 3"):
        ConstraintSet(3, velocity=[joint_rate_limit([1.0, 1.0], ["a", "b"])])


# == PointOutsideSphere ==========================================================================
def test_thesis_obstacle_phi1(absolute_model, rng, central_difference):
    c = obstacle(absolute_model)
    assert c.names == ("obstacle",)
    for th, _ in states(rng):
        assert c.value(th)[0] == pytest.approx(thesis_phi1(th), rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(c.gradient(th)[0], thesis_grad_phi1(th), atol=1e-12)
        np.testing.assert_allclose(c.gradient(th), central_difference(c.value, th), atol=1e-8)
        phi, grad = c.evaluate(th)
        assert phi[0] == pytest.approx(thesis_phi1(th), rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(grad[0], thesis_grad_phi1(th), atol=1e-12)
        assert_generic_configuration_terms(c, th)
    # the end point at (0, 2) (θ = (π/2, π/2)) is the centre of the obstacle
    assert c.value(np.array([math.pi / 2, math.pi / 2]))[0] == pytest.approx(-R_OBS**2)


def test_obstacle_in_joint_coordinates_is_the_same_function(joint_model, rng, central_difference):
    c = obstacle(joint_model)
    for th, _ in states(rng):
        q = np.array([th[0], th[1] - th[0]])
        assert c.value(q)[0] == pytest.approx(thesis_phi1(th), rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(c.gradient(q), central_difference(c.value, q), atol=1e-8)
        assert_generic_configuration_terms(c, q)


def test_obstacle_with_an_offset_point(absolute_model, rng, central_difference):
    c = obstacle(absolute_model, OFFSET)
    for th, _ in states(rng):
        ct, st = math.cos(th[1]), math.sin(th[1])
        p = np.array(
            [
                math.cos(th[0]) + ct + ct * OFFSET[0] - st * OFFSET[1],
                math.sin(th[0]) + st + st * OFFSET[0] + ct * OFFSET[1],
                OFFSET[2],
            ]
        )
        expected = float((p - X_OBS) @ (p - X_OBS)) - R_OBS**2
        assert c.value(th)[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(c.gradient(th), central_difference(c.value, th), atol=1e-8)
        assert_generic_configuration_terms(c, th)


def test_obstacle_default_name_and_values_along(absolute_model, rng):
    c = PointOutsideSphere(absolute_model, "end_point", X_OBS, R_OBS)
    assert c.names == ("clearance[end_point]",)
    xs = rng.uniform(-2, 2, (6, 2))
    np.testing.assert_allclose(
        c.values_along(xs), np.array([[thesis_phi1(x)] for x in xs]), rtol=1e-12, atol=1e-12
    )


@pytest.mark.parametrize("radius", [0.0, -0.5, float("nan"), float("inf")])
def test_obstacle_rejects_non_positive_radius(absolute_model, radius):
    with pytest.raises(CpbcError, match="radius"):
        PointOutsideSphere(absolute_model, "end_point", X_OBS, radius)


@pytest.mark.parametrize("centre", [[0.0, 2.0], [0.0, float("inf"), 0.0]])
def test_obstacle_rejects_bad_centre(absolute_model, centre):
    with pytest.raises(CpbcError, match="centre"):
        PointOutsideSphere(absolute_model, "end_point", centre, R_OBS)


def test_obstacle_rejects_unknown_frame(absolute_model):
    with pytest.raises(ModelError, match="end_point"):
        PointOutsideSphere(absolute_model, "tool", X_OBS, R_OBS)


# == RateLimit / joint_rate_limit ================================================================
RATE_CASES = {
    "all_joints": (np.eye(2), [0.3, 0.2]),
    "one_joint": (np.array([[0.0, 1.0]]), [0.2]),
    "reversed": (np.array([[0.0, 1.0], [1.0, 0.0]]), [0.2, 0.3]),
    "negative_unit": (np.array([[0.0, -1.0]]), [0.25]),
    "combination": (np.array([[1.0, 1.0]]), [0.4]),
    "general_rows": (np.array([[1.0, 1.0], [0.5, -2.0], [1.0, 0.0]]), [0.4, 0.6, 0.3]),
}


@pytest.mark.parametrize("case", list(RATE_CASES))
def test_rate_limit_value_weights_gradient(case, joint_model, rng, central_difference):
    rows, bounds = RATE_CASES[case]
    bounds = np.asarray(bounds)
    c = RateLimit(rows, bounds, [f"r{i}" for i in range(len(bounds))])
    assert c.is_per_joint == (case not in ("combination", "general_rows"))
    assert not c.needs_dynamics
    for x, dx in states(rng):
        y = rows @ dx
        np.testing.assert_allclose(c.value(x, dx, None), 0.5 * (bounds**2 - y**2), rtol=1e-13)
        weights = c.weights(x, None)
        assert weights.shape == (len(bounds), 2, 2)
        for q, a in zip(weights, rows, strict=True):
            np.testing.assert_array_equal(q, np.outer(a, a))
        # ψ = Ω − ½ẋᵀQẋ with Ω = B²/2
        np.testing.assert_allclose(
            c.value(x, dx, None), [0.5 * b**2 - 0.5 * dx @ q @ dx for b, q in
                                   zip(bounds, weights, strict=True)], rtol=1e-12, atol=1e-15,
        )
        fd = central_difference(lambda z, dx=dx: c.value(z, dx, None), x)
        np.testing.assert_array_equal(fd, 0.0)
        np.testing.assert_array_equal(c.gradient(x, dx, None), np.zeros((len(bounds), 2)))
        assert_generic_velocity_terms(c, x, dx, None)
        assert c.barrier_terms(state_at(x, dx))[2] is None
    dxs = rng.uniform(-0.1, 0.1, (5, 2))
    np.testing.assert_allclose(
        c.values_along(np.zeros((5, 2)), dxs), np.array([c.value(np.zeros(2), d) for d in dxs])
    )


def test_thesis_rate_limits_give_psi(joint_model, rng):
    """Ψ of Section 6.4: ¼(0.3² − θ̇1²)(0.2² − θ̇2²) is the product of the two ψ_j."""
    c = joint_rate_limit(B, ("theta1", "theta2"))
    assert c.names == ("rate[theta1]", "rate[theta2]")
    for x, dx in states(rng):
        psi = c.value(x, dx, None)
        big_psi = 0.25 * (B[0] ** 2 - dx[0] ** 2) * (B[1] ** 2 - dx[1] ** 2)
        assert psi.prod() == pytest.approx(big_psi, rel=1e-12)
        _, pi, _ = c.barrier_terms(state_at(x, dx))
        np.testing.assert_allclose(pi, np.diag(1.0 / psi))


def test_joint_rate_limit_on_selected_joints(joint_model):
    c = joint_rate_limit([0.7], joint_model.joint_names, joints=[1])
    assert c.names == ("rate[joint2]",)
    assert c.is_per_joint
    x, dx = np.zeros(2), np.array([5.0, 0.5])  # joint 1 is not limited
    assert c.value(x, dx)[0] == pytest.approx(0.5 * (0.49 - 0.25))
    _, pi, _ = c.barrier_terms(state_at(x, dx))
    np.testing.assert_allclose(pi, [[0.0, 0.0], [0.0, 1.0 / c.value(x, dx)[0]]])


@pytest.mark.parametrize(
    ("rows", "bounds", "match"),
    [
        (np.eye(2), [0.3, 0.0], "> 0"),
        (np.eye(2), [0.3, -0.2], "> 0"),
        (np.eye(2), [0.3, np.inf], "finite"),
        (np.eye(2), [0.3, np.nan], "finite"),
        (np.eye(2), [0.3], "rows"),
        (np.eye(2), [0.3, 0.2, 0.1], "rows"),
        (np.array([[1.0, 0.0], [1.0, 0.0]]), [0.3, 0.2], "twice"),
        (np.array([[0.0, 1.0], [0.0, -1.0]]), [0.3, 0.2], "twice"),
    ],
)
def test_rate_limit_rejects_bad_input(rows, bounds, match):
    with pytest.raises(CpbcError, match=match):
        RateLimit(rows, bounds, [f"r{i}" for i in range(rows.shape[0])])


def test_joint_rate_limit_rejects_a_joint_bounded_twice(joint_model):
    with pytest.raises(CpbcError, match="twice"):
        joint_rate_limit([0.3, 0.2], joint_model.joint_names, joints=[0, 0])


# == KineticEnergyLimit ===========================================================================
def test_kinetic_energy_limit_against_the_thesis_inertia(absolute_model, rng, central_difference):
    c = KineticEnergyLimit(absolute_model, 0.05, name="energy")
    assert c.names == ("energy",)
    assert c.needs_dynamics
    for th, dth in states(rng):
        d = thesis_inertia(th)
        dyn = absolute_model.state(th, dth, coriolis=True)
        # the state's C is the model's (T⁻ᵀ C_q T⁻¹ of the same pass, finished by the state's
        # kernel: equal to rounding), and the limit makes no call of its own: its gradient at
        # the state is −Cᵀẋ of the state's C, bit for bit
        assert dyn.coriolis_matrix is not None
        np.testing.assert_allclose(dyn.coriolis_matrix, absolute_model.coriolis(th, dth),
                                   rtol=0, atol=1e-15)
        np.testing.assert_array_equal(c.gradient(th, dth, dyn)[0],
                                      -(dyn.coriolis_matrix.T @ dth))
        for given in (None, dyn):
            assert c.value(th, dth, given)[0] == pytest.approx(0.05 - 0.5 * dth @ d @ dth,
                                                               rel=1e-12)
            np.testing.assert_allclose(c.weights(th, given), d[None], atol=1e-12)
            # ∂ψ/∂x at fixed ẋ is −Cᵀẋ (the velocity constraint's gradient in x), checked
            # by finite differences
            grad = c.gradient(th, dth, given)
            fd = central_difference(lambda z, dth=dth: c.value(z, dth, None), th)
            np.testing.assert_allclose(grad, fd, rtol=0, atol=1e-9)
            np.testing.assert_allclose(
                grad[0], -(absolute_model.coriolis(th, dth).T @ dth), atol=1e-14
            )
            assert_generic_velocity_terms(c, th, dth, dyn)


def test_kinetic_energy_gradient_is_not_trivially_zero(absolute_model):
    c = KineticEnergyLimit(absolute_model, 1.0)
    grad = c.gradient(np.array([0.2, 1.4]), np.array([0.5, -0.3]))
    assert np.linalg.norm(grad) > 0.05


@pytest.mark.parametrize("limit", [0.0, -1.0, float("nan"), float("inf")])
def test_kinetic_energy_limit_rejects_bad_limit(absolute_model, limit):
    with pytest.raises(CpbcError, match="kinetic energy limit"):
        KineticEnergyLimit(absolute_model, limit)


# == ConstraintSet ===============================================================================
@pytest.fixture
def thesis_ch6_set(absolute_model) -> ConstraintSet:
    """The constraints of Section 6.4 in absolute link angles, plus an energy bound."""
    return ConstraintSet(
        2,
        [obstacle(absolute_model), relative_limit()],
        [joint_rate_limit(B, ("theta1", "theta2")), KineticEnergyLimit(absolute_model, 0.2)],
    )


def admissible_states(constraints: ConstraintSet, rng: np.random.Generator, n: int = N_SAMPLES):
    found = 0
    while found < n:
        x, dx = rng.uniform(-2.5, 2.5, 2), rng.uniform(-0.25, 0.25, 2) * [1.0, 0.7]
        if np.all(constraints.margins(x, dx) > 0):
            found += 1
            yield x, dx


def test_constraint_set_names_and_margins(thesis_ch6_set, absolute_model, rng):
    assert thesis_ch6_set.names == (
        "obstacle", "relative_angle", "rate[theta1]", "rate[theta2]", "kinetic_energy",
    )
    assert len(thesis_ch6_set) == 5
    assert not thesis_ch6_set.empty
    assert thesis_ch6_set.needs_dynamics
    for th, dth in states(rng, 5):
        d = thesis_inertia(th)
        expected = [
            thesis_phi1(th),
            thesis_phi2(th),
            0.5 * (B[0] ** 2 - dth[0] ** 2),
            0.5 * (B[1] ** 2 - dth[1] ** 2),
            0.2 - 0.5 * dth @ d @ dth,
        ]
        np.testing.assert_allclose(thesis_ch6_set.margins(th, dth), expected, rtol=1e-12,
                                   atol=1e-14)


def test_constraint_set_barrier_is_the_sum_of_logs(thesis_ch6_set, absolute_model, rng,
                                                   central_difference):
    for th, dth in admissible_states(thesis_ch6_set, rng):
        bar = thesis_ch6_set.barrier(thesis_ch6_set.state(absolute_model, th, dth))
        assert isinstance(bar, BarrierTerms)
        phi = np.array([thesis_phi1(th), thesis_phi2(th)])
        psi_rates = 0.5 * (B**2 - dth**2)
        d = thesis_inertia(th)
        psi_ke = 0.2 - 0.5 * dth @ d @ dth
        # log Φ = Σ log φ_i;  log Ψ = Σ log ψ_j
        assert bar.log_phi == pytest.approx(math.log(phi.prod()), rel=1e-12, abs=1e-12)
        assert bar.log_psi == pytest.approx(
            math.log(psi_rates.prod() * psi_ke), rel=1e-12, abs=1e-12
        )
        # b = ∇ log Φ + ∂_x log Ψ (at fixed ẋ), by finite differences of the logs
        def log_phi_psi(z, dth=dth):
            return math.log(thesis_phi1(z) * thesis_phi2(z)) + math.log(
                0.2 - 0.5 * dth @ thesis_inertia(z) @ dth
            )

        np.testing.assert_allclose(bar.gradient, central_difference(log_phi_psi, th),
                                   rtol=1e-6, atol=1e-7)
        expected_b = (
            thesis_grad_phi1(th) / phi[0]
            + np.array([2, -2]) * (th[1] - th[0]) / phi[1]
            - absolute_model.coriolis(th, dth).T @ dth / psi_ke
        )
        np.testing.assert_allclose(bar.gradient, expected_b, rtol=1e-10, atol=1e-12)
        # Π = Σ Q_j/ψ_j
        np.testing.assert_allclose(bar.weight, np.diag(1 / psi_rates) + d / psi_ke, rtol=1e-12)


def test_barrier_without_velocity_constraints(absolute_model, rng):
    cs = ConstraintSet(2, [obstacle(absolute_model), relative_limit()])
    for th, dth in admissible_states(cs, rng, 5):
        bar = cs.barrier(cs.state(absolute_model, th, dth))
        assert bar.weight is None
        assert bar.log_psi == 0.0
        assert bar.log_phi == pytest.approx(math.log(thesis_phi1(th) * thesis_phi2(th)))


def test_barrier_with_only_rate_limits_has_no_gradient(absolute_model):
    cs = ConstraintSet(2, velocity=[joint_rate_limit(B, ("theta1", "theta2"))])
    x, dx = np.array([0.3, 0.1]), np.array([0.1, -0.1])
    bar = cs.barrier(cs.state(absolute_model, x, dx))
    assert bar.gradient is None
    assert bar.log_phi == 0.0
    np.testing.assert_allclose(bar.weight, np.diag(1 / (0.5 * (B**2 - dx**2))))


def test_empty_constraint_set(absolute_model):
    cs = ConstraintSet(2)
    assert cs.empty
    assert len(cs) == 0
    x = np.array([0.3, 0.1])
    empty = BarrierTerms(0.0, 0.0, None, None)
    assert cs.barrier(cs.state(absolute_model, x, x)) == empty
    assert cs.margins(x, x).shape == (0,)
    cs.check_admissible(x, 100 * x, "anything")  # no constraint, nothing to violate


@pytest.mark.filterwarnings("ignore:divide by zero:RuntimeWarning")  # ψ = 0 on the bound
@pytest.mark.parametrize(
    ("th", "dth", "name"),
    [
        ([math.pi / 2, math.pi / 2], [0.0, 0.0], "obstacle"),  # end point at the centre
        ([0.0, 3.0], [0.0, 0.0], "relative_angle"),  # |θ2 − θ1| > 17π/18
        ([0.0, 0.0], [0.3, 0.0], "rate[theta1]"),  # exactly on the bound
        ([0.0, 0.0], [0.0, -0.25], "rate[theta2]"),
    ],
)
def test_barrier_outside_s_raises_naming_the_constraint(thesis_ch6_set, absolute_model, th,
                                                        dth, name):
    th, dth = np.array(th), np.array(dth)
    with pytest.raises(ConstraintViolation) as info:
        thesis_ch6_set.barrier(thesis_ch6_set.state(absolute_model, th, dth))
    assert info.value.constraint == name
    assert info.value.margin <= 0
    assert name in str(info.value)


def test_barrier_outside_the_energy_bound_names_it(absolute_model):
    cs = ConstraintSet(2, velocity=[KineticEnergyLimit(absolute_model, 0.01, name="energy")])
    th, dth = np.zeros(2), np.array([0.2, 0.2])
    with pytest.raises(ConstraintViolation, match="energy") as info:
        cs.barrier(cs.state(absolute_model, th, dth))
    assert info.value.margin == pytest.approx(0.01 - 0.5 * dth @ thesis_inertia(th) @ dth)


def test_barrier_rejects_a_nan_margin_in_any_position(absolute_model):
    cs = ConstraintSet(2, velocity=[joint_rate_limit(B, ("theta1", "theta2"))])
    x, dx = np.zeros(2), np.array([0.1, np.nan])
    with pytest.raises(ConstraintViolation, match=r"rate\[theta2\]"):
        cs.barrier(state_at(x, dx))


def test_check_admissible_names_the_constraint(thesis_ch6_set):
    thesis_ch6_set.check_admissible(np.zeros(2), np.zeros(2), "initial state")
    with pytest.raises(InadmissibleStateError) as info:
        thesis_ch6_set.check_admissible(np.array([math.pi / 2] * 2), np.zeros(2), "target")
    err = info.value
    assert (err.what, err.constraint) == ("target", "obstacle")
    assert err.margin == pytest.approx(-R_OBS**2)
    assert "target" in str(err) and "obstacle" in str(err)
    with pytest.raises(InadmissibleStateError, match=r"rate\[theta1\]") as info:
        thesis_ch6_set.check_admissible(np.zeros(2), np.array([0.35, 0.0]), "initial state")
    assert info.value.margin == pytest.approx(0.5 * (0.09 - 0.35**2))
    # on the boundary is outside: S is open
    with pytest.raises(InadmissibleStateError, match=r"rate\[theta2\]"):
        thesis_ch6_set.check_admissible(np.zeros(2), np.array([0.0, 0.2]), "initial state")
    with pytest.raises(InadmissibleStateError):
        thesis_ch6_set.check_admissible(np.array([0.0, np.nan]), np.zeros(2), "initial state")


def test_check_admissible_reports_the_worst_constraint():
    """Both rates out of bounds: the more negative margin is named."""
    cs = ConstraintSet(2, velocity=[joint_rate_limit(B, ("theta1", "theta2"))])
    with pytest.raises(InadmissibleStateError, match=r"rate\[theta1\]"):
        cs.check_admissible(np.zeros(2), np.array([0.5, 0.21]), "x")
    with pytest.raises(InadmissibleStateError, match=r"rate\[theta2\]"):
        cs.check_admissible(np.zeros(2), np.array([0.31, 0.5]), "x")


def test_margins_along_marks_non_finite_rows(thesis_ch6_set, rng):
    xs = rng.uniform(-0.5, 0.5, (4, 2))
    dxs = rng.uniform(-0.1, 0.1, (4, 2))
    xs[2, 1] = np.nan
    out = thesis_ch6_set.margins_along(xs, dxs)
    assert out.shape == (4, 5)
    assert np.all(np.isnan(out[2]))
    for k in (0, 1, 3):
        np.testing.assert_allclose(out[k], thesis_ch6_set.margins(xs[k], dxs[k]), rtol=1e-12)


def test_duplicate_constraint_names_are_rejected(absolute_model):
    with pytest.raises(CpbcError, match="duplicate"):
        ConstraintSet(2, [obstacle(absolute_model), obstacle(absolute_model)])


def test_barrier_margins_are_the_margins(thesis_ch6_set, absolute_model, rng):
    """The margins the law's barrier pass reports are those ``margins`` computes afresh."""
    for th, dth in admissible_states(thesis_ch6_set, rng, 5):
        bar = thesis_ch6_set.barrier(thesis_ch6_set.state(absolute_model, th, dth),
                                     margins=True)
        np.testing.assert_allclose(bar.margins, thesis_ch6_set.margins(th, dth), rtol=1e-12,
                                   atol=1e-15)
        assert thesis_ch6_set.barrier(thesis_ch6_set.state(absolute_model, th, dth)
                                      ).margins is None


def _one_by_one(cs: ConstraintSet, state) -> tuple[float, float, np.ndarray, np.ndarray]:
    """log Φ, log Ψ, b and Π from each constraint's own barrier_terms, added in order."""
    log_phi, log_psi = 0.0, 0.0
    b, pi = np.zeros(cs.n), np.zeros((cs.n, cs.n))
    for c in cs.configuration:
        phi, grad, _ = c.barrier_terms(state)
        log_phi += float(np.sum(np.log(phi)))
        b = b + grad
    for v in cs.velocity:
        psi, weight, grad = v.barrier_terms(state)
        log_psi += float(np.sum(np.log(psi)))
        pi = pi + weight
        b = b if grad is None else b + grad
    return log_phi, log_psi, b, pi


def test_the_set_kernel_equals_each_constraints_terms(absolute_model, rng):
    """One kernel call for the packed set (cpbc.kernels.barrier_set) gives the sums of the
    constraints' own barrier terms, and every margin in the order of the names."""
    obstacle = PointOutsideSphere(absolute_model, "end_point", X_OBS, R_OBS, name="obstacle",
                                  offset=[0.0, 0.0, 0.05])
    relative = LinearLimit([[-1, 1]], [-REL], [REL], ["relative"])
    for velocity in ([joint_rate_limit(B, ("theta1", "theta2"))],
                     [KineticEnergyLimit(absolute_model, 2.0)]):
        cs = ConstraintSet(2, [obstacle, relative], velocity)
        checked = 0
        for _ in range(40):
            x, dx = rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.1, 0.1, 2)
            state = cs.state(absolute_model, x, dx)
            if not np.all(cs.margins(x, dx, state) > 0):
                continue
            bar = cs.barrier(state, margins=True)
            log_phi, log_psi, b, pi = _one_by_one(cs, state)
            assert bar.log_phi == pytest.approx(log_phi, rel=1e-12, abs=1e-12)
            assert bar.log_psi == pytest.approx(log_psi, rel=1e-12, abs=1e-12)
            np.testing.assert_allclose(bar.gradient, b, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(bar.weight, pi, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(bar.margins, cs.margins(x, dx, state), rtol=1e-12,
                                       atol=1e-14)
            checked += 1
        assert checked >= 20


def test_a_subclass_formula_overrides_the_set_kernel(absolute_model):
    """A constraint whose class overrides barrier_terms does not pack: the set asks its
    method, so its own formula reaches the law."""

    class Doubled(LinearLimit):
        def barrier_terms(self, state, margins=False):  # type: ignore[no-untyped-def]
            phi, grad, value = super().barrier_terms(state, margins)
            return phi, 2.0 * grad, value

    rows, lo, hi = [[-1, 1]], [-REL], [REL]
    plain = ConstraintSet(2, [LinearLimit(rows, lo, hi, ["relative"])])
    doubled = ConstraintSet(2, [Doubled(rows, lo, hi, ["relative"])])
    state = state_at(np.array([0.1, 0.9]), np.zeros(2))
    a, b = plain.barrier(state), doubled.barrier(state)
    assert a.gradient is not None and b.gradient is not None
    np.testing.assert_allclose(b.gradient, 2.0 * a.gradient, rtol=1e-15)
    assert b.log_phi == a.log_phi
    with pytest.raises(ConstraintViolation, match="relative"):
        doubled.barrier(state_at(np.array([0.0, 3.1]), np.zeros(2)))
