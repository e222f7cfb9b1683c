"""Sphere primitives' pairs: every sphere against every obstacle (as a rounded box) and in
self pairs, all at once.

``Spheres`` holds the pairs' constant tables; ``SpherePairs`` (a base of ``Clearance``)
computes their offsets u and core distances d, their gradients, the localised law's
factors and force, and their curvature along a motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.constraints.clearance.capsules import CapsuleGroup
from cpbc.constraints.clearance.kinematics import Kinematics
from cpbc.constraints.clearance.tables import (
    AT_POINT,
    FORCE,
    ONE,
    ONES3,
    ONES12,
    TINY,
    WRENCH,
    ZERO,
    Index,
)
from cpbc.constraints.pair_motion import point_motion, rounded_box_curvature


def core_distances(u: Array, half: Array) -> tuple[Array, Array]:
    """‖max(|u| − h, 0)‖ per column of u (3, P), and max(|u| − h, 0) itself."""
    outside = np.abs(u)
    outside -= half
    np.maximum(outside, ZERO, out=outside)
    return np.sqrt(np.dot(ONES3, outside * outside)), outside


@dataclass(frozen=True, eq=False)
class Spheres:
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
    to_world: Array  # (12, 3 O): FORCE @ (w Σ_o R_o local_o) from local.reshape(3 O, S),
    # w = 3/ℓ (1 without ℓ): see ``_sphere_factors``
    self_force: Array  # (Ps, S): w (+1 first, −1 second), the self pairs' forces per sphere
    pair_sphere: Index  # (P,) the (first) sphere of each pair
    pair_sphere2: Index  # (Ps,) the second sphere of each self pair
    pair_rot: Array  # (P, 3, 3) the obstacle's rotation R (I for a self pair)
    sphere_supports: Array  # (S, n) 1 where joint k moves sphere s's link
    starts: Index  # first pair of each reported constraint (a link against an obstacle/link)
    group: Index  # (P,) the constraint (index in ``names``) of each pair


class SpherePairs(Kinematics):
    """The sphere pairs' hot path: distances, gradients, the law's factors and force, and
    the curvature (``pair_motion``), all pairs in a fixed number of numpy calls."""

    _spheres: Spheres | None
    _groups: list[CapsuleGroup]
    _far_phi: Array  # φ̃ of every constraint with no pair within ℓ
    _inv_ell: Array  # 1/ℓ, 0-d
    _motion_data: pin.Data  # second order, apart from the state's

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
        d, outside = core_distances(u, s.half)
        return d, u, outside

    def _pair_gradients(self, q: Array, y: Array) -> tuple[Array, Array]:
        """Every sphere pair's clearance (P,) and its gradient (P, n), joint coordinates."""
        s = self._spheres
        assert s is not None
        d, u, outside = self._sphere_distances(y)
        local = np.copysign(outside, u) / np.maximum(d, TINY)
        normal = np.einsum("pab,bp->pa", s.pair_rot, local)
        centres = s.scratch[:3]
        jac = self._jacobians(q)
        grad = self._rows_times_jacobians(jac, centres[:, s.pair_sphere].T, normal,
                                          s.sphere_supports[s.pair_sphere])
        if len(s.pair_sphere2):
            at = s.n_obstacle
            grad[at:] -= self._rows_times_jacobians(
                jac, centres[:, s.pair_sphere2].T, normal[at:],
                s.sphere_supports[s.pair_sphere2])
        return d - s.rsum, grad

    def _sphere_force(self, local: Array, jac: Array) -> Array:
        """Σ_p J(s_p)ᵀ R_p local_p over the sphere pairs (s_p the pair's sphere centre, J(s)
        the Jacobian of a point fixed on its link, R_p the obstacle's rotation), minus the
        same at the second sphere of each self pair, times w (``to_world``); (n,).

        Dense over all the pairs (a pair out of the law has local_p = 0): cheaper than
        picking the active ones. The pairs' forces are first summed per sphere, f_s, in one
        product. A force f at a point s fixed on a link drives joint k, if k moves the link,
        by fᵀ(v_k + ω_k × s) = vec(s ⊗ f)·(CROSS ω_k) + f·v_k with J = [v; ω] Pinocchio's
        world joint Jacobian: so the spheres' [vec(s ⊗ f); f] (12, S), summed over the
        spheres each joint moves (one product), meet the Jacobian through WRENCH.
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
            force += np.dot(FORCE, np.dot(local[:, at:], s.self_force))
        force *= np.dot(AT_POINT, s.scratch)
        per_joint = np.dot(force, s.sphere_supports)  # (12, n)
        per_joint *= np.dot(WRENCH, jac)
        return np.dot(ONES12, per_joint)

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

    def _sphere_law(self, s: Spheres, phi: Array, low: Array, d: Array, u: Array,
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

    def _sphere_factors(self, s: Spheres, phi: Array, low: Array
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
        np.minimum(v, ONE, out=v)
        np.subtract(ONE, v, out=v)
        slope = v * v
        factor = slope * v
        np.subtract(ONE, factor, out=factor)
        slope /= factor
        return factor, slope
