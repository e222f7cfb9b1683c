"""Sphere primitives' pairs: every sphere against every obstacle (as a rounded box) and in
self pairs, all at once.

``Spheres`` holds the pairs' constant tables, packed for the compiled kernels
(cpbc.kernels.clearance, where the formulas are); ``SpherePairs`` (a base of ``Clearance``)
calls them for the pairs' distances, the law's factors and force, and each pair's gradient
and curvature along a motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.clearance.capsules import CapsuleGroup
from cpbc.constraints.clearance.kinematics import Kinematics
from cpbc.constraints.clearance.tables import Index
from cpbc.kernels.clearance import (
    Ints,
    sphere_barrier,
    sphere_clearances,
    sphere_geometry,
)
from cpbc.kernels.clearance_motion import closest_pair_gradients, sphere_pair_rows

ROUNDING = 1e-9  # [m] the broad phase's allowance for rounding, far above that of the
# centres and distances (~1e-15 m at an arm's scale), far below any influence distance


def pair_groups(pair_index: Ints, sphere_index: Ints, sphere_local: Array
                ) -> tuple[Ints, Array]:
    """The law's broad-phase groups (cpbc.kernels.clearance): each run of pairs of one
    reported constraint whose spheres share a joint, with its bounding point and radius.

    Returns ``group_index`` (G, 5) [first pair, one past the last, obstacle (−1: self
    pairs), the joint's first regressor column, the first group with the same bounding
    point] and ``group_table`` (G, 6) [M·[1, l_c], r, reach]: l_c the centre of the box
    around the group's sphere centres l_s (in the joint's frame), r = max ‖l_s − l_c‖;
    reach is set by ``Spheres.bound_groups``.
    """
    key = np.column_stack([pair_index[:, 3], sphere_index[pair_index[:, 1]]])
    key[pair_index[:, 0] < 0, 1] = -1  # self pairs: one group per constraint
    first = np.flatnonzero(np.any(np.diff(key, axis=0, prepend=-2) != 0, axis=1))
    stop = np.append(first[1:], len(pair_index))
    group_index = np.column_stack([first, stop, pair_index[first, 0],
                                   sphere_index[pair_index[first, 1]], np.zeros_like(first)]
                                  ).astype(np.int64)
    group_table = np.zeros((len(first), 6))
    seen: dict[tuple[int, ...], int] = {}  # a link's spheres against each obstacle: one point
    for g, (a, b) in enumerate(zip(first, stop, strict=True)):
        spheres = pair_index[a:b, 1]
        local = sphere_local[spheres]  # M·[1, l_s]
        centres = local[:, 1:] / local[:, :1]
        centre = 0.5 * (centres.min(axis=0) + centres.max(axis=0))
        group_table[g, :4] = local[0, 0] * np.concatenate([[1.0], centre])
        group_table[g, 4] = np.linalg.norm(centres - centre, axis=1).max()
        group_index[g, 4] = g if group_index[g, 2] < 0 else seen.setdefault(
            tuple(spheres.tolist()), g)  # self pairs: a point of their own
    return group_index, group_table


@dataclass(frozen=True, eq=False)
class Spheres:
    """Sphere primitives against every obstacle (as rounded boxes) and each other.

    For pair p of a sphere with world centre s and an obstacle with centre c, rotation R, core
    half-extents h and rounding ρ: u_p = Rᵀ(s − c), d_p = ‖max(|u_p| − h, 0)‖ − ρ. A self
    pair is the same with c the other sphere's centre (R = I, h = 0).

    Pairs are ordered obstacle by obstacle, every sphere against each (the spheres in the
    same order each time), then the self pairs; the pairs of one reported constraint are
    neighbours. The tables the kernels read (cpbc.kernels.clearance) are packed here once;
    ``half``, ``rsum``, ``rsum_law`` and ``moving`` are views of ``pair_table``.
    """

    start: int
    stop: int
    n_obstacle: int  # pairs [0, n_obstacle) are against obstacles, the rest are self pairs
    sphere_index: Ints  # (S,) first column of the sphere's joint in the static regressor
    sphere_local: Array  # (S, 4): the sphere's centre is Y[:, j:j+4] @ sphere_local[s]
    obstacles: Array  # (O, 12): each obstacle core's rotation R (row-major) and centre
    pair_index: Ints  # (P, 4): obstacle (−1: self pair), sphere, second sphere, constraint
    pair_table: Array  # (P, 6): h (3), rsum, rsum_law, moving
    sphere_supports: Array  # (S, n) 1 where joint k moves sphere s's link
    starts: Index  # first pair of each reported constraint (a link against an obstacle/link)
    group: Index  # (P,) the constraint (index in ``names``) of each pair
    group_index: Ints  # (G, 5) the broad phase's groups (``pair_groups``)
    group_table: Array  # (G, 6): M·[1, l_c], r, reach
    reach: Array  # (C, n) how far each constraint's clearance moves per unit of each joint
    # at most (Kinematics._reach, over its pairs' spheres; both spheres' of a self pair)

    def bound_groups(self) -> None:
        """Each group's reach, r + the largest rsum_law of its pairs + ``ROUNDING`` (−∞ when
        none of them can move): again whenever rsum_law changes."""
        largest = np.maximum.reduceat(self.rsum_law, self.group_index[:, 0])
        self.group_table[:, 5] = self.group_table[:, 4] + largest + ROUNDING

    @property
    def half(self) -> Array:
        """(3, P) the cores' half-extents."""
        return self.pair_table[:, :3].T

    @property
    def rsum(self) -> Array:
        """(P,) sphere radius + rounding (+ other radius) + margin."""
        return self.pair_table[:, 3]

    @property
    def rsum_law(self) -> Array:
        """(P,) rsum, −∞ on pairs that cannot move (ℓ given): they leave the law."""
        return self.pair_table[:, 4]

    @property
    def moving(self) -> Array:
        """(P,) 1.0 on pairs whose clearance can change, else 0.0."""
        return self.pair_table[:, 5]


