"""Brakes within the torque box, and whether one of them stops the arm.

Under bounded torque |τ_q| ≤ L a state of S is worth promising only if some torque in the box
can bring the arm to rest before every boundary. No closed form says which states can; a
*brake* — a feedback torque held for one control period at a time — held until the arm rests
says it for one state by construction. Three brakes, each computed from the model at the sample
(D, b = C ẋ + g + f, controller coordinates, τ = T⁻ᵀ τ_q) and held over the period h, and,
where the model has dry friction, each of them held against b without it as well
(:func:`holding_bias`, "…, friction left"):

* the **uniform** brake, b − D ẋ/h scaled toward b until it fits the box
  (:meth:`TorqueBox.toward`): ẍ = −t ẋ/h, every coordinate slowed in proportion to its speed
  (the brake of :class:`cpbc.constraints.stopping.Braking`, capped at rest in one period);
* the **least-squares** brake: the torque in the box whose acceleration is nearest to the one
  that stops every coordinate in one period,

      min ‖D⁻¹(T⁻ᵀ τ_q − b) + ẋ/h‖   subject to   −L ≤ τ_q ≤ L

  (a compiled bounded least squares, cpbc.kernels.bounded_lsq): each joint decelerates as
  hard as the box lets it, not only as hard as the weakest joint lets all of them;
* the **aimed** brake: the same problem with one more row, weighted ``aim_weight``, that asks
  the approach v_i = −∇φ_i · ẋ of the configuration constraint with the least first-order
  stopping margin (:func:`cpbc.constraints.stopping.stopping_terms`) to stop within the
  period, ∇φ_i · ẍ = v_i / h; the least-squares brake when nothing approaches.

:func:`brings_to_rest` holds a brake period after period in a given plant (the model, or the
true plant in a campaign) and says whether the arm comes to rest with every margin positive at
every step it reports.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.stopping import motion_rows, stopping_map
from cpbc.kernels.stopping_test import aimed_stop, nearest_stop
from cpbc.kernels.torque_box import box_around, box_clip, box_nearest, box_toward
from cpbc.model.robot_model import ArmState, RobotModel

_NO_ROW = np.zeros((1, 0))  # nearest_stop's aimed row where there is none (unread)


@dataclass(frozen=True, eq=False)
class TorqueBox:
    """The actuators' box lower ≤ Tᵀ τ ≤ upper in controller coordinates: |Tᵀ τ| ≤ L, or, at
    one control step under a torque-rate limit, that box narrowed to the torques one step can
    reach from the one the actuators hold (:meth:`around`).

    Attributes:
        limit: L, joint coordinates, shape (n,) [N·m].
        to_joint: Tᵀ (τ_q = Tᵀ τ), or None for joint coordinates.
        from_joint: T⁻ᵀ (τ = T⁻ᵀ τ_q), or None for joint coordinates.
        lower, upper: the box's joint-torque bounds; −L and L when omitted.
    """

    limit: Array
    to_joint: Array | None = None
    from_joint: Array | None = None
    lower: Array | None = None
    upper: Array | None = None

    @classmethod
    def of(cls, model: RobotModel, limit: Array | float) -> TorqueBox:
        coords = model.coordinates
        full = np.broadcast_to(np.asarray(limit, dtype=float), (model.n,)).copy()
        if coords.is_identity:
            return cls(full)
        return cls(full, coords.matrix.T.copy(), coords.inverse.T.copy())

    # lower, upper, Tᵀ, T⁻ᵀ and whether there is a map, as the kernels read them (writable
    # float copies; 0 × 0 maps for joint coordinates)
    _packed: tuple[Array, Array, Array, Array, bool] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        none = np.zeros((0, 0))
        limit = np.array(self.limit, dtype=float)
        object.__setattr__(self, "_packed", (
            -limit if self.lower is None else np.array(self.lower, dtype=float),
            limit if self.upper is None else np.array(self.upper, dtype=float),
            none if self.to_joint is None else np.array(self.to_joint, dtype=float),
            none if self.from_joint is None else np.array(self.from_joint, dtype=float),
            self.to_joint is not None))

    @property
    def packed(self) -> tuple[Array, Array, Array, Array, bool]:
        """(lower, upper, Tᵀ, T⁻ᵀ, whether there is a map), as the kernels read the box
        (cpbc.kernels.torque_box)."""
        return self._packed

    @property
    def bounds(self) -> tuple[Array, Array]:
        """(lower, upper) of the joint torques [N·m]."""
        return self._packed[0], self._packed[1]

    def around(self, held_q: Array, step: Array) -> TorqueBox:
        """The torques one control step can reach from the joint torques ``held_q`` that the
        actuators hold, under a rate limit of ``step`` = ρh per joint: |τ_q − held_q| ≤ ρh
        within the box. Where the held torque lies outside the box (a limit lowered under
        it), the reachable interval is the one nearest to the box
        (cpbc.kernels.torque_box.box_around)."""
        lower, upper = self.bounds
        lo, hi = np.empty(len(lower)), np.empty(len(lower))
        box_around(lower, upper, held_q, step, lo, hi)
        return self.with_bounds(lo, hi)

    def with_bounds(self, lower: Array, upper: Array) -> TorqueBox:
        """This box with the joint-torque bounds ``lower``, ``upper`` (fresh writable float
        arrays, kept as given), its maps shared with this one's, not copied: a guard under a
        rate limit narrows its box, and on a robot moves it by the robot's own torque, at
        every step."""
        box = object.__new__(TorqueBox)
        # the frozen fields set at once: 0.59 µs, against 0.93 for six object.__setattr__
        box.__dict__.update(limit=self.limit, to_joint=self.to_joint,
                            from_joint=self.from_joint, lower=lower, upper=upper,
                            _packed=(lower, upper, *self._packed[2:]))
        return box

    def joint(self, tau: Array) -> Array:
        return tau if self.to_joint is None else self.to_joint.dot(tau)

    def nearest(self, inertia: Array, tau: Array) -> Array:
        """τ itself when it fits the box, else the torque in the box whose acceleration is
        nearest to τ's, min ‖A(τ_q' − τ_q)‖ over lower ≤ τ_q' ≤ upper (A = D⁻¹T⁻ᵀ, the
        acceleration a joint torque τ_q gives, formed only then; one compiled call,
        cpbc.kernels.torque_box.box_nearest): each joint uses as much of
        its own interval as the acceleration asks, and the joints that cannot follow cost
        the acceleration as little as the coupling through D allows. (Scaling the whole
        change into the box — :meth:`toward` — lets the joint with the least room set every
        joint's share: under a torque-rate limit the FR3's light last joint got 0.14 N·m of
        its 1 N·m a period while its torque had to turn, and ran through its rate bound.)"""
        lower, upper, _, from_joint, mapped = self._packed
        tau_q = self.joint(tau)
        out = np.empty(len(tau_q))
        if not box_nearest(lower, upper, inertia, from_joint, mapped, tau_q, out):
            return tau
        return out if self.from_joint is None else self.from_joint.dot(out)

    def clip(self, tau: Array) -> Array:
        """τ with each joint torque clipped to its limit (cpbc.kernels.torque_box.box_clip)."""
        out = np.empty(len(tau))
        box_clip(*self._packed, tau, out)
        return out

    def toward(self, bias: Array, tau: Array) -> Array:
        """b + t (τ − b) with the largest t ∈ [0, 1] inside the box: the acceleration
        D⁻¹(τ − b) keeps its direction and only shrinks (τ itself when it fits). Where b alone
        exceeds a limit no scaling fits, and τ is clipped
        (cpbc.kernels.torque_box.box_toward)."""
        out = np.empty(len(tau))
        return tau if box_toward(*self._packed, bias, tau, out) == 0 else out


# a brake: (state, bias b, period h) -> the torque to hold over the period
Brake = Callable[[ArmState, Array, float], Array]


# the end of a brake's name where it is held against holding_bias
FRICTION_LEFT = ", friction left"


def holding_bias(model: RobotModel, state: ArmState) -> Array:
    """C ẋ + g + F_d ẋ, without the model's dry friction: a brake on it leaves the plant's
    dry friction, which only opposes the motion, to help it. Cancelling the model's smooth
    F_c tanh(q̇/ε) pushes a joint along its motion wherever the plant's friction is less than
    the model's, as MuJoCo's frictionloss is at low speed (it opposes the rate 1/b ahead):
    on the xArm7 with 2 N·m of friction on 0.01 kg·m² of wrist rotor every brake on the
    model's b held joint 7 creeping at 0.1 rad/s for good. In the model it is no
    better: its smooth friction then helps the brake more than MuJoCo's did under a hard
    brake (the rescue on it let the FR3 rate campaign's seed 60 cross)."""
    bias = state.coriolis_force + state.gravity
    if model.has_friction:
        bias = bias + model.viscous_friction.dot(state.dx)
    return bias


def uniform_brake(box: TorqueBox) -> Brake:
    """b − D ẋ/h scaled into the box."""

    def brake(state: ArmState, bias: Array, h: float) -> Array:
        return box.toward(bias, bias - state.inertia.dot(state.dx) / h)

    return brake


def _nearest_stop(box: TorqueBox, state: ArmState, bias: Array, h: float) -> Array:
    """The torque in the box nearest (least squares) to ẍ = −ẋ/h
    (cpbc.kernels.stopping_test.nearest_stop)."""
    out = np.empty(len(state.dx))
    nearest_stop(state.inertia, bias, state.dx, h, _NO_ROW, _NO_ROW[0], False, *box.packed,
                 out)
    return out


def least_squares_brake(box: TorqueBox) -> Brake:
    """The torque in the box nearest to stopping every coordinate in one period."""

    def brake(state: ArmState, bias: Array, h: float) -> Array:
        return _nearest_stop(box, state, bias, h)

    return brake


def aimed_brake(box: TorqueBox, constraints: ConstraintSet, model: RobotModel,
                aim_weight: float = 30.0) -> Brake:
    """The least-squares brake with the approach to the constraint of least stopping margin
    asked to stop within the period (its row weighted ``aim_weight``, gradient normalised)."""

    inverse, mapped, limit = stopping_map(model, box.limit)

    def brake(state: ArmState, bias: Array, h: float) -> Array:
        if not constraints.configuration:
            return _nearest_stop(box, state, bias, h)
        phi, grads, curvature, moving = motion_rows(constraints, model, state)
        out = np.empty(len(state.dx))  # stopping_terms, aim_row, nearest_stop in one call
        aimed_stop(phi, grads, curvature, moving.inertia, bias, moving.dx, inverse, mapped,
                   limit, h, aim_weight, *box.packed, out)
        return out

    return brake


def friction_left(brake: Brake, model: RobotModel) -> Brake:
    """``brake`` held against :func:`holding_bias` in place of the b it is given."""

    def left(state: ArmState, bias: Array, h: float) -> Array:
        return brake(state, holding_bias(model, state), h)

    return left


def brakes(box: TorqueBox, constraints: ConstraintSet,
           model: RobotModel) -> dict[str, Brake]:
    """The brakes of the module docstring, by name, in the order they are tried: the three
    on the model's b, then, where the model has dry friction, the same three on b without
    it (:data:`FRICTION_LEFT` ends their names)."""
    table = {"uniform": uniform_brake(box), "least_squares": least_squares_brake(box),
             "aimed": aimed_brake(box, constraints, model)}
    if model.coulomb_friction.any():
        table.update({name + FRICTION_LEFT: friction_left(brake, model)
                      for name, brake in list(table.items())})
    return table


# a plant to brake in: holds τ (controller coordinates) for one period from its present state,
# returns the states it passed (rows of x and ẋ, the period's end last), or None if it diverged
Advance = Callable[[Array], "tuple[Array, Array] | None"]


@dataclass(frozen=True)
class Stop:
    """The outcome of holding one brake until rest.

    Attributes:
        stopped: the arm came to rest with every margin above its floor throughout.
        periods: control periods held.
        low: the smallest margin less its floor over every reported step.
    """

    stopped: bool
    periods: int
    low: float


class Rollout:
    """One brake held in a plant from (x, ẋ), period after period, until the arm rests with
    every margin above its floor, or a margin falls to it, or ``horizon`` seconds pass; run a
    bounded number of periods at a time (:meth:`run`), so that a check can be spread over
    several control periods (the rescue's budget, cpbc.controllers.rescue).

    Args:
        brake: recomputed at every sample from ``model``.
        model: the model the brake is computed from.
        margins: each reported step's margins less their floors (rows).
        advance: the plant that holds the brake's torque for a period.
        x, dx: the start.
        h: the control period [s].
        rest: max|ẋ| under which the arm rests.
        horizon: the longest braking held [s].
    """

    def __init__(self, brake: Brake, model: RobotModel,
                 margins: Callable[[Array, Array], Array], advance: Advance, x: Array,
                 dx: Array, h: float, rest: float = 1e-3, horizon: float = 3.0) -> None:
        self.brake, self.model, self.margins, self.advance = brake, model, margins, advance
        self.x, self.dx, self.h, self.rest = x, dx, h, rest
        self.periods = max(math.ceil(horizon / h), 1)
        self.held = 0  # periods held so far
        self.low = math.inf  # the least margin less its floor so far
        self.outcome: Stop | None = None

    def run(self, budget: int | None = None) -> Stop | None:
        """Hold the brake for at most ``budget`` more periods (to the end without one); the
        outcome once it is decided, else None (the check goes on at the next call)."""
        if self.outcome is not None:
            return self.outcome
        if float(np.max(np.abs(self.dx))) <= self.rest:  # at rest already
            return self._decided(Stop(self.low > 0.0, self.held, self.low))
        end = self.periods if budget is None else min(self.periods, self.held + budget)
        while self.held < end:
            state = self.model.state(self.x, self.dx)
            bias = state.coriolis_force + state.gravity + state.dissipation
            rows = self.advance(self.brake(state, bias, self.h))
            self.held += 1
            if rows is None:
                return self._decided(Stop(False, self.held, -math.inf))
            xs, dxs = rows
            m = self.margins(xs, dxs)
            least = float(m.min()) if m.size else math.inf
            if least != least:  # a NaN margin counts as −∞
                least = -math.inf
            self.low = min(self.low, least)
            if not self.low > 0.0:
                return self._decided(Stop(False, self.held, self.low))
            self.x, self.dx = xs[-1], dxs[-1]
            if float(np.max(np.abs(self.dx))) <= self.rest:
                return self._decided(Stop(self.low > 0.0, self.held, self.low))
        if self.held >= self.periods:
            return self._decided(Stop(False, self.periods, self.low))
        return None

    def _decided(self, stop: Stop) -> Stop:
        self.outcome = stop
        return stop


def brings_to_rest(brake: Brake, model: RobotModel, margins: Callable[[Array, Array], Array],
                   advance: Advance, x: Array, dx: Array, h: float, rest: float = 1e-3,
                   horizon: float = 3.0) -> Stop:
    """Hold ``brake`` (recomputed at every sample from ``model``) in the plant ``advance``
    from (x, ẋ) until max|ẋ| ≤ ``rest``; ``margins`` gives each reported step's margins less
    their floors (rows). At most ``horizon`` seconds (:class:`Rollout`, run to its end)."""
    stop = Rollout(brake, model, margins, advance, x, dx, h, rest, horizon).run()
    assert stop is not None  # decided: no budget
    return stop


def ramped(box: TorqueBox, tau: Array, rate_step: Array | None,
           held_q: Array | None, inertia: Array | None = None) -> Array:
    """τ clipped to the box and, under a torque-rate limit (``rate_step`` = ρh per joint),
    what one step reaches of it from the held joint torque ``held_q``: with the inertia D at
    the state, the reachable torque whose acceleration is nearest to τ's
    (:meth:`TorqueBox.nearest`, as the safeguard reaches its torques); without, along the
    straight line τ_h + s(τ − τ_h) (every joint's torque arrives together: a stop ramp that
    needs no model)."""
    tau = box.clip(tau)
    if rate_step is None or held_q is None:
        return tau
    step = box.around(held_q, rate_step)
    if inertia is not None:
        return step.nearest(inertia, tau)
    held = held_q if box.from_joint is None else box.from_joint.dot(held_q)
    return step.toward(held, tau)


def model_advance(model: RobotModel, box: TorqueBox, x: Array, dx: Array, h: float,
                  steps: int, rate_step: Array | None = None,
                  held: Array | None = None) -> Advance:
    """The model as a plant from (x, ẋ): ``steps`` semi-implicit Euler steps per period of
    its forward dynamics, the torque clipped to the box; under a torque-rate limit
    (``rate_step`` = ρh per joint, from the torque ``held`` the actuators hold, controller
    coordinates) reached from the last torque held as one period allows (:func:`ramped`, with
    the model's inertia at the period's start, as the safeguard reaches it)."""
    now = [x.copy(), dx.copy()]
    dt = h / steps
    last = [None if held is None else box.joint(held)]

    def advance(tau: Array) -> tuple[Array, Array] | None:
        inertia = None if rate_step is None else model.inertia(now[0])
        tau = ramped(box, tau, rate_step, last[0], inertia)
        last[0] = box.joint(tau)
        xs, vs = now
        rows_x, rows_v = [], []
        for _ in range(steps):
            vs = vs + dt * model.forward_dynamics(xs, vs, tau)
            xs = xs + dt * vs
            rows_x.append(xs)
            rows_v.append(vs)
        if not np.all(np.isfinite(vs)):
            return None
        now[:] = [xs, vs]
        return np.array(rows_x), np.array(rows_v)

    return advance


def first_stop(names: Sequence[str], table: dict[str, Brake], run: Callable[[Brake], Stop],
               ) -> tuple[str | None, Stop | None]:
    """The first brake of ``names`` that stops the arm (``run`` holds one until rest)."""
    last = None
    for name in names:
        last = run(table[name])
        if last.stopped:
            return name, last
    return None, last
