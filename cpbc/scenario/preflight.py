"""Before a run: can the motors hold the arm up at the target and along the way there?

A target whose gravity load exceeds a motor's limit is refused (no law can hold it); a
case whose straight path to the target leaves a motor no room to brake over gravity
(cpbc.model.gravity_load) is run with a warning, which a failed run then names as its
likely cause.
"""

from __future__ import annotations

from collections.abc import Sequence

from cpbc.arrays import Array
from cpbc.errors import ScenarioError
from cpbc.model.gravity_load import GravityLoad, heaviest_on_path, unheld
from cpbc.model.robot_model import RobotModel


def check_gravity(model: RobotModel, target: Array, starts: Sequence[tuple[str, Array]],
                  limit: Array) -> dict[str, GravityLoad]:
    """Refuse a target the motors cannot hold; the worst load on each case's path (by case
    name) where the brake lacks room.

    Args:
        model: the controller's model.
        target: x_d, controller coordinates.
        starts: (case name, initial position) of every case.
        limit: the joint torque limits [N·m].
    """
    load = unheld(model, target, limit)
    if load is not None:
        raise ScenarioError(
            "target", f"the motors cannot hold the arm there: {load.describe()}. Choose a "
            "target where gravity pulls less on that joint, or raise simulation.torque_limit")
    paths = {name: heaviest_on_path(model, start, target, limit) for name, start in starts}
    return {name: load for name, load in paths.items() if load is not None}


def warning(case: str, load: GravityLoad) -> str:
    """The line printed before the runs; a run of the case that fails names the load as its
    cause (RunSummary.cause)."""
    return f"case '{case}': {load.describe()}; the safeguard may find no torque to brake with"

