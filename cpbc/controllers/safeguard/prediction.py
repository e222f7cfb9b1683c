"""The safeguard's prediction of one control period under a held torque (step 2 of the package
docstring): in closed form with the dynamics frozen at the sample (and, with the corrector, to
second order beside it), or in semi-implicit Euler sub-steps of the model's forward dynamics
(with Heun's steps beside them)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels.sampled_guard import frozen_rows, frozen_start
from cpbc.model.robot_model import ArmState, RobotModel

# (mid-period positions, end positions, end rates, then positions and rates inside the
# period), one row per prediction (per prediction and sub-step for the inner ones)
Predictor = Callable[[Array], "tuple[Array, Array, Array, Array, Array]"]


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


def predictor(model: RobotModel, state: ArmState, bias: Array, h: float, substeps: int,
              saturate: Callable[[Array], Array], corrector: bool,
              travel: float = 0.5) -> Predictor:
    """(mid-period x, end x, end ẋ, then x and ẋ inside the period) under a held τ, one
    row per prediction (per prediction and inner instant for the last two; the Predictor
    alias): the frozen closed form with the dynamics of the sample, its end at
    x + hẋ + c h² a with c = ``travel`` (:func:`travel_share`: where the plant's own steps
    land), and, with ``corrector``, the second-order one in continuous time beside it; or
    ``substeps`` semi-implicit Euler steps of the model. ``saturate`` clips a torque to the
    box."""
    x, dx = state.x, state.dx
    if substeps == 1:
        inertia, n = state.inertia, len(x)
        work = np.empty((n, n))  # the Cholesky factor of D
        rows = 2 if corrector else 1

        def frozen(t: Array) -> tuple[Array, Array, Array, Array, Array]:
            t = saturate(t)
            acc, smooth, speed = np.empty(n), np.empty(n), np.empty(n)
            frozen_start(inertia, bias, t, x, dx, h, work, acc, smooth, speed)
            # continuous time: the model's acceleration at the predicted end
            after = model.forward_dynamics(smooth, speed, t) if corrector else acc
            shape = (rows, n)  # four arrays: cheaper than the rows of one (4, rows, n)
            mids, ends, speeds, mid_speeds = (np.empty(shape), np.empty(shape),
                                              np.empty(shape), np.empty(shape))
            frozen_rows(x, dx, acc, after, h, travel, mids, ends, speeds, mid_speeds)
            return mids, ends, speeds, mids, mid_speeds

        return frozen
    return substepped(model, x, dx, h, substeps, saturate, corrector)


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
