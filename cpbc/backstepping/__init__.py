"""Backstepping designs with barrier Lyapunov functions (Part I, Chapter 3).

One law per module: :class:`NonStrictClfLaw` (§3.1, Prop. 3.2/Thm 3.6), :class:`IssClfLaw`
(§3.2, Thm 3.8), :class:`TwoConstraintLaw` (§3.4, Prop. 3.11/Thm 3.13), and their applications
:class:`SuspensionController` (§3.3) and :class:`ReactionWheelController` (§3.5). The laws are
pure functions of the state: they never import MuJoCo.
"""

from cpbc.backstepping.barriers import Barrier, LogBarrier, QuadraticTerm, RationalBarrier
from cpbc.backstepping.cascade import Cascade, FirstStep, Rated
from cpbc.backstepping.errors import DesignError, OutsideDomainError
from cpbc.backstepping.iss_clf import IssCascade, IssClfLaw, companion
from cpbc.backstepping.nonstrict_clf import NonStrictClfLaw
from cpbc.backstepping.reaction_wheel import (
    ReactionWheelController,
    WheelPendulumBounds,
    WheelPendulumConstants,
    WheelPendulumGains,
)
from cpbc.backstepping.suspension import (
    QuarterCarConstants,
    SuspensionController,
    SuspensionGains,
)
from cpbc.backstepping.two_constraints import Growth, TwoConstraintLaw
from cpbc.backstepping.virtual_control import VirtualControl, virtual_control

__all__ = [
    "Barrier",
    "Cascade",
    "DesignError",
    "FirstStep",
    "Growth",
    "IssCascade",
    "IssClfLaw",
    "LogBarrier",
    "NonStrictClfLaw",
    "OutsideDomainError",
    "QuadraticTerm",
    "QuarterCarConstants",
    "Rated",
    "RationalBarrier",
    "ReactionWheelController",
    "SuspensionController",
    "SuspensionGains",
    "TwoConstraintLaw",
    "VirtualControl",
    "WheelPendulumBounds",
    "WheelPendulumConstants",
    "WheelPendulumGains",
    "companion",
    "virtual_control",
]