class SpherePairs(Kinematics):
    """The sphere pairs: their clearances, the law's terms, and each pair's gradient and
    curvature along a motion (compiled kernels, cpbc.kernels.clearance)."""

    _spheres: Spheres | None
    _groups: list[CapsuleGroup]
    _far_phi: Array  # φ̃ of every constraint with no pair within ℓ
    _no_value: Array  # an empty array: ``sphere_barrier`` without the reported values

    def _sphere_geometry(self, y: Array) -> tuple[Array, Array, Array, Array]:
        """The sphere centres (3, S), every pair's u (3, P), max(|u| − h, 0) (3, P) and core
        distance d (P,) at the joint placements y."""
        s = self._spheres
        assert s is not None
        n_pair = len(s.group)
        centres = np.empty((3, len(s.sphere_index)))
        u, outside, d = np.empty((3, n_pair)), np.empty((3, n_pair)), np.empty(n_pair)
        sphere_geometry(y, s.sphere_index, s.sphere_local, s.obstacles, s.pair_index,
                        s.pair_table, centres, u, outside, d)
        return centres, u, outside, d

    def _sphere_values(self, y: Array, out: Array) -> None:
        """The sphere constraints' reported clearances at y into ``out[:stop]``."""
        s = self._spheres
        assert s is not None
        sphere_clearances(y, s.sphere_index, s.sphere_local, s.obstacles, s.pair_index,
                          s.pair_table, out)

    def _sphere_terms(self, y: Array, jac: Array, phi_out: Array, b: Array, value: Array
                      ) -> float:
        """The law's terms of the sphere pairs (cpbc.kernels.clearance.sphere_barrier):
        returns the smallest law clearance; φ̃ into ``phi_out`` and Σ ∇φ̃/φ̃ into ``b``
        (joint coordinates) only when it is in (0, ℓ); the reported clearances into a
        non-empty ``value``."""
        s = self._spheres
        assert s is not None
        return sphere_barrier(y, jac, s.sphere_index, s.sphere_local, s.obstacles,
                              s.pair_index, s.pair_table, s.group_index, s.group_table,
                              s.sphere_supports, self._far_phi, self.influence or 0.0,
                              phi_out, b, value)

    def _closest_gradients(self, y: Array, jac: Array, out: Array) -> None:
        """Each sphere constraint's gradient, its closest pair's, joint coordinates, into
        the rows of ``out`` (cpbc.kernels.clearance_motion.closest_pair_gradients: the rows
        ``_pair_rows`` and ``Clearance._closest`` pick, without the other pairs')."""
        s = self._spheres
        assert s is not None
        closest_pair_gradients(y, jac, s.sphere_index, s.sphere_local, s.obstacles,
                               s.pair_index, s.pair_table, s.sphere_supports, s.starts, out)

    def _pair_rows(self, y: Array, jac: Array, dq: Array) -> tuple[Array, Array, Array]:
        """Every sphere pair's clearance (P,), gradient (P, n) and curvature q̇ᵀ∇²φ_p q̇
        (P,), joint coordinates, at the joint placements y, joint Jacobians ``jac`` and rates
        ``dq`` (cpbc.kernels.clearance_motion.sphere_pair_rows)."""
        s = self._spheres
        assert s is not None
        n_pair = len(s.group)
        phi, grad, curv = np.empty(n_pair), np.empty((n_pair, self._n)), np.empty(n_pair)
        sphere_pair_rows(y, jac, dq, s.sphere_index, s.sphere_local, s.obstacles,
                         s.pair_index, s.pair_table, s.sphere_supports, self._joint_supports,
                         phi, grad, curv)
        return phi, grad, curv
