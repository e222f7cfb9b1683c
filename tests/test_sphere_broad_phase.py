"""The law's broad phase over the clearance's sphere pairs (cpbc.kernels.clearance
``near_groups``): a group of pairs is skipped only when every pair of it is beyond ℓ, and
skipping changes nothing — φ̃, Σ ∇φ̃/φ̃ and the law's torque equal, bit for bit, those of
the same clearance with the broad phase off (every group's reach ∞)."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from cpbc.bench_arms import panda
from cpbc.constraints import ConstraintSet
from cpbc.constraints.clearance import Clearance
from cpbc.constraints.covering import cover_links
from cpbc.constraints.geometry import PlaneObstacle, SphereObstacle
from cpbc.controllers import CPBC, Power
from cpbc.kernels.clearance import near_groups
from cpbc.model import RobotModel
from cpbc.model.loading import load_arm

UR5_HOME = np.array([0.0, -1.56, 1.57, -1.58, -1.57, 0.0])
UR5_OBSTACLES = (SphereObstacle("ball", [0.45, 0.1, 0.45], 0.08),
                 PlaneObstacle("floor", [0.0, 0.0, -0.25]))
UR5_SELF = (("upper_arm_link", "wrist_2_link"),)


def _never_skipping(c: Clearance) -> Clearance:
    """``c`` with the broad phase off: every group's reach ∞, so no group is ever beyond ℓ
    (before any constraint set packs its tables)."""
    s = c._spheres
    assert s is not None
    s.group_table[:, 5] = np.inf
    return c


def _copy(c: Clearance, influence: float | None) -> Clearance:
    return Clearance(c.model, c.primitives, c.obstacles, margin=c.margin, influence=influence,
                     self_pairs=c.self_pairs)


@cache
def _bench():  # type: ignore[no-untyped-def]
    """The Panda bench's CPBC, its 64 states, and the same law with the broad phase off."""
    setup = panda()
    law = setup.controllers["cpbc"]
    limits, clearance = law.constraints.configuration
    full = _never_skipping(_copy(clearance, clearance.influence))
    reference = CPBC(law.model, law.target, ConstraintSet(7, [limits, full],
                                                          law.constraints.velocity),
                     law.kp, law.kd, Power(0.2))
    return law, reference, clearance, full, setup.states


@cache
def _ur5(influence: float) -> tuple[Clearance, Clearance]:
    """A UR5 with a ball, the floor and a self pair, none of which the bench uses; and the
    same with the broad phase off."""
    arm = load_arm("ur5")
    model = RobotModel(arm.model, name="ur5")
    cover = cover_links(arm.model, arm.collision_model)

    def build() -> Clearance:
        return Clearance(model, cover, UR5_OBSTACLES, margin=0.01, influence=influence,
                         self_pairs=UR5_SELF)

    return build(), _never_skipping(build())


