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

from cpbc.constraints.base import Array, ConfigurationConstraint
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
from cpbc.model.robot_model import RobotModel

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

# 0-d arrays: numpy takes them faster than Python floats as ufunc operands
_ZERO, _ONE, _THREE = np.array(0.0), np.array(1.0), np.array(3.0)

_FAR = 1e9  # clearance given to the missing second end of a sphere against a plane
_TINY = 1e-300


@dataclass
class _Spheres:
    """Sphere primitives against every obstacle (as rounded boxes) and each other.

    For pair p of sphere centre s and an obstacle with centre c, rotation R, core half-extents
    h and rounding ρ: u_p = Rᵀ(s − c) is linear in Pinocchio's static regressor Y, so all
    u_p come out of one product w @ vec(Y) + c; then d_p = ‖max(|u_p| − h, 0)‖ − ρ. A self
    pair is the same with c the other sphere's centre (R = I, h = 0).

    Per-pair 3-vectors are stored component-major, (3, P): numpy's inner loops then run
    along the pairs, not along a length-3 axis (several times cheaper per step).
    """

    start: int
    stop: int
    w: Array  # (3P, 12 nj): u = (w @ vec(Y) + c).reshape(3, P)
    w_k: Array  # w, columns reordered (joint j, column a of Y_j, row r): ``_sphere_force``
    c: Array  # (3P,)
    half: Array  # (3, P)
    rsum: Array  # sphere radius + rounding (+ other radius) + margin, (P,)
    rot: Array  # (P, 3, 3)
    centres: Array  # (4 nj, P): first sphere centre of each pair
    mask: Array  # (P, n)
    n_obstacle: int  # pairs [0, n_obstacle) are against obstacles, the rest are self pairs
    centres2: Array  # (4 nj, S) second sphere of each self pair
    mask2: Array  # (S, n)
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
    obstacle; the centres of all spheres, in every obstacle's frame, come out of a single
    matrix product with Pinocchio's static regressor (all joint placements in one call).
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
    gradient at random configurations, and leave the hot path.

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

    barrier_is_margin = False  # the law's φ̃ (and per-link products), not the clearance

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
        self._data = model.model.createData()
        self._n = model.n
        self._identity = model.coordinates.is_identity
        self._t_inv = model.coordinates.inverse
        self._setup_kinematics()
        self._setup_pairs(name)
        self._far_phi = np.full(len(self.names), self.influence or 1.0)
        self._moving = self._split_static()
        self._far_phi.setflags(write=False)
        self._setup_products()
        self._zero = np.zeros(self._n)
        self._zero.setflags(write=False)

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
        # Ŷ_j = [Y_j; (1/scale, 0, 0, 0)]: Ŷ_j ĉ = (point, 1) for a column block ĉ of _column
        self._yhat = np.zeros((self._nj, 4, 4))
        self._yhat[:, 3, 0] = 1.0 / self._scale
        self._supports = np.zeros((pm.njoints, self._n))
        for j in range(1, pm.njoints):
            for k in pm.supports[j].tolist()[1:]:
                jm = pm.joints[k]
                self._supports[j, jm.idx_v: jm.idx_v + jm.nv] = 1.0
        self._link_supports_t = np.ascontiguousarray(self._supports[1:].T)  # (n, nj)
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
        obs_pairs, group = [], []
        for o in self.obstacles:
            for f in sphere_frames:
                obs_pairs += [(i, o) for i in by_frame[f] if prims[i].kind == "sphere"]
                group += [len(names)] * (len(obs_pairs) - len(group))
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
        self._sphere_lists = (obs_pairs, sphere_self, group)
        if obs_pairs or sphere_self:
            self._spheres = self._sphere_group(obs_pairs, sphere_self, 0, group)
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

    def _split_static(self, samples: int = 8) -> _Spheres | None:
        """The sphere pairs whose clearance can change, as their own group.

        A sphere on the first link of an arm whose first axis is vertical keeps its height
        above a table: its clearance is constant, its barrier gradient zero. Such pairs are
        found by their gradient, which vanishes at every one of ``samples`` random
        configurations (an analytic function of q that vanishes on random samples is zero);
        their constant factor φ̃ goes into ``_far_phi`` once, and the hot path skips them.
        """
        s = self._spheres
        if s is None:
            return None
        pm = self._pin
        lo = np.where(np.isfinite(pm.lowerPositionLimit), pm.lowerPositionLimit, -np.pi)
        hi = np.where(np.isfinite(pm.upperPositionLimit), pm.upperPositionLimit, np.pi)
        rng = np.random.default_rng(0)
        slope = np.zeros(len(s.group))
        for _ in range(samples):
            q = rng.uniform(lo, hi)
            _, d, u, outside = self._sphere_distances(self._regressor(q))
            rows = self._sphere_rows(self._regressor(q), u, outside,
                                     1.0 / np.maximum(d, _TINY))
            g = self._rows_times_jacobians(q, *rows[0])
            if len(rows) > 1:
                g[s.n_obstacle:] += self._rows_times_jacobians(q, *rows[1])
            slope = np.maximum(slope, np.abs(g).max(axis=1))
        static = slope < 1e-12
        if not static.any():
            return s
        phi = self._sphere_distances(self._regressor(pin.neutral(pm)))[0][static]
        shaped = phi if self.influence is None else self._shape(phi)[0] / self.influence
        np.multiply.at(self._far_phi, s.group[static], shaped)
        if static.all():
            return None
        obs_pairs, self_pairs, group = self._sphere_lists
        keep = ~static
        n_obs = len(obs_pairs)
        return self._sphere_group(
            [p for p, k in zip(obs_pairs, keep[:n_obs], strict=True) if k],
            [p for p, k in zip(self_pairs, keep[n_obs:], strict=True) if k],
            0, [gi for gi, k in zip(group, keep, strict=True) if k],
        )

    def _setup_products(self) -> None:
        """The buffer of ``_link_products``: one segment per sphere constraint g, its head
        ``_far_phi[g]`` (fixed) followed by the factors of g's moving pairs (rewritten each
        step), so that one multiply.reduceat gives every constraint's product."""
        s, full = self._moving, self._spheres
        ell = self.influence
        self._unit_exact = ell is None or ell * (1.0 / ell) == 1.0
        if s is None or full is None:
            self._factors = np.zeros(0)
            self._slots = self._heads = np.zeros(0, dtype=np.intp)
            return
        groups = full.stop  # sphere constraints are names[0:groups]; some may have no moving pair
        counts = np.bincount(s.group, minlength=groups)
        self._heads = np.arange(groups, dtype=np.intp) + np.concatenate(
            [[0], np.cumsum(counts)[:-1]]).astype(np.intp)
        self._slots = np.arange(len(s.group), dtype=np.intp) + s.group + 1  # pairs sorted by g
        self._factors = np.ones(len(s.group) + groups)
        self._factors[self._heads] = self._far_phi[:groups]

    def _sphere_group(
        self, obs_pairs: list[tuple[int, Obstacle]], self_pairs: list[tuple[int, int]],
        start: int, group: list[int],
    ) -> _Spheres:
        cols, consts, half, rsum, rots = [], [], [], [], []
        for i, o in obs_pairs:
            core = o.core()
            s = self._column(i, 0)
            for c in range(3):  # u_c = R[:, c]·(Y s − centre)
                cols.append(np.outer(core.rotation[:, c], s).reshape(-1))
            consts.extend((-(core.rotation.T @ core.centre)).tolist())
            half.append(core.half_extents)
            rsum.append(self.primitives[i].radius + core.rounding + self.margin)
            rots.append(core.rotation)
        for i, j in self_pairs:
            s = self._column(i, 0) - self._column(j, 0)
            for c in range(3):
                w = np.zeros((3, 4 * self._nj))
                w[c] = s
                cols.append(w.reshape(-1))
            consts.extend([0.0, 0.0, 0.0])
            half.append(np.zeros(3))
            rsum.append(self.primitives[i].radius + self.primitives[j].radius + self.margin)
            rots.append(np.eye(3))
        first = [i for i, _ in obs_pairs] + [i for i, _ in self_pairs]
        second = [j for _, j in self_pairs]
        empty = np.zeros((4 * self._nj, 0))
        centres, masks = self._columns(first, 0), self._masks(first)
        rot = np.array(rots)
        grp = np.array(group, dtype=np.intp)
        n_pairs = len(grp)

        def component_major(a: Array) -> Array:  # rows/entries of pair p, component k → (k, p)
            return np.ascontiguousarray(a.reshape(n_pairs, 3, -1).transpose(1, 0, 2)
                                        .reshape(a.shape))

        starts = np.flatnonzero(np.diff(grp, prepend=-1)).astype(np.intp)
        w = component_major(np.vstack(cols))
        return _Spheres(
            start, start + int(grp[-1]) + 1, w, w.reshape(3 * n_pairs, 3, -1)
            .transpose(0, 2, 1).reshape(w.shape).copy(),
            component_major(np.array(consts)), np.ascontiguousarray(np.array(half).T),
            np.array(rsum), rot, centres, masks,
            len(obs_pairs),
            self._columns(second, 0) if second else empty,
            self._masks(second) if second else np.zeros((0, self._n)),
            starts, grp,
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
    def _sphere_distances(
        self, y: Array, s: _Spheres | None = None
    ) -> tuple[Array, Array, Array, Array]:
        """Sphere pairs (all of them unless ``s`` is given): φ (P,), the core distance d (P,),
        u (3, P) and max(|u| − h, 0) (3, P)."""
        s = self._spheres if s is None else s
        assert s is not None
        u = np.dot(s.w, y.reshape(-1))
        u += s.c
        u = u.reshape(3, -1)
        outside = np.abs(u)
        outside -= s.half
        np.maximum(outside, _ZERO, out=outside)
        d = np.sqrt(np.add.reduce(outside * outside, axis=0))
        return d - s.rsum, d, u, outside

    def _sphere_rows(
        self, y: Array, u: Array, outside: Array, scale: Array, s: _Spheres | None = None
    ) -> list[tuple[Array, Array, Array]]:
        """(points, normals × scale·d, masks) of the sphere pairs' gradient rows: pass
        ``scale`` already divided by the core distance d."""
        s = self._spheres if s is None else s
        assert s is not None
        local = np.ascontiguousarray((np.copysign(outside, u) * scale).T)
        normal = (s.rot @ local[:, :, None])[:, :, 0]
        rows = [((y @ s.centres).T, normal, s.mask)]
        if s.n_obstacle < len(s.group):
            rows.append(((y @ s.centres2).T, -normal[s.n_obstacle:], s.mask2))
        return rows

    @staticmethod
    def _local_normals(u: Array, outside: Array, ratio: Array, d: Array) -> Array:
        """Each pair's normal in its obstacle's frame, copysign(max(|u| − h, 0), u)/d, times
        ``ratio`` (3, P); in place: ``outside`` and ``ratio`` are overwritten."""
        ratio /= d
        local = np.copysign(outside, u, out=outside)
        local *= ratio
        return local

    def _sphere_force(self, y: Array, s: _Spheres, local: Array, jac: Array) -> Array:
        """Σ_p J(c_p)ᵀ n_p over the pairs of ``s`` (c_p the first sphere's centre, J(c) the
        Jacobian of a point fixed on its link, n_p = R_p local_p), minus the same at the second
        sphere of each self pair; (n,).

        Dense over all the pairs (a pair out of the law has local_p = 0): cheaper than picking
        the active ones. Σ_p n_p·δc_p = Σ local·δu, and u = w vec(Y) + c, so the pairs' sum
        is G = localᵀ w, a 3 × 4nj cotangent of Y: one product for every pair, rotation and
        self pair included (w_k: the same columns ordered so that it comes out as the blocks
        K_j = G_jᵀ, contiguous). Column block j of Y is joint j's placement [t_j R_j]/scale;
        its variation is that of points fixed on link j, so with Ŷ_j = [Y_j; e₀ᵀ/scale] the
        link's wrench about the origin is vec(Ŷ_j K_j) = (Σ c ⊗ n, Σ n), and only the nj link
        wrenches meet the Jacobian (through _WRENCH), each on the joints that move its link.
        (np.dot: less call overhead than ``@`` on small 2-d products.)
        """
        nj = self._nj
        k = np.dot(local.reshape(-1), s.w_k).reshape(nj, 4, 3)  # K_j, contiguous
        yhat = self._yhat
        yhat[:, :3] = y.reshape(3, nj, 4).transpose(1, 0, 2)
        wrench = (yhat @ k).reshape(nj, 12)
        # Σ_j supports_jk (wrench_j · J12[:, k]): the diagonal of (supportsᵀ wrench) J12
        per_joint = np.dot(self._link_supports_t, wrench)  # wrenches of the links joint k moves
        return np.dot(per_joint, np.dot(_WRENCH, jac)).diagonal().copy()

    def _link_products(self, phi: Array, shaped: Array) -> Array:
        """The law's function of every constraint: far_phi times the φ̃/ℓ of its moving sphere
        pairs within ℓ, multiplied left to right (far_phi first, then pair by pair in order:
        bit for bit the product taken one pair at a time); capsule constraints get far_phi."""
        assert self.influence is not None
        factors = shaped * self._inv_ell
        if not self._unit_exact:  # a pair beyond ℓ must contribute exactly 1
            factors = np.where(phi < self.influence, factors, 1.0)
        self._factors[self._slots] = factors
        sph = np.multiply.reduceat(self._factors, self._heads)
        if len(sph) == len(self.names):
            return sph
        out = self._far_phi.copy()
        out[:len(sph)] = sph
        return out

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
        s = self._spheres
        if s is None:
            out = np.empty(len(self.names))
        else:
            phi, d, u, _ = self._sphere_distances(y)
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

    def evaluate(self, x: Array) -> tuple[Array, Array]:
        q = self._q(x)
        y = self._regressor(q)
        k = len(self.names)
        grad = np.empty((k, self._n))
        out = self.value(x)
        s = self._spheres
        if s is not None:
            phi, d, u, outside = self._sphere_distances(y)
            rows = self._sphere_rows(y, u, outside, 1.0 / np.maximum(d, _TINY))
            g0 = self._rows_times_jacobians(q, *rows[0])
            if len(rows) > 1:
                g0[s.n_obstacle:] += self._rows_times_jacobians(q, *rows[1])
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

    def barrier_terms(self, x: Array) -> tuple[Array, Array]:
        q = self._q(x)
        y = self._regressor(q)
        ell = self.influence
        rows: list[tuple[Array, Array, Array]] = []
        phi_out: Array | None = None
        sphere_local: Array | None = None  # the pairs' normals × (dφ̃/dφ)/φ̃, obstacle frames
        s = self._moving
        if s is not None:
            phi, d, u, outside = self._sphere_distances(y, s)
            low = phi[phi.argmin()]  # phi.min(), cheaper
            if low <= 0.0:  # outside S: report it, the constraint set raises
                return self.value(x), self._zero
            # a link's barrier is the product of its spheres' terms (their log-barriers add);
            # spheres that cannot move relative to an obstacle give a constant factor
            if ell is None:
                shaped, inv = self._shape(phi)
                phi_out = self._far_phi.copy()
                phi_out[s.group[s.starts]] *= np.multiply.reduceat(shaped, s.starts)
                sphere_local = self._local_normals(u, outside, inv, d)
            elif low < ell:  # only the pairs within ℓ enter the law: the others have φ̃ = ℓ
                shaped, inv = self._shape(phi)  # and inv = 0, so all pairs go through densely
                phi_out = self._link_products(phi, shaped)
                sphere_local = self._local_normals(u, outside, inv, d)
        for g in self._near_groups(y):
            phi, grows, _ = self._narrow(g, y)
            if phi.min() <= 0.0:
                return self.value(x), self._zero
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
        if phi_out is None:
            return self._far_phi, self._zero
        jac = self._jacobians(q)
        b = self._zero
        if sphere_local is not None:
            assert s is not None
            b = self._sphere_force(y, s, sphere_local, jac)
        if rows:
            b = b + self._rows_times_jacobians(
                q, *(np.concatenate(part) for part in zip(*rows, strict=True)), jac=jac
            ).sum(axis=0)
        if not self._identity:
            b = b @ self._t_inv
        return phi_out, b
