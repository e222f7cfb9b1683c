"""``type: recentred``: the re-centred barrier (Cases 2–3, eqs. 6.53–6.65)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from cpbc.arrays import Array
from cpbc.controllers import RecentredBarrier
from cpbc.controllers.controller import Controller
from cpbc.scenario.schema.controller_specs import ConstrainedLawSpec
from cpbc.scenario.schema.kinds.law_inputs import LINEAR, LawInputs
from cpbc.scenario.schema.kinds.registry import LawKind


class RecentredSpec(ConstrainedLawSpec):
    type: Literal["recentred"] = Field(
        description=(
            "the re-centred barrier (Cases 2–3, eqs. 6.53–6.65): joint_position_limit and "
            "velocity constraints"))


def build(spec: RecentredSpec, given: LawInputs) -> Controller:
    gains: dict[str, Any] = dict(given.gains)
    return RecentredBarrier(given.model, given.target, given.constraint_set(spec.constraints),
                            **gains)


def start_problem(law: Controller, x: Array, dx: Array, names: tuple[str, ...],
                  torque_limit: Array | None, period: float | None) -> str | None:
    """RecentredBarrier.start_problem: the torque limit and, in a loop without the safeguard,
    the first held period against its velocity constraints."""
    assert isinstance(law, RecentredBarrier)
    return law.start_problem(law.state(x, dx), names, torque_limit, period)


KINDS = (LawKind(RecentredSpec, build, slopes=LINEAR,
                 examples={"recentred": {"constraints": ["limits", "rates"]}},
                 start_problem=start_problem),)
