"""Plant descriptions of the Part-I systems (MJCF, state and input maps, constraints, ODE;
the integrator chain of §4.4 is an ODE only, the Aerosonde of Ch. 5 an ODE whose MJCF only
replays its path)."""

from cpbc.systems.aerosim import AerosondeParameters
from cpbc.systems.aerosonde import AerosondePlant, AirspeedLoop
from cpbc.systems.integrator_chain import IntegratorChain
from cpbc.systems.ode_plant import ConstrainedQuantity, OdePlant, Plant
from cpbc.systems.quarter_car import QuarterCar
from cpbc.systems.reaction_wheel_pendulum import ReactionWheelPendulum
from cpbc.systems.road import HaversineBump

__all__ = [
    "AerosondeParameters",
    "AerosondePlant",
    "AirspeedLoop",
    "ConstrainedQuantity",
    "HaversineBump",
    "IntegratorChain",
    "OdePlant",
    "Plant",
    "QuarterCar",
    "ReactionWheelPendulum",
]
