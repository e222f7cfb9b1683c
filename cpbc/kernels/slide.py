"""The slide's acceleration (cpbc.controllers.safeguard.braking.Brakes.slide) in one call: the
half-spaces (S1) asks of each configuration margin to first order, the law's acceleration, and
that acceleration projected onto them (``project_halfspaces``). Written here, not in numpy,
because the slide runs only in steps the guard acts in, where its dozen numpy calls and a
LAPACK solve ran cold: 80–100 µs at the median on the Panda under a torque-rate limit,
against a few µs warm."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import kernel
from cpbc.kernels.clearance import Ints
from cpbc.kernels.joint_placements import joint_placements
from cpbc.kernels.sampled_guard import margins_along, project_halfspaces
from cpbc.kernels.small_solves import nan_max, solve_spd


@kernel("void(float64[:, :], float64[:], float64[:], float64[:], float64[:], float64, float64,"
        " float64[:, :], float64[:], float64[:, :], float64[:], float64[:], float64[:],"
        " float64[:])")
def slide_acceleration(grads: Array, dx: Array, phi: Array, end_floor: Array,
                       mid_floor: Array, h: float, travel: float, inertia: Array, push: Array,
                       work: Array, rate: Array, need: Array, law: Array, acc: Array) -> None:
    """Into ``rate`` ∇φ_i·ẋ, into ``need`` the r_i of the half-spaces ∇φ_i·a ≥ r_i,

        r_i = max((φ̲_i − φ_i − h∇φ_i·ẋ)/(c h²),  8(φ̲ᵐ_i − φ_i − ½h∇φ_i·ẋ)/h²),

    with each floor aimed a little past itself (a twentieth of its step, and 10⁻⁴ of the
    floor for a margin resting on it: the projection lands on the first-order boundary,
    which the curvature of φ may put a hair short of the floor), into ``law`` the law's
    acceleration D⁻¹ ``push`` (``push`` = τ − b; ``work`` n × n) and into ``acc`` that
    acceleration projected onto the half-spaces. ``grads``: ∇φ_i, one row per
    configuration margin; ``phi``: the margins now; c = ``travel``."""
    m, n = grads.shape
    for i in range(m):
        r = 0.0
        for j in range(n):
            r += grads[i, j] * dx[j]
        rate[i] = r
        e, mf, p = end_floor[i], mid_floor[i], phi[i]
        end = e + 0.05 * abs(e - p) + 1e-4 * abs(e)
        mid = mf + 0.05 * abs(mf - p) + 1e-4 * abs(mf)
        need[i] = nan_max((end - p - h * r) / (travel * h * h),
                          8.0 * (mid - p - 0.5 * h * r) / (h * h))
    solve_spd(inertia, push, work, law)
    project_halfspaces(grads, need, law, acc)


@kernel("void(float64[:], float64[:], float64[:], float64, float64, float64, float64[:])")
def stopping_point(x: Array, dx: Array, acc: Array, h: float, travel: float, reach: float,
                   out: Array) -> None:
    """Where the uniform brake stops the arm after a period at the acceleration ``acc``,

        x_s = x + hẋ + c h² a + r |v₁| v₁,   v₁ = ẋ + h a,

    (c = ``travel``, r = 1/(2θA) of (S2): ``reach``), into ``out``: the point the slide
    tests its braking margins at (Brakes.slide). |v₁|² is BLAS's dot, as numpy's is (numba's
    np.dot of two contiguous vectors; the same bits on 20 000 random cases of 2, 6 and 7
    joints here)."""
    n = x.shape[0]
    v1 = np.empty(n)
    for i in range(n):
        v1[i] = dx[i] + h * acc[i]
    lead = reach * math.sqrt(np.dot(v1, v1))
    c = travel * h * h
    for i in range(n):
        out[i] = ((x[i] + h * dx[i]) + c * acc[i]) + lead * v1[i]


@kernel("void(float64[:], float64[:], float64[:], float64, float64, float64, int64[:, :],"
        " int64[:, :], float64[:, :], int64[:], boolean, int64[:], int64[:], float64[:, :],"
        " float64[:, :, :], float64[:, :], int64[:], float64, float64[:, :])")
def stopping_point_margins(x: Array, dx: Array, acc: Array, h: float, travel: float,
                           reach: float, plan: Ints, ints: Ints, floats: Array, slots: Ints,
                           spheres: bool, parents: Ints, kinds: Ints, axes: Array,
                           rotations: Array, translations: Array, coordinates: Ints,
                           scale: float, out: Array) -> None:
    """``stopping_point`` and every packed configuration margin there (``margins_along``;
    the joint placements from the arm's compiled chain where there are sphere pairs,
    ``joint_placements``) into the one row of ``out``, NaN where the point is not finite:
    what PredictedMargins.configuration_margins gives at it, in one call."""
    n = x.shape[0]
    point = np.empty((1, n))
    stopping_point(x, dx, acc, h, travel, reach, point[0])
    placements = np.zeros((0, 1, 1))
    if spheres:
        placements = np.empty((1, 3, 4 * parents.shape[0]))
        joint_placements(parents, kinds, axes, rotations, translations, coordinates, scale,
                         point, placements)
    margins_along(plan, ints, floats, point, point, placements, slots, out)
    for i in range(n):
        if not math.isfinite(point[0, i]):
            out[0, :] = math.nan
