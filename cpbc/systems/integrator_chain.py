"""The integrator chain of §4.4 as an ODE plant (4.92)–(4.93).

    ξ̇1 = ξ2,  ξ̇2 = ξ3,  ξ̇3 = ξ4,  ξ̇4 = u,     |ξ2| ≤ 2.5,  |ξ3| ≤ 12,  |ξ4| ≤ 700

(4.93) prints one-sided bounds (ξ2 ≤ 2.5, …); the problem statement (4.2) is symmetric, so they
are read as |ξ_i| ≤ Ξ_i. ξ1 is unconstrained. There is no mechanism to simulate, so no MJCF: a
chain of pure integrators is exactly its ODE, integrated by scipy (the thesis used Simulink's
fixed-step Dormand–Prince, h = 0.005 s).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import positive
from cpbc.errors import CpbcError
from cpbc.margin_kinds import STATE
from cpbc.systems.ode_plant import ConstrainedQuantity, OdePlant, State


@dataclass(frozen=True)
class IntegratorChain(OdePlant):
    """ξ^{(n)} = u with symmetric bounds on some of the states.

    Args:
        limits: Ξ_i per state (None: unconstrained); default (None, 2.5, 12, 700) of (4.93),
            whose length is the chain's order.
    """

    limits: Sequence[float | None] = (None, 2.5, 12.0, 700.0)

    def __post_init__(self) -> None:
        if len(self.limits) < 1:
            raise CpbcError("an integrator chain needs at least one state")
        limits = tuple(None if v is None else positive(f"limits[{i}]", v)
                       for i, v in enumerate(self.limits))
        object.__setattr__(self, "limits", limits)

    @property
    def state_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(f"xi{i + 1}" for i in range(len(self.limits)))

    input_name = "u"

    @property
    def constrained(self) -> tuple[ConstrainedQuantity, ...]:
        return tuple(
            ConstrainedQuantity(f"xi{i + 1}", -v, v, "state", i, STATE)
            for i, v in enumerate(self.limits) if v is not None
        )

    def rhs(self, x: State, u: float, t: float) -> State:
        return (*x[1:], u)
