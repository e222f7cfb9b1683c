"""The controller interface: a pure function of the state and the controller's model."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, ClassVar, NamedTuple

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.errors import ConstraintViolation, ParameterError
from cpbc.model.measured_state import (
    finite_vector,
    measured,
    not_finite,
    refuse_non_finite,
)
from cpbc.model.robot_model import ArmState, RobotModel

if TYPE_CHECKING:
    from cpbc.controllers.potentials import Potential
    from cpbc.controllers.terms import StateDamping


class Evaluation(NamedTuple):
    """A law at one per-step state.

    Attributes:
        torque: τ, shape (n,), controller coordinates.
        lyapunov: V at the state.
        margins: every margin of the law's constraints (in the order of their names) when
            asked for, else None.
    """

    torque: Array
    lyapunov: float
    margins: Array | None = None


def vector3(value: object, name: str) -> Array:
    """A point or a velocity in space as a read-only vector of 3 finite numbers."""
    a = np.array(value, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ParameterError(name, f"{name} must be 3 finite numbers, got {value!r}")
    a.setflags(write=False)
    return a


def positive_vector(value: object, n: int, field: str) -> Array:
    """A gain or parameter as a read-only vector of n strictly positive entries.

    A scalar is broadcast; anything else must have shape (n,).
    """
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ParameterError(
            field, f"{field} must be a number or a list of {n} numbers, got shape {a.shape}")
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ParameterError(
            field, f"{field} must be finite and > 0 in every entry, got {a.tolist()}")
    a.setflags(write=False)
    return a


class Controller(ABC):
    """A set-point controller τ = k(x, ẋ) in the model's controller coordinates.

    It knows nothing of the simulator: the same object could drive a real arm.

    Attributes:
        type_name: the scenario ``type`` of this law.
        model: the controller's robot model.
        target: the joint set point x_d, or the posture x_n of a task potential, shape (n,).
        constraints: the constraints this law enforces (empty for the baselines).
        potential: the law's potential U (cpbc.controllers.potentials), or None for a law
            without one; the per-step state holds the frames it reads.
        task_damping: a damping force read from the state (task-space damping), added to
            the law's joint damping, or None.
        torque_bound: an explicit bound on ‖τ‖ from the theory, or None.
    """

    type_name: ClassVar[str]
    torque_bound: float | None = None
    potential: Potential | None = None
    task_damping: StateDamping | None = None

    def __init__(
        self, model: RobotModel, target: Array, constraints: ConstraintSet | None = None
    ) -> None:
        # a copy: the caller's array is not made read-only with it
        target = finite_vector(target, model.n, "target", "the set-point, one per coordinate")
        if constraints is not None and constraints.n != model.n:
            raise ParameterError("constraints", f"constraints are of an arm of {constraints.n} "
                                 f"coordinates; the model has {model.n}")
        self.model = model
        self.target = target
        self.target.setflags(write=False)
        self.constraints = constraints or ConstraintSet(model.n)

    def state(self, x: Array, dx: Array) -> ArmState:
        """The per-step state this law reads: the model's dynamics terms and, when a
        constraint or the potential needs them, its kinematics — computed once, read by law,
        constraints and potential."""
        return self.constraints.state(self.model, x, dx, self.frames, self.reads_motion)

    @property
    def reads_motion(self) -> bool:
        """Whether it reads the constraints' second-order terms (``motion_terms``: a filter
        on φ̈) from the per-step state, which then carries what they read."""
        return False

    @property
    def frames(self) -> tuple[int, ...]:
        """The frames the potential and the task damping read from the per-step state."""
        frames = () if self.potential is None else self.potential.frames
        if self.task_damping is not None:
            frames = tuple(dict.fromkeys(frames + self.task_damping.frames))
        return frames

    def task_damping_force(self, state: ArmState) -> Array | float:
        """The task-space damping force F at the state (0 without task damping)."""
        if self.task_damping is None:
            return 0.0
        return self.task_damping.force(state, state.dx)

    @abstractmethod
    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        """τ, V and (with ``margins``) every constraint margin at a per-step state; raises
        ConstraintViolation outside the admissible set."""

    def torque(self, x: Array, dx: Array) -> Array:
        """Generalised force τ, shape (n,), in controller coordinates.

        Raises:
            ParameterError: ``x`` or ``dx`` is not n numbers, or not finite
                (NonFiniteState); the law as it was.
        """
        return self._evaluation(x, dx).torque

    def lyapunov(self, x: Array, dx: Array) -> float:
        """The law's Lyapunov function V(x, ẋ) (non-increasing along the closed loop)."""
        return self._evaluation(x, dx).lyapunov

    def evaluate(self, x: Array, dx: Array) -> tuple[Array, float]:
        """τ and V together (x and ẋ as :meth:`torque` takes them)."""
        out = self._evaluation(x, dx)
        return out.torque, out.lyapunov

    def _evaluation(self, x: Array, dx: Array) -> Evaluation:
        """The step at (x, ẋ) as a caller gives them (cpbc.model.measured_state)."""
        x, dx = measured(x, dx, self.model.n)
        try:
            out = self.evaluate_state(self.state(x, dx))
        except ConstraintViolation as exc:  # a margin not finite: from a state not finite?
            found = None if math.isfinite(exc.margin) else not_finite(x, dx)
            if found is None:
                raise
            raise found from None
        refuse_non_finite(out.torque, x, dx)
        return out

    def prime(self, x: Array, dx: Array) -> None:
        """Touch what a step at (x, ẋ) reads, moving nothing: a real-time loop's last act
        before its first cycle, after the set-up that left the caches cold. Nothing for a
        law; the safeguard touches its own data (Safeguard.prime), a tracker its run's."""
        return None  # nothing evaluated: a peer filter counts its evaluations

    def check_admissible(self, x: Array, dx: Array, what: str) -> None:
        """Raise InadmissibleStateError if (x, ẋ) is outside this law's admissible set."""
        self.constraints.check_admissible(x, dx, what)


class SafetyFilter(Controller):
    """A controller that corrects a torque for safety and counts what it did: the sampled-data
    safeguard around a law, or a peer filter (cpbc.peers). The loop reports its counts; the
    scenario builder does not wrap it in another filter.

    Attributes:
        acted: control steps at which it changed the torque it filters.
        infeasible: of those, steps at which it could not meet all its conditions.
        rescues: steps at which it held a rescue brake (the safeguard's rescue; 0 for a
            peer).
        out_of_tests: steps that spent their budget of tests (the safeguard's
            ``test_budget``; 0 for a peer).
    """

    acted: int = 0
    infeasible: int = 0
    rescues: int = 0
    out_of_tests: int = 0

    @property
    def row_active_steps(self) -> int:
        """Steps at which its own safety conditions, not the torque box alone, changed the
        torque: every step it acted, unless the filter counts them apart (a peer whose
        nominal torque is clipped to the box counts that clip in ``acted`` too)."""
        return self.acted

    def restarted(self) -> SafetyFilter:
        """The same filter with its counts at zero, for a new run."""
        return self

    def holding(self, tau: Array, added: Array | None = None) -> None:
        """The torque the actuators hold now (controller coordinates), and the torque the
        robot adds to every command itself (``added``), for a filter that limits the
        torque's rate of change; others ignore them."""
