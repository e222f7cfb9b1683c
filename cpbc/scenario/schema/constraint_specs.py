"""What the ``constraints:`` items share (each kind's own spec is in cpbc.scenario.schema.kinds)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from cpbc.scenario.schema.common import Strict

FromModel = Literal["from_model"]  # a limit read from the robot's URDF/MJCF


class ConstraintEntrySpec(Strict):
    """What every ``constraints:`` entry has: its ``type`` and its unique ``name``. Each
    constraint kind (cpbc.scenario.schema.kinds) narrows ``type`` to its name, gives ``name`` its
    default and adds its own keys."""

    type: str = Field(description="the constraint")
    name: str = Field(description=(
        "unique name, used by controllers' constraints lists and in the summary"))
