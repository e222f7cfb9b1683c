"""The laws of Chapters 6–7: equal to the thesis's product forms, V̇ as the theorems state,
torque bounds, admissibility checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from lyapunov_rates import measured_rate

from cpbc.constraints import (
    ConstraintSet,
    KineticEnergyLimit,
    LinearLimit,
    PointOutsideSphere,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.controllers import (
    BPBC,
    CPBC,
    PD,
    BPBCKineticEnergy,
    CPBCKineticEnergy,
    Identity,
    PDGravity,
    Power,
    RecentredBarrier,
    Tanh,
)
from cpbc.controllers.potentials import Configuration
from cpbc.controllers.safeguard import Safeguard, SafeguardSettings
from cpbc.errors import ConstraintViolation, CpbcError, ParameterError
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.input_bounds import InputBounds
from cpbc.resources import models_dir

PLANAR = models_dir() / "planar_2link.xml"
X_OBS = np.array([0.0, 2.0])
R_OBS = 0.5
REL = 17 * np.pi / 18
B = np.array([0.3, 0.2])


# -- the thesis's own model (6.69) and constraints (Section 6.4), written out by hand --------
def thesis_dynamics(th: np.ndarray, dth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """D and C of eq. 6.69 in absolute link angles (m = 1, l = 1, l_c = 0.5, I = 1)."""
    d11 = 1 * 0.25 + 1 * 1 + 1
    d12 = 1 * 1 * 0.5 * math.cos(th[1] - th[0])
    d22 = 1 * 0.25 + 1
    h = 1 * 1 * 0.5 * math.sin(th[1] - th[0])
    return np.array([[d11, d12], [d12, d22]]), np.array([[0, -h * dth[1]], [h * dth[0], 0]])


def thesis_phi(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """φ₁ (end point outside the circle) and φ₂ (relative angle), with gradients."""
    px, py = math.cos(th[0]) + math.cos(th[1]), math.sin(th[0]) + math.sin(th[1])
    phi1 = (px - X_OBS[0]) ** 2 + (py - X_OBS[1]) ** 2 - R_OBS**2
    g1 = np.array(
        [
            2 * (px - X_OBS[0]) * -math.sin(th[0]) + 2 * (py - X_OBS[1]) * math.cos(th[0]),
            2 * (px - X_OBS[0]) * -math.sin(th[1]) + 2 * (py - X_OBS[1]) * math.cos(th[1]),
        ]
    )
    phi2 = REL**2 - (th[1] - th[0]) ** 2
    g2 = np.array([2 * (th[1] - th[0]), -2 * (th[1] - th[0])])
    return np.array([phi1, phi2]), np.array([g1, g2])


def product_form(th, dth, target, kp, kd, s, ds, with_phi=True, bounded=False):
    """Eq. 6.24 / 6.70 / 7.17 with general shaping s (s' = ds), products formed explicitly."""
    d, c = thesis_dynamics(th, dth)
    err = th - target
    if bounded:
        lag = 0.5 * dth @ d @ dth + np.sum(kp * np.log(np.cosh(err)))
        shaped = kp * np.tanh(err) + kd * np.tanh(dth)
    else:
        lag = 0.5 * dth @ d @ dth + 0.5 * err @ (kp * err)
        shaped = kp * err + kd * dth
    psi = 0.5 * (B**2 - dth**2)
    big_psi = psi.prod()
    p_mat = np.diag([psi[1], psi[0]])  # Σ_s (Π_{j≠s} ψ_j) e_s e_sᵀ
    if with_phi:
        phi, grads = thesis_phi(th)
        big_phi = phi.prod()
        a_phi = phi[1] * grads[0] + phi[0] * grads[1]
    else:
        big_phi, a_phi = 1.0, np.zeros(2)
    x = big_phi * big_psi
    lhs = s(x) * d + lag * ds(x) * big_phi * p_mat
    rhs = (
        -s(x) * shaped
        + lag * ds(x) * big_psi * a_phi  # a_ψ = 0: Ω and Q are constant
        + lag * ds(x) * big_phi * p_mat @ np.linalg.solve(d, c @ dth)
    )
    return d @ np.linalg.solve(lhs, rhs)


SHAPINGS = {
    "identity": (Identity(), lambda x: x, lambda x: 1.0),
    "power": (Power(0.2), lambda x: x**0.2, lambda x: 0.2 * x ** (-0.8)),
    "tanh": (Tanh(5.0), lambda x: math.tanh(5 * x), lambda x: 5 / math.cosh(5 * x) ** 2),
}


@pytest.fixture(scope="module")
def absolute_model() -> RobotModel:
    return RobotModel.from_mjcf(PLANAR, coordinates=LinearCoordinates.absolute_link_angles(2))


def thesis_ch6_constraints(model: RobotModel) -> ConstraintSet:
    obstacle = PointOutsideSphere(model, "end_point", [0, 2, 0], 0.5, name="obstacle")
    relative = LinearLimit([[-1, 1]], [-REL], [REL], ["relative"])
    return ConstraintSet(2, [obstacle, relative], [joint_rate_limit(B, ["t1", "t2"])])


def admissible_states(rng: np.random.Generator, count: int, with_phi: bool = True):
    out = []
    while len(out) < count:
        th = rng.uniform(-np.pi, np.pi, 2)
        dth = rng.uniform(-0.95, 0.95, 2) * B
        if with_phi and not np.all(thesis_phi(th)[0] > 1e-3):
            continue
        out.append((th, dth))
    return out


@pytest.mark.parametrize("shaping", sorted(SHAPINGS))
def test_cpbc_equals_thesis_product_form(absolute_model: RobotModel, shaping: str) -> None:
    obj, s, ds = SHAPINGS[shaping]
    target = np.array([np.pi, 2 * np.pi / 3])
    ctrl = CPBC(absolute_model, target, thesis_ch6_constraints(absolute_model), 4, 20, obj)
    for th, dth in admissible_states(np.random.default_rng(1), 40):
        expected = product_form(th, dth, target, np.full(2, 4.0), np.full(2, 20.0), s, ds)
        np.testing.assert_allclose(ctrl.torque(th, dth), expected, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("shaping", sorted(SHAPINGS))
def test_bpbc_equals_thesis_product_form(absolute_model: RobotModel, shaping: str) -> None:
    obj, s, ds = SHAPINGS[shaping]
    target = np.array([np.pi, np.pi])
    kp, kd = np.array([2.0, 10.0]), np.array([4.0, 20.0])
    rates = ConstraintSet(2, velocity=[joint_rate_limit(B, ["t1", "t2"])])
    ctrl = BPBC(absolute_model, target, rates, kp, kd, 1.0, 1.0, obj)
    for th, dth in admissible_states(np.random.default_rng(2), 40, with_phi=False):
        expected = product_form(th, dth, target, kp, kd, s, ds, with_phi=False, bounded=True)
        np.testing.assert_allclose(ctrl.torque(th, dth), expected, rtol=1e-7, atol=1e-9)


def test_cpbc_ke_equals_corollary_6_11(absolute_model: RobotModel) -> None:
    target = np.array([np.pi, 2 * np.pi / 3])
    omega = 0.2
    obstacle = PointOutsideSphere(absolute_model, "end_point", [0, 2, 0], 0.5)
    relative = LinearLimit([[-1, 1]], [-REL], [REL], ["relative"])
    ke = KineticEnergyLimit(absolute_model, omega)
    ctrl = CPBCKineticEnergy(
        absolute_model, target, ConstraintSet(2, [obstacle, relative], [ke]), 4, 20
    )
    rng = np.random.default_rng(3)
    checked = 0
    for th, dth in admissible_states(rng, 60):
        d, _ = thesis_dynamics(th, dth)
        kinetic = 0.5 * dth @ d @ dth
        if kinetic >= omega:
            continue
        phi, grads = thesis_phi(th)
        big_phi, a_phi = phi.prod(), phi[1] * grads[0] + phi[0] * grads[1]
        err = th - target
        lag = kinetic + 0.5 * 4 * err @ err
        psi = omega - kinetic
        expected = psi / (big_phi * (psi + lag)) * (-big_phi * (4 * err + 20 * dth) + lag * a_phi)
        np.testing.assert_allclose(ctrl.torque(th, dth), expected, rtol=1e-8, atol=1e-10)
        checked += 1
    assert checked > 20


# -- V̇ along the closed loop, on a model with gravity and friction ---------------------------
def tilted_laws(model: RobotModel):
    target = np.array([0.4, -0.3])
    rates = joint_rate_limit([1.5, 2.0], ["j1", "j2"])
    limits = joint_position_limit([-1.2, -2.0], [1.5, 1.0], ["j1", "j2"])
    sphere = PointOutsideSphere(model, "tip", [1.2, 0.0, -1.2], 0.3)
    ke = KineticEnergyLimit(model, 2.0)
    kp, kd = np.array([30.0, 20.0]), np.array([5.0, 3.0])
    n = 2
    return [
        ("pd_gravity", PDGravity(model, target, kp, kd), None),
        ("cpbc", CPBC(model, target, ConstraintSet(n, [limits, sphere], [rates]), kp, kd,
                      Power(0.3)), "s"),
        ("cpbc_tanh", CPBC(model, target, ConstraintSet(n, [sphere], [rates, ke]), kp, kd,
                           Tanh(0.7)), "s"),
        ("cpbc_ke", CPBCKineticEnergy(model, target, ConstraintSet(n, [limits, sphere], [ke]),
                                      kp, kd, Power(0.5)), "ke"),
        ("recentred", RecentredBarrier(model, target, ConstraintSet(n, [limits]), kp, kd), 1),
        ("recentred_rates", RecentredBarrier(model, target, ConstraintSet(n, [limits], [rates]),
                                             kp, kd), "psi"),
        ("bpbc", BPBC(model, target, ConstraintSet(n, [], [rates]), kp, kd, 2.0, 3.0,
                      Power(0.2)), "s"),
        ("bpbc_ke", BPBCKineticEnergy(model, target, ConstraintSet(n, [], [ke]), kp, kd, 2.0,
                                      3.0, Identity()), "ke"),
    ]


def expected_rate(name: str, ctrl, model: RobotModel, x, dx, divisor) -> float:
    """The V̇ each theorem states (6.11, 6.32, 6.58/6.64, 7.22, Corollaries 6.11 and 7.8)."""
    f = model.dissipation(dx)
    damping = ctrl.damping.force(dx) if hasattr(ctrl, "damping") else ctrl.kd * dx
    if divisor is None:
        return -dx @ (damping + f)
    if divisor == 1:
        return -dx @ (damping + f)
    if divisor == "psi":
        psi = np.prod(ctrl._velocity.margins(x, dx))
        return -dx @ (damping + f) / psi
    bar = ctrl.constraints.barrier(ctrl.constraints.state(model, x, dx))
    log_x = bar.log_phi + bar.log_psi
    s = math.exp(ctrl.shaping.log_s(log_x))
    if divisor == "s":
        return -dx @ (damping + f) / s
    psi = ctrl.energy.limit - model.kinetic_energy(x, dx)
    lag = model.kinetic_energy(x, dx) + ctrl.potential.evaluate(Configuration(x))[0]
    rho = ctrl.shaping.ratio(log_x) * lag
    return -(dx @ damping + (1 + rho / psi) * dx @ f) / s


@pytest.mark.parametrize("index", range(8))
def test_lyapunov_rate_matches_theorem(tilted: RobotModel, index: int) -> None:
    name, ctrl, divisor = tilted_laws(tilted)[index]
    rng = np.random.default_rng(10 + index)
    checked = 0
    for _ in range(200):
        x = rng.uniform([-1.1, -1.9], [1.4, 0.9])
        dx = rng.uniform(-1.0, 1.0, 2)
        try:
            ctrl.constraints.check_admissible(x, dx, "sample")
        except CpbcError:
            continue
        got = measured_rate(ctrl, tilted, x, dx)
        want = expected_rate(name, ctrl, tilted, x, dx, divisor)
        assert want <= 0
        assert got == pytest.approx(want, rel=1e-4, abs=1e-6), name
        checked += 1
        if checked == 15:
            break
    assert checked == 15


# -- torque bounds (7.32), (7.40) ------------------------------------------------------------
def test_bpbc_bound_matches_thesis_7_42(absolute_model: RobotModel) -> None:
    rates = ConstraintSet(2, velocity=[joint_rate_limit(B, ["t1", "t2"])])
    ctrl = BPBC(absolute_model, np.array([np.pi, np.pi]), rates, [2, 10], [4, 20], 1, 1,
                Power(0.2))
    assert ctrl.model_bounds.gravity == pytest.approx(0.0, abs=1e-12)
    assert ctrl.model_bounds.coriolis == pytest.approx(0.5, rel=1e-3)
    assert ctrl.torque_bound == pytest.approx(30.065, rel=1e-4)


@pytest.mark.parametrize("kind", ["bpbc", "bpbc_ke"])
def test_torque_stays_below_bound_on_random_states(tilted: RobotModel, kind: str) -> None:
    laws = dict((n, c) for n, c, _ in tilted_laws(tilted))
    ctrl = laws[kind]
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(2000):
        x = rng.uniform(-np.pi, np.pi, 2)
        dx = rng.uniform(-2.0, 2.0, 2)
        try:
            tau = ctrl.torque(x, dx)
        except ConstraintViolation:
            continue
        worst = max(worst, float(np.linalg.norm(tau)))
    assert 0 < worst <= ctrl.torque_bound_norm
    assert ctrl.torque_bound <= ctrl.torque_bound_norm


def test_constrained_law_refuses_state_outside_set(absolute_model: RobotModel) -> None:
    ctrl = CPBC(absolute_model, np.array([np.pi, 2 * np.pi / 3]),
                thesis_ch6_constraints(absolute_model), 4, 20, Power(0.2))
    with pytest.raises(ConstraintViolation, match="rate"):
        ctrl.torque(np.zeros(2), np.array([0.31, 0.0]))
    with pytest.raises(ConstraintViolation, match="obstacle"):
        ctrl.torque(np.array([np.pi / 2, np.pi / 2]), np.zeros(2))  # end point at (0, 2)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"kp": 0}, "kp"), ({"kd": [1, -1]}, "kd"), ({"kp": [1, 2, 3]}, "kp"),
     ({"kd": float("nan")}, "kd")],
)
def test_gain_validation(absolute_model: RobotModel, kwargs: dict, match: str) -> None:
    gains = {"kp": 1.0, "kd": 1.0} | kwargs
    with pytest.raises(CpbcError, match=match):
        PD(absolute_model, np.zeros(2), **gains)


