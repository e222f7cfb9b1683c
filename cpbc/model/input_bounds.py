"""The input bounds: what the actuators can do and how often the controller speaks to them.

One value per scenario, built once (cpbc.scenario.loop_setup) and read by everything that
must respect it: the safeguard (cpbc.controllers.safeguard), the CBF-QP peer, the plant
(cpbc.simulation.loop: the motor that can do no more), a robot's backend (cpbc.hardware) and
the summary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ParameterError


@dataclass(frozen=True, eq=False)
class InputBounds:
    """|τ_q,i| ≤ torque_i and |τ̇_q,i| ≤ rate_i per joint, the command held for ``period``.

    Attributes:
        period: the control period h [s] (zero-order hold), > 0.
        torque: joint torque limits [N·m], one per joint or one for every joint, or None
            (unbounded).
        rate: joint torque-rate limits [N·m/s], likewise, or None (unbounded): a command
            moves at most ρ_i h from the one before it.
    """

    period: float
    torque: Array | None = None
    rate: Array | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.period) and self.period > 0):
            raise ParameterError("period", f"control period must be > 0 [s], got {self.period}")
        for name in ("torque", "rate"):
            given = getattr(self, name)
            if given is None:
                continue
            value = np.array(given, dtype=float).reshape(-1)
            if value.size == 0 or np.any(np.isnan(value)) or not np.all(value > 0):
                raise ParameterError(name, f"{name} limits must be > 0 per joint, got {given}")
            object.__setattr__(self, name, value)

    @property
    def step(self) -> Array | None:
        """ρh: how far one control period can move each joint torque, or None."""
        return None if self.rate is None else self.rate * self.period
