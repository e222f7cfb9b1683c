"""Backstepping designs with barrier Lyapunov functions (Part I, Chapters 3 to 5).

One law per module: :class:`NonStrictClfLaw` (§3.1, Prop. 3.2/Thm 3.6), :class:`IssClfLaw`
(§3.2, Thm 3.8; with :class:`StrictFeedbackIss`, §4.2, Thm 4.4), :class:`TwoConstraintLaw`
(§3.4, Prop. 3.11/Thm 3.13), :class:`MultipleConstraintLaw` (§4.3, Thm 4.12), and their
applications :class:`SuspensionController` (§3.3), :class:`ReactionWheelController` (§3.5),
:class:`IntegratorChainController` (§4.4) and the Aerosonde's altitude laws
:class:`TraditionalAltitudeLaw` (§5.3) and :class:`ConstrainedAltitudeLaw` (§5.4).
Chapter 4's systems are :class:`StrictFeedback` subclasses whose time derivatives come from
Taylor jets (:mod:`cpbc.backstepping.jets`), as do Chapter 5's α̇_ref and q̇_ref. The laws are
pure functions of the state: they never import MuJoCo.
"""

from cpbc.backstepping.altitude_backstepping import (
    TraditionalAltitudeGains,
    TraditionalAltitudeLaw,
)
from cpbc.backstepping.altitude_command import AltitudeCommand, TrackingLaw
from cpbc.backstepping.altitude_model import AltitudeModel
from cpbc.backstepping.barrier_terms import Barrier, LogBarrier, QuadraticTerm, RationalBarrier
from cpbc.backstepping.cascade import Cascade, FirstStep, Rated
from cpbc.backstepping.constrained_altitude import (
    ConstrainedAltitudeGains,
    ConstrainedAltitudeLaw,
)
from cpbc.backstepping.design_errors import DesignError, OutsideDomainError
from cpbc.backstepping.integrator_chain_law import (
    ChainGains,
    ChainSystem,
    IntegratorChainController,
)
from cpbc.backstepping.iss_clf import IssCascade, IssClfLaw, companion
from cpbc.backstepping.multiple_constraints import LawTerms, MultipleConstraintLaw
from cpbc.backstepping.nonstrict_clf import NonStrictClfLaw
from cpbc.backstepping.reaction_wheel import (
    ReactionWheelController,
    WheelPendulumBounds,
    WheelPendulumConstants,
    WheelPendulumGains,
)
from cpbc.backstepping.strict_feedback import StrictFeedback, nominal_jets
from cpbc.backstepping.suspension import (
    QuarterCarConstants,
    SuspensionController,
    SuspensionGains,
)
from cpbc.backstepping.two_constraints import Growth, TwoConstraintLaw
from cpbc.backstepping.virtual_control import VirtualControl, virtual_control

__all__ = [
    "AltitudeCommand",
    "AltitudeModel",
    "Barrier",
    "Cascade",
    "ChainGains",
    "ChainSystem",
    "ConstrainedAltitudeGains",
    "ConstrainedAltitudeLaw",
    "DesignError",
    "FirstStep",
    "Growth",
    "IntegratorChainController",
    "IssCascade",
    "IssClfLaw",
    "LawTerms",
    "LogBarrier",
    "MultipleConstraintLaw",
    "NonStrictClfLaw",
    "OutsideDomainError",
    "QuadraticTerm",
    "QuarterCarConstants",
    "Rated",
    "RationalBarrier",
    "ReactionWheelController",
    "StrictFeedback",
    "SuspensionController",
    "SuspensionGains",
    "TrackingLaw",
    "TraditionalAltitudeGains",
    "TraditionalAltitudeLaw",
    "TwoConstraintLaw",
    "VirtualControl",
    "WheelPendulumBounds",
    "WheelPendulumConstants",
    "WheelPendulumGains",
    "companion",
    "nominal_jets",
    "virtual_control",
]