@pytest.mark.parametrize(("target", "says"), [
    ([0.1, float("nan")], "got nan at index 1"), ([0.1], r"got shape \(1,\)"),
    ([0.0, float("-inf")], "got -inf at index 1")])
def test_target_validation(absolute_model: RobotModel, target, says) -> None:
    """A target that is not n finite numbers: a ValueError naming ``target`` (a NaN one was
    taken, and every torque of the law was NaN)."""
    with pytest.raises(ParameterError, match=rf"^target must be 2 finite numbers .*{says}"):
        PD(absolute_model, np.array(target), 1.0, 1.0)


def test_the_callers_target_is_not_frozen(absolute_model: RobotModel) -> None:
    """The law keeps its own read-only copy: the caller's array stays writable (it was
    made read-only in place)."""
    mine = np.array([0.1, 0.2])
    law = PD(absolute_model, mine, 1.0, 1.0)
    mine[0] = 0.5
    assert law.target[0] == 0.1 and not law.target.flags.writeable


def test_law_specific_constraint_checks(absolute_model: RobotModel) -> None:
    ch6 = thesis_ch6_constraints(absolute_model)
    with pytest.raises(CpbcError, match="per-joint rate limits only"):
        BPBC(absolute_model, np.zeros(2), ch6, 1, 1)
    with pytest.raises(CpbcError, match="kinetic_energy_limit"):
        CPBCKineticEnergy(absolute_model, np.zeros(2), ch6, 1, 1)
    with pytest.raises(CpbcError, match="joint position limits"):
        RecentredBarrier(absolute_model, np.zeros(2), ch6, 1, 1)


