"""Exception hierarchy: every error cpbc raises on purpose derives from :class:`CpbcError`."""

from __future__ import annotations


class CpbcError(Exception):
    """Root of cpbc's errors. The CLI turns these into a message and exit code 2."""


class ModelError(CpbcError):
    """A robot model file is missing, malformed, or lacks a named joint/frame.

    Attributes:
        parameter: the loader's argument at fault (``locked_joints``), or None when it is
            the model file itself.
    """

    def __init__(self, message: str, parameter: str | None = None) -> None:
        self.parameter = parameter
        super().__init__(message)

    def __reduce__(self) -> tuple[object, ...]:  # survives pickling to and from workers
        return type(self), (str(self), self.parameter)


class ParameterError(CpbcError, ValueError):
    """A named constructor argument is invalid (``kp``, ``mass_scale``, …): a ``ValueError``
    too, as Python callers expect of a bad argument.

    Attributes:
        parameter: the argument's name, so that a caller can map it to its own field.
    """

    def __init__(self, parameter: str, message: str) -> None:
        self.parameter = parameter
        super().__init__(message)

    def __reduce__(self) -> tuple[object, ...]:
        return type(self), (self.parameter, str(self))


class InadmissibleStateError(CpbcError):
    """A state lies outside the admissible set S (Assumption 6.8).

    Attributes:
        what: which state ("target", "initial state of case 'x'", ...).
        constraint: name of the first violated constraint.
        margin: its value (<= 0).
        field: the scenario entry of the state (``target``, ``cases[0]``), set by the
            scenario builder; None elsewhere.
    """

    def __init__(self, what: str, constraint: str, margin: float,
                 field: str | None = None) -> None:
        self.what = what
        self.constraint = constraint
        self.margin = margin
        self.field = field
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


class NonFiniteState(ConstraintViolation, ParameterError):
    """A state handed to a law is not finite (a NaN or an infinity in ``x`` or ``dx``): a
    ``ValueError`` naming the argument (``parameter``), as a bad argument is, and a
    ConstraintViolation too, so that a loop that refuses a state outside S (the reference
    integrator's trial stages, computed from NaN) refuses this one alike.

    Attributes:
        parameter: ``x`` or ``dx``.
        constraint: the same name (what a loop reports as crossed).
        margin: NaN.
    """

    def __init__(self, parameter: str, message: str) -> None:
        self.parameter = self.constraint = parameter
        self.margin = float("nan")
        Exception.__init__(self, message)


class ScenarioError(CpbcError):
    """A scenario file is invalid. ``field`` is the dotted path of the offending entry."""

    def __init__(self, field: str, message: str) -> None:
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}" if field else message)

    def __reduce__(self) -> tuple[object, ...]:
        return _rebuild_scenario_error, (self.field, self.message, self.args)


def _rebuild_scenario_error(field: str, message: str, args: tuple[object, ...]) -> ScenarioError:
    err = ScenarioError(field, message)
    err.args = args  # format_validation_error replaces the text with every error's line
    return err
