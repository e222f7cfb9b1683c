"""Exception hierarchy: every error cpbc raises on purpose derives from :class:`CpbcError`."""

from __future__ import annotations


class CpbcError(Exception):
    """Root of cpbc's errors. The CLI turns these into a message and exit code 2."""


class ModelError(CpbcError):
    """A robot model file is missing, malformed, or lacks a named joint/frame."""


class InadmissibleStateError(CpbcError):
    """A state lies outside the admissible set S (Assumption 6.8).

    Attributes:
        what: which state ("target", "initial state of case 'x'", ...).
        constraint: name of the first violated constraint.
        margin: its value (<= 0).
    """

    def __init__(self, what: str, constraint: str, margin: float) -> None:
        self.what = what
        self.constraint = constraint
        self.margin = margin
        super().__init__(
            f"{what} is outside the admissible set: constraint '{constraint}' has margin "
            f"{margin:.6g} (must be > 0). Move the state inside every constraint, or relax "
            f"the constraint."
        )


class ConstraintViolation(CpbcError):
    """Raised by a constrained controller asked for a torque at a state outside S."""

    def __init__(self, constraint: str, margin: float) -> None:
        self.constraint = constraint
        self.margin = margin
        super().__init__(f"constraint '{constraint}' crossed its boundary (margin {margin:.3g})")


class ScenarioError(CpbcError):
    """A scenario file is invalid. ``field`` is the dotted path of the offending entry."""

    def __init__(self, field: str, message: str) -> None:
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}" if field else message)
