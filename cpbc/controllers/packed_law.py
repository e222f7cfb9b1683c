"""A law's terms packed for its one kernel call per step (cpbc.kernels.laws.cpbc_step,
``cpbc_ke_step``): the potential, the damping, the task damping and the shaping hand their
constants over (their ``packed``), stacked as the constraint set stacks its constraints'
(cpbc.constraints.packing).

A term packs only when its class keeps the formula the kernel computes: a subclass that
overrides a term's method returns None from ``packed``, and so does a law whose class
overrides a method the kernel stands in for (``_law``, ``_shaped_value``,
``task_damping_force``). The law then takes its general path, method by method: nothing
dispatches on type, and every override is honoured. The kernel reads one frame: the terms
and the set's point constraint must all read the same frame, or the law takes the general
path too. A constraint that packs nothing costs only its own terms: they are asked in Python
before each call and copied into the law's tables (cpbc.constraints.python_terms), and the
law says so once, when it packs (:class:`PythonPathWarning`).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.packing import Ints, Packed, PackedSet
from cpbc.constraints.python_terms import PythonTerms
from cpbc.controllers.controller import Controller
from cpbc.errors import CpbcError
from cpbc.kernels.law_terms import FRAME_KINDS, pack_shaping
from cpbc.kernels.laws import pack_tables
from cpbc.model.robot_model import ArmState, RobotModel

# the set's and the terms' tables packed in one int and one float array
# (cpbc.kernels.laws.pack_tables)
Tables = tuple[Ints, Array]
PassArguments = Callable[[Array, Array], tuple[Any, ...]]
_NO_MATRIX = np.zeros((0, 0))


class PythonPathWarning(UserWarning):
    """A law's constraint runs in Python at every step (it has no kernel): said once, when
    the law packs, with what it costs."""


def packed_terms(term: object) -> tuple[Packed, ...] | None:
    """A term's share of its law's kernel (its ``packed``), or None when it has none."""
    packed = getattr(term, "packed", None)
    return None if packed is None else packed()


def shaping_term(shaping: object) -> tuple[Packed, ...] | None:
    """The shaping's (kind, parameter) as a packed term, or None."""
    packed = getattr(shaping, "packed", None)
    found = None if packed is None else packed()
    if found is None:
        return None
    return (pack_shaping(*found),)


def keeps(cls: type, base: type, methods: Iterable[str]) -> bool:
    """Whether ``cls`` keeps ``base``'s ``methods`` (a subclass overriding none of them)."""
    return all(getattr(cls, m) is getattr(base, m) for m in methods)


def law_terms(law: Any, base: type, formulas: Sequence[str]) -> list[tuple[Packed, ...] | None]:
    """A law's terms as its kernel packs them: potential, damping, task damping, shaping —
    and a None (the general path) when ``type(law)`` overrides one of ``base``'s
    ``formulas`` or the frames it asks the state for."""
    parts = [packed_terms(law.potential), packed_terms(law.damping),
             () if law.task_damping is None else packed_terms(law.task_damping),
             shaping_term(law.shaping)]
    if not keeps(type(law), base, formulas):
        parts.append(None)
    if not keeps(type(law), Controller, ("frames",)):
        parts.append(None)
    return parts


def python_path_notes(law: object) -> list[str]:
    """Pack ``law`` now (or the law a wrapper holds as ``law``) and return what it says
    (its :class:`PythonPathWarning` notes) instead of warning: for a caller that reports them
    its own way, once, at build (cpbc.run). Other warnings go on as they were."""
    inner = getattr(law, "law", law)
    pack = getattr(inner, "packed_law", None)
    if not callable(pack):
        return []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PythonPathWarning)
        pack()
    notes = []
    for w in caught:
        if issubclass(w.category, PythonPathWarning):
            notes.append(str(w.message))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return notes


# the methods of a packed law's state path: a class that keeps them may step from the pass
STATE_PATH = ("state", "evaluate_state", "_packed_step")


