"""Clearance constraints of the whole arm: values, gradients, the localised barrier."""

from __future__ import annotations

from functools import cache

import numpy as np
import pinocchio as pin
import pytest

from cpbc.constraints import ConstraintSet
from cpbc.constraints.clearance import Clearance
from cpbc.constraints.covering import LinkPrimitive, cover_links
from cpbc.constraints.geometry import (
    BoxObstacle,
    CapsuleObstacle,
    PlaneObstacle,
    SphereObstacle,
)
from cpbc.constraints.linear_limit import joint_position_limit
from cpbc.errors import ConstraintViolation, CpbcError, ModelError
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.loading import LoadedArm, load_arm

HOME = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
OBSTACLES = (
    SphereObstacle("ball", [0.5, 0.0, 0.5], 0.1),
    BoxObstacle("crate", [0.4, -0.4, 0.2], [0.1, 0.15, 0.2], [0.0, 0.0, 0.3]),
    PlaneObstacle("table", [0.0, 0.0, -0.05]),
    CapsuleObstacle("pole", [0.3, 0.5, 0.0], [0.3, 0.5, 1.0], 0.04, kind="cylinder"),
)
SELF = (("panda_link1", "panda_hand"), ("panda_link2", "panda_link6"))


@cache
def _panda() -> tuple[LoadedArm, RobotModel]:
    arm = load_arm("panda")
    return arm, RobotModel(arm.model, name="panda")


@cache
def _cover(kind: str) -> tuple[LinkPrimitive, ...]:
    arm, _ = _panda()
    if kind == "mixed":
        caps = cover_links(arm.model, arm.collision_model, kind="capsules")[:5]
        rest = cover_links(arm.model, arm.collision_model,
                           links=["panda_link6", "panda_link7", "panda_hand"])
        return tuple(caps + rest)
    return tuple(cover_links(arm.model, arm.collision_model, kind=kind))


def _clearance(kind: str = "spheres", influence: float | None = 0.3, **kw) -> Clearance:
    _, model = _panda()
    kw.setdefault("self_pairs", SELF)
    return Clearance(model, _cover(kind), OBSTACLES, margin=0.01, influence=influence, **kw)


def _states(rng: np.random.Generator, count: int = 12):
    return [HOME + rng.normal(scale=0.5, size=7) for _ in range(count)]


