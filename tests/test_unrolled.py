"""The unrolled scalar law and safeguard test agree with the array code they replace."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin
import pytest

from cpbc.constraints import (
    ConstraintSet,
    KineticEnergyLimit,
    LinearLimit,
    PointOutsideSphere,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.constraints.rate_limit import RateLimit
from cpbc.controllers import (
    BPBC,
    CPBC,
    BPBCKineticEnergy,
    Controller,
    CPBCKineticEnergy,
    Identity,
    Power,
    RecentredBarrier,
    Tanh,
)
from cpbc.controllers.safeguard import Safeguard, SafeguardSettings
from cpbc.controllers.unrolled import MAX_JOINTS, SCALAR_SOLVE
from cpbc.errors import ConstraintViolation
from cpbc.model import LinearCoordinates, RobotModel

NAMES = ["theta1", "theta2"]
TARGET = np.array([np.pi, 2 * np.pi / 3])


def thesis_constraints(model: RobotModel, offset: list[float] | None = None) -> ConstraintSet:
    """Section 6.4: end-point obstacle, relative angle, two rate limits."""
    return ConstraintSet(
        2,
        [PointOutsideSphere(model, "end_point", [0, 2, 0], 0.5, offset),
         LinearLimit([[-1, 1]], [-17 * np.pi / 18], [17 * np.pi / 18], ["relative"])],
        [joint_rate_limit([0.3, 0.2], NAMES)],
    )


Build = Callable[[RobotModel], Controller]
LAWS: dict[str, Build] = {
    "thesis_power": lambda m: CPBC(m, TARGET, thesis_constraints(m), 4.0, 20.0, Power(0.2)),
    "identity_shaping": lambda m: CPBC(m, TARGET, thesis_constraints(m), [4.0, 3.0], 20.0,
                                       Identity()),
    "tanh_shaping_offset_point": lambda m: CPBC(
        m, TARGET, thesis_constraints(m, [0.05, 0.02, 0.0]), 4.0, [20.0, 9.0], Tanh(5.0)),
    "no_velocity_constraint": lambda m: CPBC(
        m, TARGET, ConstraintSet(2, [joint_position_limit([-0.5, -0.5], [3.5, 3.5], NAMES)]),
        4.0, 20.0, Power(0.5)),
    "combined_rate_rows": lambda m: CPBC(
        m, TARGET, ConstraintSet(2, [], [RateLimit([[1.0, 0.0], [-1.0, 1.0]], [0.3, 0.25],
                                                   ["r1", "r12"])]), 4.0, 20.0),
    "bpbc": lambda m: BPBC(m, TARGET, ConstraintSet(2, [], [joint_rate_limit([0.3, 0.2], NAMES)]),
                           [2, 10], [4, 20], [1.0, 2.0], [1.0, 0.5], Power(0.2)),
    "cpbc_ke": lambda m: CPBCKineticEnergy(
        m, TARGET, ConstraintSet(2, thesis_constraints(m).configuration,
                                 [KineticEnergyLimit(m, 0.05)]), 4.0, [20.0, 9.0], Power(0.2)),
    "bpbc_ke": lambda m: BPBCKineticEnergy(
        m, TARGET, ConstraintSet(2, [], [KineticEnergyLimit(m, 0.05)]), [2, 10], [4, 20],
        [1.0, 2.0], [1.0, 0.5], Tanh(3.0)),
    "recentred": lambda m: RecentredBarrier(
        m, TARGET, ConstraintSet(2, [joint_position_limit([-0.5, -0.6], [3.5, 3.6], NAMES)],
                                 [joint_rate_limit([0.3, 0.2], NAMES)]), [4.0, 3.0], 20.0),
    "recentred_no_rates": lambda m: RecentredBarrier(
        m, TARGET, ConstraintSet(2, [joint_position_limit([-0.5, -0.6], [3.5, 3.6], NAMES)]),
        [4.0, 3.0], 20.0),
}


def models(planar_path) -> dict[str, RobotModel]:
    return {
        "absolute": RobotModel.from_mjcf(
            planar_path, coordinates=LinearCoordinates.absolute_link_angles(2)),
        "joint": RobotModel.from_mjcf(planar_path),
        "friction": RobotModel.from_mjcf(
            planar_path, coordinates=LinearCoordinates.absolute_link_angles(2),
            viscous_friction=[0.3, 0.1]),
    }


def largest_speed(law: Controller, x: np.ndarray, direction: np.ndarray) -> float:
    """The s at which s·direction reaches the boundary of the velocity constraints."""
    def inside(s: float) -> bool:
        return all(np.all(c.value(x, s * direction, None) > 0) for c in law.constraints.velocity)

    lo, hi = 0.0, 1.0
    while inside(hi):
        lo, hi = hi, 2.0 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if inside(mid) else (lo, mid)
    return lo


def admissible_states(law: Controller, rng: np.random.Generator, count: int,
                      near_bound: bool = False) -> list[tuple[np.ndarray, np.ndarray]]:
    """States of S; with ``near_bound`` the velocity is 10⁻⁷–10⁻¹ (relative) short of the
    boundary of the velocity constraints, where a law is stiff and the safeguard often refuses
    its torque."""
    out = []
    while len(out) < count:
        x = rng.uniform([-0.4, -0.4], [3.4, 3.4])
        dx = rng.uniform(-0.99, 0.99, 2) * np.array([0.3, 0.2])
        if near_bound:
            dx *= largest_speed(law, x, dx) * (1.0 - 10.0 ** rng.uniform(-7, -1))
        if np.all(law.constraints.margins(x, dx) > 0):
            out.append((x, dx))
    return out


@pytest.mark.parametrize("coords", ["absolute", "joint", "friction"])
@pytest.mark.parametrize("name", sorted(LAWS))
def test_unrolled_law_equals_the_array_law(planar_path, rng, name: str, coords: str) -> None:
    law = LAWS[name](models(planar_path)[coords])
    states = admissible_states(law, rng, 200)
    assert law.unrolled(*states[0]) is not None  # the scalar code runs for this law
    for x, dx in states:
        tau, v = law.unrolled(x, dx)  # type: ignore[misc]
        tau_ref, v_ref = law.evaluate_arrays(x, dx)
        scale = max(1.0, float(np.abs(tau_ref).max()))
        np.testing.assert_allclose(tau, tau_ref, rtol=1e-12, atol=1e-12 * scale)
        assert v == pytest.approx(v_ref, rel=1e-12, abs=1e-300)
        np.testing.assert_array_equal(law.torque(x, dx), tau)


def test_outside_the_set_the_array_law_names_the_constraint(absolute_model) -> None:
    law = LAWS["thesis_power"](absolute_model)
    x = np.array([0.3, 0.5])
    for dx in (np.array([0.31, 0.0]), np.array([np.nan, 0.0])):
        assert law.unrolled(x, dx) is None
        with pytest.raises(ConstraintViolation, match=r"rate\[theta1\]"):
            law.evaluate(x, dx)
        with pytest.raises(ConstraintViolation, match=r"rate\[theta1\]"):
            law.torque(x, dx)  # the torque-only code keeps the check


def test_torque_alone_skips_what_only_v_needs(absolute_model) -> None:
    law = LAWS["thesis_power"](absolute_model)
    x, dx = np.array([0.3, 0.5]), np.array([0.05, -0.02])
    np.testing.assert_array_equal(law.torque(x, dx), law.unrolled(x, dx)[0])  # type: ignore[index]
    full, alone = law._unrolled.source, law._unrolled_torque.source  # type: ignore[union-attr]
    assert "lsum" in full and "V = " in full
    assert "lsum" not in alone and "V = " not in alone and "if not (" in alone


def test_laws_without_a_scalar_form_keep_the_array_code(absolute_model) -> None:
    energy = ConstraintSet(2, [], [KineticEnergyLimit(absolute_model, 0.5)])
    law = CPBC(absolute_model, TARGET, energy, 4.0, 20.0)
    x, dx = np.array([0.3, 0.5]), np.array([0.05, -0.02])
    assert law.unrolled(x, dx) is None
    assert np.all(np.isfinite(law.torque(x, dx)))
    n = MAX_JOINTS + 1
    long_chain = RobotModel(chain(n), name="chain")
    rates = joint_rate_limit(np.ones(n), [f"j{i}" for i in range(n)])
    law = CPBC(long_chain, np.zeros(n), ConstraintSet(n, [], [rates]), 1.0, 1.0)
    x, dx = np.full(n, 0.1), np.full(n, 0.2)
    assert law.unrolled(x, dx) is None
    assert np.all(np.isfinite(law.torque(x, dx)))


def chain(n: int) -> pin.Model:
    """n revolute joints in a row, alternating axes, a 1 kg ball on each link."""
    model = pin.Model()
    parent = 0
    for i in range(n):
        axis = pin.JointModelRY() if i % 2 else pin.JointModelRZ()
        parent = model.addJoint(parent, axis, pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.1])),
                                f"j{i}")
        model.appendBodyToJoint(parent, pin.Inertia.FromSphere(1.0, 0.05), pin.SE3.Identity())
    return model


def guard_decisions(guard: Safeguard, states) -> tuple[int, int]:
    """(accepted, refused) by the unrolled test, each checked against the array guard."""
    guard.evaluate(*states[0])  # builds the scalar code
    kernel = guard._unrolled
    assert callable(kernel)
    counts = [0, 0]
    for x, dx in states:
        fast = kernel(x, dx)
        tau, v = guard.law.evaluate_arrays(x, dx)  # type: ignore[attr-defined]
        acted = guard.acted
        out = guard.guard(x, dx, tau)
        passed = guard.acted == acted  # the array guard kept the law's torque
        assert passed == (fast is not None)
        if fast is not None:
            # ψ = Ω − ½ẋᵀQẋ keeps only the digits of its share of Ω: both codes round it
            # differently, and τ and V inherit that relative error
            tol = 1e-12 / min([1.0] + [
                float(np.min(c.value(x, dx, None) / c.value(x, 0 * dx, None)))
                for c in guard.law.constraints.velocity])
            np.testing.assert_allclose(fast[0], out, rtol=tol, atol=1e-12)
            assert fast[1] == pytest.approx(v, rel=tol)
        counts[fast is None] += 1
    return counts[0], counts[1]


@pytest.mark.parametrize("name", ["thesis_power", "tanh_shaping_offset_point", "bpbc",
                                  "combined_rate_rows", "cpbc_ke", "bpbc_ke", "recentred"])
@pytest.mark.parametrize("period", [0.001, 0.005])
def test_unrolled_guard_decides_as_the_array_guard(planar_path, rng, name: str,
                                                   period: float) -> None:
    """Near the rate bounds the law's torque is refused often enough that both answers
    are exercised; 5 ms is predicted in one step here (max_step)."""
    law = LAWS[name](models(planar_path)["absolute"])
    guard = Safeguard(law, period, SafeguardSettings(max_step=0.01))
    accepted, refused = guard_decisions(guard, admissible_states(law, rng, 200, True))
    assert accepted > 20 and refused > 20


def test_unrolled_guard_with_torque_limits_and_an_extra_constraint(planar_path, rng) -> None:
    model = models(planar_path)["absolute"]
    law = LAWS["bpbc"](model)
    extra = [PointOutsideSphere(model, "end_point", [0, 2, 0], 0.5, name="obstacle"),
             joint_position_limit([-0.5, -0.5], [3.5, 3.5], NAMES)]
    guard = Safeguard(law, 0.005, SafeguardSettings(max_step=0.01),
                      torque_limit=np.array([0.5, 0.3]), also_keep=extra)
    states = [s for s in admissible_states(law, rng, 300, True)
              if all(np.all(c.value(s[0]) > 0) for c in extra)]
    accepted, refused = guard_decisions(guard, states)
    assert accepted > 20 and refused > 20


def test_longer_periods_keep_the_sub_stepped_array_guard(absolute_model) -> None:
    law = LAWS["thesis_power"](absolute_model)
    guard = Safeguard(law, 0.005)  # 5 sub-steps of 1 ms
    guard.evaluate(np.array([0.3, 0.5]), np.array([0.05, -0.02]))
    assert guard._unrolled is None


def three_joint_arm() -> RobotModel:
    """Pinocchio's sample manipulator with its first and wrist joints locked (3 joints left),
    in coordinates x = T q with a dense T, friction on."""
    full = pin.buildSampleModelManipulator()
    reduced = pin.buildReducedModel(full, [1, 5, 6], np.array([0.2, 0, 0, 0, 0.3, -0.1]))
    coords = LinearCoordinates(np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.5, -1.0, 1.0]]))
    return RobotModel(reduced, coordinates=coords, viscous_friction=[0.2, 0.1, 0.05],
                      name="three")


def test_three_joint_arm_law_and_guard_agree_with_the_arrays(rng) -> None:
    model = three_joint_arm()
    assert model.n == SCALAR_SOLVE  # the largest unrolled Cholesky factorisation
    names = ["a", "b", "c"]
    target = np.array([0.1, -0.2, 0.3])
    constraints = ConstraintSet(
        3, [joint_position_limit([-1.0, -1.2, -1.1], [1.1, 1.0, 1.3], names),
            PointOutsideSphere(model, "effector_body", [0.3, 0.3, 0.6], 0.15,
                               offset=[0.0, 0.0, 0.05])],
        [joint_rate_limit([0.5, 0.6, 0.7], names)])
    law = CPBC(model, target, constraints, [30.0, 20.0, 10.0], 5.0, Power(0.3))
    states: list[tuple[np.ndarray, np.ndarray]] = []
    while len(states) < 150:
        x = rng.uniform(-1.0, 1.0, 3)
        dx = rng.uniform(-1.0, 1.0, 3)
        if all(np.all(c.value(x) > 0) for c in constraints.configuration):
            dx *= largest_speed(law, x, dx) * (1.0 - 10.0 ** rng.uniform(-7, 0))
            states.append((x, dx))
    for x, dx in states:
        tau, v = law.unrolled(x, dx)  # type: ignore[misc]
        tau_ref, v_ref = law.evaluate_arrays(x, dx)
        np.testing.assert_allclose(tau, tau_ref, rtol=1e-12, atol=1e-12)
        assert v == pytest.approx(v_ref, rel=1e-12)
    accepted, refused = guard_decisions(Safeguard(law, 0.001), states)
    assert accepted > 20 and refused > 20


@pytest.fixture(scope="module")
def panda():
    """The Panda of ``python -m cpbc.bench --robot panda``: joint and rate limits, a table, a
    ball and a crate against 33 link spheres (Clearance runs its own array code inside)."""
    from cpbc.bench_arms import panda as setup

    return setup(states=48)


@pytest.mark.parametrize("name", ["cpbc", "cpbc_ke", "bpbc"])
def test_panda_laws_and_guard_agree_with_the_arrays(panda, rng, name: str) -> None:
    law = panda.controllers[name]
    states = []
    for x, dx in panda.states:  # half as sampled, half close to the velocity boundary
        states.append((x, dx))
        states.append((x, dx * largest_speed(law, x, dx) * (1.0 - 10.0 ** rng.uniform(-7, -1))))
    for x, dx in states:
        tau, v = law.unrolled(x, dx)
        tau_ref, v_ref = law.evaluate_arrays(x, dx)
        tol = 1e-12 / min([1.0] + [float(np.min(c.value(x, dx, None) / c.value(x, 0 * dx, None)))
                                   for c in law.constraints.velocity])
        np.testing.assert_allclose(tau, tau_ref, rtol=tol, atol=tol * np.abs(tau_ref).max())
        assert v == pytest.approx(v_ref, rel=tol)
        np.testing.assert_array_equal(law.torque(x, dx), tau)
    accepted, refused = guard_decisions(Safeguard(law, 0.001), states)
    assert accepted > 10 and refused > 10
