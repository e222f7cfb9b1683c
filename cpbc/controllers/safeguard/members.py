"""What the guard's parts read of the guard: the attributes and the torque-box method that
:class:`cpbc.controllers.safeguard.guard.Safeguard` provides to the parts it mixes in
(acceptance, brakes), declared once so that each part type-checks on its own."""

from __future__ import annotations

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.stopping import Braking
from cpbc.controllers.rescue import Rescue
from cpbc.controllers.safeguard.predicted_margins import PredictedMargins, RampTest
from cpbc.controllers.safeguard.settings import SafeguardSettings
from cpbc.model.robot_model import RobotModel


class GuardMembers:
    """The guard's state as its mixed-in parts see it (set by ``Safeguard.__init__``)."""

    model: RobotModel
    period: float
    settings: SafeguardSettings
    guarded: ConstraintSet
    along: PredictedMargins  # the guarded margins along a prediction, F (compiled)
    cushion: Array
    keep: float
    keep_half: float
    hold_share: float
    travel: float
    calls: int
    infeasible: int
    uncorrected: int
    scaled: int
    rescues: int
    rescue: Rescue | None
    braking: Braking | None
    _n_config: int
    _sigma_floor: Array
    _holding: Array | None  # the torque the actuators hold, under a torque-rate limit
    _rate_step: Array | None  # ρh per joint, under a torque-rate limit
    _ramp: RampTest | None  # this step's velocity lookahead under a torque-rate limit

    def _box(self, bias: Array, tau: Array, brake: bool = False) -> Array:
        raise NotImplementedError