def _terms(c: Clearance, x: np.ndarray, margins: bool = False
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Clearance's barrier terms as a law reads them: from the per-step state at (x, 0)."""
    return c.barrier_terms(c.model.state(x, np.zeros(len(x)), kinematics=True), margins)


@pytest.mark.parametrize("kind", ["spheres", "capsules", "mixed"])
def test_gradient_matches_finite_differences(kind, rng, central_difference) -> None:
    c = _clearance(kind)
    for x in _states(rng):
        phi, grad = c.evaluate(x)
        np.testing.assert_allclose(phi, c.value(x))
        np.testing.assert_allclose(grad, c.gradient(x))
        fd = central_difference(c.value, x)
        ok = phi > 0
        np.testing.assert_allclose(grad[ok], fd[ok], atol=2e-7)


@pytest.mark.parametrize("influence", [None, 0.3])
@pytest.mark.parametrize("kind", ["spheres", "capsules", "mixed"])
def test_barrier_terms_are_the_gradient_of_the_log_barrier(
    kind, influence, rng, central_difference
) -> None:
    c = _clearance(kind, influence)
    checked = 0
    for x in _states(rng, 16):
        if not np.all(c.value(x) > 0):
            continue
        phi_tilde, b = _terms(c, x)[:2]
        assert np.all(phi_tilde > 0)
        fd = central_difference(lambda z: np.log(_terms(c, z)[0]).sum(), x)
        np.testing.assert_allclose(b, fd, atol=1e-6 * max(1.0, np.abs(b).max()))
        checked += 1
    assert checked >= 5


def test_skipping_far_capsule_groups_is_exact(rng) -> None:
    """The capsules' broad phase changes nothing in the barrier."""
    c = _clearance("capsules", 0.15)
    reference = _clearance("capsules", 0.15)
    reference._near_groups = lambda y: reference._groups  # type: ignore[method-assign]
    for x in _states(rng, 30):
        if not np.all(c.value(x) > 0):
            continue
        phi, b = _terms(c, x)[:2]
        phi_r, b_r = _terms(reference, x)[:2]
        np.testing.assert_allclose(phi, phi_r, rtol=1e-12)
        np.testing.assert_allclose(b, b_r, atol=1e-12)


@pytest.mark.parametrize("influence", [None, 0.3, 0.167, 0.15])  # 0.167 · (1/0.167) ≠ 1
def test_dense_sphere_barrier_is_the_pairwise_product_and_sum(influence, rng) -> None:
    """The sphere pairs go through the barrier densely (a pair beyond ℓ, or one that cannot
    move: factor 1, no slope) and their forces are summed per sphere and per link: the same
    as taking the pairs one by one, each with its clearance, φ̃ and gradient."""
    c = _clearance("spheres", influence)  # self pairs and a rotated box included
    s = c._spheres
    assert s is not None and s.n_obstacle < len(s.group)
    static = s.moving == 0.0
    checked = far = 0
    for x in _states(rng, 30):
        if not np.all(c.value(x) > 0):
            continue
        phi_t, b = _terms(c, x)[:2]
        phi, grad = c.sphere_pairs(x, np.zeros(7))[:2]
        shaped, ratio = c._shape(phi)
        expect = np.array(c._far_phi)
        b_ref = np.zeros(7)
        for p in np.flatnonzero(~static):  # pair by pair
            expect[s.group[p]] *= shaped[p] / (influence or 1.0)
            b_ref += ratio[p] * grad[p]
        np.testing.assert_allclose(phi_t[:s.stop], expect[:s.stop], rtol=1e-13)
        np.testing.assert_allclose(b, b_ref, rtol=0, atol=1e-12 * max(1.0, np.abs(b_ref).max()))
        far += influence is not None and phi[~static].min() >= influence
        checked += 1
    assert checked >= 5
    if influence == 0.15:
        assert far >= 1  # the early exit is among the states checked


def test_localised_barrier_shape() -> None:
    c = _clearance(influence=0.2)
    phi = np.array([1e-6, 0.05, 0.1999, 0.2, 0.5])
    shaped, ratio = c._shape(phi)
    np.testing.assert_allclose(shaped[0], 3e-6, rtol=1e-5)  # 3φ at the boundary
    np.testing.assert_allclose(ratio[0], 1 / 1e-6, rtol=1e-5)  # the same barrier force
    assert shaped[3] == shaped[4] == 0.2 and ratio[3] == ratio[4] == 0.0
    assert np.all(np.diff(shaped) >= 0)
    # C¹ at the cut-off: the slope tends to zero
    assert ratio[2] < 1e-5


def test_far_from_everything_costs_no_gradient() -> None:
    _, model = _panda()
    far = [SphereObstacle("far", [3.0, 3.0, 3.0], 0.1)]
    c = Clearance(model, _cover("spheres"), far, influence=0.1)
    phi, b = _terms(c, HOME)[:2]
    assert np.all(phi == 0.1) and np.all(b == 0)
    assert np.all(c.value(HOME) > 2.0)


def _hand_at_home() -> np.ndarray:
    arm, _ = _panda()
    pdata = arm.model.createData()
    pin.framesForwardKinematics(arm.model, pdata, HOME)
    return pdata.oMf[arm.model.getFrameId("panda_hand")].translation.copy()


def test_penetration_is_negative_and_the_law_refuses_it() -> None:
    _, model = _panda()
    hand = _hand_at_home()
    inside = [SphereObstacle("on_hand", hand, 0.05),
              BoxObstacle("box_on_hand", hand, [0.05, 0.05, 0.05])]
    c = Clearance(model, _cover("spheres"), inside, influence=0.1, name="hit")
    values = dict(zip(c.names, c.value(HOME), strict=True))
    assert values["hit[panda_hand|on_hand]"] < 0
    assert values["hit[panda_hand|box_on_hand]"] < 0
    with pytest.raises(ConstraintViolation):
        ConstraintSet(7, [c]).barrier(model.state(HOME, np.zeros(7), kinematics=True))


def test_names_are_per_link_and_obstacle() -> None:
    c = _clearance()
    assert "clearance[panda_hand|ball]" in c.names
    assert "clearance[panda_link1|panda_hand]" in c.names
    assert len(c.names) == 10 * len(OBSTACLES) + len(SELF)
    assert len(set(c.names)) == len(c.names)


@pytest.mark.parametrize("kind", ["spheres", "capsules", "mixed"])
def test_the_gradient_at_a_state_is_the_gradient_at_its_configuration(kind, rng) -> None:
    """gradient_at reads the per-step state's kinematics (the guard's path: no Pinocchio
    pass), and a set's rows stack its constraints' in the order of its names: the same rows
    as ``gradient`` at x; a state built without kinematics falls back to ``gradient``."""
    c = _clearance(kind)
    _, model = _panda()
    lower, upper = -np.full(7, 2.8), np.full(7, 2.8)
    limits = joint_position_limit(lower, upper, [f"j{i}" for i in range(7)])
    both = ConstraintSet(7, [limits, c])
    for x in _states(rng, 6):
        dx = rng.normal(size=7)
        state = model.state(x, dx, kinematics=True)
        np.testing.assert_allclose(c.gradient_at(state), c.gradient(x), rtol=1e-12,
                                   atol=1e-14)
        np.testing.assert_allclose(both.configuration_gradients(state),
                                   np.vstack([limits.gradient(x), c.gradient(x)]),
                                   rtol=1e-12, atol=1e-14)
        np.testing.assert_array_equal(c.gradient_at(model.state(x, dx)), c.gradient(x))


def test_controller_coordinates(rng, central_difference) -> None:
    arm, _ = _panda()
    t = np.eye(7) + np.tril(rng.normal(scale=0.3, size=(7, 7)), -1)
    model = RobotModel(arm.model, LinearCoordinates(t), name="panda")
    c = Clearance(model, _cover("spheres"), OBSTACLES[:2], margin=0.01, influence=0.3)
    plain = _clearance(self_pairs=())
    x = t @ HOME
    np.testing.assert_allclose(c.value(x)[:20], plain.value(HOME)[:20])
    np.testing.assert_allclose(c.gradient(x), central_difference(c.value, x), atol=2e-7)


def test_constructor_validates() -> None:
    _, model = _panda()
    prims = _cover("spheres")
    with pytest.raises(CpbcError, match="margin"):
        Clearance(model, prims, OBSTACLES, margin=-0.1)
    with pytest.raises(CpbcError, match="influence"):
        Clearance(model, prims, OBSTACLES, influence=0.0)
    with pytest.raises(CpbcError, match="no primitive on link 'panda_link9'"):
        Clearance(model, prims, OBSTACLES, self_pairs=[("panda_link1", "panda_link9")])
    with pytest.raises(CpbcError, match="welded to the world"):
        Clearance(model, [LinkPrimitive("base", "panda_link0", np.zeros(3), np.zeros(3), 0.1)],
                  OBSTACLES)
    with pytest.raises(ModelError, match="no frame 'nope'"):
        Clearance(model, [LinkPrimitive("x", "nope", np.zeros(3), np.zeros(3), 0.1)],
                  OBSTACLES)
    with pytest.raises(CpbcError, match="obstacle names must be unique"):
        Clearance(model, prims, [OBSTACLES[0], OBSTACLES[0]])


def test_pairs_that_cannot_move_leave_the_law() -> None:
    """Link 1 turns about the vertical: its height above the table never changes. Its four
    sphere pairs with the table are a constant factor, and a link resting within ℓ of the
    table does not keep the sphere barrier awake."""
    c = _clearance(influence=0.1, self_pairs=())
    s = c._spheres
    assert s is not None
    static = s.moving == 0.0
    assert {c.names[i] for i in s.group[static]} == {"clearance[panda_link1|table]"}
    assert static.sum() == 4 and np.all(np.isneginf(s.rsum_law[static]))
    _, model = _panda()
    low_table = Clearance(model, _cover("spheres"), [PlaneObstacle("table", [0.0, 0.0, 0.05])],
                          influence=0.1)
    x = np.array([0.0, -0.8, 0.0, -2.2, 0.0, 2.5, 0.8])  # the arm up, link 1 near the table
    values = dict(zip(low_table.names, low_table.value(x), strict=True))
    assert 0 < values["clearance[panda_link1|table]"] < 0.1
    assert min(v for k, v in values.items() if "link1" not in k) > 0.1
    phi, b = _terms(low_table, x)[:2]
    assert np.all(b == 0.0) and phi is low_table._far_phi


def test_margins_after_the_barrier_are_clearances_not_the_shaped_barrier(rng) -> None:
    c = _clearance("spheres", influence=0.3)
    cs = ConstraintSet(7, [c])
    _, model = _panda()
    for x in _states(rng, 4):
        dx = np.zeros(7)
        try:
            bar = cs.barrier(model.state(x, dx, kinematics=True), margins=True)
        except ConstraintViolation:
            continue
        np.testing.assert_array_equal(bar.margins, c.value(x))


@pytest.mark.parametrize("kind", ["spheres", "mixed"])
def test_the_barrier_reads_the_state_not_the_models_pinocchio_data(kind, rng) -> None:
    """The barrier terms are a function of the per-step state alone: the model's Pinocchio
    data moved to another configuration (any later model call) changes nothing, bit for bit."""
    c = _clearance(kind, influence=0.3)
    cs = ConstraintSet(7, [c])
    _, model = _panda()
    checked = 0
    for x in _states(rng, 6):
        state = cs.state(model, x, np.zeros(7))
        try:
            first = cs.barrier(state, margins=True)
        except ConstraintViolation:
            continue
        model.state(x[::-1].copy(), np.ones(7), kinematics=True, coriolis=True)
        again = cs.barrier(state, margins=True)
        for a, b in zip(first, again, strict=True):
            np.testing.assert_array_equal(a, b)
        checked += 1
    assert checked >= 3


@pytest.mark.parametrize("kind", ["spheres", "mixed"])
def test_values_along_and_barrier_with_value_are_value_bit_for_bit(kind, rng) -> None:
    """The batched values and the barrier pass's values are ``value`` row by row, exactly
    (the safeguard's acceptance test reads them in place of ``value``)."""
    c = _clearance(kind, 0.3)
    xs = np.array(_states(rng, 6))
    along = c.values_along(xs)
    assert along.shape == (6, len(c.names))
    for x, row in zip(xs, along, strict=True):
        np.testing.assert_array_equal(row, c.value(x))
        phi, b, value = _terms(c, x, margins=True)
        np.testing.assert_array_equal(value, c.value(x))
        phi_b, b_b = _terms(c, x)[:2]
        np.testing.assert_array_equal(phi, phi_b)
        np.testing.assert_array_equal(b, b_b)


def test_the_clearances_of_some_constraints_are_theirs_bit_for_bit(rng) -> None:
    """``sphere_clearances_of`` (the safeguard's test, where a bound settles the rest)
    writes the marked constraints' clearances exactly as ``value`` gives them and leaves the
    others' entries as they were: at random states and masks, and with the hand inside an
    obstacle's core."""
    from cpbc.kernels.clearance import sphere_clearances_of

    _, model = _panda()
    core = Clearance(model, _cover("spheres"),
                     [BoxObstacle("box", _hand_at_home(), [0.05, 0.05, 0.05])])
    data = model.model.createData()
    for c, states in ((_clearance("spheres", 0.3), _states(rng, 6)), (core, [HOME])):
        s = c._spheres
        assert s is not None
        k = int(s.pair_index[:, 3].max()) + 1
        work = np.empty(3 * len(s.sphere_index) + 7 * len(s.pair_index))
        for x in states:
            y = pin.computeStaticRegressor(model.model, data, x)
            full = np.empty(k)
            sphere_clearances_of(y, s.sphere_index, s.sphere_local, s.obstacles,
                                 s.pair_index, s.pair_table, work, np.ones(k, dtype=bool),
                                 full)
            np.testing.assert_array_equal(full, c.value(x)[:k])
            for _ in range(4):
                need = rng.random(k) < 0.3
                out = np.full(k, 7.0)
                sphere_clearances_of(y, s.sphere_index, s.sphere_local, s.obstacles,
                                     s.pair_index, s.pair_table, work, need, out)
                np.testing.assert_array_equal(out[need], full[need])
                assert np.all(out[~need] == 7.0)
    assert core.value(HOME).min() < 0.0


def test_values_along_inside_an_obstacle_core() -> None:
    """A sphere centre inside a box: the signed depth there, as ``value`` gives it."""
    _, model = _panda()
    hand = _hand_at_home()
    c = Clearance(model, _cover("spheres"), [BoxObstacle("box", hand, [0.05, 0.05, 0.05])])
    xs = np.array([HOME, HOME + 0.3])
    along = c.values_along(xs)
    assert along[0].min() < 0
    for x, row in zip(xs, along, strict=True):
        np.testing.assert_array_equal(row, c.value(x))


@pytest.mark.parametrize("step", [0.01, 0.3])
def test_a_clearance_moves_no_further_than_its_reach(step: float, rng) -> None:
    """The sphere constraints' ``reach`` (Kinematics._reach) bounds how far each clearance
    moves between two configurations, against its value computed at both, on random pairs
    near each other and far apart; with room to spare of at most a few times the motion
    (not a vacuous bound)."""
    from cpbc.kernels.clearance import MOVED_ROUNDING

    c = _clearance("spheres")
    assert c._spheres is not None
    reach = c._spheres.reach
    assert reach.shape == (len(c.names), 7) and np.all(np.isfinite(reach))
    worst = 0.0
    for x in _states(rng, 40):
        q = x + rng.uniform(-step, step, size=7)
        moved = reach @ np.abs(q - x)
        assert np.all(c.value(q) >= c.value(x) - moved - MOVED_ROUNDING)
        worst = max(worst, float(np.max(np.abs(c.value(q) - c.value(x)) / moved)))
    assert 0.2 < worst <= 1.0


def test_reach_counts_each_joint_that_moves_a_sphere() -> None:
    """A joint moves a link's spheres only when it supports the link: reach is zero on the
    others, and the base joint's reach of the hand's spheres is at least their height above
    its axis's origin."""
    c = _clearance("spheres", self_pairs=())
    s = c._spheres
    assert s is not None
    for row, name in enumerate(c.names):
        link = name.split("[")[1].split("|")[0]
        supports = c.model.joint_supports()[c.model.model.frames[
            c.model.frame_id(link)].parentJoint]
        assert np.all((s.reach[row] > 0) == (supports > 0)), name
    hand = next(i for i, n in enumerate(c.names) if "panda_hand|" in n)
    assert s.reach[hand, 0] >= 0.1


def test_motion_terms_of_sphere_primitives_are_the_calls_apart_bit_for_bit(rng) -> None:
    """Sphere primitives in joint coordinates take φ, ∇φ and ẋᵀ∇²φ ẋ from one compiled call
    (sphere_motion_terms): the clearances ``value`` gives at x, the gradients ``gradient_at``
    gives at the state and the curvature ``curvature`` gives at (x, ẋ), to the bit."""
    c = _clearance("spheres")
    _, model = _panda()
    for x in _states(rng, 8):
        dx = rng.normal(size=7)
        state = model.state(x, dx, kinematics=True)
        phi, grad, curv = c.motion_terms(state)
        np.testing.assert_array_equal(phi, c.value(x))
        np.testing.assert_array_equal(grad, c.gradient_at(state))
        np.testing.assert_array_equal(curv, c.curvature(x, dx))
