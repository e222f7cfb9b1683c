"""Capsule primitives' pairs, one group per kind of partner, one pair per row.

``CapsuleGroup`` carries the capsule side (segment ends over Pinocchio's static
regressor, supports, radii); its subclasses measure the pairs exactly against sphere,
capsule and box obstacles (``CapsuleSphere``, ``CapsuleCapsule``, ``CapsuleBox``), against
another primitive of the arm (``CapsuleSelf``) and above planes (``CapsulePlane``), and
give the rows n̂ᵀ J(p) of their gradients and of the law's force.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.geometry import (
    BoxObstacle,
    CapsuleObstacle,
    PlaneObstacle,
    SphereObstacle,
    segment_box,
    segment_point,
    segment_segment,
)

Rows = tuple[Array, Array, Array]  # points p (m, 3), unit normals n̂ (m, 3), supports (m, n)
JacobianRows = Callable[[Array, Array, Array], Array]  # (p, n̂, supports) ↦ rows n̂ᵀ J(p)


@dataclass(frozen=True, eq=False)
class CapsuleGroup:
    """Capsule primitives paired with shapes of one kind, one pair per row.

    Pair p's primitive is the segment [a_p, b_p] with a = (Y @ ea).T and b = (Y @ eb).T (Y
    the static regressor), its radius plus the margin (and the other shape's radius) in
    ``rsum``. The base gives one clearance per pair, reported and in the law as it is;
    ``CapsulePlane`` changes that. A subclass says how far its pairs are (``narrow``); the
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

    def narrow(self, y: Array) -> tuple[Array, list[Rows]]:
        """The exact clearances φ and the rows of their gradient: ∇φ = Σ_rows n̂ᵀ J(p)."""
        raise NotImplementedError

    def reported(self, phi: Array) -> Array:
        """The reported clearance of each pair from ``narrow``'s φ."""
        return phi

    def gradient(self, phi: Array, rows: list[Rows], jacobian_rows: JacobianRows) -> Array:
        """The gradients (P, n) of the reported clearances, from ``narrow``'s φ and rows
        (summed from 0, as ever: the same bits, signed zeros included)."""
        return np.asarray(sum(jacobian_rows(p, n, mask) for p, n, mask in rows), dtype=float)

    def law(self, shaped: Array, ratio: Array, rows: list[Rows], influence: float | None
            ) -> tuple[Array, list[Rows]]:
        """The law's φ̃ of the group's constraints and the rows of its force, from φ̃ and
        (dφ̃/dφ)/φ̃ of ``narrow``'s clearances (``Clearance._shape``)."""
        return shaped, [(p, n * ratio[:, None], mask) for p, n, mask in rows]


@dataclass(frozen=True, eq=False)
class _AgainstObstacle(CapsuleGroup):
    """Capsules against fixed obstacles: φ = d − rsum, d, p and n̂ from ``distance``."""

    def narrow(self, y: Array) -> tuple[Array, list[Rows]]:
        d, p, n = self.distance(*self.ends(y))
        return d - self.rsum, [(p, n, self.mask)]

    def distance(self, a: Array, b: Array) -> tuple[Array, Array, Array]:
        """The distance d (P,) from the segments [a, b] to the obstacles' cores, the closest
        points p (P, 3) on the segments and the unit normals n̂ (P, 3) towards them."""
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class CapsuleSphere(_AgainstObstacle):
    """Capsules against spheres (the sphere's radius in ``rsum``)."""

    centre: Array  # (P, 3)

    @classmethod
    def against(cls, caps: CapsuleGroup, obstacles: Sequence[SphereObstacle]) -> CapsuleSphere:
        return cls(caps.start, caps.stop, caps.ea, caps.eb, caps.mask,
                   caps.rsum + np.array([o.radius for o in obstacles]),
                   centre=np.array([o.centre for o in obstacles]))

    def distance(self, a: Array, b: Array) -> tuple[Array, Array, Array]:
        return segment_point(a, b, self.centre)


@dataclass(frozen=True, eq=False)
class CapsuleCapsule(_AgainstObstacle):
    """Capsules against capsule obstacles (the obstacle's radius in ``rsum``)."""

    axis_start: Array  # (P, 3)
    axis_end: Array

    @classmethod
    def against(cls, caps: CapsuleGroup, obstacles: Sequence[CapsuleObstacle]
                ) -> CapsuleCapsule:
        return cls(caps.start, caps.stop, caps.ea, caps.eb, caps.mask,
                   caps.rsum + np.array([o.radius for o in obstacles]),
                   axis_start=np.array([o.start for o in obstacles]),
                   axis_end=np.array([o.end for o in obstacles]))

    def distance(self, a: Array, b: Array) -> tuple[Array, Array, Array]:
        d, p, _, n = segment_segment(a, b, self.axis_start, self.axis_end)
        return d, p, n


@dataclass(frozen=True, eq=False)
class CapsuleBox(_AgainstObstacle):
    """Capsules against oriented boxes."""

    centre: Array  # (P, 3)
    rotation: Array  # (P, 3, 3) box to world
    half: Array  # (P, 3) half-extents

    @classmethod
    def against(cls, caps: CapsuleGroup, obstacles: Sequence[BoxObstacle]) -> CapsuleBox:
        return cls(caps.start, caps.stop, caps.ea, caps.eb, caps.mask, caps.rsum,
                   centre=np.array([o.centre for o in obstacles]),
                   rotation=np.array([o.rotation for o in obstacles]),
                   half=np.array([o.half_extents for o in obstacles]))

    def distance(self, a: Array, b: Array) -> tuple[Array, Array, Array]:
        d, p, _, n = segment_box(a, b, self.centre, self.rotation, self.half)
        return d, p, n


@dataclass(frozen=True, eq=False)
class CapsuleSelf(CapsuleGroup):
    """Self pairs with a capsule: both segments move, so ∇φ = n̂ᵀ (J_P − J_Q)."""

    ea2: Array  # the other primitive's ends and supports, as ea, eb, mask
    eb2: Array
    mask2: Array

    def narrow(self, y: Array) -> tuple[Array, list[Rows]]:
        a, b = self.ends(y)
        d, p, q, n = segment_segment(a, b, (y @ self.ea2).T, (y @ self.eb2).T)
        return d - self.rsum, [(p, n, self.mask), (q, -n, self.mask2)]


@dataclass(frozen=True, eq=False)
class CapsulePlane(CapsuleGroup):
    """Capsules above planes. ``narrow`` gives the law the heights of both ends, φ_a then φ_b
    (2P,): the pair's barrier is the product of its two end terms (each smooth, where
    min(φ_a, φ_b) is not); the reported clearance is the smaller one."""

    normal: Array  # (P, 3) unit normals
    offset: Array  # (P,) n̂·x on the plane

    @classmethod
    def against(cls, caps: CapsuleGroup, obstacles: Sequence[PlaneObstacle]) -> CapsulePlane:
        return cls(caps.start, caps.stop, caps.ea, caps.eb, caps.mask, caps.rsum,
                   normal=np.array([o.normal for o in obstacles]),
                   offset=np.array([o.offset for o in obstacles]))

    @property
    def terms(self) -> int:
        return 2 * (self.stop - self.start)

    def narrow(self, y: Array) -> tuple[Array, list[Rows]]:
        a, b = self.ends(y)
        phi_a = (a * self.normal).sum(axis=1) - self.offset - self.rsum
        phi_b = (b * self.normal).sum(axis=1) - self.offset - self.rsum
        return np.concatenate([phi_a, phi_b]), [(a, self.normal, self.mask),
                                                (b, self.normal, self.mask)]

    def reported(self, phi: Array) -> Array:
        size = self.stop - self.start
        return np.minimum(phi[:size], phi[size:])

    def gradient(self, phi: Array, rows: list[Rows], jacobian_rows: JacobianRows) -> Array:
        """The gradient of the lower end's height."""
        size = self.stop - self.start
        (pa, n, mask), (pb, _, _) = rows
        use_b = (phi[size:] < phi[:size])[:, None]
        return jacobian_rows(np.where(use_b, pb, pa), n, mask)

    def law(self, shaped: Array, ratio: Array, rows: list[Rows], influence: float | None
            ) -> tuple[Array, list[Rows]]:
        """φ̃_a φ̃_b/ℓ (φ_a φ_b without ℓ) and both ends' force rows."""
        size = self.stop - self.start
        (pa, n, mask), (pb, _, _) = rows
        return (shaped[:size] * (shaped[size:] / (influence or 1.0)),
                [(pa, n * ratio[:size, None], mask), (pb, n * ratio[size:, None], mask)])
