"""A law's potential or damping without a kernel in the law's one kernel call: its terms
computed in Python before each call (a potential's ``evaluate``, a damping's ``force``) and
copied into the law's tables (cpbc.kernels.python_rows), so that only its own terms leave the
compiled path — and a note that says so, once, with what it costs (as a constraint without a
kernel does: cpbc.constraints.python_terms).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.python_terms import TIMED_CALLS, cost_clause
from cpbc.kernels.plan_tables import Packed
from cpbc.kernels.python_rows import pack_python_term
from cpbc.model.robot_model import ArmState

POTENTIAL, DAMPING, TASK_DAMPING = "potential", "damping", "task damping"


@dataclass(frozen=True, eq=False)
class PythonLawTerm:
    """One potential (U and ∂U/∂x), joint damping (its ``force(ẋ)``) or task damping (its
    ``force(state, ẋ)``) asked in Python before each kernel call.

    Attributes:
        term: the potential or damping.
        what: ``POTENTIAL``, ``DAMPING`` or ``TASK_DAMPING``.
        n: the number of coordinates.
    """

    term: Any
    what: str
    n: int
    _values: Array = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_values",
                           np.zeros(self.n + 1 if self.what == POTENTIAL else self.n))

    def packed(self) -> Packed:
        """Its table in the law's kernel, which reads the array :meth:`fill` writes."""
        return pack_python_term(self._values, self.what != POTENTIAL)

    def fill(self, state: ArmState, margins: bool = False) -> None:
        """Its terms at the per-step state, written where the kernel reads them (copied in
        before the call, ``Packed.live``)."""
        if self.what == POTENTIAL:
            value, grad = self.term.evaluate(state)
            self._values[0] = value
            self._values[1:] = grad
        elif self.what == DAMPING:
            self._values[:] = self.term.force(state.dx)
        else:
            self._values[:] = self.term.force(state, state.dx)

    def cost(self, state: ArmState) -> float:
        """What one :meth:`fill` costs [s], the fastest of ``TIMED_CALLS`` at ``state``."""
        best = np.inf
        for _ in range(TIMED_CALLS):
            start = time.perf_counter()
            self.fill(state)
            best = min(best, time.perf_counter() - start)
        return float(best)

    def note(self, law: str, state: ArmState | None) -> str:
        """The sentence a law says once, at build: which term runs in Python, and what it
        costs a step (measured at ``state``, when given)."""
        cost = cost_clause(self.cost, state)
        return (f"{law}: its {self.what} ({type(self.term).__name__}) has no kernel: it runs "
                f"in Python at every step{cost}, and the law finishes its per-step state in "
                f"Python for it; the law's other terms stay in its one kernel call")
