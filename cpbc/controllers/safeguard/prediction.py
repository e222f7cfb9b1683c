"""The safeguard's prediction of one control period under a held torque (step 2 of the package
docstring): in closed form with the dynamics frozen at the sample (and, with the corrector, to
second order beside it), or in semi-implicit Euler sub-steps of the model's forward dynamics
(with Heun's steps beside them)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.brakes import TorqueBox
from cpbc.kernels.frozen_slack import clipped_start
from cpbc.kernels.sampled_guard import frozen_rows
from cpbc.model.robot_model import ArmState, RobotModel

# (mid-period positions, end positions, end rates, then positions and rates inside the
# period), one row per prediction (per prediction and sub-step for the inner ones)
Predictor = Callable[[Array], "tuple[Array, Array, Array, Array, Array]"]
# no box: (lower, upper, Tᵀ, T⁻ᵀ, mapped, clip) as clipped_start reads them
_NO_BOX = (np.zeros(0), np.zeros(0), np.zeros((0, 0)), np.zeros((0, 0)), False, False)


def travel_share(period: float, plant_step: float | None) -> float:
    """c of the end position x + hẋ + c h² a that a held acceleration a gives over one
    period h. In continuous time (an arm, an RK4 plant: ``plant_step`` None) c = ½. A plant
    stepped k = h / plant_step times a period by a one-stage (semi-implicit Euler)
    integrator, v ← v + (h/k) a then x ← x + (h/k) v, moves (h/k)² a (1 + 2 + … + k):
    c = ½ (1 + 1/k), and c = 1 at one step per period. Predicting ½ there leaves the
    prediction short by ½h² ∇φ·a on every margin φ, a bias of one sign wherever the law
    pushes into a boundary (2–4 μm a period on the Panda figure-8's clearance at 1 kHz,
    more than its cushion wins back: the margin was worn to 7e-7 m)."""
    if plant_step is None:
        return 0.5
    k = max(round(period / plant_step), 1)
    return 0.5 * (1.0 + 1.0 / k)


class Frozen:
    """The frozen closed form under a held τ, its end at x + hẋ + c h² a with c = ``travel``
    (:func:`travel_share`: where the plant's own steps land), and with ``corrector`` the
    second-order prediction in continuous time beside it (a second row): a Predictor, and
    its :meth:`start`, the accelerations the compiled test reads (PredictedMargins.
    frozen_slack), which makes the rows itself. ``box``: the step's box each torque is
    clipped to, as the actuators would apply it (StepBox.reachable), or None."""

    __slots__ = ("_box", "bias", "corrector", "dx", "h", "inertia", "model", "rows", "travel", "x")

    def __init__(self, model: RobotModel, state: ArmState, bias: Array, h: float,
                 box: TorqueBox | None, corrector: bool, travel: float) -> None:
        self.model, self.x, self.dx, self.inertia = model, state.x, state.dx, state.inertia
        self.bias, self.h, self.corrector, self.travel = bias, h, corrector, travel
        self.rows = 2 if corrector else 1  # predictions
        self._box = _NO_BOX if box is None else (*box.packed, True)

    def start(self, t: Array) -> tuple[Array, Array]:
        """(a, the model's acceleration at the continuous-time end — a itself without the
        corrector) under τ = ``t`` clipped to the box."""
        x = self.x
        n = len(x)
        held, acc, smooth, speed = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        clipped_start(*self._box, self.inertia, self.bias, t, x, self.dx, self.h, held, acc,
                      smooth, speed)
        # continuous time: the model's acceleration at the predicted end
        after = self.model.forward_dynamics(smooth, speed, held) if self.corrector else acc
        return acc, after

    def first(self) -> Frozen:
        """This prediction's first row alone, the frozen closed form (without the
        corrector's): still a Frozen, so its test is the compiled one."""
        if not self.corrector:
            return self
        first = object.__new__(Frozen)  # every slot, as __init__ sets them
        first.model, first.x, first.dx, first.inertia = self.model, self.x, self.dx, self.inertia
        first.bias, first.h, first.travel, first._box = self.bias, self.h, self.travel, self._box
        first.corrector, first.rows = False, 1
        return first

    def __call__(self, t: Array) -> tuple[Array, Array, Array, Array, Array]:
        acc, after = self.start(t)
        shape = (self.rows, len(self.x))  # four arrays: cheaper than one (4, rows, n)
        mids, ends, speeds, mid_speeds = (np.empty(shape), np.empty(shape), np.empty(shape),
                                          np.empty(shape))
        frozen_rows(self.x, self.dx, acc, after, self.h, self.travel, mids, ends, speeds,
                    mid_speeds)
        return mids, ends, speeds, mids, mid_speeds


def predictor(model: RobotModel, state: ArmState, bias: Array, h: float, substeps: int,
              box: TorqueBox | None, corrector: bool, travel: float = 0.5) -> Predictor:
    """(mid-period x, end x, end ẋ, then x and ẋ inside the period) under a held τ, one
    row per prediction (per prediction and inner instant for the last two; the Predictor
    alias): the frozen closed form with the dynamics of the sample (:class:`Frozen`), or
    ``substeps`` semi-implicit Euler steps of the model. ``box``: the step's box a torque
    is clipped to (StepBox.reachable), or None."""
    if substeps == 1:
        return Frozen(model, state, bias, h, box, corrector, travel)
    saturate = (lambda t: t) if box is None else box.clip
    return substepped(model, state.x, state.dx, h, substeps, saturate, corrector)


def substepped(model: RobotModel, x: Array, dx: Array, h: float, k: int,
                saturate: Callable[[Array], Array], corrector: bool) -> Predictor:
    """The prediction in k semi-implicit Euler steps of the model's forward dynamics, and
    with ``corrector`` beside it in k second-order (Heun) steps."""
    dt = h / k
    mid_step = k // 2 if k % 2 == 0 else (k + 1) // 2  # the step that ends nearest h/2

    def predict(t: Array) -> tuple[Array, Array, Array, Array, Array]:
        t = saturate(t)
        xs, vs = x.copy(), dx.copy()
        inner_x, inner_v = [], []  # the states after every sub-step but the last
        for _ in range(k):
            vs = vs + dt * model.forward_dynamics(xs, vs, t)
            xs = xs + dt * vs
            inner_x.append(xs)
            inner_v.append(vs)
        mid = inner_x[mid_step - 1]
        if not corrector:
            return (mid[None], xs[None], vs[None], np.array(inner_x[:-1]).reshape(-1, len(x)),
                    np.array(inner_v[:-1]).reshape(-1, len(x)))
        xh, vh = x.copy(), dx.copy()
        heun_x, heun_v = [], []
        for _ in range(k):
            a0 = model.forward_dynamics(xh, vh, t)
            a1 = model.forward_dynamics(xh + dt * vh + (0.5 * dt * dt) * a0, vh + dt * a0, t)
            xh = xh + dt * vh + (dt * dt) * (a0 / 3.0 + a1 / 6.0)
            vh = vh + (0.5 * dt) * (a0 + a1)
            heun_x.append(xh)
            heun_v.append(vh)
        rows_x = np.array(inner_x[:-1] + heun_x[:-1]).reshape(-1, len(x))
        rows_v = np.array(inner_v[:-1] + heun_v[:-1]).reshape(-1, len(x))
        return (np.array((mid, heun_x[mid_step - 1])), np.array((xs, xh)), np.array((vs, vh)),
                rows_x, rows_v)

    return predict
