"""``type: pd`` and ``pd_gravity``: the thesis's baselines −K_P x̃ − K_D ẋ (and + g, eq.
6.10); constraints are only monitored."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from cpbc.controllers import PD, PDGravity
from cpbc.controllers.controller import Controller
from cpbc.scenario.schema.controller_specs import LawSpec
from cpbc.scenario.schema.kinds.law_inputs import LINEAR, LawInputs
from cpbc.scenario.schema.kinds.registry import LawKind


class PDSpec(LawSpec):
    type: Literal["pd", "pd_gravity"] = Field(
        description=(
            "pd: −K_P x̃ − K_D ẋ (the thesis's baseline); pd_gravity: g − K_P x̃ − K_D ẋ "
            "(6.10). Constraints are only monitored"))


def build(spec: PDSpec, given: LawInputs) -> Controller:
    law = PD if spec.type == "pd" else PDGravity
    gains: dict[str, Any] = dict(given.gains)
    return law(given.model, given.target, **gains)


KINDS = (LawKind(PDSpec, build, slopes=LINEAR, examples={"pd": {}, "pd_gravity": {}},
                 goal_types=("pd_gravity",)),)