class PacksItsLaw(Controller):
    """A law that keeps its :class:`PackedLaw`: made at the first step (``_pack``) and again
    after any attribute named in ``_packed_from`` is set or the object's class changes.

    ``torque``, ``evaluate`` and ``lyapunov`` at (x, ẋ) go from the model's pass straight to
    the law's kernel (``PackedLaw.from_pass``: ``_pass_value``) — the same formulas as
    ``evaluate_state(state(x, dx))``, without building the state — unless the law does not
    pack or its class overrides a method of that path (``STATE_PATH``)."""

    _packed_from: ClassVar[frozenset[str]] = frozenset()
    _packed_law: PackedLaw | None = None
    _said: tuple[str, ...] = ()  # the notes the law has said (``PythonPathWarning``)

    def torque(self, x: Array, dx: Array) -> Array:
        packed = self._packed_law
        if packed is None or packed.law is not type(self):
            packed = self.packed_law()
        step = packed.pass_arguments
        if step is None:
            return self.evaluate_state(self.state(x, dx)).torque
        try:
            args = step(x, dx)
            self._pass_value(args)
        except TypeError:  # numba's kernels refuse read-only arrays (``_copied_step``)
            args = self._copied_step(step, x, dx)[0]
        return args[-1]

    def evaluate(self, x: Array, dx: Array) -> tuple[Array, float]:
        step = self.packed_law().pass_arguments
        if step is None:
            out = self.evaluate_state(self.state(x, dx))
            return out.torque, out.lyapunov
        try:
            args = step(x, dx)
            value = self._pass_value(args)
        except TypeError:
            args, value = self._copied_step(step, x, dx)
        return args[-1], value

    def _copied_step(self, step: PassArguments, x: Array, dx: Array
                     ) -> tuple[tuple[Any, ...], float]:
        """The step from the pass at writable float copies of (x, ẋ). numba types a
        read-only array (a law's own target, say) apart and raises TypeError: asking once
        here is cheaper than checking the flags at every step (about 80 ns)."""
        args = step(np.array(x, dtype=float), np.array(dx, dtype=float))
        return args, self._pass_value(args)

    def lyapunov(self, x: Array, dx: Array) -> float:
        return self.evaluate(x, dx)[1]

    def _pass_value(self, args: tuple[Any, ...]) -> float:
        """V from the law's ``*_pass_step`` kernel on ``PackedLaw.pass_arguments`` (τ into
        the last); raises outside S."""
        raise NotImplementedError

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without its packed law, which is made again at the next step: its step
        from the pass is a function bound to this process's Pinocchio data (a law is sent
        to worker processes whole)."""
        state = dict(self.__dict__)
        state.pop("_packed_law", None)
        return state

    def __setattr__(self, name: str, value: object) -> None:
        super().__setattr__(name, value)
        if name in self._packed_from:  # pack again at the next step
            super().__setattr__("_packed_law", None)

    def packed_law(self) -> PackedLaw:
        """The law's packed terms; ``terms`` None when a term or the class's formula does
        not pack."""
        found = self._packed_law
        if found is None or found.law is not type(self):
            found = self._pack()
            self._packed_law = found
            if found.python:
                self._say(found)
        return found

    def _say(self, packed: PackedLaw) -> None:
        """Which constraints run in Python and what they cost, once (a warning per new
        note), measured at the target at rest."""
        try:
            state = packed.state(self.model, self.target, np.zeros_like(self.target))
        except (CpbcError, ArithmeticError, ValueError):  # no state at the target
            state = None
        name = getattr(self, "type_name", type(self).__name__)
        notes = tuple(t.note(name, state) for t in packed.python)
        said = tuple(note.split(", about")[0] for note in notes)  # the cost varies
        if said != self._said:
            self._said = said
            for note in notes:
                warnings.warn(note, PythonPathWarning, stacklevel=3)

    def _pack(self) -> PackedLaw:
        """:meth:`PackedLaw.build` for this law's terms, constraints and frames."""
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class PackedLaw:
    """A law's packed terms and the inputs of its kernel that do not change per step.

    Attributes:
        law: the class it was packed for (a law whose class changes packs again).
        terms: the terms' tables (cpbc.kernels.law_terms), or None: the law takes its
            general path.
        constants: the kernel's constant arguments: the set's plan, ints and floats
            (cpbc.constraints.packing) and the terms' plan and floats, packed in two arrays
            (cpbc.kernels.laws.pack_tables).
        frame: the one frame the terms and the set read (−1: none).
        kinematics: whether the set reads the joint placements and Jacobians.
        margins: the number of the set's margins; n: the number of coordinates.
        frames: the frames the per-step state holds (the set's, then the law's).
        coriolis: whether the state holds the matrix C (a kinetic-energy limit).
        pass_arguments: for a step straight from the model's pass to the kernel (the law's
            ``_pass_value``), the function of (x, ẋ) that gives the kernel's arguments
            (``step_from_pass``), or None: the law builds the state. A step may go from
            the pass when the law's class keeps the state path (``STATE_PATH``) of the
            class it was packed by and its state holds no frame besides the one the kernel
            reads.
        pass_reads: the frame the model's pass reads for that step (−1: none, or the
            kernel reads the law's frame from the joint kinematics, ``pack_tables``'
            ``frame``, as it does for any frame on a joint).
        live: (its place in the packed floats, a view; source) of each row a term keeps in
            step with a moving goal, or a constraint without a kernel its terms
            (``Packed.live``), refreshed before each kernel call.
        python: the set's constraints without a kernel, asked before each call
            (cpbc.constraints.python_terms; the law then builds the state).
    """

    law: type
    terms: PackedSet | None = None
    constants: Tables = ()  # type: ignore[assignment]
    frame: int = -1
    kinematics: bool = False
    margins: int = 0
    n: int = 0
    frames: tuple[int, ...] = ()
    coriolis: bool = False
    pass_arguments: PassArguments | None = None
    pass_reads: int = -1
    live: tuple[tuple[Array, Array], ...] = ()
    python: tuple[PythonTerms, ...] = ()

    @property
    def from_pass(self) -> bool:
        """Whether a step goes from the model's pass straight to the kernel."""
        return self.pass_arguments is not None

    def refreshed(self) -> tuple[Ints, Array]:
        """The constant tables, the rows of a moving goal and the terms of a constraint
        without a kernel (``live``) copied in from their sources first."""
        copy_live(self.live)
        return self.constants

    def state(self, model: RobotModel, x: Array, dx: Array) -> ArmState:
        """The per-step state the kernel reads (as ``ConstraintSet.state`` with the law's
        frames builds it), from one call of ``model.state``."""
        return model.state(x, dx, self.kinematics, self.frames, self.coriolis)

    @classmethod
    def build(cls, law: type, parts: Sequence[tuple[Packed, ...] | None],
              constraints: ConstraintSet, frames: tuple[int, ...], model: RobotModel,
              base: type) -> PackedLaw:
        """From the terms' ``packed`` (None for one that does not pack), the set, the
        frames the law reads besides the set's (``Controller.frames``), the law's model
        (its coordinates and friction, for a step from its pass) and the class whose
        state path (``STATE_PATH``) a step from the pass stands in for."""
        tables = constraints.packed_tables
        if tables is None or any(p is None for p in parts) or (
                type(constraints).state is not ConstraintSet.state):
            return cls(law)
        terms = [t for p in parts for t in p or ()]
        read = {t.frame for t in terms if t.kind in FRAME_KINDS}
        if tables.frame >= 0:
            read.add(tables.frame)
        if len(read) > 1:
            return cls(law)
        packed = PackedSet.build([(0, 0, t) for t in terms])
        margins = len(constraints.names)
        frame = read.pop() if read else -1
        held = tuple(dict.fromkeys((*constraints.frames, *frames)))
        # the kernel reads a frame on a joint from the pass's joint kinematics: the static
        # regressor is one Pinocchio call where the frame's placement and Jacobian are two
        # (planar CPBC about 0.15 us a step less), and a clearance's pass has it already
        on_joints = model.frame_on_joints(frame) if frame >= 0 else None
        pass_reads = frame if on_joints is None else -1
        python = constraints.python_terms
        from_pass = keeps(law, base, STATE_PATH) and all(f == frame for f in held) and (
            not python)
        constants = pack_tables(margins, tables.plan, tables.ints, tables.floats,
                                packed.plan, packed.floats, model.coordinates.inverse,
                                model.viscous_friction, model.coulomb_friction,
                                model.friction_smoothing, on_joints)
        flat, start = constants[1], tables.floats.size
        # each live row's place in the packed floats as a view, made once (a slice a step
        # costs about 0.1 µs a row)
        live = tuple((flat[at:at + source.shape[0]], source) for at, source in tables.live)
        live += tuple((flat[start + at:start + at + source.shape[0]], source)
                      for at, source in packed.live)
        step = step_from_pass(constants, live, model,
                              constraints.needs_kinematics or on_joints is not None,
                              pass_reads, constraints.needs_coriolis,
                              margins) if from_pass else None
        return cls(law, packed, constants, frame, constraints.needs_kinematics, margins,
                   constraints.n, held, constraints.needs_coriolis, step, pass_reads, live,
                   python)

    def arguments(self, state: ArmState, margins: bool) -> tuple[Any, ...]:
        """The kernel's arguments: the tables (``constants``); x, ẋ, D, g, C ẋ, f, C, the
        frame's placement and Jacobian, the joint placements and Jacobians, read from the
        state; and where it writes the barrier values φ̃ followed by the margins (with
        ``margins``, else φ̃ alone), and τ (the last two). τ has an array of its own, the
        barrier values share one: numpy's slicing costs more per step than numba's passing
        an argument (about 120 ns against 40–70 ns here)."""
        frame = self.frame
        if frame >= 0:
            kin = state.frames.get(frame)
            if kin is None:
                raise CpbcError(f"the law reads frame {frame} from the state: build it with "
                                "the law's state(x, dx)")
            placement, jacobian = kin
        else:
            placement, jacobian = _NO_FRAME
        if self.kinematics:
            y, jac = state.regressor, state.joint_jacobians
            if y is None or jac is None:
                raise CpbcError("clearance reads the state's joint kinematics: build the "
                                "state with kinematics=True (a law's state(x, dx) does)")
        else:
            y, jac = _NO_JOINTS
        for terms in self.python:
            terms.fill(state, margins)
        coriolis = _NO_MATRIX if state.coriolis_matrix is None else state.coriolis_matrix
        return (
            *self.refreshed(), state.x, state.dx, state.inertia, state.gravity,
            state.coriolis_force, state.dissipation, coriolis, placement, jacobian, y, jac,
            np.empty(2 * self.margins if margins else self.margins), np.empty(self.n))


