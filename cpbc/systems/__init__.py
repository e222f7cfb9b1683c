"""Plant descriptions of the Part-I systems (MJCF, state and input maps, constraints, ODE)."""

from cpbc.systems.plant import ConstrainedQuantity, Plant
from cpbc.systems.quarter_car import QuarterCar
from cpbc.systems.reaction_wheel_pendulum import ReactionWheelPendulum
from cpbc.systems.road import HaversineBump

__all__ = ["ConstrainedQuantity", "HaversineBump", "Plant", "QuarterCar", "ReactionWheelPendulum"]
