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
path too. A packed law's per-step state comes from its one producer
(cpbc.model.state_pass.StatePass, made when it packs), and every step — a bare ``torque``,
a guard's, a steered one — is ``evaluate_state`` on it: the law's kernel finishes the
state's pass itself when nothing read the state before. A constraint that packs nothing
costs only its own terms: they are asked in Python before each call and copied into the
law's tables (cpbc.constraints.python_terms), and the law says so once, when it packs
(:class:`PythonPathWarning`).
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, NamedTuple

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.packing import Ints, Packed, PackedSet
from cpbc.constraints.python_terms import TIMED_CALLS, PythonTerms
from cpbc.controllers.controller import Controller
from cpbc.controllers.potentials import PotentialSum
from cpbc.controllers.python_law_terms import (
    DAMPING,
    POTENTIAL,
    TASK_DAMPING,
    PythonLawTerm,
)
from cpbc.errors import CpbcError
from cpbc.kernels.law_terms import FRAME_KINDS, pack_shaping
from cpbc.kernels.laws import pack_tables
from cpbc.model.robot_model import ArmState, RobotModel
from cpbc.model.state_pass import FINISHED, StatePass

# the set's and the terms' tables packed in one int and one float array
# (cpbc.kernels.laws.pack_tables)
Tables = tuple[Ints, Array]


class PythonPathWarning(UserWarning):
    """A law's constraint runs in Python at every step (it has no kernel), or the whole law
    does (a term without a kernel, a class or a constraint set overriding a formula the
    kernel stands in for): said once, when the law packs, with what it costs."""


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


class LawParts(NamedTuple):
    """A law's terms as its kernel packs them (``law_terms``).

    Attributes:
        parts: each term's packed rows (None: the law takes its general path).
        general: what sends the law down its general path, said once at build.
        python: the terms without a kernel asked in Python before each call (their rows in
            ``parts``; cpbc.controllers.python_law_terms).
    """

    parts: list[tuple[Packed, ...] | None]
    general: tuple[str, ...]
    python: tuple[PythonLawTerm, ...]


def law_terms(law: Any, base: type, formulas: Sequence[str]) -> LawParts:
    """A law's terms as its kernel packs them: potential, damping, task damping, shaping. A
    potential or damping without a kernel (a sum's part without one) is asked in Python
    before each call and read by the kernel as a row of its own (``PythonLawTerm``); a
    shaping without one, or a class overriding one of ``base``'s ``formulas`` or the frames
    it asks the state for, sends the law down its general path (a None, and what runs in
    Python, said once at build: :class:`PythonPathWarning`)."""
    parts: list[tuple[Packed, ...] | None] = []
    reasons, python = [], []
    n = law.model.n
    for what, term in ((POTENTIAL, law.potential), (DAMPING, law.damping),
                       (TASK_DAMPING, law.task_damping)):
        if term is None:
            parts.append(())
            continue
        rows: list[Packed] = []
        summed = getattr(type(term), "evaluate", None) is PotentialSum.evaluate
        pieces = term.parts if summed else (term,)
        for piece in pieces:
            found = packed_terms(piece)
            if found is None:
                python.append(PythonLawTerm(piece, what, n))
                found = (python[-1].packed(),)
            rows.extend(found)
        parts.append(tuple(rows))
    shaped = shaping_term(law.shaping)
    parts.append(shaped)
    if shaped is None:
        reasons.append(f"its shaping ({type(law.shaping).__name__}) has no kernel")
    overridden = [m for m in formulas if getattr(type(law), m) is not getattr(base, m)]
    if not keeps(type(law), Controller, ("frames",)):
        overridden.append("frames")
    if overridden:
        parts.append(None)
        reasons.append(f"its class {type(law).__name__} overrides {', '.join(overridden)}")
    return LawParts(parts, tuple(reasons), tuple(python))


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


