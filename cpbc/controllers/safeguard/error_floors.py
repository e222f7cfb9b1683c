"""The floors of (S1) raised by the errors the safeguard holds (step 3 of the package
docstring): what the model's acceleration error — declared, its smooth Coulomb friction's, a
declared inertia error's — can take off each margin in one period, and what a measurement error
can hide (cpbc.controllers.safeguard.model_error).

A margin's loss is first order in its slope, ∇φ_i at the state, which for a clearance takes the
closest pairs' gradients from the joint Jacobians: about a third of a calm guarded step on the
FR3, whose Coulomb friction makes every step hold an error. The step's first test (the law's
torque, which passes on a calm step) raises its floors by a bound of the slope instead, each
sphere constraint's reach (MarginSlopes.bounding), which only takes more off: a torque that
passes under those floors passes under the exact ones. Where it fails, the floors are made
exact in place before the test's F is taken again (:meth:`ErrorFloors.raise_floors`'s
``refine``), so that every F the guard acts on is the one the exact floors give, and the
torques are those of the exact floors.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.margin_slopes import MarginSlopes
from cpbc.controllers.safeguard.model_error import (
    DeclaredError,
    friction_error,
    margin_losses,
    measurement_losses,
    mujoco_friction,
)
from cpbc.controllers.safeguard.step_box import StepBox
from cpbc.kernels.margin_losses import friction_floors
from cpbc.kernels.small_solves import inverse_inertia
from cpbc.model.robot_model import ArmState, RobotModel

Refine = Callable[[], None]  # makes a step's floors, raised by bounds, exact in place


class ErrorFloors:
    """The errors one guard holds and how they raise its floors.

    Args:
        guarded: the constraints the guard keeps.
        model: the controller's model (its Coulomb friction is an error held).
        box: the step's input bounds (the torques a step may hold: the friction's reach).
        model_error: ā, the declared bound on the acceleration error per coordinate, or None.
        declared: a declared inertia error and measurement errors, or None.
        period, travel: h and c of the predicted end x + hẋ + c h² a.
        cushion: δ_i, every guarded margin's.

    Attributes:
        exact: no error is held: the floors stay (S1)'s.
    """

    def __init__(self, guarded: ConstraintSet, model: RobotModel, box: StepBox,
                 model_error: Array | None, declared: DeclaredError | None, period: float,
                 travel: float, cushion: Array) -> None:
        self.guarded, self.model, self.box = guarded, model, box
        self.model_error, self.declared = model_error, declared
        self.period, self.travel, self.cushion = period, travel, cushion
        self._inertia_error = None if declared is None else declared.acceleration_bound(model)
        self._coulomb = bool(np.any(model.coulomb_friction))
        self._dry = mujoco_friction(model)  # how the plant's dry friction takes its sign
        self.exact = model_error is None and not self._coulomb and (
            declared is None or not (declared.dynamic or declared.measured))
        self._measured = declared if declared is not None and declared.measured else None
        # the first test's floors from slope bounds: only where a kind has a cheaper one
        self._bounded = self._measured is None and guarded.gradients_bounded
        self._friction_only = (self._coulomb and model_error is None and self._measured is None
                               and self._inertia_error is None)

    def raise_floors(self, state: ArmState, bias: Array, tau: Array, floor: Array,
                     mid: Array) -> Refine | None:
        """The floors of (S1), in place, raised by whatever the model's error can take off
        each margin in one period (model_error.margin_losses), and to at least what a
        measurement error can hide above the cushion (measurement_losses): the true margin
        then ends above its cushion too. Raised by the slopes' bounds (the module
        docstring), it returns ``refine``, which raises them from (S1)'s again by the
        exact slopes; else None."""
        if self.exact:
            return None
        box = self.box.reachable
        fused = self._friction_only and box is not None
        error = None if fused else self._error_bound(state, bias, tau)
        if not fused and error is None and self._measured is None:
            return None
        bounded = self._bounded  # then no measurement error, and an error bound to hold
        base = (floor.copy(), mid.copy()) if bounded else None
        slopes = (MarginSlopes.bounding if bounded else MarginSlopes.at)(self.guarded, state)
        if fused:
            assert box is not None
            error = self._raise_by_friction(state, bias, box.bounds, slopes, floor, mid)
        else:
            self._raise(state, error, slopes, floor, mid)
        if base is None:
            return None

        def refine() -> None:
            floor[:], mid[:] = base
            self._raise(state, error, MarginSlopes.at(self.guarded, state), floor, mid)

        return refine

    def _raise_by_friction(self, state: ArmState, bias: Array, bounds: tuple[Array, Array],
                           slopes: MarginSlopes, floor: Array, mid: Array) -> Array:
        """The floors raised, in place, where the smooth Coulomb friction is the only error
        held and the step has a torque box: the bound and the losses at ``slopes`` in one
        call (cpbc.kernels.margin_losses.friction_floors: _error_bound's friction_error and
        :meth:`_raise`'s margin_losses, the same sums). Returns the bound ā."""
        model, coords, plant = self.model, self.model.coordinates, self._dry
        error = np.empty(model.n)
        friction_floors(state.inertia, coords.inverse, not coords.is_identity,
                        model.coulomb_friction, model.friction_smoothing, plant.build_up,
                        plant.creep, state.dx, bias, *bounds, self.period, self.travel,
                        slopes.configuration, slopes.weights, floor, mid, error)
        return error

    def _raise(self, state: ArmState, error: Array | None, slopes: MarginSlopes,
               floor: Array, mid: Array) -> None:
        """The floors raised, in place, by ``error``'s losses and the measurement's, at
        ``slopes`` (read once for both errors)."""
        if error is not None:
            end_loss, mid_loss = margin_losses(self.guarded, state, error, self.period,
                                               self.travel, slopes)
            floor += end_loss
            mid += mid_loss
        measured = self._measured
        if measured is not None:
            end_loss, mid_loss = measurement_losses(self.guarded, state, measured,
                                                    self.period, slopes)
            np.maximum(floor, end_loss + self.cushion, out=floor)
            np.maximum(mid, mid_loss + self.cushion[: len(mid)], out=mid)

    def _error_bound(self, state: ArmState, bias: Array, tau: Array) -> Array | None:
        """The bound on the model's acceleration error at this state: the declared one plus
        its smooth Coulomb friction's (model_error.friction_error) plus a declared inertia
        error's at the law's acceleration D⁻¹(τ − b) (model_error.InertiaError), or None."""
        inertia_error = self._inertia_error
        # D⁻¹ once a step for every bound that reads it
        inverse = inverse_inertia(state.inertia) if (
            self._coulomb or inertia_error is not None) else None
        parts = [p for p in (self.model_error, self._friction_error(state, bias, inverse)
                             if inverse is not None and self._coulomb else None)
                 if p is not None]
        if inertia_error is not None and inverse is not None:
            parts.append(inertia_error.bound(state, inverse @ (tau - bias), inverse))
        return sum(parts[1:], parts[0]) if parts else None

    def _friction_error(self, state: ArmState, bias: Array, inverse: Array) -> Array | None:
        """model_error.friction_error over this period, for the accelerations of the torques
        this step may hold (the step's box; any without a torque box); ``inverse``: D⁻¹."""
        box = self.box.reachable
        return friction_error(self.model, state, None, self.period, self._dry, inverse,
                              torques=None if box is None else (bias, *box.bounds))
