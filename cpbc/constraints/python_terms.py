"""A constraint without a kernel in a law's one kernel call: its ``barrier_terms`` asked in
Python before each call, its answer copied into the law's tables (cpbc.kernels.python_rows),
so that only its own terms leave the compiled path — and a note that says so, once, with
what it costs.

A constraint packs nothing when its kind has no kernel (a user's kind), when its class
overrides its kind's ``barrier_terms`` (its own formula), or when the set's kernel cannot
take it (capsules; a second point frame): :class:`PythonTerms` holds it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.errors import CpbcError
from cpbc.kernels.plan_tables import Packed
from cpbc.kernels.python_rows import pack_python_terms
from cpbc.model.robot_model import ArmState

TIMED_CALLS = 20  # the calls timed at build (the fastest counts)


def cost_clause(cost: Callable[[ArmState], float], state: ArmState | None) -> str:
    """", about N µs a step (measured at build)" for a note, from ``cost`` [s] at ``state``;
    nothing without a state or where it cannot be measured there."""
    if state is None:
        return ""
    try:
        return f", about {cost(state) * 1e6:.1f} µs a step (measured at build)"
    except (CpbcError, ArithmeticError, ValueError):  # not measurable there
        return ""


@dataclass(frozen=True, eq=False)
class PythonTerms:
    """One constraint asked through its ``barrier_terms`` before each kernel call.

    Attributes:
        constraint: the constraint.
        n: the number of coordinates.
    """

    constraint: ConfigurationConstraint | VelocityConstraint
    n: int
    _values: Array = field(init=False, repr=False)
    _gradient: Array = field(init=False, repr=False)
    _last: Array = field(init=False, repr=False)  # the margins, or Π

    def __post_init__(self) -> None:
        k = len(self.constraint.names)
        object.__setattr__(self, "_values", np.ones(k))
        object.__setattr__(self, "_gradient", np.zeros(self.n))
        object.__setattr__(self, "_last", np.zeros((self.n, self.n)) if self.velocity
                           else np.ones(k))

    @property
    def velocity(self) -> bool:
        return isinstance(self.constraint, VelocityConstraint)

    def packed(self) -> Packed:
        """Its tables in the law's kernel, which read the arrays :meth:`fill` writes."""
        return pack_python_terms(self._values, self._gradient, self._last, self.velocity)

    def fill(self, state: ArmState, margins: bool) -> None:
        """Its terms at the per-step state, written where the kernel reads them (copied in
        before the call, ``Packed.live``)."""
        c = self.constraint
        if isinstance(c, VelocityConstraint):
            psi, pi, b = c.barrier_terms(state)
            self._values[:] = psi
            self._last[:] = pi
            self._gradient[:] = 0.0 if b is None else b
            return
        phi, b, shown = c.barrier_terms(state, margins)
        self._values[:] = phi
        self._gradient[:] = b
        if margins and shown is not None:
            self._last[:] = shown

    def cost(self, state: ArmState) -> float:
        """What one :meth:`fill` costs [s], the fastest of ``TIMED_CALLS`` at ``state``."""
        best = np.inf
        for _ in range(TIMED_CALLS):
            start = time.perf_counter()
            self.fill(state, False)
            best = min(best, time.perf_counter() - start)
        return float(best)

    def note(self, law: str, state: ArmState | None) -> str:
        """The sentence a law says once, at build: which constraint runs in Python, and what
        it costs a step (measured at ``state``, when given and inside S)."""
        c = self.constraint
        cost = cost_clause(self.cost, state)
        return (f"{law}: constraint '{c.names[0].split('[')[0]}' ({type(c).__name__}) has "
                f"no kernel in its set's plan: its barrier terms run in Python at every "
                f"step{cost}, and the law builds its per-step state in Python for them; the "
                f"law's other terms stay in its one kernel call")
