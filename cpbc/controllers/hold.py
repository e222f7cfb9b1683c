"""The law's torque corrected for the zero-order hold (first order).

A controller that holds τ over a period h does not hold the acceleration it asked for: with
the arm moving, D(x), C(x, ẋ)ẋ and g(x) change within the period, and the acceleration under
the held τ drifts from a₀ = D⁻¹(τ − b) at the sample to a₀ + Δa at the end. Holding instead

    τ_h = τ − ½ D Δa,     Δa = D(x₁)⁻¹(τ − b(x₁, ẋ₁)) − a₀,

with (x₁, ẋ₁) the frozen prediction of the period's end, keeps a₀ on average over the period
to first order: the continuous-time law's acceleration, which its theorem is about, instead
of one that is off by ½Δa. It matters where the law's authority is small: the CPBC laws near
a velocity bound (their shaped inertia D + ρΠ grows as 1/ψ, so the acceleration they can ask
for shrinks with the margin), where the hold error alone, not the law, would wear the margin
down (docs/reliability.md, "A law that rides a rate bound").

The ½ is what an arm in continuous time does. A simulated plant stepped by a one-stage
integrator (MuJoCo's Euler, implicit, implicitfast) evaluates the dynamics only at the start
of each of its steps: at one step per control period it holds a₀ exactly and has no drift to
cancel, and a correction of ½ D Δa would itself be the hold error — one that a law riding a
rate bound (its authority ∝ the margin) cannot overcome, so that the correction rather than
the law decided where the joint went (the Panda reach with α = 0.1 under implicitfast never
settled). :func:`hold_share` gives the share s of Δa the plant has.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels.sampled_guard import frozen_start, hold_torque
from cpbc.model.robot_model import ArmState, RobotModel


def hold_corrected(model: RobotModel, state: ArmState, bias: Array, tau: Array,
                   period: float, share: float = 0.5) -> Array:
    """τ − s D Δa: the torque whose hold keeps the acceleration of τ at the sample on average
    over ``period``, to first order, on a plant whose acceleration drifts on average by s Δa
    over the period (s = ½ in continuous time, :func:`hold_share`). ``bias`` is
    C ẋ + g (+ f) at the sample."""
    n = len(tau)
    acc, end, speed, out = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    # a₀ = D⁻¹(τ − b) and the frozen prediction's end (x₁, ẋ₁) (cpbc.kernels.sampled_guard)
    frozen_start(state.inertia, bias, tau, state.x, state.dx, period, np.empty((n, n)), acc,
                 end, speed)
    hold_torque(state.inertia, tau, acc, model.forward_dynamics(end, speed, tau), share, out)
    return out


# integrators that evaluate the dynamics once per step, at its start: (semi-)implicit Euler
ONE_STAGE = frozenset({"Euler", "implicit", "implicitfast"})


def plant_step(integrator: str, timestep: float) -> float | None:
    """The plant's step as the safeguard takes it (``SafeguardSettings.plant_step``): the
    timestep of a plant whose integrator is one-stage (ONE_STAGE), else None — a plant
    integrated with RK4, or an arm, in continuous time."""
    return timestep if integrator in ONE_STAGE else None


def hold_share(period: float, plant_step: float | None) -> float:
    """s: the share of the drift Δa of one period that the plant's acceleration has on
    average under a held torque, to first order.

    An arm in continuous time, or a plant integrated with RK4 (``plant_step`` None), sees the
    acceleration move from a₀ to a₀ + Δa along the period: s = ½. A plant stepped by a
    one-stage (semi-implicit Euler) integrator every ``plant_step``, k = period / plant_step
    times a period, holds the acceleration of each step's start, a₀ + Δa j/k for
    j = 0 … k − 1: s = ½ (1 − 1/k), and at one step per period (k = 1) s = 0: such a plant
    holds the sample's acceleration exactly, and a correction would not cancel a drift but
    add a bias of ½Δa of its own.
    """
    if plant_step is None:
        return 0.5
    k = max(round(period / plant_step), 1)
    return 0.5 * (1.0 - 1.0 / k)
