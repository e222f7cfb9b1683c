"""LinearCoordinates: x = T q, its inverse, and the power-preserving force map τ_q = Tᵀ τ_x."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.errors import ModelError
from cpbc.model import LinearCoordinates


def general_map(rng: np.random.Generator, n: int = 3) -> LinearCoordinates:
    """A well-conditioned non-triangular T."""
    return LinearCoordinates(np.eye(n) + 0.3 * rng.normal(size=(n, n)), name="custom")


@pytest.mark.parametrize("n", [1, 2, 3, 7])
def test_absolute_link_angles_is_lower_triangular_ones(n):
    c = LinearCoordinates.absolute_link_angles(n)
    expected = np.array([[1.0 if j <= i else 0.0 for j in range(n)] for i in range(n)])
    np.testing.assert_array_equal(c.matrix, expected)
    assert c.name == "absolute"
    assert c.is_identity == (n == 1)


def test_absolute_link_angles_of_the_planar_arm():
    c = LinearCoordinates.absolute_link_angles(2)
    np.testing.assert_array_equal(c.matrix, [[1, 0], [1, 1]])
    np.testing.assert_allclose(c.inverse, [[1, 0], [-1, 1]])
    # θ2 is the angle of link 2 from the x-axis: q1 + q2
    np.testing.assert_allclose(c.from_joint(np.array([0.4, 0.5])), [0.4, 0.9])
    np.testing.assert_allclose(c.to_joint(np.array([0.4, 0.9])), [0.4, 0.5])


def test_identity():
    c = LinearCoordinates.identity(3)
    assert c.is_identity
    assert c.name == "joint"
    v = np.array([0.1, -2.0, 3.0])
    np.testing.assert_array_equal(c.from_joint(v), v)
    np.testing.assert_array_equal(c.torque_to_joint(v), v)


@pytest.mark.parametrize("kind", ["absolute", "general"])
def test_round_trips(kind, rng):
    c = LinearCoordinates.absolute_link_angles(3) if kind == "absolute" else general_map(rng)
    assert not c.is_identity
    np.testing.assert_allclose(c.matrix @ c.inverse, np.eye(3), atol=1e-12)
    for _ in range(10):
        q, x, tau = rng.normal(size=(3, 3))
        np.testing.assert_allclose(c.to_joint(c.from_joint(q)), q, atol=1e-12)
        np.testing.assert_allclose(c.from_joint(c.to_joint(x)), x, atol=1e-12)
        np.testing.assert_allclose(c.torque_from_joint(c.torque_to_joint(tau)), tau, atol=1e-12)
        np.testing.assert_allclose(c.from_joint(q), c.matrix @ q, atol=1e-15)


@pytest.mark.parametrize("kind", ["absolute", "general"])
def test_torque_mapping_preserves_power(kind, rng):
    c = LinearCoordinates.absolute_link_angles(3) if kind == "absolute" else general_map(rng)
    for _ in range(10):
        dq, tau_x = rng.normal(size=(2, 3))
        dx = c.from_joint(dq)
        tau_q = c.torque_to_joint(tau_x)
        assert tau_x @ dx == pytest.approx(tau_q @ dq, rel=1e-12, abs=1e-12)
        # and the other way round
        tau_q2 = rng.normal(size=3)
        assert c.torque_from_joint(tau_q2) @ dx == pytest.approx(tau_q2 @ dq, rel=1e-12)


@pytest.mark.parametrize("kind", ["absolute", "general"])
def test_matrix_congruence_preserves_quadratic_forms(kind, rng):
    """D_x = T⁻ᵀ D_q T⁻¹ gives the same kinetic energy: ẋᵀ D_x ẋ = q̇ᵀ D_q q̇."""
    c = LinearCoordinates.absolute_link_angles(3) if kind == "absolute" else general_map(rng)
    a = rng.normal(size=(3, 3))
    d_q = a @ a.T + np.eye(3)
    d_x = c.matrix_from_joint(d_q)
    np.testing.assert_allclose(d_x, c.inverse.T @ d_q @ c.inverse, atol=1e-12)
    for _ in range(5):
        dq = rng.normal(size=3)
        dx = c.from_joint(dq)
        assert dx @ d_x @ dx == pytest.approx(dq @ d_q @ dq, rel=1e-12)


def test_matrices_are_read_only():
    c = LinearCoordinates.absolute_link_angles(2)
    with pytest.raises(ValueError):
        c.matrix[0, 1] = 5.0
    with pytest.raises(ValueError):
        c.inverse[0, 0] = 5.0


def test_the_caller_array_is_copied():
    t = np.array([[1.0, 0.0], [1.0, 1.0]])
    c = LinearCoordinates(t)
    t[0, 0] = 7.0
    assert c.matrix[0, 0] == 1.0


@pytest.mark.parametrize(
    "matrix",
    [
        [[1.0, 2.0], [2.0, 4.0]],  # rank 1
        [[0.0, 0.0], [0.0, 0.0]],
        [[1.0, 1.0, 0.0], [0.0, 1.0, 1.0], [1.0, 2.0, 1.0]],  # row 3 = row 1 + row 2
    ],
)
def test_singular_matrix_is_rejected(matrix):
    with pytest.raises(ModelError, match="invertible"):
        LinearCoordinates(np.array(matrix))


@pytest.mark.parametrize("matrix", [np.ones((2, 3)), np.ones(3), np.ones((2, 2, 2))])
def test_non_square_matrix_is_rejected(matrix):
    with pytest.raises(ModelError, match="square"):
        LinearCoordinates(matrix)


def test_well_conditioned_small_scale_matrix_is_accepted():
    c = LinearCoordinates(0.01 * np.eye(7))
    np.testing.assert_allclose(c.inverse, 100.0 * np.eye(7))
