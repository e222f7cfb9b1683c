"""Clearance between the whole arm and the obstacles (and between its own links).

One scalar configuration constraint per (robot primitive, obstacle) pair and per
self-collision pair, all evaluated together so that the hot path is a fixed, small number of
vectorised operations whatever the number of pairs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
import pinocchio as pin

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
from cpbc.errors import CpbcError
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

_FAR = 1e9  # clearance given to the missing second end of a sphere against a plane
_TINY = 1e-300


def _core_distances(u: Array, half: Array) -> tuple[Array, Array]:
    """‖max(|u| − h, 0)‖ per column of u (3, P), and max(|u| − h, 0) itself."""
    outside = np.abs(u)
    outside -= half
    np.maximum(outside, _ZERO, out=outside)
    return np.sqrt(np.dot(_ONES3, outside * outside)), outside


@dataclass
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
    # w = 3/ℓ (1 without ℓ): see ``barrier_terms``
    self_force: Array  # (Ps, S): w (+1 first, −1 second), the self pairs' forces per sphere
    pair_sphere: Array  # (P,) the (first) sphere of each pair
    pair_sphere2: Array  # (Ps,) the second sphere of each self pair
    pair_rot: Array  # (P, 3, 3) the obstacle's rotation R (I for a self pair)
    sphere_supports: Array  # (S, n) 1 where joint k moves sphere s's link
    starts: Array  # first pair of each reported constraint (a link against an obstacle/link)
    group: Array  # (P,) the constraint (index in ``names``) of each pair


@dataclass
class _Group:
    """Capsule primitives against obstacles of one kind (or capsule self pairs).

    Segment ends of every pair: a = (Y @ ea).T, b = (Y @ eb).T.
    """

    kind: str
    start: int
    stop: int
    ea: Array
    eb: Array
    mask: Array  # (P, n) support of the robot body of each pair (1 where q_k moves it)
    rsum: Array  # radii + margin, (P,)
    ea2: Array | None = None  # self pairs: the other primitive
    eb2: Array | None = None
    mask2: Array | None = None
    other: Array | None = None  # sphere centres / capsule starts / box centres / plane normals
    other2: Array | None = None  # capsule ends / box half-extents / plane offsets
    rot: Array | None = None  # box rotations (P, 3, 3)
    has_b: Array | None = None  # planes: 1 where the primitive has a distinct second end


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
            raise CpbcError(f"clearance margin must be ≥ 0, got {margin}")
        if influence is not None and not (np.isfinite(influence) and influence > 0):
            raise CpbcError(f"clearance influence distance must be > 0, got {influence}")
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
        self._along: dict[int, tuple[Array, Array, Array]] = {}  # see values_along

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
        prims = self.primitives
        spheres = [i for i, p in enumerate(prims) if p.kind == "sphere"]
        capsules = [i for i, p in enumerate(prims) if p.kind == "capsule"]
        by_frame: dict[str, list[int]] = {}
        for i, p in enumerate(prims):
            by_frame.setdefault(p.frame, []).append(i)
        self_pairs = [(i, j) for a, b in self.self_pairs for i in by_frame[a] for j in by_frame[b]]
        names: list[str] = []
        # sphere primitives: one fast group, reported per (link, obstacle) and (link, link)
        sphere_frames = list(dict.fromkeys(prims[i].frame for i in spheres))
        order = [i for f in sphere_frames for i in by_frame[f] if prims[i].kind == "sphere"]
        group: list[int] = []
        for o in self.obstacles:
            for f in sphere_frames:
                group += [len(names)] * sum(prims[i].kind == "sphere" for i in by_frame[f])
                names.append(f"{name}[{f}|{o.name}]")
        sphere_self = []
        for a, b in self.self_pairs:
            pairs = [(i, j) for i in by_frame[a] for j in by_frame[b]
                     if prims[i].kind == "sphere" and prims[j].kind == "sphere"]
            if pairs:
                sphere_self += pairs
                group += [len(names)] * len(pairs)
                names.append(f"{name}[{a}|{b}]")
        self._spheres: _Spheres | None = None
        if group:
            self._spheres = self._sphere_group(order, sphere_self, group)
        # capsule primitives: one group per obstacle kind
        self._groups: list[_Group] = []
        broad: list[tuple[Array, float]] = []  # (column over vec(Y), constant)
        thresholds: list[float] = []  # reach² per bounded pair
        span = self.influence or 0.0
        half_len = [0.5 * p.length for p in prims]

        def bounded(i: int, col: Array, centre: Array, reach: float) -> None:
            for c in range(3):  # Δ = mid − centre, component c, over vec(Y)
                w = np.zeros((3, 4 * self._nj))
                w[c] = col
                broad.append((w.reshape(-1), -float(centre[c])))
            thresholds.append(reach * reach)

        for kind, cls in (("sphere", SphereObstacle), ("capsule", CapsuleObstacle),
                          ("box", BoxObstacle)):
            pairs = [(i, o) for o in self.obstacles if isinstance(o, cls) for i in capsules]
            if not pairs:
                continue
            start = len(names)
            names += [f"{name}[{prims[i].name}|{o.name}]" for i, o in pairs]
            for i, o in pairs:
                centre, rad = o.bounding_sphere()
                reach = half_len[i] + prims[i].radius + rad + self.margin + span
                bounded(i, self._column(i, None), centre, reach)
            pi = [i for i, _ in pairs]
            g = _Group(kind, start, len(names), self._columns(pi, 0), self._columns(pi, 1),
                       self._masks(pi), np.array([prims[i].radius for i in pi]) + self.margin)
            if kind == "sphere":
                g.other = np.array([o.centre for _, o in pairs])  # type: ignore[attr-defined]
                g.rsum = g.rsum + np.array([o.radius for _, o in pairs])  # type: ignore[attr-defined]
            elif kind == "capsule":
                g.other = np.array([o.start for _, o in pairs])  # type: ignore[attr-defined]
                g.other2 = np.array([o.end for _, o in pairs])  # type: ignore[attr-defined]
                g.rsum = g.rsum + np.array([o.radius for _, o in pairs])  # type: ignore[attr-defined]
            else:
                g.other = np.array([o.centre for _, o in pairs])  # type: ignore[attr-defined]
                g.other2 = np.array([o.half_extents for _, o in pairs])  # type: ignore[attr-defined]
                g.rot = np.array([o.rotation for _, o in pairs])  # type: ignore[attr-defined]
            self._groups.append(g)
        capsule_self = [(i, j) for i, j in self_pairs if (i, j) not in set(sphere_self)]
        if capsule_self:
            start = len(names)
            names += [f"{name}[{prims[i].name}|{prims[j].name}]" for i, j in capsule_self]
            for i, j in capsule_self:
                reach = (half_len[i] + half_len[j] + prims[i].radius + prims[j].radius
                         + self.margin + span)
                bounded(i, self._column(i, None) - self._column(j, None), np.zeros(3), reach)
            pi, pj = [i for i, _ in capsule_self], [j for _, j in capsule_self]
            self._groups.append(_Group(
                "self", start, len(names), self._columns(pi, 0), self._columns(pi, 1),
                self._masks(pi),
                np.array([prims[i].radius + prims[j].radius for i, j in capsule_self])
                + self.margin,
                ea2=self._columns(pj, 0), eb2=self._columns(pj, 1), mask2=self._masks(pj),
            ))
        self._n_bounded = len(broad) // 3
        planes = [(i, o) for o in self.obstacles if isinstance(o, PlaneObstacle) for i in capsules]
        plane_cols: list[tuple[Array, float]] = []
        if planes:
            start = len(names)
            names += [f"{name}[{prims[i].name}|{o.name}]" for i, o in planes]
            pi = [i for i, _ in planes]
            g = _Group("plane", start, len(names), self._columns(pi, 0), self._columns(pi, 1),
                       self._masks(pi), np.array([prims[i].radius for i in pi]) + self.margin)
            g.other = np.array([o.normal for _, o in planes])  # type: ignore[attr-defined]
            g.other2 = np.array([o.offset for _, o in planes])  # type: ignore[attr-defined]
            g.has_b = np.array([float(prims[i].kind == "capsule") for i in pi])
            for e in (g.ea, g.eb):  # heights n·a − offset − r − Δ and n·b − …, over vec(Y)
                for p in range(len(planes)):
                    plane_cols.append((np.outer(g.other[p], e[:, p]).reshape(-1),
                                       -(g.other2[p] + g.rsum[p])))
            self._groups.append(g)
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise CpbcError(f"clearance pairs {dup} appear twice: give primitives on one link "
                            "one kind, or distinct names")
        self.names = tuple(names)
        cols = [c for c, _ in broad] + [c for c, _ in plane_cols]
        self._broad_w = (np.ascontiguousarray(np.column_stack(cols)) if cols
                         else np.zeros((12 * self._nj, 0)))
        self._broad_c = np.array([k for _, k in broad] + [k for _, k in plane_cols])
        self._broad_thr = np.array(thresholds)
        starts, pos = [], 0
        for g in self._groups:
            starts.append(pos)
            pos += 2 * (g.stop - g.start) if g.kind == "plane" else g.stop - g.start
        self._reduce_at = np.array(starts, dtype=np.intp)

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
        slope = 1.0 if self.influence is None else 3.0 / self.influence  # see barrier_terms
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

    def _narrow(
        self, g: _Group, y: Array
    ) -> tuple[Array, list[tuple[Array, Array, Array]], Array | None]:
        """Exact clearances of a capsule group and its gradient rows (points, unit normals,
        masks). For planes: φ of the a ends then the b ends (2P,), and min(φ_a, φ_b)."""
        a = (y @ g.ea).T
        b = (y @ g.eb).T
        if g.kind == "sphere":
            d, p, n = segment_point(a, b, g.other)  # type: ignore[arg-type]
            return d - g.rsum, [(p, n, g.mask)], None
        if g.kind == "capsule":
            d, p, _, n = segment_segment(a, b, g.other, g.other2)  # type: ignore[arg-type]
            return d - g.rsum, [(p, n, g.mask)], None
        if g.kind == "box":
            d, p, _, n = segment_box(a, b, g.other, g.rot, g.other2)  # type: ignore[arg-type]
            return d - g.rsum, [(p, n, g.mask)], None
        if g.kind == "self":
            d, p, q, n = segment_segment(a, b, (y @ g.ea2).T, (y @ g.eb2).T)
            return d - g.rsum, [(p, n, g.mask), (q, -n, g.mask2)], None  # type: ignore[list-item]
        normal = g.other
        phi_a = (a * normal).sum(axis=1) - g.other2 - g.rsum  # type: ignore[operator]
        phi_b = (b * normal).sum(axis=1) - g.other2 - g.rsum  # type: ignore[operator]
        phi_b_term = phi_b + (1.0 - g.has_b) * _FAR  # type: ignore[operator]
        rows = [(a, normal, g.mask), (b, normal, g.mask)]
        return np.concatenate([phi_a, phi_b_term]), rows, np.minimum(phi_a, phi_b)  # type: ignore[return-value]

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
            phi, _, pair = self._narrow(g, y)
            out[g.start:g.stop] = phi if pair is None else pair
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
        for g in self._groups:
            phi, rows, _ = self._narrow(g, y)
            size = g.stop - g.start
            if g.kind == "plane":
                (pa, n, mask), (pb, _, _) = rows
                use_b = (phi[size:] < phi[:size])[:, None]
                grad[g.start:g.stop] = self._rows_times_jacobians(
                    q, np.where(use_b, pb, pa), n, mask)
            else:
                grad[g.start:g.stop] = sum(
                    self._rows_times_jacobians(q, p, n, mask) for p, n, mask in rows)
        if not self._identity:
            grad = grad @ self._t_inv
        return out, grad

    def gradient(self, x: Array) -> Array:
        return self.evaluate(x)[1]

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

    def _near_groups(self, y: Array) -> list[_Group]:
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
        y = self._regressor(q)
        value: Array | None = None
        ell = self.influence
        rows: list[tuple[Array, Array, Array]] = []
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
            # a link's barrier is the product of its spheres' terms (their log-barriers add);
            # spheres that cannot move relative to an obstacle give a constant factor
            slope: Array | None = None
            if ell is None:
                factor = np.where(s.moving > 0.0, phi, 1.0)
                slope = s.moving / phi
            elif low < ell:  # only the pairs within ℓ enter the law: the others have φ̃ = ℓ,
                # so factor 1 and slope 0, and all pairs go through densely. In place, with
                # v = 1 − min(φ/ℓ, 1): φ̃/ℓ = 1 − v³ and (dφ̃/dφ)/φ̃ = (3/ℓ) v²/(1 − v³),
                # 3/ℓ kept in ``to_world``
                v = phi * self._inv_ell
                np.minimum(v, _ONE, out=v)
                np.subtract(_ONE, v, out=v)
                slope = v * v
                factor = slope * v
                np.subtract(_ONE, factor, out=factor)
                slope /= factor
            if slope is not None:
                products = np.multiply.reduceat(factor, s.starts)
                if self._groups:
                    phi_out = self._far_phi.copy()
                    phi_out[:s.stop] *= products
                else:
                    phi_out = np.multiply(products, self._far_phi)
                slope /= d
                sphere_local = np.copysign(outside, u, out=outside)
                sphere_local *= slope
        for g in self._near_groups(y):
            phi, grows, _ = self._narrow(g, y)
            if phi.min() <= 0.0:
                value = self.value(x)
                return value, self._zero, value
            shaped, inv = self._shape(phi)
            phi_out = self._far_phi.copy() if phi_out is None else phi_out
            size = g.stop - g.start
            if g.kind == "plane":  # the pair's barrier is the product of its end terms
                (pa, n, mask), (pb, _, _) = grows
                keep_b = shaped[size:] if ell is not None else np.where(
                    g.has_b > 0, shaped[size:], 1.0)  # type: ignore[operator]
                phi_out[g.start:g.stop] = shaped[:size] * (keep_b / (ell or 1.0))
                rows += [(pa, n * inv[:size, None], mask),
                         (pb, n * (inv[size:] * g.has_b)[:, None], mask)]  # type: ignore[operator]
            else:
                phi_out[g.start:g.stop] = shaped
                rows += [(p, n * inv[:, None], mask) for p, n, mask in grows]
        if with_value and value is None:
            value = self.value(x)
        if phi_out is None:
            return self._far_phi, self._zero, value
        jac = self._data.J  # the state's joint Jacobians (RobotModel.state, kinematics=True)
        b = self._zero
        if sphere_local is not None:
            assert s is not None
            b = self._sphere_force(sphere_local, jac)
        if rows:
            b = b + self._rows_times_jacobians(
                q, *(np.concatenate(part) for part in zip(*rows, strict=True)), jac=jac
            ).sum(axis=0)
        if not self._identity:
            b = b @ self._t_inv
        return phi_out, b, value