_NO_FRAME = (np.eye(4), np.zeros((6, 0)))
_NO_JOINTS = (np.zeros((3, 0)), np.zeros((6, 0)))


def copy_live(live: tuple[tuple[Array, Array], ...]) -> None:
    """The rows of a moving goal (``PackedLaw.live``) copied from their sources into their
    places in the packed floats."""
    for place, source in live:
        place[:] = source


def step_from_pass(constants: Tables, live: tuple[tuple[Array, Array], ...], model: RobotModel,
                   kinematics: bool, frame: int, coriolis: bool, margins: int
                   ) -> PassArguments:
    """The function of (x, ẋ) that gives a law's ``*_pass_step`` kernel its arguments: the
    model's pass (cpbc.model.robot_model.RobotModel.joint_pass) with the tables
    (``constants``; the rows of a moving goal, ``live``, copied in first), where the
    kernel writes the barrier values φ̃ and τ (a new array). φ̃ is read only to name the
    margin when the state is outside S: it has one array, overwritten by every step (one
    allocation fewer a step, about 90 ns)."""
    reader = model.joint_pass(kinematics, frame, coriolis, constants, np.empty(margins))
    if not live:
        return reader
    def steered(x: Array, dx: Array) -> tuple[Any, ...]:
        copy_live(live)
        return reader(x, dx)

    return steered