def _offset_law(law):
    """The same law as an instance of a subclass whose formula ``_law`` adds a constant
    torque: how a user extends a law (BPBC extends CPBC the same way)."""
    base = type(law)
    extra = np.array([1.0, -1.0])

    class Shifted(base):  # type: ignore[misc, valid-type]
        def _law(self, *args, **kwargs):  # type: ignore[no-untyped-def]
            return super()._law(*args, **kwargs) + extra

    law.__class__ = Shifted  # the same object, now of the subclass
    return law, extra


@pytest.mark.parametrize("index", range(8))
def test_overriding_a_laws_formula_changes_its_torque(tilted: RobotModel, index: int) -> None:
    """torque(), evaluate() and the safeguarded torque all come from the one formula: a
    subclass that overrides it gets its own torque, for every law."""
    name, law, _ = tilted_laws(tilted)[index]
    shifted, extra = _offset_law(tilted_laws(tilted)[index][1])
    rng = np.random.default_rng(index)
    checked = 0
    for _ in range(20):
        x, dx = rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.3, 0.3, 2)
        if not np.all(law.constraints.margins(x, dx) > 0):
            continue
        tau = law.torque(x, dx)
        np.testing.assert_allclose(shifted.torque(x, dx), tau + extra, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(shifted.evaluate(x, dx)[0], tau + extra, rtol=1e-12,
                                   atol=1e-12)
        np.testing.assert_allclose(shifted.evaluate_state(shifted.state(x, dx)).torque,
                                   tau + extra, rtol=1e-12, atol=1e-12)
        # V to rounding, as τ: the subclass takes the general path, which reads the frame's
        # placement from Pinocchio; the packed step reads it from the joint kinematics
        assert shifted.evaluate(x, dx)[1] == pytest.approx(law.evaluate(x, dx)[1], rel=1e-12)
        if not law.constraints.empty:  # the guard asks the subclass, not the base class
            guarded = Safeguard(shifted, InputBounds(0.001),
                                SafeguardSettings(decay_rate=1e6, hold_correction=False))
            np.testing.assert_allclose(guarded.torque(x, dx), tau + extra, rtol=1e-12,
                                       atol=1e-12)
        checked += 1
    assert checked >= 5, name


@pytest.mark.parametrize("base", [PD, PDGravity])
def test_overriding_a_baselines_feed_forward_changes_every_path(tilted: RobotModel,
                                                                  base: type[PD]) -> None:
    """The baselines' state-only feed-forward (none; gravity) is one hook, ``_bias``: a
    subclass that overrides it gets its torque from torque(), evaluate() and evaluate_state()
    alike (evaluate_state once read a hook of its own, so the override reached only two)."""
    extra = np.array([0.7, -0.4])

    class Biased(base):  # type: ignore[misc, valid-type]
        def _bias(self, x, state):  # type: ignore[no-untyped-def]
            return super()._bias(x, state) + extra

    target, kp, kd = np.array([0.4, -0.3]), np.array([30.0, 20.0]), np.array([5.0, 3.0])
    law, biased = base(tilted, target, kp, kd), Biased(tilted, target, kp, kd)
    x, dx = np.array([0.2, 0.5]), np.array([-0.3, 0.1])
    tau = law.torque(x, dx)
    for got in (biased.torque(x, dx), biased.evaluate(x, dx)[0],
                biased.evaluate_state(biased.state(x, dx)).torque):
        np.testing.assert_allclose(got, tau + extra, rtol=1e-12, atol=1e-12)
