"""Set-up of the clearance's pairs from the link covers: which primitive meets which
obstacle or link, in which order, named how, and the capsule groups' broad phase.

``_Layout`` collects the names and broad-phase columns pair by pair; ``PairLayout`` (a
base of ``Clearance``) builds the sphere pairs' tables (``Spheres``) and the capsule
groups once, at construction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.clearance.capsules import (
    CapsuleBox,
    CapsuleCapsule,
    CapsuleGroup,
    CapsulePlane,
    CapsuleSelf,
    CapsuleSphere,
)
from cpbc.constraints.clearance.spheres import SpherePairs, Spheres, pair_groups
from cpbc.constraints.clearance.tables import Index
from cpbc.constraints.geometry import (
    BoxObstacle,
    CapsuleObstacle,
    Obstacle,
    PlaneObstacle,
    SphereObstacle,
)
from cpbc.errors import CpbcError

_O = TypeVar("_O", bound=Obstacle)


def _only(kind: type[_O], obstacles: Sequence[Obstacle]) -> list[_O]:
    """The obstacles of one kind, in their order."""
    return [o for o in obstacles if isinstance(o, kind)]


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


class PairLayout(SpherePairs):
    """Set-up: the pairs, in the order of ``names``, from the link covers (primitives), the
    obstacles and the self pairs, and the capsule groups' broad phase."""

    _broad_w: Array  # (12 nj, columns) the broad phase's z = vec(Y) @ w + c
    _broad_c: Array
    _broad_thr: Array  # reach² per bounded pair
    _n_bounded: int
    _reduce_at: Index  # each capsule group's first broad-phase term

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
            self._obstacle_group(CapsuleSphere.against, _only(SphereObstacle, obstacles),
                                 capsules, layout),
            self._obstacle_group(CapsuleCapsule.against, _only(CapsuleObstacle, obstacles),
                                 capsules, layout),
            self._obstacle_group(CapsuleBox.against, _only(BoxObstacle, obstacles),
                                 capsules, layout),
            self._self_group(by_frame, sphere_self, layout),
            self._plane_group(capsules, layout),  # last: its tests follow the bounded ones
        ]
        self._groups = [g for g in groups if g is not None]
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

    def _capsules(self, start: int, stop: int, prims: Sequence[int]) -> CapsuleGroup:
        """The capsule side of pairs: primitive ``prims[p]`` in pair p, radius + margin."""
        return CapsuleGroup(start, stop, self._columns(prims, 0), self._columns(prims, 1),
                             self._masks(prims),
                             np.array([self.primitives[i].radius for i in prims]) + self.margin)

    def _obstacle_group(
        self,
        against: Callable[[CapsuleGroup, list[_O]], CapsuleGroup],
        obstacles: list[_O],
        capsules: list[int],
        layout: _Layout,
    ) -> CapsuleGroup | None:
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
                    layout: _Layout) -> CapsuleSelf | None:
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
        return CapsuleSelf(
            start, stop, self._columns(pi, 0), self._columns(pi, 1), self._masks(pi),
            np.array([prims[i].radius + prims[j].radius for i, j in pairs]) + self.margin,
            ea2=self._columns(pj, 0), eb2=self._columns(pj, 1), mask2=self._masks(pj),
        )

    def _plane_group(self, capsules: list[int], layout: _Layout) -> CapsulePlane | None:
        """Every capsule primitive above each plane; in the broad phase, its ends' heights."""
        pairs = [(i, o) for o in _only(PlaneObstacle, self.obstacles) for i in capsules]
        if not pairs:
            return None
        start, stop = layout.add([f"{self.primitives[i].name}|{o.name}" for i, o in pairs])
        g = CapsulePlane.against(self._capsules(start, stop, [i for i, _ in pairs]),
                                  [o for _, o in pairs])
        for e in (g.ea, g.eb):  # heights n·a − offset − r − Δ and n·b − …, over vec(Y)
            for p in range(len(pairs)):
                layout.height(np.outer(g.normal[p], e[:, p]).reshape(-1),
                              -(g.offset[p] + g.rsum[p]))
        return g

    def _sphere_group(
        self, spheres: list[int], self_pairs: list[tuple[int, int]], group: list[int]
    ) -> Spheres:
        """The sphere pairs: every sphere in ``spheres`` against every obstacle, then
        ``self_pairs``; ``group`` gives each pair's constraint."""
        prims, margin = self.primitives, self.margin
        index = {i: k for k, i in enumerate(spheres)}
        cores = [o.core() for o in self.obstacles]
        n_obs, n_sph = len(cores), len(spheres)
        radius = np.array([prims[i].radius for i in spheres])
        rsum = np.concatenate(
            [radius + core.rounding + margin for core in cores]
            + [[prims[i].radius + prims[j].radius + margin for i, j in self_pairs]])
        table = np.zeros((len(rsum), 6))  # h, rsum, rsum_law, moving
        for o, core in enumerate(cores):
            table[o * n_sph:(o + 1) * n_sph, :3] = core.half_extents
        table[:, 3] = table[:, 4] = rsum
        table[:, 5] = 1.0
        grp = np.array(group, dtype=np.intp)
        pair_index = np.full((len(rsum), 4), -1, dtype=np.int64)
        pair_index[:n_obs * n_sph, 0] = np.repeat(np.arange(n_obs), n_sph)
        pair_index[:, 1] = np.concatenate([np.tile(np.arange(n_sph), n_obs),
                                           [index[i] for i, _ in self_pairs]])
        pair_index[n_obs * n_sph:, 2] = [index[j] for _, j in self_pairs]
        pair_index[:, 3] = grp
        columns = self._columns(spheres, 0)  # (4 nj, S), four entries of each column nonzero
        first = np.array([4 * (self._joint[i] - 1) for i in spheres], dtype=np.int64)
        local = np.ascontiguousarray(
            np.array([columns[j:j + 4, s] for s, j in enumerate(first)]).reshape(-1, 4))
        group_index, group_table = pair_groups(pair_index, first, local)
        moved = self._reach(spheres)[pair_index[:, 1]]  # by the pair's sphere(s)
        moved[n_obs * n_sph:] += self._reach(spheres)[pair_index[n_obs * n_sph:, 2]]
        reach = np.zeros((int(grp[-1]) + 1, self._n))
        np.maximum.at(reach, grp, moved)
        out = Spheres(
            start=0, stop=int(grp[-1]) + 1, n_obstacle=n_obs * n_sph,
            sphere_index=first, sphere_local=local,
            obstacles=np.array([np.concatenate([core.rotation.reshape(-1), core.centre])
                                for core in cores]).reshape(-1, 12),
            pair_index=pair_index, pair_table=table,
            sphere_supports=self._masks(spheres),
            starts=np.flatnonzero(np.diff(grp, prepend=-1)).astype(np.intp),
            group=grp, group_index=group_index, group_table=group_table, reach=reach,
        )
        out.bound_groups()
        return out
