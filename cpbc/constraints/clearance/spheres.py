"""Sphere primitives' pairs: every sphere against every obstacle (as a rounded box) and in
self pairs, all at once.

``Spheres`` holds the pairs' constant tables, packed for the compiled kernels
(cpbc.kernels.clearance, where the formulas are); ``SpherePairs`` (a base of ``Clearance``)
calls them for the pairs' distances, the law's factors and force, and reads their offsets
for the gradients and the curvature along a motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.constraints.clearance.capsules import CapsuleGroup
from cpbc.constraints.clearance.kinematics import Kinematics
from cpbc.constraints.clearance.tables import TINY, Index
from cpbc.constraints.pair_motion import point_motion, rounded_box_curvature
from cpbc.kernels.clearance import Ints, sphere_barrier, sphere_clearances, sphere_geometry


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
    pair_sphere: Index  # (P,) the (first) sphere of each pair
    pair_sphere2: Index  # (Ps,) the second sphere of each self pair
    pair_rot: Array  # (P, 3, 3) the obstacle's rotation R (I for a self pair)
    sphere_supports: Array  # (S, n) 1 where joint k moves sphere s's link
    starts: Index  # first pair of each reported constraint (a link against an obstacle/link)
    group: Index  # (P,) the constraint (index in ``names``) of each pair

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
    """The sphere pairs: their clearances and the law's terms (compiled kernels,
    cpbc.kernels.clearance), their gradients and their curvature (``pair_motion``)."""

    _spheres: Spheres | None
    _groups: list[CapsuleGroup]
    _far_phi: Array  # φ̃ of every constraint with no pair within ℓ
    _no_value: Array  # an empty array: ``sphere_barrier`` without the reported values
    _motion_data: pin.Data  # second order, apart from the state's

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
                              s.pair_index, s.pair_table, s.sphere_supports, self._far_phi,
                              self.influence or 0.0, phi_out, b, value)

    def _pair_gradients(self, q: Array, y: Array) -> tuple[Array, Array]:
        """Every sphere pair's clearance (P,) and its gradient (P, n), joint coordinates."""
        s = self._spheres
        assert s is not None
        centres, u, outside, d = self._sphere_geometry(y)
        local = np.copysign(outside, u) / np.maximum(d, TINY)
        normal = np.einsum("pab,bp->pa", s.pair_rot, local)
        jac = self._jacobians(q)
        grad = self._rows_times_jacobians(jac, centres[:, s.pair_sphere].T, normal,
                                          s.sphere_supports[s.pair_sphere])
        if len(s.pair_sphere2):
            at = s.n_obstacle
            grad[at:] -= self._rows_times_jacobians(
                jac, centres[:, s.pair_sphere2].T, normal[at:],
                s.sphere_supports[s.pair_sphere2])
        return d - s.rsum, grad

    def _pair_curvature(self, q: Array, dq: Array, y: Array) -> Array:
        """ẋᵀ∇²φ_p ẋ of every sphere pair (pair_motion, eqs. 1 and 2)."""
        s = self._spheres
        assert s is not None
        data = self._motion_data
        pin.computeJointJacobiansTimeVariation(self._pin, data, q, dq)
        pin.computeJointJacobians(self._pin, data, q)
        centres, u, _, _ = self._sphere_geometry(y)
        vel, acc = point_motion(data.J, data.dJ, s.sphere_supports, dq,
                                np.ascontiguousarray(centres.T))
        rot = s.pair_rot
        first = s.pair_sphere
        du = np.einsum("pba,pb->ap", rot, vel[first])
        ddu = np.einsum("pba,pb->ap", rot, acc[first])
        if len(s.pair_sphere2):
            at, second = s.n_obstacle, s.pair_sphere2
            du[:, at:] -= vel[second].T
            ddu[:, at:] -= acc[second].T
        return rounded_box_curvature(u, du, ddu, s.half)