class PacksItsLaw(Controller):
    """A law that keeps its :class:`PackedLaw`: made at the first step (``_pack``) and again
    after any attribute named in ``_packed_from`` is set or the object's class changes.
    ``torque``, ``evaluate`` and ``lyapunov`` at (x, ẋ) are ``evaluate_state`` on
    ``state(x, ẋ)`` (cpbc.controllers.controller.Controller), as every step is."""

    _packed_from: ClassVar[frozenset[str]] = frozenset()
    _packed_law: PackedLaw | None = None
    _said: tuple[str, ...] = ()  # the notes the law has said (``PythonPathWarning``)

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without its packed law, which is made again at the next step: its rows
        of a moving goal are views of its packed floats (``PackedLaw.live``), which a copy
        would not share."""
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
            if found.python or found.general:
                self._say(found)
        return found

    def _say(self, packed: PackedLaw) -> None:
        """Which constraints run in Python, or what sends the whole law down its general
        path, and what it costs, once (a warning per new note), measured at the target at
        rest."""
        try:
            state = self.state(self.target, np.zeros_like(self.target))
        except (CpbcError, ArithmeticError, ValueError):  # no state at the target
            state = None
        name = getattr(self, "type_name", type(self).__name__)
        notes = tuple(t.note(name, state) for t in packed.python)
        if packed.general:
            cost = self._general_cost(state)
            notes += tuple(f"{name}: {reason}: the law takes its general path, every term "
                           f"and constraint in Python at every step{cost}"
                           for reason in packed.general)
        said = tuple(note.split(", about")[0] for note in notes)  # the cost varies
        if said != self._said:
            self._said = said
            for note in notes:
                warnings.warn(note, PythonPathWarning, stacklevel=3)

    def _general_cost(self, state: ArmState | None) -> str:
        """What the general path's step costs at ``state`` (the fastest of
        ``TIMED_CALLS``), as the note says it, or nothing where it cannot be measured."""
        if state is None:
            return ""
        best = math.inf
        try:
            for _ in range(TIMED_CALLS):
                start = time.perf_counter()
                self.evaluate_state(state)
                best = min(best, time.perf_counter() - start)
        except (CpbcError, ArithmeticError, ValueError):  # not measurable there
            return ""
        return f", about {best * 1e6:.1f} µs a step (measured at build)"

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
            (cpbc.constraints.packing), the terms' plan and floats and the state's tables,
            packed in two arrays (cpbc.kernels.laws.pack_tables).
        frame: the one frame the terms and the set read (−1: none).
        margins: the number of the set's margins; n: the number of coordinates.
        produce: the producer of the law's per-step state (cpbc.model.state_pass: the set's
            frames, then the law's, its joint kinematics and C as the set asks), or None.
        live: (its place in the packed floats, a view; source) of each row a term keeps in
            step with a moving goal, or a constraint without a kernel its terms
            (``Packed.live``), refreshed before each kernel call.
        python: the set's constraints and the law's potentials and dampings without a
            kernel, asked before each call (cpbc.constraints.python_terms,
            cpbc.controllers.python_law_terms).
        general: what sends the whole law down its general path (``terms`` None), said
            once at build (:class:`PythonPathWarning`).
    """

    law: type
    terms: PackedSet | None = None
    constants: Tables = ()  # type: ignore[assignment]
    frame: int = -1
    margins: int = 0
    n: int = 0
    produce: StatePass | None = None
    live: tuple[tuple[Array, Array], ...] = ()
    python: tuple[PythonTerms | PythonLawTerm, ...] = ()
    general: tuple[str, ...] = ()
    # where the kernel writes φ̃ without the margins: one array, overwritten by every step
    # (read only to name the margin of a state outside S; one allocation fewer a step)
    _phi: Array = field(init=False, repr=False)
    # where a step that keeps no state finishes its pass: one array, overwritten by every
    # such step (the kernel allocated it each step, about 0.1 µs)
    _terms: Array = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_phi", np.empty(self.margins))
        size = 0 if self.produce is None else self.produce.size
        object.__setattr__(self, "_terms", np.empty(size))

    def state(self, x: Array, dx: Array) -> ArmState:
        """The law's per-step state at (x, ẋ) (``produce``)."""
        assert self.produce is not None  # a packed law
        return self.produce(x, dx)

    @classmethod
    def build(cls, law: type, parts: LawParts, constraints: ConstraintSet,
              frames: tuple[int, ...], model: RobotModel) -> PackedLaw:
        """From the terms' ``packed`` (None for one that does not pack) and what runs in
        Python (``law_terms``), the set, the frames the law reads besides the set's
        (``Controller.frames``) and the law's model."""
        packs, general, python = parts
        tables = constraints.packed_tables
        kind = type(constraints).__name__
        if tables is None:
            general += (f"its constraint set's class {kind} overrides barrier",)
        if type(constraints).state is not ConstraintSet.state:
            general += (f"its constraint set's class {kind} overrides state",)
        if tables is None or general:
            return cls(law, general=general)
        terms = [t for p in packs for t in p or ()]
        read = {t.frame for t in terms if t.kind in FRAME_KINDS}
        if tables.frame >= 0:
            read.add(tables.frame)
        if len(read) > 1:
            return cls(law, general=(f"its terms and its point constraint read {len(read)} "
                                     "frames, where its kernel reads one",))
        packed = PackedSet.build([(0, 0, t) for t in terms])
        margins = len(constraints.names)
        frame = read.pop() if read else -1
        held = tuple(dict.fromkeys((*constraints.frames, *frames)))
        if frame >= 0 and frame not in held:
            held += (frame,)
        produce = model.state_pass(constraints.needs_kinematics, held,
                                   constraints.needs_coriolis)
        constants = pack_tables(margins, tables.plan, tables.ints, tables.floats,
                                packed.plan, packed.floats, produce.tables,
                                produce.frames.index(frame) if frame >= 0 else -1)
        flat, start = constants[1], tables.floats.size
        # each live row's place in the packed floats as a view, made once (a slice a step
        # costs about 0.1 µs a row)
        live = tuple((flat[at:at + source.shape[0]], source) for at, source in tables.live)
        live += tuple((flat[start + at:start + at + source.shape[0]], source)
                      for at, source in packed.live)
        return cls(law, packed, constants, frame, margins, constraints.n, produce, live,
                   (*constraints.python_terms, *python))

    def arguments(self, state: ArmState, margins: bool) -> tuple[Any, ...]:
        """The kernel's arguments: the tables (``constants``, the rows of a moving goal
        copied in first); x, ẋ; the state's pass unfinished (its kernel finishes it: into
        the state's own terms when the margins are asked for, as a guard reads the state
        next; else into the law's one array for it, ``_terms``), or — when it was read
        already, or made elsewhere — empty, and its terms; and where the kernel writes the
        barrier values φ̃ followed by the margins (with ``margins``, else φ̃ alone), and τ
        (the last two). Built as one tuple of named values: unpacking the constants and the
        pass into it costs about 0.1 µs more a step."""
        produce = self.produce
        assert produce is not None  # a packed law
        if self.python:
            for python in self.python:  # (reading the state finishes it)
                python.fill(state, margins)
        raw = state.raw
        if raw is not None and state.source is produce and produce.model.holder is state:
            if margins:  # read next: finished into the state's own terms
                terms = np.empty(produce.size)
                state.terms, state.raw = terms, None
                barriers = np.empty(2 * self.margins)
            else:
                terms, barriers = self._terms, self._phi
        else:
            raw, terms = FINISHED, produce.terms_of(state)
            barriers = np.empty(2 * self.margins) if margins else self._phi
        if self.live:
            copy_live(self.live)
        ints, floats = self.constants
        mass, bias, weight, coriolis, placements, jacobians = raw
        return (ints, floats, state.x, state.dx, mass, bias, weight, coriolis, placements,
                jacobians, terms, barriers, np.empty(self.n))


def writable(args: tuple[Any, ...]) -> tuple[Any, ...]:
    """A kernel's arguments with x and ẋ (the third and fourth) as float copies: numba's
    kernels refuse a read-only or integer array with a TypeError, on which a law steps
    again from these (asking once is cheaper than checking the flags at every step)."""
    return (*args[:2], np.array(args[2], dtype=float), np.array(args[3], dtype=float),
            *args[4:])


def copy_live(live: tuple[tuple[Array, Array], ...]) -> None:
    """The rows of a moving goal (``PackedLaw.live``) copied from their sources into their
    places in the packed floats."""
    for place, source in live:
        place[:] = source
