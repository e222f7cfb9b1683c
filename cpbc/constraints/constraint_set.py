"""A set of constraints: the admissible set S (eq. 6.18) and its log-barrier sums."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from itertools import groupby
from typing import NamedTuple, TypeVar

import numpy as np

from cpbc.arrays import Array, unfinite_rows
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.constraints.packing import Packed, PackedSet
from cpbc.constraints.python_terms import PythonTerms
from cpbc.errors import ConstraintViolation, CpbcError, InadmissibleStateError, ParameterError
from cpbc.kernels.barrier_set import RATE, set_barrier
from cpbc.kernels.barriers import log_sum
from cpbc.model.robot_model import ArmState, RobotModel

Constraint = TypeVar("Constraint", ConfigurationConstraint, VelocityConstraint)


def _violation(margins: Array, names: Sequence[str]) -> ConstraintViolation:
    """The worst margin (≤ 0 or NaN) by name."""
    i = int(np.argmin(np.nan_to_num(margins, nan=-np.inf)))
    return ConstraintViolation(names[i], float(margins[i]))


def _stack(items: Sequence[Constraint]) -> tuple[Constraint, ...]:
    """Neighbours of one class that stacks, evaluated as one constraint (the same names in
    the same order); a group that cannot stack (a joint bounded twice) stays as it is."""
    out: list[Constraint] = []
    for _, group in groupby(items, key=type):
        run = list(group)
        if len(run) > 1 and run[0].stacks:
            try:
                out.append(run[0].stacked(run))
                continue
            except CpbcError:
                pass
        out.extend(run)
    return tuple(out)


class BarrierTerms(NamedTuple):
    """The laws' log-barrier sums (Σ ∇φ/φ, never the products Φ, Ψ) at one state.

    Attributes:
        log_phi: Σ log φ̃_i = log Φ.
        log_psi: Σ log ψ_j = log Ψ.
        gradient: b_φ + b_ψ = Σ ∇φ̃_i/φ̃_i + Σ ∂_xψ_j/ψ_j, shape (n,), or None when zero.
        weight: Π = Σ Q_j/ψ_j, shape (n, n), or None without velocity constraints.
        margins: every φ_i and ψ_j in the order of ``ConstraintSet.names`` when asked for,
            else None.
    """

    log_phi: float
    log_psi: float
    gradient: Array | None
    weight: Array | None
    margins: Array | None = None


class ConstraintSet:
    """Configuration and velocity constraints that together define S.

    Neighbouring constraints of a kind that stacks (linear limits, rate limits) are
    evaluated together, as one constraint with all their rows.
    """

    def __init__(
        self,
        n: int,
        configuration: Sequence[ConfigurationConstraint] = (),
        velocity: Sequence[VelocityConstraint] = (),
    ) -> None:
        self.n = n
        self.configuration = tuple(configuration)
        self.velocity = tuple(velocity)
        for field, group in (("configuration", self.configuration), ("velocity", self.velocity)):
            for c in group:
                rows = getattr(c, "rows", None)  # a linear or rate limit's a (k × n)
                if rows is not None and rows.shape[1] != n:
                    raise ParameterError(field, f"constraint '{c.names[0]}' has rows of "
                                         f"{rows.shape[1]} coordinates; the set's arm has {n}")
        self.names: tuple[str, ...] = tuple(
            [name for c in self.configuration for name in c.names]
            + [name for v in self.velocity for name in v.names])
        if len(set(self.names)) != len(self.names):
            dup = sorted({x for x in self.names if self.names.count(x) > 1})
            raise CpbcError(f"duplicate constraint names: {dup}; give each constraint its own name")
        self.needs_dynamics = any(c.needs_dynamics for c in self.velocity)
        self.needs_kinematics = any(c.needs_kinematics for c in self.configuration)
        # what a filter on φ̈ reads besides (``motion_terms``; ``state(..., motion=True)``)
        self.motion_kinematics = self.needs_kinematics or any(
            c.motion_kinematics for c in self.configuration)
        self.needs_coriolis = any(c.needs_coriolis for c in self.velocity)
        self.frames: tuple[int, ...] = tuple(
            dict.fromkeys(f for c in self.configuration for f in c.frames))
        self._config = _stack(self.configuration)
        self._velocity = _stack(self.velocity)
        self.n_configuration = sum(len(c.names) for c in self.configuration)
        self._pack()

    def _pack(self) -> None:
        """The constants of every constraint that packs, for one kernel call per step
        (cpbc.kernels.plan_tables); the others (a kind without a kernel, a subclass's own
        formula, capsules, a second frame) are asked through ``barrier_terms`` — after the
        set's own kernel call (``barrier``), before a law's (``python_terms``)."""
        parts: list[tuple[int, int, Packed]] = []
        rest_config: list[tuple[int, ConfigurationConstraint]] = []
        rest_velocity: list[tuple[int, VelocityConstraint]] = []
        frame, at = -1, 0
        for c in self._config:
            p = c.packed()
            # the set's kernel reads one frame: a kind on another frame is asked in Python
            if p is not None and (p.frame < 0 or frame in (-1, p.frame)):
                frame = max(frame, p.frame)
                parts.append((at, len(c.names), p))
            else:
                rest_config.append((at, c))
            at += len(c.names)
        for v in self._velocity:
            p = v.packed()
            if p is not None:
                parts.append((at, len(v.names), p))
            else:
                rest_velocity.append((at, v))
            at += len(v.names)
        self._packed = PackedSet.build(parts)
        self._rest_config = tuple(rest_config)
        self._rest_velocity = tuple(rest_velocity)
        # a law's plan: the same, with the others' terms asked in Python before its call
        rest: list[tuple[int, ConfigurationConstraint | VelocityConstraint]] = [
            *rest_config, *rest_velocity]
        self._python = tuple(PythonTerms(c, self.n) for _, c in rest)
        every = parts + [(at, len(c.names), p.packed())
                         for (at, c), p in zip(rest, self._python, strict=True)]
        self._law_packed = PackedSet.build(sorted(every, key=lambda part: part[0]))
        # b = 0 always (rate limits only): the laws skip it
        self._no_gradient = not self._config and not rest_velocity and all(
            p.kind == RATE for _, _, p in parts)
        n = self.n
        self._empty = np.zeros(0)
        self._no_matrix = np.zeros((0, 0))
        self._no_frame = (np.zeros(3), np.eye(3), np.zeros((6, n)))
        self._no_joints = (np.zeros((3, 0)), np.zeros((6, 0)))

    def __len__(self) -> int:
        return len(self.names)

    @property
    def empty(self) -> bool:
        return not self.names

    def state(self, model: RobotModel, x: Array, dx: Array, frames: Iterable[int] = (),
              motion: bool = False) -> ArmState:
        """The per-step state these constraints read (with ``frames`` besides, e.g. a
        potential's), from one call of ``model.state``; with ``motion``, what their
        ``motion_terms`` read too (the joint kinematics of a point's curvature)."""
        wanted = tuple(dict.fromkeys((*self.frames, *frames))) if frames else self.frames
        kinematics = self.motion_kinematics if motion else self.needs_kinematics
        return model.state(x, dx, kinematics=kinematics, frames=wanted,
                           coriolis=self.needs_coriolis)

    def margins(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        """Every φ_i and ψ_j at (x, ẋ), in the order of ``names``."""
        parts = [c.value(x) for c in self._config]
        parts += [c.value(x, dx, state) for c in self._velocity]
        return np.concatenate(parts) if parts else np.zeros(0)

    def configuration_margins(self, x: Array) -> Array:
        """Every φ_i at x, in the order of ``names``."""
        parts = [c.value(x) for c in self._config]
        return np.concatenate(parts) if parts else np.zeros(0)

    def configuration_gradients(self, state: ArmState) -> Array:
        """Every ∇φ_i at the per-step state, shape (number of φ_i, n), in the order of
        ``names`` (each kind's ``gradient_at``: from the state's kinematics where it reads
        them)."""
        if not self._config:
            return np.zeros((0, self.n))
        return np.concatenate([c.gradient_at(state) for c in self._config])

    @property
    def gradients_bounded(self) -> bool:
        """Whether a configuration constraint bounds its gradient without the state's
        kinematics (``gradient_bound``)."""
        return any(c.gradient_bound() is not None for c in self._config)

    def configuration_gradient_bounds(self, state: ArmState) -> Array:
        """B ≥ |∇φ_i| entry by entry, shape (number of φ_i, n), in the order of ``names``:
        each constraint's ``gradient_bound`` where it has one, else its gradient at the
        per-step state."""
        if not self._config:
            return np.zeros((0, self.n))
        parts = []
        for c in self._config:
            bound = c.gradient_bound()
            parts.append(c.gradient_at(state) if bound is None else bound)
        return np.concatenate(parts)

    def velocity_margins(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        """Every ψ_j at (x, ẋ), in the order of ``names``."""
        parts = [c.value(x, dx, state) for c in self._velocity]
        return np.concatenate(parts) if parts else np.zeros(0)

    def margins_along(self, xs: Array, dxs: Array) -> Array:
        """Every margin at every sample, shape (N, m); NaN rows where the state is not finite."""
        bad = unfinite_rows(xs, dxs)
        if bad is None:  # the usual case, without masks (a third of a rescue period)
            parts = [c.values_along(xs) for c in self._config]
            parts += [c.values_along(xs, dxs) for c in self._velocity]
            return np.concatenate(parts, axis=1) if parts else np.zeros((len(xs), 0))
        out = np.full((len(xs), len(self.names)), np.nan)
        ok = ~bad
        parts = [c.values_along(xs[ok]) for c in self._config]
        parts += [c.values_along(xs[ok], dxs[ok]) for c in self._velocity]
        if parts:
            out[ok] = np.concatenate(parts, axis=1)
        return out

    def check_admissible(self, x: Array, dx: Array, what: str) -> None:
        """Raise InadmissibleStateError if (x, ẋ) is not in S (Assumption 6.8)."""
        m = self.margins(x, dx)
        if m.size and not np.all(m > 0):
            i = int(np.argmin(np.where(np.isnan(m), -np.inf, m)))
            raise InadmissibleStateError(what, self.names[i], float(m[i]))

    def barrier(self, state: ArmState, margins: bool = False) -> BarrierTerms:
        """Log-barrier sums at the per-step state (with ``margins``, every margin too);
        raises ConstraintViolation outside S. One kernel call for the packed constraints
        (cpbc.kernels.barrier_set.set_barrier), then the others' ``barrier_terms``."""
        n, m, pk = self.n, len(self.names), self._packed
        phi = np.empty(m)
        gradient = np.empty(n)
        weight = np.empty((n, n)) if self.velocity else self._no_matrix
        value = np.empty(m) if margins else self._empty
        if self.needs_coriolis and state.coriolis_matrix is None:
            raise CpbcError("the kinetic-energy limit reads C from the state: build it with "
                            "coriolis=True (a law's state(x, dx) does)")
        coriolis = self._no_matrix if state.coriolis_matrix is None else state.coriolis_matrix
        origin, rotation, frame_jac = self._point_frame(state)
        y, jac = self.joint_kinematics(state)
        inertia = state.inertia if self.needs_dynamics else self._no_matrix
        log_phi, log_psi = set_barrier(pk.plan, pk.ints, pk.floats, state.x, state.dx,
                                       inertia, coriolis, origin, rotation, frame_jac,
                                       y, jac, phi, gradient, weight, value)
        if self._rest_config or self._rest_velocity:
            log_phi, log_psi = self._rest(state, margins, log_phi, log_psi, phi, gradient,
                                          weight, value)
        if log_phi != log_phi or log_psi != log_psi:  # a margin ≤ 0 or NaN
            raise self.violation(log_phi, phi)
        return BarrierTerms(log_phi, log_psi, None if self._no_gradient else gradient,
                            weight if self.velocity else None, value if margins else None)

    def _point_frame(self, state: ArmState) -> tuple[Array, Array, Array]:
        """The origin, axes and Jacobian of the packed point constraint's frame."""
        frame = self._packed.frame
        if frame < 0:
            return self._no_frame
        kin = state.frames.get(frame)
        if kin is None:
            raise CpbcError(f"a point constraint reads frame {frame} from the state: build "
                            "it with the constraint set's frames (a law's state(x, dx))")
        return kin.position, kin.rotation, kin.jacobian

    @property
    def packed_tables(self) -> PackedSet | None:
        """The tables of the set kernel for a law's one kernel call (cpbc.kernels.laws):
        every constraint that packs, and a row for each that does not, whose terms
        ``python_terms`` writes before each call; None when the class overrides
        ``barrier``."""
        if type(self).barrier is not ConstraintSet.barrier:
            return None
        return self._law_packed

    @property
    def python_terms(self) -> tuple[PythonTerms, ...]:
        """The constraints that pack nothing, asked in Python before a law's kernel call
        (``packed_tables``' rows for them), in the set's order."""
        return self._python

    def violation(self, log_phi: float, phi: Array) -> ConstraintViolation:
        """The worst margin outside S, from the barrier values ``phi`` (in the order of
        ``names``) of a NaN log Φ (a configuration constraint), else of a NaN log Ψ."""
        nc = self.n_configuration
        if log_phi != log_phi:
            return _violation(phi[:nc], self.names[:nc])
        return _violation(phi[nc:], self.names[nc:])

    def joint_kinematics(self, state: ArmState) -> tuple[Array, Array]:
        """The joint placements and Jacobians the clearance kernels read."""
        if not self.needs_kinematics:
            return self._no_joints
        if state.regressor is None or state.joint_jacobians is None:
            raise CpbcError("clearance reads the state's joint kinematics: build the state "
                            "with kinematics=True (a law's state(x, dx) does)")
        return state.regressor, state.joint_jacobians

    def _rest(self, state: ArmState, margins: bool, log_phi: float, log_psi: float,
              phi: Array, gradient: Array, weight: Array, value: Array) -> tuple[float, float]:
        """The terms of the constraints that do not pack, from their ``barrier_terms``,
        added to the kernel's."""
        for at, c in self._rest_config:
            part, b, shown = c.barrier_terms(state, margins)
            k = len(part)
            phi[at:at + k] = part
            gradient += b
            log_phi += log_sum(part)
            if margins:
                value[at:at + k] = shown
        for at, v in self._rest_velocity:
            psi, pi, b_psi = v.barrier_terms(state)
            k = len(psi)
            phi[at:at + k] = psi
            weight += pi
            if b_psi is not None:
                gradient += b_psi
            log_psi += log_sum(psi)
            if margins:
                value[at:at + k] = psi
        return log_phi, log_psi