def _terms(c: Clearance, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    state = c.model.state(x, np.zeros(len(x)), kinematics=True)
    phi, b, _ = c.barrier_terms(state)
    return np.array(phi), np.array(b)


def _near(c: Clearance, x: np.ndarray, limit: float) -> np.ndarray:
    """The broad phase's verdict per group at x (``near_groups``), as booleans."""
    s = c._spheres
    assert s is not None
    y = c.model.state(x, np.zeros(len(x)), kinematics=True).regressor
    near, points = np.empty(len(s.group_index)), np.empty((3, len(s.group_index)))
    near_groups(y, s.group_index, s.group_table, s.obstacles, s.pair_table, limit, near,
                points)
    return near == 1.0


def _law_clearances(c: Clearance, x: np.ndarray) -> np.ndarray:
    """Every sphere pair's law clearance d_p − rsum_law_p (∞ for a pair that cannot move)."""
    s = c._spheres
    assert s is not None
    phi, _, _, moving = c.sphere_pairs(x, np.zeros(len(x)))
    return np.where(moving, phi, np.inf)


def _pairs_of(c: Clearance, groups: np.ndarray) -> np.ndarray:
    s = c._spheres
    assert s is not None
    return np.concatenate([np.arange(a, b) for a, b, *_ in s.group_index[groups]]
                          + [np.zeros(0, dtype=int)])


def test_the_bench_law_is_bitwise_the_same_without_the_broad_phase() -> None:
    """On the 64 bench states (most with a pair within ℓ) and one far from everything: the
    clearance's φ̃ and b, and the CPBC torque, equal the full computation's bit for bit."""
    law, reference, clearance, full, states = _bench()
    inside = 0
    for x, dx in states:
        phi, b = _terms(clearance, x)
        phi_r, b_r = _terms(full, x)
        assert np.array_equal(phi, phi_r) and np.array_equal(b, b_r)
        assert np.array_equal(law.torque(x, dx), reference.torque(x, dx))
        inside += bool(_law_clearances(clearance, x).min() < clearance.influence)
    assert inside >= 40  # the bench's states mostly have a pair within ℓ


@pytest.mark.parametrize("influence", [0.1, 0.167])  # 0.167 · (1/0.167) ≠ 1
def test_another_arm_and_scene_is_bitwise_the_same(influence: float) -> None:
    """The UR5 against a ball and the floor, with a self pair: states with a pair within ℓ,
    states with none (the early exit), and a NaN state give the same φ̃ and b as the full
    computation, bit for bit (NaN where it is NaN)."""
    c, full = _ur5(influence)
    rng = np.random.default_rng(3)
    within = beyond = 0
    for _ in range(60):
        x = UR5_HOME + rng.normal(scale=0.6, size=6)
        low = _law_clearances(c, x).min()
        if not low > 0.0:
            continue
        phi, b = _terms(c, x)
        phi_r, b_r = _terms(full, x)
        assert np.array_equal(phi, phi_r) and np.array_equal(b, b_r)
        within += bool(low < influence)
        beyond += bool(low >= influence)
    assert within >= 5 and beyond >= 5
    x = UR5_HOME.copy()
    x[2] = np.nan
    phi, b = _terms(c, x)
    phi_r, b_r = _terms(full, x)
    assert np.isnan(phi).any()
    assert np.array_equal(phi, phi_r, equal_nan=True) and np.array_equal(b, b_r, equal_nan=True)


@pytest.mark.parametrize("scene", ["bench", "ur5"])
def test_a_skipped_group_is_beyond_the_influence_distance(scene: str) -> None:
    """``near_groups`` skips groups on most states, and only groups whose every pair is
    beyond ℓ (law clearance ≥ ℓ): every pair within ℓ is in a near group."""
    if scene == "bench":
        _, _, c, _, bench_states = _bench()
        states = [x for x, _ in bench_states]
    else:
        c = _ur5(0.1)[0]
        rng = np.random.default_rng(5)
        states = [UR5_HOME + rng.normal(scale=0.6, size=6) for _ in range(40)]
    ell = c.influence
    assert ell is not None
    skipped = []
    for x in states:
        near = _near(c, x, ell)
        law = _law_clearances(c, x)
        assert np.all(law[_pairs_of(c, ~near)] >= ell)
        assert set(np.flatnonzero(law < ell)) <= set(_pairs_of(c, near).tolist())
        skipped.append(int((~near).sum()))
    assert np.median(skipped) >= len(near) // 2  # most groups skipped on a typical state


def test_what_the_broad_phase_never_skips() -> None:
    """Self pairs, every group with no limit (ℓ off, or the reported clearances asked for:
    ``limit`` ∞), and at a NaN state every group with a pair within ℓ or NaN (the test of
    a NaN bound never skips; max(|u| − h, 0) takes a NaN offset to 0, so such a pair, and
    such a bound, has core distance 0: outside S)."""
    c = _ur5(0.1)[0]
    s = c._spheres
    assert s is not None
    self_groups = s.group_index[:, 2] < 0
    assert self_groups.any() and (~self_groups).any()
    far = UR5_HOME.copy()
    assert not _near(c, far, 0.1)[~self_groups].all()  # some skipped here
    assert _near(c, far, 0.1)[self_groups].all()
    assert _near(c, far, np.inf).all()
    for joint in range(6):
        nan = UR5_HOME.copy()
        nan[joint] = np.nan
        near, law = _near(c, nan, 0.1), _law_clearances(c, nan)
        hit = ~(law >= 0.1)
        assert hit.sum() > 1
        assert set(np.flatnonzero(hit)) <= set(_pairs_of(c, near).tolist())


def test_the_groups_bound_their_spheres() -> None:
    """Each group is the pairs of one reported constraint; its bounding point lies within r of
    every sphere centre of the group, at random configurations (where it is computed)."""
    c = _ur5(0.1)[0]
    s = c._spheres
    assert s is not None
    for a, b, _, _, shared in s.group_index:
        assert len(set(s.group[a:b].tolist())) == 1
        assert s.group_index[shared, 0] <= a
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = UR5_HOME + rng.normal(scale=1.0, size=6)
        y = c.model.state(x, np.zeros(6), kinematics=True).regressor
        centres = np.column_stack([y[:, j:j + 4] @ s.sphere_local[k]
                                   for k, j in enumerate(s.sphere_index)])
        for g, (a, b, o, j, _) in enumerate(s.group_index):
            if o < 0:
                continue
            point = y[:, j:j + 4] @ s.group_table[g, :4]
            gap = np.linalg.norm(centres[:, s.pair_index[a:b, 1]] - point[:, None], axis=0)
            assert gap.max() <= s.group_table[g, 4] + 1e-12
