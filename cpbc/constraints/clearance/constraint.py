"""``Clearance``: the coordinator of the clearance constraint.

It checks the arguments, lays out the pairs (``layout``), and answers the
``ConfigurationConstraint`` calls — values, gradients, curvature and the localised
barrier's terms — by combining the sphere pairs' fast path (``spheres``) with the
capsule groups (``capsules``).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from cpbc.arrays import Array
from cpbc.constraints.clearance.capsules import CapsuleGroup, Rows
from cpbc.constraints.clearance.layout import PairLayout
from cpbc.constraints.constraint_types import ConfigurationConstraint
from cpbc.constraints.covering import LinkPrimitive
from cpbc.constraints.geometry import Obstacle
from cpbc.constraints.margins import CLEARANCE
from cpbc.constraints.packing import Packed
from cpbc.errors import CpbcError, ParameterError
from cpbc.kernels.clearance import localised_terms, pack_sphere_pairs
from cpbc.kernels.clearance_motion import closest_pairs, sphere_motion_terms
from cpbc.model.robot_model import ArmState, RobotModel


class Clearance(PairLayout, ConfigurationConstraint):
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
    capsule groups are skipped after a conservative bounding-sphere test. The sphere kernel
    (cpbc.kernels.clearance.sphere_barrier) skips the groups of sphere pairs (a link against
    an obstacle) that a bounding sphere proves beyond ℓ before it computes their distances,
    and the pairs beyond ℓ among the rest (factor exactly 1, zero slope) as a written
    branch: φ̃ and its gradient come out bit for bit as with every pair computed. With
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

    margin_type = CLEARANCE  # φ_p is in m already
    needs_kinematics = True  # the law's pass reads the state's joint Jacobians
    #: (primitive, obstacle) pairs of an automatic cover that no configuration clears, left
    #: out by the scenario's default clearance (cpbc.constraints.clearance.unclearable)
    left_out: tuple[tuple[str, str], ...] = ()
    #: (link, distance [m]) of links whose declared primitives leave part of their collision
    #: geometry outside, by that much (cpbc.constraints.covering.uncovered)
    uncovered: tuple[tuple[str, float], ...] = ()

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
        self.self_pairs = tuple((str(a), str(b)) for a, b in self_pairs)
        self._pin = model.model
        self._data = self._pin.createData()  # its own, for evaluations away from the state
        self._n = model.n
        self._identity = model.coordinates.is_identity
        self._t_inv = model.coordinates.inverse
        self._setup_kinematics()
        self._setup_pairs(name)
        self._far_phi = np.full(len(self.names), self.influence or 1.0)
        self._split_static()
        self._far_phi.setflags(write=False)
        self._finite_reach = self._spheres is not None and bool(
            np.all(np.isfinite(self._spheres.reach)))
        self._zero = np.zeros(self._n)
        self._zero.setflags(write=False)
        self._no_value = np.empty(0)

    # -- set-up (the pairs themselves: layout) -------------------------------------------
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
            g = self._pair_rows(self._regressor(q), self._jacobians(q), np.zeros(self._n))[1]
            slope = np.maximum(slope, np.abs(g).max(axis=1))
        static = slope < 1e-12
        if not static.any():
            return
        phi = self._sphere_geometry(self._regressor(pin.neutral(pm)))[3] - s.rsum
        shaped = phi if self.influence is None else self._shape(phi)[0] / self.influence
        np.multiply.at(self._far_phi, s.group[static], shaped[static])
        s.moving[static] = 0.0
        if self.influence is not None:
            s.rsum_law[static] = -np.inf
            s.bound_groups()

    # -- ConfigurationConstraint ----------------------------------------------------------
    def value(self, x: Array) -> Array:
        return self._value(self._regressor(self._q(x)))

    def _value(self, y: Array) -> Array:
        """The clearances from the joint placements y: the sphere constraints' first
        (cpbc.kernels.clearance.sphere_clearances), then the capsule groups'."""
        out = np.empty(len(self.names))
        if self._spheres is not None:
            self._sphere_values(y, out)
        self._group_values(y, out)
        return out

    def _group_values(self, y: Array, out: Array) -> None:
        """The capsule groups' reported clearances at y into their entries of ``out``."""
        for g in self._groups:
            out[g.start:g.stop] = g.reported(g.narrow(y)[0])

    def evaluate(self, x: Array) -> tuple[Array, Array]:
        q = self._q(x)
        phi, grad, _ = self._reported(self._regressor(q), self._jacobians(q),
                                        np.zeros(self._n))
        return phi, grad

    def gradient(self, x: Array) -> Array:
        return self.evaluate(x)[1]

    def gradient_at(self, state: ArmState) -> Array:
        """∂φ/∂x at the per-step state, from its joint placements and Jacobians (no
        Pinocchio pass; ``gradient`` at x for a state built without them)."""
        if state.regressor is None or state.joint_jacobians is None:
            return self.gradient(state.x)
        return self._gradients(state.regressor, state.joint_jacobians)

    def gradient_bound(self) -> Array | None:
        """Each sphere constraint's reach (Spheres.reach; Kinematics._reach: |∂φ/∂q_k| of
        any of its pairs is at most how far their spheres move per unit of q_k), when every
        reported constraint is a sphere constraint's, the coordinates are the joints' and
        every reach is finite; else None."""
        s = self._spheres
        if s is None or self._groups or not self._identity or not self._finite_reach:
            return None
        return s.reach

    def _reported(self, y: Array, jac: Array, dq: Array) -> tuple[Array, Array, Array]:
        """The reported clearances, their gradients (controller coordinates) and the sphere
        constraints' curvature along q̇ ``dq`` (the capsule entries 0) at the joint
        placements y and joint Jacobians ``jac``."""
        grad, curv = self._rows(y, jac, dq)
        return self._value(y), grad, curv

    def _rows(self, y: Array, jac: Array, dq: Array) -> tuple[Array, Array]:
        """The reported constraints' gradients (controller coordinates) and the sphere
        constraints' curvature along q̇ ``dq`` (the capsule entries 0): a sphere constraint's
        are its closest pair's (cpbc.kernels.clearance_motion.sphere_pair_rows), a capsule
        group's its own."""
        curv = np.zeros(len(self.names))
        s = self._spheres
        if s is None:
            return self._gradients(y, jac), curv
        phi, g0, c0 = self._pair_rows(y, jac, dq)
        closest = self._closest(phi)
        curv[s.start:s.stop] = c0[closest]
        return self._gradients(y, jac, g0[closest]), curv

    def _gradients(self, y: Array, jac: Array, spheres: Array | None = None) -> Array:
        """The reported constraints' gradients (controller coordinates) at the joint
        placements y and joint Jacobians ``jac``: the sphere constraints' rows ``spheres``
        (their closest pairs', joint coordinates; computed here when None), a capsule
        group's its own."""
        grad = np.empty((len(self.names), self._n))
        s = self._spheres
        if s is not None:
            if spheres is None:
                self._closest_gradients(y, jac, grad[s.start:s.stop])
            else:
                grad[s.start:s.stop] = spheres
        if self._groups:  # (no partial made in a step of sphere constraints alone)
            jacobian_rows = partial(self._rows_times_jacobians, jac)
            for g in self._groups:
                grad[g.start:g.stop] = g.gradient(*g.narrow(y), jacobian_rows)
        return grad if self._identity else grad @ self._t_inv

    def _closest(self, phi: Array) -> NDArray[np.int64]:
        """Each sphere constraint's closest pair, from every pair's clearance ``phi``."""
        s = self._spheres
        assert s is not None
        out = np.empty(len(s.starts), dtype=np.int64)
        closest_pairs(phi, s.starts, out)
        return out

    # -- second order (cpbc.kernels.clearance, eqs. 1 and 2) -------------------------------
    @property
    def sphere_count(self) -> int:
        """How many reported constraints are sphere primitives' (they come first)."""
        return 0 if self._spheres is None else self._spheres.stop

    def sphere_pairs(self, x: Array, dx: Array
                     ) -> tuple[Array, Array, Array, NDArray[np.bool_]]:
        """Every sphere pair on its own (not the per-link minimum): its clearance φ_p (P,),
        gradient ∇φ_p (P, n), curvature ẋᵀ∇²φ_p ẋ (P,) and whether it can move (P,) bool.

        Each pair is smooth where the minimum over a link's spheres is not: a filter that
        wants C¹ rows keeps one row per pair. Empty without sphere primitives. At the
        per-step state: ``sphere_pairs_at``.
        """
        q = self._q(x)
        return self._sphere_pairs(self._regressor(q), self._jacobians(q), self._q(dx))

    def sphere_pairs_at(self, state: ArmState
                        ) -> tuple[Array, Array, Array, NDArray[np.bool_]]:
        """``sphere_pairs`` at the per-step state, from its joint placements and Jacobians
        (``RobotModel.state(kinematics=True)``): no Pinocchio pass of its own."""
        return self._sphere_pairs(*self._state_kinematics(state), state.dq)

    def _sphere_pairs(self, y: Array, jac: Array, dq: Array
                      ) -> tuple[Array, Array, Array, NDArray[np.bool_]]:
        s = self._spheres
        if s is None:
            n = self._n
            return np.zeros(0), np.zeros((0, n)), np.zeros(0), np.zeros(0, dtype=bool)
        phi, grad, curv = self._pair_rows(y, jac, dq)
        if not self._identity:
            grad = grad @ self._t_inv
        return phi, grad, curv, s.moving > 0.0

    def curvature(self, x: Array, dx: Array) -> Array:
        """ẋᵀ∇²φ ẋ of each reported constraint: that of its closest sphere pair (as its
        gradient is), and for capsule primitives a central difference of the gradient along
        ẋ (step 1e-6 rad of motion; their closed forms are piecewise and not given here)."""
        q = self._q(x)
        out = self._reported(self._regressor(q), self._jacobians(q), self._q(dx))[2]
        self._capsule_curvature(x, dx, out)
        return out

    def motion_terms(self, state: ArmState) -> tuple[Array, Array, Array]:
        """φ, ∇φ and ẋᵀ∇²φ ẋ of the reported constraints (``evaluate``, ``curvature``) from
        the state's joint placements and Jacobians; only the capsule primitives' curvature,
        a difference of gradients away from the state, takes Pinocchio passes of its own.
        Sphere primitives alone, in joint coordinates: one compiled call
        (cpbc.kernels.clearance_motion.sphere_motion_terms)."""
        y, jac = self._state_kinematics(state)
        s = self._spheres
        if s is not None and not self._groups and self._identity:
            k = len(self.names)
            phi, grad, curv = np.empty(k), np.empty((k, self._n)), np.empty(k)
            sphere_motion_terms(y, jac, state.dq, s.sphere_index, s.sphere_local, s.obstacles,
                                s.pair_index, s.pair_table, s.sphere_supports,
                                self._joint_supports, s.starts, phi, grad, curv)
            return phi, grad, curv
        phi, grad, curv = self._reported(y, jac, state.dq)
        self._capsule_curvature(state.x, state.dx, curv)
        return phi, grad, curv

    def _capsule_curvature(self, x: Array, dx: Array, out: Array) -> None:
        """The capsule primitives' entries of ``curvature`` into ``out``."""
        if not self._groups:
            return
        speed = float(np.linalg.norm(dx))
        if speed > 0.0:
            t = 1e-6 / speed
            diff = self.gradient(x + t * dx) - self.gradient(x - t * dx)
            rest = slice(self.sphere_count, len(self.names))
            out[rest] = (diff @ dx)[rest] / (2.0 * t)

    @staticmethod
    def _state_kinematics(state: ArmState) -> tuple[Array, Array]:
        """The state's joint placements and Jacobians, which the clearance reads."""
        if state.regressor is None or state.joint_jacobians is None:
            raise CpbcError("clearance reads the state's joint kinematics: build the state "
                            "with kinematics=True (a law's state(x, dx) does)")
        return state.regressor, state.joint_jacobians

    # -- the localised barrier -------------------------------------------------------------
    def _shape(self, phi: Array) -> tuple[Array, Array]:
        """φ̃ and (dφ̃/dφ)/φ̃ of the class docstring (φ and 1/φ without an influence;
        cpbc.kernels.clearance.localised)."""
        ell = self.influence
        if ell is None:
            return phi, 1.0 / phi
        shaped, ratio = np.empty_like(phi), np.empty_like(phi)
        localised_terms(phi, ell, shaped, ratio)
        return shaped, ratio

    def barrier_ratio(self, phi: Array) -> Array:
        """(dφ̃/dφ)/φ̃: zero for a pair beyond the influence distance."""
        return self._shape(phi)[1]

    def _near_groups(self, y: Array) -> list[CapsuleGroup]:
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
        """φ̃, Σ ∇φ̃/φ̃ and (with ``margins``) the clearances φ, from the state's joint
        placements and Jacobians (``RobotModel.state(kinematics=True)``)."""
        return self._barrier(state.x, *self._state_kinematics(state), margins)

    def packed(self) -> Packed | None:
        """The sphere pairs' tables (cpbc.kernels.barrier_set), when every primitive is a
        sphere, the coordinates are the joints' and no subclass overrides
        ``barrier_terms``."""
        s = self._spheres
        if (type(self).barrier_terms is not Clearance.barrier_terms or s is None
                or self._groups or not self._identity):
            return None
        return pack_sphere_pairs(s.sphere_local, s.obstacles, s.pair_table, s.sphere_supports,
                                 self._far_phi, self.influence, s.group_table, s.reach,
                                 s.sphere_index, s.pair_index, s.group_index)

    def _barrier(self, x: Array, y: Array, jac: Array, with_value: bool
                 ) -> tuple[Array, Array, Array | None]:
        """The sphere pairs' φ̃ and force (one kernel, ``_sphere_terms``), then the terms of
        the capsule groups that may be within ℓ, then the force of both (``_force``).
        Outside S: the clearances φ for φ̃ and no force (the constraint set raises). ``y``,
        ``jac``: the joint placements and Jacobians at x."""
        value: Array | None = None
        phi_out: Array | None = None
        b_sphere: Array | None = None
        if self._spheres is not None:
            phi_out, b_sphere = np.empty(len(self.names)), np.empty(self._n)
            value = np.empty(len(self.names)) if with_value else self._no_value
            low = self._sphere_terms(y, jac, phi_out, b_sphere, value)
            if not low > 0.0:  # outside S (or NaN): report it, the constraint set raises
                value = self._value(y)
                return value, self._zero, value
            if with_value:
                self._group_values(y, value)
            else:
                value = None
            if self.influence is not None and not low < self.influence:
                phi_out = b_sphere = None  # no sphere pair within ℓ
        capsules = self._capsule_law(y, phi_out)
        if capsules is None:  # a capsule pair outside S
            value = self.value(x)
            return value, self._zero, value
        phi_out, rows = capsules
        if with_value and value is None:
            value = self.value(x)
        if phi_out is None:
            return self._far_phi, self._zero, value
        return phi_out, self._force(b_sphere, rows, jac), value

    def _capsule_law(self, y: Array, phi_out: Array | None
                     ) -> tuple[Array | None, list[Rows]] | None:
        """The terms of the capsule groups that may be within ℓ: their φ̃ into ``phi_out``
        (a copy of the far values first if None) and the rows of their force; None when a
        pair is outside S."""
        rows: list[Rows] = []
        for g in self._near_groups(y):
            phi, grows = g.narrow(y)
            if phi.min() <= 0.0:
                return None
            shaped, ratio = self._shape(phi)
            phi_out = self._far_phi.copy() if phi_out is None else phi_out
            phi_out[g.start:g.stop], g_rows = g.law(shaped, ratio, grows, self.influence)
            rows += g_rows
        return phi_out, rows

    def _force(self, b_sphere: Array | None, rows: list[Rows], jac: Array) -> Array:
        """Σ ∇φ̃/φ̃: the sphere pairs' (``b_sphere``, joint coordinates) plus the capsule
        rows', from the state's joint Jacobians ``jac`` (RobotModel.state,
        kinematics=True)."""
        b = self._zero if b_sphere is None else b_sphere
        if rows:
            points, normals, masks = (np.concatenate(part) for part in zip(*rows, strict=True))
            b = b + self._rows_times_jacobians(jac, points, normals, masks).sum(axis=0)
        if not self._identity:
            b = b @ self._t_inv
        return b
