"""The types of margin the results know: a key, a label and a unit each.

A margin is a constraint's distance to its bound in a unit a person can compare. Every arm
constraint class (cpbc.constraints.margins) and every constrained quantity of a Part I system
(cpbc.systems.ode_plant) declares the type of its margins; the results (summaries, logs,
figures, the page) group and label margins by it. This table sits below every layer, beside
cpbc.arrays and cpbc.errors, so that both can declare theirs.

==============  =============================================  ======
type            margin reported                                unit
==============  =============================================  ======
position        distance of a coordinate to its nearer limit   rad
                (joint and relative-joint limits)
rate            B − |aᵀẋ|, rate headroom (and a Part I         rad/s
                pendulum's rate)
travel          a position limit on prismatic joints           m
speed           a rate limit on prismatic joints               m/s
clearance       distance between robot and obstacle            m
energy          Ω − ½ẋᵀDẋ, kinetic-energy headroom             J
deflection      a suspension's deflection to its travel        m
climb           a climb rate to its bound                      m/s
angle           an angle (of attack, of a control surface)     rad
input_torque    a system's input torque to its limit           N m
state           a dimensionless state to its bound             (none)
                (the integrator chain of §4.4)
==============  =============================================  ======

A limit whose row mixes revolute and prismatic coordinates has no one unit: it is "other".
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MarginType:
    """A family of constraints whose margins share a unit.

    Attributes:
        key: short name used in summary.json and the viewer ("position", "rate", …).
        label: heading of its figure panel and table entry.
        unit: unit of its margins.
    """

    key: str
    label: str
    unit: str


POSITION = MarginType("position", "position limits", "rad")
RATE = MarginType("rate", "rate limits", "rad/s")
TRAVEL = MarginType("travel", "prismatic position limits", "m")
SPEED = MarginType("speed", "prismatic rate limits", "m/s")
CLEARANCE = MarginType("clearance", "clearance", "m")
ENERGY = MarginType("energy", "kinetic energy", "J")
# the Part I systems' constrained quantities (Chapters 3–5)
DEFLECTION = MarginType("deflection", "suspension deflection", "m")
CLIMB = MarginType("climb", "climb rate", "m/s")
ANGLE = MarginType("angle", "angle limits", "rad")
INPUT_TORQUE = MarginType("input_torque", "input torque", "N m")
STATE = MarginType("state", "state bounds", "")
OTHER = MarginType("other", "other constraints", "")
#: Every type, in the order figures and tables show them.
TYPES: tuple[MarginType, ...] = (POSITION, RATE, TRAVEL, SPEED, CLEARANCE, ENERGY,
                                 DEFLECTION, CLIMB, ANGLE, INPUT_TORQUE, STATE, OTHER)
BY_KEY = {t.key: t for t in TYPES}
