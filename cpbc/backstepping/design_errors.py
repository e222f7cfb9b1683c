"""Errors of the backstepping designs; both derive from :class:`cpbc.errors.CpbcError`, and a
state outside a law's domain is a :class:`cpbc.errors.ConstraintViolation` (the one the closed
loop, cpbc.simulation.loop, ends a run on, for an arm's law and a Part I law alike)."""

from __future__ import annotations

from cpbc.errors import ConstraintViolation, CpbcError


class DesignError(CpbcError):
    """A design constant is invalid (not finite, not positive, or breaks a design condition).

    Attributes:
        parameter: the name of the offending constant, as the thesis writes it.
        value: the value given.
    """

    def __init__(self, parameter: str, value: float, reason: str) -> None:
        self.parameter = parameter
        self.value = value
        self.reason = reason
        super().__init__(f"design constant {parameter} = {value!r}: {reason}")


class OutsideDomainError(ConstraintViolation):
    """A state lies outside the domain D on which a barrier law is defined.

    Attributes:
        variable: the error variable that left its interval ("z1", "z2"); also
            ``constraint``, as for any ConstraintViolation.
        value: its value at the state.
        lower, upper: the open interval it must lie in.
        margin: the distance to the nearer end (≤ 0, or NaN for a NaN value).
    """

    def __init__(self, variable: str, value: float, lower: float, upper: float, why: str) -> None:
        self.variable = self.constraint = variable
        self.value = value
        self.lower = lower
        self.upper = upper
        self.margin = min(value - lower, upper - value)
        super(ConstraintViolation, self).__init__(  # its message, not ConstraintViolation's
            f"{variable} = {value:.6g} is outside the controller's domain ({lower:.6g}, "
            f"{upper:.6g}): {why}"
        )
