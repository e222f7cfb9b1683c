"""Clearance between the whole arm and the obstacles (and between its own links).

One scalar configuration constraint per (robot primitive, obstacle) pair and per
self-collision pair, all evaluated together so that the hot path is a fixed, small number of
vectorised operations whatever the number of pairs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from itertools import pairwise
from typing import TypeVar

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from cpbc.arrays import Array
from cpbc.constraints.base import ConfigurationConstraint
from cpbc.constraints.covering import LinkPrimitive
from cpbc.constraints.geometry import (
    BoxObstacle,
    CapsuleObstacle,
    Obstacle,
    PlaneObstacle,
    SphereObstacle,
    segment_box,
    segment_point,
    segment_segment,
)
from cpbc.constraints.pair_motion import point_motion, rounded_box_curvature
from cpbc.errors import CpbcError, ParameterError
from cpbc.model.robot_model import ArmState, RobotModel

# vec(p ⊗ n) @ _CROSS = p × n
_CROSS = np.zeros((9, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _CROSS[3 * _j + _k, _i] = 1.0
    _CROSS[3 * _k + _j, _i] = -1.0
_CROSS.setflags(write=False)

# vec((P; 1) ⊗ n) @ (_WRENCH @ J) = nᵀ J_P for J = [v; ω] Pinocchio's world joint Jacobian
# (column k of J_P is v_k + ω_k × P): rows 3i + j hold _CROSS @ ω, rows 9 + j hold v
_WRENCH = np.zeros((12, 6))
_WRENCH[:9, 3:] = _CROSS
_WRENCH[9:, :3] = np.eye(3)
_WRENCH.setflags(write=False)

# [vec(s ⊗ f); f] (12,) = (_AT_POINT @ [s; 1]) * (_FORCE @ f), for the force f at a point s
_AT_POINT = np.zeros((12, 4))
_AT_POINT[np.arange(9), np.arange(9) // 3] = 1.0
_AT_POINT[9:, 3] = 1.0
_AT_POINT.setflags(write=False)
_FORCE = np.vstack([np.eye(3)] * 4)
_FORCE.setflags(write=False)
_ONES3, _ONES12 = np.ones(3), np.ones(12)  # sums over a short first axis: a dot is cheaper

# 0-d arrays: numpy takes them faster than Python floats as ufunc operands
_ZERO, _ONE, _THREE = np.array(0.0), np.array(1.0), np.array(3.0)

_TINY = 1e-300

_Index = NDArray[np.intp]
_O = TypeVar("_O", bound=Obstacle)


def _only(kind: type[_O], obstacles: Sequence[Obstacle]) -> list[_O]:
    """The obstacles of one kind, in their order."""
    return [o for o in obstacles if isinstance(o, kind)]


def _core_distances(u: Array, half: Array) -> tuple[Array, Array]:
    """‖max(|u| − h, 0)‖ per column of u (3, P), and max(|u| − h, 0) itself."""
    outside = np.abs(u)
    outside -= half
    np.maximum(outside, _ZERO, out=outside)
    return np.sqrt(np.dot(_ONES3, outside * outside)), outside


@dataclass(frozen=True, eq=False)
class _Spheres:
    """Sphere primitives against every obstacle (as rounded boxes) and each other.

    For pair p of a sphere with world centre s and an obstacle with centre c, rotation R, core
    half-extents h and rounding ρ: u_p = Rᵀ(s − c), d_p = ‖max(|u_p| − h, 0)‖ − ρ. A self
    pair is the same with c the other sphere's centre (R = I, h = 0).

    Pairs are ordered obstacle by obstacle, every sphere against each (the spheres in the
    same order each time), then the self pairs. The S sphere centres come out of one
    product with Pinocchio's static regressor, and every obstacle pair's u from one more:
    rows (k, o) of ``to_obstacle`` @ [centres; 1] are u_k against obstacle o, so the result
    *is* u in the (3, P) component-major layout (numpy's inner loops then run along the
    pairs, not along a length-3 axis). Per numpy call this costs the same whatever the
    number of pairs, and the call count, not the arithmetic, is what a step costs here.
    """

    start: int
    stop: int
    n_obstacle: int  # pairs [0, n_obstacle) are against obstacles, the rest are self pairs
    centres: Array  # (4 nj, S): sphere s is at Y @ centres[:, s]
    scratch: Array  # (4, S): rows 0–2 the centres at the current state, row 3 ones
    to_obstacle: Array  # (3 O, 4): u of every obstacle pair from the scratch
    self_map: Array  # (S, Ps): u of the self pairs, centres @ self_map (+1 first, −1 second)
    half: Array  # (3, P)
    rsum: Array  # (P,) sphere radius + rounding (+ other radius) + margin
    rsum_law: Array  # (P,) rsum, −∞ on pairs that cannot move (ℓ given): they leave the law
    moving: Array  # (P,) 1.0 on pairs whose clearance can change, else 0.0
    to_world: Array  # (12, 3 O): _FORCE @ (w Σ_o R_o local_o) from local.reshape(3 O, S),
    # w = 3/ℓ (1 without ℓ): see ``_sphere_factors``
    self_force: Array  # (Ps, S): w (+1 first, −1 second), the self pairs' forces per sphere
    pair_sphere: _Index  # (P,) the (first) sphere of each pair
    pair_sphere2: _Index  # (Ps,) the second sphere of each self pair
    pair_rot: Array  # (P, 3, 3) the obstacle's rotation R (I for a self pair)
    sphere_supports: Array  # (S, n) 1 where joint k moves sphere s's link
    starts: _Index  # first pair of each reported constraint (a link against an obstacle/link)
    group: _Index  # (P,) the constraint (index in ``names``) of each pair


_Rows = tuple[Array, Array, Array]  # points p (m, 3), unit normals n̂ (m, 3), supports (m, n)
_JacobianRows = Callable[[Array, Array, Array], Array]  # (p, n̂, supports) ↦ rows n̂ᵀ J(p)


@dataclass(frozen=True, eq=False)
class _CapsuleGroup:
    """Capsule primitives paired with shapes of one kind, one pair per row.

    Pair p's primitive is the segment [a_p, b_p] with a = (Y @ ea).T and b = (Y @ eb).T (Y
    the static regressor), its radius plus the margin (and the other shape's radius) in
    ``rsum``. The base gives one clearance per pair, reported and in the law as it is;
    ``_CapsulePlane`` changes that. A subclass says how far its pairs are (``narrow``); the
    base itself only carries the capsule side of the pairs to a subclass's ``against``.
    """

    start: int  # the group's constraints are names[start:stop]
    stop: int
    ea: Array  # (4 nj, P)
    eb: Array
    mask: Array  # (P, n) 1 where joint k moves the primitive's link
    rsum: Array  # (P,)

    @property
    def terms(self) -> int:
        """How many clearances ``narrow`` gives the law."""
        return self.stop - self.start

    def ends(self, y: Array) -> tuple[Array, Array]:
        """The segment ends a, b (P, 3) of the primitives at the regressor y."""
        return (y @ self.ea).T, (y @ self.eb).T

    def narrow(self, y: Array) -> tuple[Array, list[_Rows]]:
        """The exact clearances φ and the rows of their gradient: ∇φ = Σ_rows n̂ᵀ J(p)."""
        raise NotImplementedError

    def reported(self, phi: Array) -> Array:
        """The reported clearance of each pair from ``narrow``'s φ."""
        return phi

    def gradient(self, phi: Array, rows: list[_Rows], jacobian_rows: _JacobianRows) -> Array:
        """The gradients (P, n) of the reported clearances, from ``narrow``'s φ and rows
        (summed from 0, as ever: the same bits, signed zeros included)."""
        return np.asarray(sum(jacobian_rows(p, n, mask) for p, n, mask in rows), dtype=float)

    def law(self, shaped: Array, ratio: Array, rows: list[_Rows], influence: float | None
            ) -> tuple[Array, list[_Rows]]:
        """The law's φ̃ of the group's constraints and the rows of its force, from φ̃ and
        (dφ̃/dφ)/φ̃ of ``narrow``'s clearances (``Clearance._shape``)."""
        return shaped, [(p, n * ratio[:, None], mask) for p, n, mask in rows]


@dataclass(frozen=True, eq=False)
class _AgainstObstacle(_CapsuleGroup):
    """Capsules against fixed obstacles: φ = d − rsum, d, p and n̂ from ``distance``."""

    def narrow(self, y: Array) -> tuple[Array, list[_Rows]]:
        d, p, n = self.distance(*self.ends(y))
        return d - self.rsum, [(p, n, self.mask)]

    def distance(self, a: Array, b: Array) -> tuple[Array, Array, Array]:
        """The distance d (P,) from the segments [a, b] to the obstacles' cores, the closest
        points p (P, 3) on the segments and the unit normals n̂ (P, 3) towards them."""
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class _CapsuleSphere(_AgainstObstacle):
    """Capsules against spheres (the sphere's radius in ``rsum``)."""

    centre: Array  # (P, 3)

    @classmethod
    def against(cls, caps: _CapsuleGroup, obstacles: Sequence[SphereObstacle]) -> _CapsuleSphere:
        return cls(caps.start, caps.stop, caps.ea, caps.eb, caps.mask,
                   caps.rsum + np.array([o.radius for o in obstacles]),
                   centre=np.array([o.centre for o in obstacles]))

    def distance(self, a: Array, b: Array) -> tuple[Array, Array, Array]:
        return segment_point(a, b, self.centre)


@dataclass(frozen=True, eq=False)
class _CapsuleCapsule(_AgainstObstacle):
    """Capsules against capsule obstacles (the obstacle's radius in ``rsum``)."""

    axis_start: Array  # (P, 3)
    axis_end: Array

    @classmethod
    def against(cls, caps: _CapsuleGroup, obstacles: Sequence[CapsuleObstacle]
                ) -> _CapsuleCapsule:
        return cls(caps.start, caps.stop, caps.ea, caps.eb, caps.mask,
                   caps.rsum + np.array([o.radius for o in obstacles]),
                   axis_start=np.array([o.start for o in obstacles]),
                   axis_end=np.array([o.end for o in obstacles]))

    def distance(self, a: Array, b: Array) -> tuple[Array, Array, Array]:
        d, p, _, n = segment_segment(a, b, self.axis_start, self.axis_end)
        return d, p, n


@dataclass(frozen=True, eq=False)
class _CapsuleBox(_AgainstObstacle):
    """Capsules against oriented boxes."""

    centre: Array  # (P, 3)
    rotation: Array  # (P, 3, 3) box to world
    half: Array  # (P, 3) half-extents

    @classmethod
    def against(cls, caps: _CapsuleGroup, obstacles: Sequence[BoxObstacle]) -> _CapsuleBox:
        return cls(caps.start, caps.stop, caps.ea, caps.eb, caps.mask, caps.rsum,
                   centre=np.array([o.centre for o in obstacles]),
                   rotation=np.array([o.rotation for o in obstacles]),
                   half=np.array([o.half_extents for o in obstacles]))

    def distance(self, a: Array, b: Array) -> tuple[Array, Array, Array]:
        d, p, _, n = segment_box(a, b, self.centre, self.rotation, self.half)
        return d, p, n


@dataclass(frozen=True, eq=False)
class _CapsuleSelf(_CapsuleGroup):
    """Self pairs with a capsule: both segments move, so ∇φ = n̂ᵀ (J_P − J_Q)."""

    ea2: Array  # the other primitive's ends and supports, as ea, eb, mask
    eb2: Array
    mask2: Array

    def narrow(self, y: Array) -> tuple[Array, list[_Rows]]:
        a, b = self.ends(y)
        d, p, q, n = segment_segment(a, b, (y @ self.ea2).T, (y @ self.eb2).T)
        return d - self.rsum, [(p, n, self.mask), (q, -n, self.mask2)]


@dataclass(frozen=True, eq=False)
class _CapsulePlane(_CapsuleGroup):
    """Capsules above planes. ``narrow`` gives the law the heights of both ends, φ_a then φ_b
    (2P,): the pair's barrier is the product of its two end terms (each smooth, where
    min(φ_a, φ_b) is not); the reported clearance is the smaller one."""

    normal: Array  # (P, 3) unit normals
    offset: Array  # (P,) n̂·x on the plane

    @classmethod
    def against(cls, caps: _CapsuleGroup, obstacles: Sequence[PlaneObstacle]) -> _CapsulePlane:
        return cls(caps.start, caps.stop, caps.ea, caps.eb, caps.mask, caps.rsum,
                   normal=np.array([o.normal for o in obstacles]),
                   offset=np.array([o.offset for o in obstacles]))

    @property
    def terms(self) -> int:
        return 2 * (self.stop - self.start)

    def narrow(self, y: Array) -> tuple[Array, list[_Rows]]:
        a, b = self.ends(y)
        phi_a = (a * self.normal).sum(axis=1) - self.offset - self.rsum
        phi_b = (b * self.normal).sum(axis=1) - self.offset - self.rsum
        return np.concatenate([phi_a, phi_b]), [(a, self.normal, self.mask),
                                                (b, self.normal, self.mask)]

    def reported(self, phi: Array) -> Array:
        size = self.stop - self.start
        return np.minimum(phi[:size], phi[size:])

    def gradient(self, phi: Array, rows: list[_Rows], jacobian_rows: _JacobianRows) -> Array:
        """The gradient of the lower end's height."""
        size = self.stop - self.start
        (pa, n, mask), (pb, _, _) = rows
        use_b = (phi[size:] < phi[:size])[:, None]
        return jacobian_rows(np.where(use_b, pb, pa), n, mask)

    def law(self, shaped: Array, ratio: Array, rows: list[_Rows], influence: float | None
            ) -> tuple[Array, list[_Rows]]:
        """φ̃_a φ̃_b/ℓ (φ_a φ_b without ℓ) and both ends' force rows."""
        size = self.stop - self.start
        (pa, n, mask), (pb, _, _) = rows
        return (shaped[:size] * (shaped[size:] / (influence or 1.0)),
                [(pa, n * ratio[:size, None], mask), (pb, n * ratio[size:, None], mask)])


@dataclass
class _Layout:
    """What set-up lays out pair by pair: the constraint names, and the capsule groups'
    broad phase ``Clearance._near_groups``, z = vec(Y) @ w + c.

    A bounded pair adds three columns, the offset Δ (3,) of its primitive's midpoint from
    the centre of a sphere bounding the other shape, and the square of its reach (the pair
    may be within ℓ only if ‖Δ‖ < reach); a pair above a plane adds the heights of its two
    ends above plane + radius + margin, a column each (within ℓ only if one is < ℓ).
    """

    prefix: str  # the constraint names are prefix[…]
    names: list[str] = field(default_factory=list)
    columns: list[Array] = field(default_factory=list)  # over vec(Y)
    constants: list[float] = field(default_factory=list)
    thresholds: list[float] = field(default_factory=list)  # reach² per bounded pair

    def add(self, labels: Sequence[str]) -> tuple[int, int]:
        """Name constraints ``prefix[label]``; their first index and one past the last."""
        start = len(self.names)
        self.names += [f"{self.prefix}[{label}]" for label in labels]
        return start, len(self.names)

    def bound(self, column: Array, centre: Array, reach: float) -> None:
        """A bounded pair: Y @ column is its primitive's midpoint (or offset from the other
        primitive's), to be compared with ``centre`` (3,)."""
        for c in range(3):  # Δ = mid − centre, component c, over vec(Y)
            w = np.zeros((3, len(column)))
            w[c] = column
            self.columns.append(w.reshape(-1))
            self.constants.append(-float(centre[c]))
        self.thresholds.append(reach * reach)

    def height(self, column: Array, constant: float) -> None:
        """A height above a plane: vec(Y) @ column + constant."""
        self.columns.append(column)
        self.constants.append(constant)


class Clearance(ConfigurationConstraint):
    """φ_p(x) = d_p(x) − Δ > 0 for every pair p of a robot primitive and an obstacle (or of
    two robot primitives on different links), d_p the exact distance between the two shapes
    (cpbc.constraints.geometry) and Δ the margin.

    Gradient (envelope theorem): ∇φ_p = n̂ᵀ J_P(x), with P the closest point of the robot
    primitive held fixed on its link, n̂ the unit vector from the obstacle's closest point to
    P, and J_P the Jacobian of that point, assembled for all pairs at once from Pinocchio's
    world joint Jacobians: column k of J_P is v_k + ω_k × P (zero for joints that do not move
    the link). For a self pair both points move: ∇φ = n̂ᵀ (J_P − J_Q).

    **Spheres are the fast path.** Every obstacle is a rounded box (geometry.RoundedBox), so a
    sphere primitive's distance to any obstacle is one formula, exact and C¹ outside the
    obstacle; the centres of all spheres, in every obstacle's frame, come out of two small
    matrix products with Pinocchio's static regressor (all joint placements in one call).
    Capsule primitives are supported too (segment–sphere, segment–segment, segment–box and
    segment–plane, each exact; see the smoothness notes in cpbc.constraints.geometry), at a
    higher cost per step. A capsule above a plane enters the barrier as the product of its
    two end spheres' clearances (each smooth, where min(n·a, n·b) is not); its reported value
    is the smaller of the two.

    **Localised barrier.** Theorem 6.9 sums ∇φ_p/φ_p over every pair, so an obstacle far
    away still pulls (weakly) on the arm and every pair enters every step. With an
    ``influence`` distance ℓ the law is given instead the constraint functions

        φ̃_p = ℓ σ(φ_p/ℓ),   σ(u) = 1 − (1 − u)³ for u < 1,   σ(u) = 1 for u ≥ 1,

    which are C² wherever φ_p is, positive exactly where φ_p is (the same admissible set S),
    equal to 3φ_p + O(φ_p²) at the boundary (the same barrier there) and constant, with zero
    gradient, once the pair is farther apart than ℓ. This is Theorem 6.9 applied to the
    constraints φ̃_p, so its guarantees hold unchanged, and a pair beyond ℓ is *exactly*
    inactive: when no pair is within ℓ the barrier costs the distance computation only, and
    capsule groups are skipped after a conservative bounding-sphere test. Once one sphere
    pair is within ℓ, all of them go through the rest densely (those beyond ℓ with factor
    exactly 1 and zero slope): per numpy call that costs the same as a few, and it needs no
    picking. With
    ``influence=None`` the barrier is φ_p itself (the plain thesis form).

    ``value`` and ``gradient`` report the clearance φ_p itself [m] (what the run summary
    shows); ``barrier_terms`` gives the law φ̃_p and Σ ∇φ̃_p/φ̃_p. Sphere primitives are
    reported per link: ``name[link|obstacle]`` is the smallest clearance of the link's
    spheres (its gradient that of the closest sphere), and the law's function for it is the
    product of the spheres' φ̃ — one log-barrier term per sphere pair, exactly as if each
    were its own constraint, with the same zero set as the minimum but smooth. Capsule
    primitives are reported per primitive. Sphere pairs whose clearance cannot change (a
    link turning about the normal of a plane, say) are detected once, by their vanishing
    gradient at random configurations, and leave the law (a constant factor).

    Args:
        model: the controller's robot model.
        primitives: robot primitives (spheres or capsules fixed in link frames).
        obstacles: fixed obstacles.
        margin: Δ ≥ 0 [m].
        influence: ℓ > 0 [m], or None for the non-localised barrier.
        self_pairs: pairs of link (frame) names to keep apart; every primitive of the one
            against every primitive of the other.
        name: prefix of the constraint names, ``name[primitive|obstacle]``.
    """

    needs_kinematics = True  # the law's pass reads the state's joint Jacobians

    def __init__(
        self,
        model: RobotModel,
        primitives: Sequence[LinkPrimitive],
        obstacles: Sequence[Obstacle],
        margin: float = 0.0,
        influence: float | None = 0.1,
        self_pairs: Sequence[tuple[str, str]] = (),
        name: str = "clearance",
    ) -> None:
        if not (np.isfinite(margin) and margin >= 0):
            raise ParameterError("margin", f"clearance margin must be ≥ 0, got {margin}")
        if influence is not None and not (np.isfinite(influence) and influence > 0):
            raise ParameterError(
                "influence", f"clearance influence distance must be > 0, got {influence}")
        if not primitives:
            raise CpbcError("clearance needs at least one robot primitive")
        prim_names = [p.name for p in primitives]
        if len(set(prim_names)) != len(prim_names):
            raise CpbcError(f"primitive names must be unique, got {prim_names}")
        obs_names = [o.name for o in obstacles]
        if len(set(obs_names)) != len(obs_names):
            raise CpbcError(f"obstacle names must be unique, got {obs_names}")
        frames = sorted({p.frame for p in primitives})
        for a, b in self_pairs:
            for f in (a, b):
                if f not in frames:
                    raise CpbcError(
                        f"self-collision pair ({a}, {b}): no primitive on link '{f}'; "
                        f"links with primitives: {frames}"
                    )
            if a == b:
                raise CpbcError(f"self-collision pair ({a}, {b}) names one link twice")
        if not obstacles and not self_pairs:
            raise CpbcError("clearance needs at least one obstacle or self-collision pair")
        self.model = model
        self.primitives = tuple(primitives)
        self.obstacles = tuple(obstacles)
        self.margin = float(margin)
        self.influence = None if influence is None else float(influence)
        self._ell = np.array(self.influence or 1.0)  # ℓ and 1/ℓ as 0-d arrays (see _ONE)
        self._inv_ell = np.array(1.0 / (self.influence or 1.0))
        self.self_pairs = tuple((str(a), str(b)) for a, b in self_pairs)
        self._pin = model.model
        self._data = model.data  # the model's: the per-step state leaves its Jacobians there
        self._n = model.n
        self._identity = model.coordinates.is_identity
        self._t_inv = model.coordinates.inverse
        self._setup_kinematics()
        self._setup_pairs(name)
        self._far_phi = np.full(len(self.names), self.influence or 1.0)
        self._split_static()
        self._far_phi.setflags(write=False)
        self._zero = np.zeros(self._n)
        self._zero.setflags(write=False)
        self._along: dict[int, tuple[Array, Array, _Index]] = {}  # see values_along
        self._motion_data = self._pin.createData()  # second order, apart from the state's

    # -- set-up ------------------------------------------------------------------------------
    def _setup_kinematics(self) -> None:
        """Points fixed on links as columns over Pinocchio's static regressor.

        ``computeStaticRegressor`` returns, in one call, Y = [t_1 R_1 … t_n R_n]/M (3 × 4n):
        every joint placement, divided by the total mass M. A point l fixed in joint j's frame
        is then at M·Y[:, 4(j−1):4j] @ [1, l]: Y times a constant column.
        """
        pm, data = self._pin, self._data
        self._nj = pm.njoints - 1
        q = pin.neutral(pm) + 0.3
        y = pin.computeStaticRegressor(pm, data, q)
        pin.forwardKinematics(pm, data, q)
        scale = np.sqrt(3.0) / np.linalg.norm(y[:, 1:4])
        rebuilt = np.hstack(
            [np.column_stack([data.oMi[j].translation, data.oMi[j].rotation])
             for j in range(1, pm.njoints)]
        )
        if not np.allclose(scale * y, rebuilt, atol=1e-9):  # pragma: no cover
            raise CpbcError("unexpected layout of Pinocchio's static regressor")
        self._scale = float(scale)
        self._supports = np.zeros((pm.njoints, self._n))
        for j in range(1, pm.njoints):
            for k in pm.supports[j].tolist()[1:]:
                jm = pm.joints[k]
                self._supports[j, jm.idx_v: jm.idx_v + jm.nv] = 1.0
        self._joint: list[int] = []
        self._local: list[tuple[Array, Array]] = []
        for p in self.primitives:
            frame = pm.frames[self.model.frame_id(p.frame)]
            if frame.parentJoint == 0:
                raise CpbcError(
                    f"primitive '{p.name}' is on '{p.frame}', which is welded to the world: "
                    "its clearance cannot change; leave it out"
                )
            self._joint.append(frame.parentJoint)
            self._local.append((frame.placement.act(p.start), frame.placement.act(p.end)))

    def _column(self, i: int, end: int | None) -> Array:
        """The column giving primitive i's start (0), end (1) or midpoint (None) from Y."""
        a, b = self._local[i]
        local = 0.5 * (a + b) if end is None else (a if end == 0 else b)
        j = self._joint[i]
        col = np.zeros(4 * self._nj)
        col[4 * (j - 1)] = self._scale
        col[4 * (j - 1) + 1: 4 * j] = self._scale * local
        return col

    def _columns(self, prims: Sequence[int], end: int | None) -> Array:
        return np.ascontiguousarray(np.column_stack([self._column(i, end) for i in prims]))

    def _masks(self, prims: Sequence[int]) -> Array:
        return self._supports[[self._joint[i] for i in prims]]

    def _setup_pairs(self, name: str) -> None:
        """Every pair, in the order of ``names``: the sphere primitives' pairs first (one fast
        group, ``_spheres``), then the capsule primitives' groups (``_groups``): against the
        sphere, capsule and box obstacles, in self pairs, above the planes; with the capsule
        groups' broad phase (``_near_groups``)."""
        by_frame: dict[str, list[int]] = {}
        for i, p in enumerate(self.primitives):
            by_frame.setdefault(p.frame, []).append(i)
        layout = _Layout(name)
        sphere_self = self._setup_spheres(by_frame, layout)
        capsules = [i for i, p in enumerate(self.primitives) if p.kind == "capsule"]
        obstacles = self.obstacles
        groups = [
            self._obstacle_group(_CapsuleSphere.against, _only(SphereObstacle, obstacles),
                                 capsules, layout),
            self._obstacle_group(_CapsuleCapsule.against, _only(CapsuleObstacle, obstacles),
                                 capsules, layout),
            self._obstacle_group(_CapsuleBox.against, _only(BoxObstacle, obstacles),
                                 capsules, layout),
            self._self_group(by_frame, sphere_self, layout),
            self._plane_group(capsules, layout),  # last: its tests follow the bounded ones
        ]
        self._groups: list[_CapsuleGroup] = [g for g in groups if g is not None]
        names = layout.names
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise CpbcError(f"clearance pairs {dup} appear twice: give primitives on one link "
                            "one kind, or distinct names")
        self.names = tuple(names)
        self._broad_w = (np.ascontiguousarray(np.column_stack(layout.columns)) if layout.columns
                         else np.zeros((12 * self._nj, 0)))
        self._broad_c = np.array(layout.constants)
        self._broad_thr = np.array(layout.thresholds)
        self._n_bounded = len(layout.thresholds)
        self._reduce_at = np.cumsum([0] + [g.terms for g in self._groups])[:-1].astype(np.intp)

    def _setup_spheres(self, by_frame: dict[str, list[int]], layout: _Layout
                       ) -> list[tuple[int, int]]:
        """The sphere primitives' pairs (``_spheres``), reported per link: every link against
        each obstacle, then each self pair of links with spheres on both; the sphere self
        pairs (primitive indices)."""
        prims = self.primitives
        on = {f: [i for i in ids if prims[i].kind == "sphere"] for f, ids in by_frame.items()}
        frames = list(dict.fromkeys(p.frame for p in prims if p.kind == "sphere"))
        group: list[int] = []  # the constraint of each pair
        for o in self.obstacles:
            for f in frames:
                group += [len(layout.names)] * len(on[f])
                layout.add([f"{f}|{o.name}"])
        sphere_self: list[tuple[int, int]] = []
        for a, b in self.self_pairs:
            pairs = [(i, j) for i in on[a] for j in on[b]]
            if pairs:
                sphere_self += pairs
                group += [len(layout.names)] * len(pairs)
                layout.add([f"{a}|{b}"])
        order = [i for f in frames for i in on[f]]
        self._spheres = self._sphere_group(order, sphere_self, group) if group else None
        return sphere_self

    def _capsules(self, start: int, stop: int, prims: Sequence[int]) -> _CapsuleGroup:
        """The capsule side of pairs: primitive ``prims[p]`` in pair p, radius + margin."""
        return _CapsuleGroup(start, stop, self._columns(prims, 0), self._columns(prims, 1),
                             self._masks(prims),
                             np.array([self.primitives[i].radius for i in prims]) + self.margin)

    def _obstacle_group(
        self,
        against: Callable[[_CapsuleGroup, list[_O]], _CapsuleGroup],
        obstacles: list[_O],
        capsules: list[int],
        layout: _Layout,
    ) -> _CapsuleGroup | None:
        """Every capsule primitive against each of the obstacles (of one kind), each pair
        bounded in the broad phase by the obstacle's bounding sphere."""
        pairs = [(i, o) for o in obstacles for i in capsules]
        if not pairs:
            return None
        prims, span = self.primitives, self.influence or 0.0
        start, stop = layout.add([f"{prims[i].name}|{o.name}" for i, o in pairs])
        for i, o in pairs:
            centre, rad = o.bounding_sphere()
            reach = 0.5 * prims[i].length + prims[i].radius + rad + self.margin + span
            layout.bound(self._column(i, None), centre, reach)
        return against(self._capsules(start, stop, [i for i, _ in pairs]),
                       [o for _, o in pairs])

    def _self_group(self, by_frame: dict[str, list[int]], sphere_self: list[tuple[int, int]],
                    layout: _Layout) -> _CapsuleSelf | None:
        """The self pairs not both spheres, each bounded by the reach between midpoints."""
        prims, span, taken = self.primitives, self.influence or 0.0, set(sphere_self)
        pairs = [(i, j) for a, b in self.self_pairs for i in by_frame[a] for j in by_frame[b]
                 if (i, j) not in taken]
        if not pairs:
            return None
        start, stop = layout.add([f"{prims[i].name}|{prims[j].name}" for i, j in pairs])
        for i, j in pairs:
            reach = (0.5 * prims[i].length + 0.5 * prims[j].length + prims[i].radius
                     + prims[j].radius + self.margin + span)
            layout.bound(self._column(i, None) - self._column(j, None), np.zeros(3), reach)
        pi, pj = [i for i, _ in pairs], [j for _, j in pairs]
        return _CapsuleSelf(
            start, stop, self._columns(pi, 0), self._columns(pi, 1), self._masks(pi),
            np.array([prims[i].radius + prims[j].radius for i, j in pairs]) + self.margin,
            ea2=self._columns(pj, 0), eb2=self._columns(pj, 1), mask2=self._masks(pj),
        )

    def _plane_group(self, capsules: list[int], layout: _Layout) -> _CapsulePlane | None:
        """Every capsule primitive above each plane; in the broad phase, its ends' heights."""
        pairs = [(i, o) for o in _only(PlaneObstacle, self.obstacles) for i in capsules]
        if not pairs:
            return None
        start, stop = layout.add([f"{self.primitives[i].name}|{o.name}" for i, o in pairs])
        g = _CapsulePlane.against(self._capsules(start, stop, [i for i, _ in pairs]),
                                  [o for _, o in pairs])
        for e in (g.ea, g.eb):  # heights n·a − offset − r − Δ and n·b − …, over vec(Y)
            for p in range(len(pairs)):
                layout.height(np.outer(g.normal[p], e[:, p]).reshape(-1),
                              -(g.offset[p] + g.rsum[p]))
        return g

    def _split_static(self, samples: int = 8) -> None:
        """Take the sphere pairs whose clearance cannot change out of the law.

        A sphere on the first link of an arm whose first axis is vertical keeps its height
        above a table: its clearance is constant, its barrier gradient zero. Such pairs are
        found by their gradient, which vanishes at every one of ``samples`` random
        configurations (an analytic function of q that vanishes on random samples is zero);
        their constant factor φ̃ goes into ``_far_phi`` once. In the law they then count as
        beyond ℓ (rsum_law = −∞: φ = ∞, factor 1, no slope), so a link that always sits
        near the table does not keep the whole barrier awake.
        """
        s = self._spheres
        if s is None:
            return
        pm = self._pin
        lo = np.where(np.isfinite(pm.lowerPositionLimit), pm.lowerPositionLimit, -np.pi)
        hi = np.where(np.isfinite(pm.upperPositionLimit), pm.upperPositionLimit, np.pi)
        rng = np.random.default_rng(0)
        slope = np.zeros(len(s.group))
        for _ in range(samples):
            q = rng.uniform(lo, hi)
            g = self._pair_gradients(q, self._regressor(q))[1]
            slope = np.maximum(slope, np.abs(g).max(axis=1))
        static = slope < 1e-12
        if not static.any():
            return
        phi = self._sphere_distances(self._regressor(pin.neutral(pm)))[0] - s.rsum
        shaped = phi if self.influence is None else self._shape(phi)[0] / self.influence
        np.multiply.at(self._far_phi, s.group[static], shaped[static])
        s.moving[static] = 0.0
        if self.influence is not None:
            s.rsum_law[static] = -np.inf

    def _sphere_group(
        self, spheres: list[int], self_pairs: list[tuple[int, int]], group: list[int]
    ) -> _Spheres:
        """The sphere pairs: every sphere in ``spheres`` against every obstacle, then
        ``self_pairs``; ``group`` gives each pair's constraint."""
        prims, margin = self.primitives, self.margin
        index = {i: k for k, i in enumerate(spheres)}
        cores = [o.core() for o in self.obstacles]
        n_obs, n_sph = len(cores), len(spheres)
        radius = np.array([prims[i].radius for i in spheres])
        to_obstacle = np.zeros((3 * n_obs, 4))
        to_world = np.zeros((3, 3 * n_obs))
        slope = 1.0 if self.influence is None else 3.0 / self.influence  # see _sphere_factors
        for o, core in enumerate(cores):
            for k in range(3):  # row (k, o): u_k = R[:, k]·(s − c)
                to_obstacle[k * n_obs + o, :3] = core.rotation[:, k]
                to_obstacle[k * n_obs + o, 3] = -core.rotation[:, k] @ core.centre
                to_world[:, k * n_obs + o] = slope * core.rotation[:, k]
        self_map = np.zeros((n_sph, len(self_pairs)))
        for p, (i, j) in enumerate(self_pairs):
            self_map[index[i], p] = 1.0
            self_map[index[j], p] = -1.0
        rsum = np.concatenate(
            [radius + core.rounding + margin for core in cores]
            + [[prims[i].radius + prims[j].radius + margin for i, j in self_pairs]])
        half = np.zeros((3, len(rsum)))
        for o, core in enumerate(cores):
            half[:, o * n_sph:(o + 1) * n_sph] = core.half_extents[:, None]
        grp = np.array(group, dtype=np.intp)
        return _Spheres(
            start=0, stop=int(grp[-1]) + 1, n_obstacle=n_obs * n_sph,
            centres=self._columns(spheres, 0),
            scratch=np.ones((4, n_sph)),
            to_obstacle=to_obstacle, self_map=self_map, half=half,
            rsum=rsum, rsum_law=rsum.copy(), moving=np.ones(len(rsum)),
            to_world=_FORCE @ to_world,
            self_force=np.ascontiguousarray(slope * self_map.T),
            pair_sphere=np.concatenate([np.tile(np.arange(n_sph), n_obs),
                                        [index[i] for i, _ in self_pairs]]).astype(np.intp),
            pair_sphere2=np.array([index[j] for _, j in self_pairs], dtype=np.intp),
            pair_rot=np.array([core.rotation for core in cores for _ in spheres]
                              + [np.eye(3)] * len(self_pairs)).reshape(-1, 3, 3),
            sphere_supports=self._masks(spheres),
            starts=np.flatnonzero(np.diff(grp, prepend=-1)).astype(np.intp),
            group=grp,
        )

    # -- shared kinematics ---------------------------------------------------------------
    def _q(self, x: Array) -> Array:
        return x if self._identity else self._t_inv @ x

    def _regressor(self, q: Array) -> Array:
        """Y (3, 4n): every joint placement, scaled, in one Pinocchio call."""
        return pin.computeStaticRegressor(self._pin, self._data, q)

    def _jacobians(self, q: Array) -> Array:
        """Pinocchio's world joint Jacobians J = [v; ω] (6, n)."""
        pin.computeJointJacobians(self._pin, self._data, q)
        return self._data.J

    def _rows_times_jacobians(
        self, q: Array, points: Array, normals: Array, masks: Array, jac: Array | None = None
    ) -> Array:
        """Rows n_rᵀ J(p_r) with J(p) the Jacobian of a point fixed on its link, shape (r, n),
        joint coordinates (``jac``: the joint Jacobians at q, if already computed)."""
        jac = self._jacobians(q) if jac is None else jac
        outer = (points[:, :, None] * normals[:, None, :]).reshape(-1, 9)
        return (normals @ jac[:3] + outer @ (_CROSS @ jac[3:])) * masks

    # -- distances ---------------------------------------------------------------------------
    def _offsets(self, y: Array) -> Array:
        """u (3, P) of every sphere pair; the sphere centres at y are left in
        ``scratch[:3]``."""
        s = self._spheres
        assert s is not None
        centres = s.scratch
        np.dot(y, s.centres, out=centres[:3])
        u = np.dot(s.to_obstacle, centres).reshape(3, s.n_obstacle)
        if len(s.pair_sphere2):
            u = np.concatenate((u, np.dot(centres[:3], s.self_map)), axis=1)
        return u

    def _sphere_distances(self, y: Array) -> tuple[Array, Array, Array]:
        """Every sphere pair's core distance d (P,), u (3, P) and max(|u| − h, 0) (3, P);
        the sphere centres at y are left in ``scratch[:3]``."""
        s = self._spheres
        assert s is not None
        u = self._offsets(y)
        d, outside = _core_distances(u, s.half)
        return d, u, outside

    def _pair_gradients(self, q: Array, y: Array) -> tuple[Array, Array]:
        """Every sphere pair's clearance (P,) and its gradient (P, n), joint coordinates."""
        s = self._spheres
        assert s is not None
        d, u, outside = self._sphere_distances(y)
        local = np.copysign(outside, u) / np.maximum(d, _TINY)
        normal = np.einsum("pab,bp->pa", s.pair_rot, local)
        centres = s.scratch[:3]
        jac = self._jacobians(q)
        grad = self._rows_times_jacobians(q, centres[:, s.pair_sphere].T, normal,
                                          s.sphere_supports[s.pair_sphere], jac)
        if len(s.pair_sphere2):
            at = s.n_obstacle
            grad[at:] -= self._rows_times_jacobians(
                q, centres[:, s.pair_sphere2].T, normal[at:],
                s.sphere_supports[s.pair_sphere2], jac)
        return d - s.rsum, grad

    def _sphere_force(self, local: Array, jac: Array) -> Array:
        """Σ_p J(s_p)ᵀ R_p local_p over the sphere pairs (s_p the pair's sphere centre, J(s)
        the Jacobian of a point fixed on its link, R_p the obstacle's rotation), minus the
        same at the second sphere of each self pair, times w (``to_world``); (n,).

        Dense over all the pairs (a pair out of the law has local_p = 0): cheaper than
        picking the active ones. The pairs' forces are first summed per sphere, f_s, in one
        product. A force f at a point s fixed on a link drives joint k, if k moves the link,
        by fᵀ(v_k + ω_k × s) = vec(s ⊗ f)·(_CROSS ω_k) + f·v_k with J = [v; ω] Pinocchio's
        world joint Jacobian: so the spheres' [vec(s ⊗ f); f] (12, S), summed over the
        spheres each joint moves (one product), meet the Jacobian through _WRENCH.
        (np.dot, and no broadcasting: each costs less call overhead here.)
        """
        s = self._spheres
        assert s is not None
        n_sph, at = s.scratch.shape[1], s.n_obstacle
        if at:
            force = np.dot(s.to_world, local[:, :at].reshape(-1, n_sph))
        else:
            force = np.zeros((12, n_sph))
        if len(s.pair_sphere2):
            force += np.dot(_FORCE, np.dot(local[:, at:], s.self_force))
        force *= np.dot(_AT_POINT, s.scratch)
        per_joint = np.dot(force, s.sphere_supports)  # (12, n)
        per_joint *= np.dot(_WRENCH, jac)
        return np.dot(_ONES12, per_joint)

    # -- ConfigurationConstraint ----------------------------------------------------------
    def value(self, x: Array) -> Array:
        y = self._regressor(self._q(x))
        if self._spheres is None:
            return self._value(y, None, None)
        d, u, _ = self._sphere_distances(y)
        return self._value(y, d, u)

    def _value(self, y: Array, d: Array | None, u: Array | None) -> Array:
        """The clearances from the regressor y and (with spheres) their pairs' d and u."""
        s = self._spheres
        if s is None:
            out = np.empty(len(self.names))
        else:
            assert d is not None and u is not None
            phi = d - s.rsum
            # (x[x.argmin()]: min without a ufunc reduction, several times cheaper)
            if not d[d.argmin()] > 0.0:  # a centre inside a core box: signed distance there
                depth = np.max(np.abs(u) - s.half, axis=0) - s.rsum
                phi = np.where(d > 0.0, phi, depth)
            out = np.minimum.reduceat(phi, s.starts)  # the sphere constraints come first
            if not self._groups:
                return out
            out = np.concatenate([out, np.empty(len(self.names) - s.stop)])
        for g in self._groups:
            out[g.start:g.stop] = g.reported(g.narrow(y)[0])
        return out

    def values_along(self, xs: Array) -> Array:
        """φ at each row of xs, (N, k): with sphere primitives only, the pairs of all rows go
        through one set of numpy calls (the same numbers as ``value`` row by row)."""
        s = self._spheres
        xs = np.asarray(xs, dtype=float)
        if s is None or self._groups or len(xs) < 2:
            return super().values_along(xs)
        rows = len(xs)
        if rows not in self._along:  # h, rsum and the constraints' first pairs, row after row
            pairs = len(s.rsum)
            self._along[rows] = (np.tile(s.half, rows), np.tile(s.rsum, rows),
                                 (s.starts + pairs * np.arange(rows)[:, None]).reshape(-1))
        half, rsum, starts = self._along[rows]
        u = np.concatenate([self._offsets(self._regressor(self._q(x))) for x in xs], axis=1)
        d, _ = _core_distances(u, half)
        if not d[d.argmin()] > 0.0:  # a centre inside a core box: row by row
            return super().values_along(xs)
        d -= rsum
        return np.minimum.reduceat(d, starts).reshape(rows, -1)

    def evaluate(self, x: Array) -> tuple[Array, Array]:
        q = self._q(x)
        y = self._regressor(q)
        k = len(self.names)
        grad = np.empty((k, self._n))
        out = self.value(x)
        s = self._spheres
        if s is not None:
            phi, g0 = self._pair_gradients(q, y)
            # each reported constraint is its closest sphere pair
            bounds = [*s.starts.tolist(), len(phi)]
            closest = [lo + int(np.argmin(phi[lo:hi])) for lo, hi in pairwise(bounds)]
            grad[s.start:s.stop] = g0[closest]
        jacobian_rows = partial(self._rows_times_jacobians, q)
        for g in self._groups:
            grad[g.start:g.stop] = g.gradient(*g.narrow(y), jacobian_rows)
        if not self._identity:
            grad = grad @ self._t_inv
        return out, grad

    def gradient(self, x: Array) -> Array:
        return self.evaluate(x)[1]

    # -- second order (cpbc.constraints.pair_motion) ----------------------------------------
    @property
    def sphere_count(self) -> int:
        """How many reported constraints are sphere primitives' (they come first)."""
        return 0 if self._spheres is None else self._spheres.stop

    def sphere_pairs(self, x: Array, dx: Array
                     ) -> tuple[Array, Array, Array, NDArray[np.bool_]]:
        """Every sphere pair on its own (not the per-link minimum): its clearance φ_p (P,),
        gradient ∇φ_p (P, n), curvature ẋᵀ∇²φ_p ẋ (P,) and whether it can move (P,) bool.

        Each pair is smooth where the minimum over a link's spheres is not: a filter that
        wants C¹ rows keeps one row per pair. Empty without sphere primitives.
        """
        s = self._spheres
        if s is None:
            n = self._n
            return np.zeros(0), np.zeros((0, n)), np.zeros(0), np.zeros(0, dtype=bool)
        q, dq = self._q(x), self._q(dx)
        y = self._regressor(q)
        phi, grad = self._pair_gradients(q, y)
        if not self._identity:
            grad = grad @ self._t_inv
        return phi, grad, self._pair_curvature(q, dq, y), s.moving > 0.0

    def _pair_curvature(self, q: Array, dq: Array, y: Array) -> Array:
        """ẋᵀ∇²φ_p ẋ of every sphere pair (pair_motion, eqs. 1 and 2)."""
        s = self._spheres
        assert s is not None
        data = self._motion_data
        pin.computeJointJacobiansTimeVariation(self._pin, data, q, dq)
        pin.computeJointJacobians(self._pin, data, q)
        u = self._offsets(y)
        centres = s.scratch[:3].T.copy()
        vel, acc = point_motion(data.J, data.dJ, s.sphere_supports, dq, centres)
        rot = s.pair_rot
        first = s.pair_sphere
        du = np.einsum("pba,pb->ap", rot, vel[first])
        ddu = np.einsum("pba,pb->ap", rot, acc[first])
        if len(s.pair_sphere2):
            at, second = s.n_obstacle, s.pair_sphere2
            du[:, at:] -= vel[second].T
            ddu[:, at:] -= acc[second].T
        return rounded_box_curvature(u, du, ddu, s.half)

    def curvature(self, x: Array, dx: Array) -> Array:
        """ẋᵀ∇²φ ẋ of each reported constraint: that of its closest sphere pair (as its
        gradient is), and for capsule primitives a central difference of the gradient along
        ẋ (step 1e-6 rad of motion; their closed forms are piecewise and not given here)."""
        out = np.zeros(len(self.names))
        s = self._spheres
        if s is not None:
            phi, _, curv, _ = self.sphere_pairs(x, dx)
            bounds = [*s.starts.tolist(), len(phi)]
            closest = [lo + int(np.argmin(phi[lo:hi])) for lo, hi in pairwise(bounds)]
            out[s.start:s.stop] = curv[closest]
        speed = float(np.linalg.norm(dx))
        if self._groups and speed > 0.0:
            t = 1e-6 / speed
            diff = self.gradient(x + t * dx) - self.gradient(x - t * dx)
            rest = slice(0 if s is None else s.stop, len(self.names))
            out[rest] = (diff @ dx)[rest] / (2.0 * t)
        return out

    def _shape(self, phi: Array) -> tuple[Array, Array]:
        """φ̃ and (dφ̃/dφ)/φ̃ of the class docstring (φ and 1/φ without an influence)."""
        ell = self.influence
        if ell is None:
            return phi, 1.0 / phi
        # ℓ − ℓ(1 − min(φ/ℓ, 1))³ and 3(1 − …)²/φ̃, operation by operation as ever (the same
        # bits), in place and with 0-d array constants (cheaper per call than Python floats)
        v = phi * self._inv_ell
        np.minimum(v, _ONE, out=v)
        np.subtract(_ONE, v, out=v)
        v2 = v * v
        shaped = v2 * v
        shaped *= self._ell
        np.subtract(self._ell, shaped, out=shaped)
        v2 *= _THREE
        v2 /= shaped
        return shaped, v2

    def _near_groups(self, y: Array) -> list[_CapsuleGroup]:
        """Capsule groups with a pair that may be within the influence distance."""
        if not self._groups:
            return []
        if self.influence is None:
            return self._groups
        z = y.reshape(-1) @ self._broad_w + self._broad_c
        n3 = 3 * self._n_bounded
        delta = z[:n3].reshape(-1, 3)
        slack = np.concatenate([(delta * delta).sum(axis=1) - self._broad_thr,
                                z[n3:] - self.influence])
        low = (np.minimum.reduceat(slack, self._reduce_at) < 0.0).tolist()
        return [g for g, hit in zip(self._groups, low, strict=True) if hit]

    def barrier_terms(self, state: ArmState, margins: bool = False
                      ) -> tuple[Array, Array, Array | None]:
        """φ̃, Σ ∇φ̃/φ̃ and (with ``margins``) the clearances φ, from one pass that reads
        the state's joint Jacobians."""
        return self._barrier(state.x, state.q, margins)

    def _barrier(self, x: Array, q: Array, with_value: bool
                 ) -> tuple[Array, Array, Array | None]:
        """The sphere pairs' factors of φ̃ and their normals, then the terms of the capsule
        groups that may be within ℓ, then the force of both (``_force``). Outside S: the
        clearances φ for φ̃ and no force (the constraint set raises)."""
        y = self._regressor(q)
        value: Array | None = None
        phi_out: Array | None = None
        sphere_local: Array | None = None  # the pairs' normals × (dφ̃/dφ)/φ̃, obstacle frames
        s = self._spheres
        if s is not None:
            d, u, outside = self._sphere_distances(y)
            phi = d - s.rsum_law  # pairs that cannot move: ∞ (with ℓ)
            low = phi[phi.argmin()]  # phi.min(), cheaper
            if low <= 0.0:  # outside S: report it, the constraint set raises
                value = self._value(y, d, u)
                return value, self._zero, value
            if with_value:
                value = self._value(y, d, u)
            phi_out, sphere_local = self._sphere_law(s, phi, low, d, u, outside)
        capsules = self._capsule_law(y, phi_out)
        if capsules is None:  # a capsule pair outside S
            value = self.value(x)
            return value, self._zero, value
        phi_out, rows = capsules
        if with_value and value is None:
            value = self.value(x)
        if phi_out is None:
            return self._far_phi, self._zero, value
        return phi_out, self._force(q, sphere_local, rows), value

    def _sphere_law(self, s: _Spheres, phi: Array, low: Array, d: Array, u: Array,
                    outside: Array) -> tuple[Array | None, Array | None]:
        """φ̃ of every constraint, its sphere constraints' the product of their pairs'
        factors (their log-barriers add; a pair that cannot move gives a constant factor),
        and the pairs' normals × (dφ̃/dφ)/φ̃ in the obstacles' frames (``outside`` is
        overwritten); (None, None) when no pair is within ℓ."""
        factors = self._sphere_factors(s, phi, low)
        if factors is None:
            return None, None
        factor, slope = factors
        products = np.multiply.reduceat(factor, s.starts)
        if self._groups:
            phi_out = self._far_phi.copy()
            phi_out[:s.stop] *= products
        else:
            phi_out = np.multiply(products, self._far_phi)
        slope /= d
        sphere_local = np.copysign(outside, u, out=outside)
        sphere_local *= slope
        return phi_out, sphere_local

    def _sphere_factors(self, s: _Spheres, phi: Array, low: Array
                        ) -> tuple[Array, Array] | None:
        """Each sphere pair's factor φ̃/ℓ (φ without ℓ) and (dφ̃/dφ)/φ̃ (without the 3/ℓ kept
        in ``to_world``); None when no pair is within ℓ (the sphere pairs are all far)."""
        if self.influence is None:
            return np.where(s.moving > 0.0, phi, 1.0), s.moving / phi
        if not low < self.influence:
            return None
        # only the pairs within ℓ enter the law: the others have φ̃ = ℓ, so factor 1 and
        # slope 0, and all pairs go through densely. In place, with v = 1 − min(φ/ℓ, 1):
        # φ̃/ℓ = 1 − v³ and (dφ̃/dφ)/φ̃ = (3/ℓ) v²/(1 − v³)
        v = phi * self._inv_ell
        np.minimum(v, _ONE, out=v)
        np.subtract(_ONE, v, out=v)
        slope = v * v
        factor = slope * v
        np.subtract(_ONE, factor, out=factor)
        slope /= factor
        return factor, slope

    def _capsule_law(self, y: Array, phi_out: Array | None
                     ) -> tuple[Array | None, list[_Rows]] | None:
        """The terms of the capsule groups that may be within ℓ: their φ̃ into ``phi_out``
        (a copy of the far values first if None) and the rows of their force; None when a
        pair is outside S."""
        rows: list[_Rows] = []
        for g in self._near_groups(y):
            phi, grows = g.narrow(y)
            if phi.min() <= 0.0:
                return None
            shaped, ratio = self._shape(phi)
            phi_out = self._far_phi.copy() if phi_out is None else phi_out
            phi_out[g.start:g.stop], g_rows = g.law(shaped, ratio, grows, self.influence)
            rows += g_rows
        return phi_out, rows

    def _force(self, q: Array, sphere_local: Array | None, rows: list[_Rows]) -> Array:
        """Σ ∇φ̃/φ̃: the sphere pairs' (``_sphere_force``) plus the capsule rows', from the
        state's joint Jacobians (RobotModel.state, kinematics=True)."""
        jac = self._data.J
        b = self._zero
        if sphere_local is not None:
            b = self._sphere_force(sphere_local, jac)
        if rows:
            points, normals, masks = (np.concatenate(part) for part in zip(*rows, strict=True))
            b = b + self._rows_times_jacobians(q, points, normals, masks, jac).sum(axis=0)
        if not self._identity:
            b = b @ self._t_inv
        return b
