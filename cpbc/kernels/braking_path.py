"""The uniform brake of the braking set V in compiled code (cpbc.constraints.stopping.Braking):
its deceleration θA, the time its torque takes to build under a torque-rate limit, and the
path from each predicted end to where it stops, whose configurations the guard's (S2) tests
(cpbc.controllers.safeguard.predicted_margins)."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, inner, kernel
from cpbc.kernels.small_solves import times


@inner("void(float64[:, :], float64[:, :], float64[:], float64, float64, float64, int64,"
       " int64, float64[:, :])")
def brake_path(ends: Array, speeds: Array, start: Array, h: float, per_speed: float,
               ramp: float, j: int, points: int, rows: Array) -> None:
    """The ``points`` points of the uniform brake's path from the end of prediction ``j``
    (configuration_rows) into its rows of the stopping blocks."""
    r, n = ends.shape[0], ends.shape[1]
    sq = 0.0
    for i in range(n):
        sq += speeds[j, i] * speeds[j, i]
    speed = math.sqrt(sq)
    if not (ramp > 0.0 and speed > 0.0):
        f = per_speed * speed
        for k in range(points):
            for i in range(n):
                rows[(2 + k) * r + j, i] = ends[j, i] + (f * (k + 1) / points) * speeds[j, i]
        return
    along = 0.0
    for i in range(n):
        along += speeds[j, i] * (speeds[j, i] - start[i])
    along /= speed * h  # a_∥
    across = np.empty(n)  # a_⊥
    for i in range(n):
        across[i] = (speeds[j, i] - start[i]) / h - along * speeds[j, i] / speed
    lead = max(along, 0.0)
    on_ramp = points // 2
    for k in range(on_ramp):
        t = ramp * (k + 1) / on_ramp
        ahead, turn = t + 0.5 * lead * t * t / speed, t * t * (0.5 - t / (6.0 * ramp))
        for i in range(n):
            rows[(2 + k) * r + j, i] = ends[j, i] + ahead * speeds[j, i] + turn * across[i]
    # from x(T), straight on along ẋ(T) to where θA stops it
    ahead, grow = ramp + 0.5 * lead * ramp * ramp / speed, 1.0 + 0.5 * lead * ramp / speed
    sq = 0.0
    for i in range(n):
        v = grow * speeds[j, i] + 0.5 * ramp * across[i]
        sq += v * v
    stop = per_speed * math.sqrt(sq)
    left = points - on_ramp
    for k in range(left):
        share = stop * (k + 1) / left
        for i in range(n):
            v = grow * speeds[j, i] + 0.5 * ramp * across[i]
            rows[(2 + on_ramp + k) * r + j, i] = (ends[j, i] + ahead * speeds[j, i]
                                                  + (ramp * ramp / 3.0) * across[i]
                                                  + share * v)


@kernel("void(float64[:, :], float64[:, :], float64[:, :], float64[:], float64, float64,"
        " float64, float64[:, :])")
def configuration_rows(mids: Array, ends: Array, speeds: Array, start: Array, h: float,
                       per_speed: float, ramp: float, rows: Array) -> None:
    """The configurations whose margins the guard tests: the mid-period ones, the ends and,
    when ``rows`` has room, the path of the uniform brake from each end to where it stops,
    x_s = x₁ + (|ẋ₁|/(2θA)) ẋ₁ (``per_speed`` = 1/(2θA), A frozen at the sample).

    Under a torque-rate limit the brake takes ``ramp`` = T seconds to build from the torque
    held over the period (Braking.ramp). With a = (ẋ₁ − ẋ₀)/h the period's acceleration
    (``start`` = ẋ₀), ê = ẋ₁/|ẋ₁|, a_∥ = ê·a and a_⊥ = a − a_∥ê, the arm is taken over the
    ramp along

        x(t) = x₁ + ẋ₁ t + ½ a_∥⁺ t² ê + a_⊥ (t²/2 − t³/(6T)),   0 ≤ t ≤ T,

    reaching ẋ(T) = (|ẋ₁| + ½ a_∥⁺ T) ê + ½ a_⊥ T, a_∥⁺ = max(a_∥, 0), and then braked at θA
    along ẋ(T) to x(T) + (|ẋ(T)|/(2θA)) ẋ(T). Along the motion no deceleration is credited
    while the torque ramps — the held one's acceleration kept for the travel, fading to
    nothing for the speed (crediting the linear ramp from a to −θA, a speed of
    |ẋ₁| + ½(a − θA)T after it, was too hopeful: on the UR5 of the rate campaign, from two
    starts inside V, (S2) passed for 30 periods while the σ that credits nothing fell below
    zero; then no brake was left and a link crossed the floor's clearance by 0.1–0.5 mm.
    Braking.margins, by which ``cpbc.verify`` classes starts, credits nothing either).
    Across it the held acceleration fades linearly as the torque ramps to the brake, whose
    acceleration is along the motion: the arm keeps turning for T. Both are the frozen
    dynamics' path, so that the next period's test, run from where this one's torque leads,
    sees a continuation of the same path.

    The rows hold K points of that path (``rows`` of (2 + K) r rows), the stopping point the
    last: under a ramp ⌊K/2⌋ at even times of the ramp and the rest evenly along the brake;
    without one (or with K = 1) the stopping point x₁ + (|ẋ₁|/(2θA)) ẋ₁ alone, the way
    there straight and short. The arm passes every point of the path, and a margin that is
    not linear in x (a clearance) can dip along it and rise again by its end. (On the
    Panda's figure eight under a 1000 N·m/s limit the hand and link 6 skimmed the table at
    0.3–4 mm, the law accelerating at 200–300 rad/s² of which 100–130 across the motion, T
    ≈ 90 ms: tested at the end of a straight path 1.2–1.8 rad long, (S2) passed with the
    stopping point 3–5 cm above the table while the turning path went under it, and from
    starts inside V the arm crossed the clearance by 0.7–2.1 mm.)"""
    r, n = ends.shape[0], ends.shape[1]
    for j in range(r):
        for i in range(n):
            rows[j, i] = mids[j, i]
            rows[r + j, i] = ends[j, i]
    points = rows.shape[0] // r - 2
    for j in range(r):
        if points > 0:
            brake_path(ends, speeds, start, h, per_speed, ramp, j, points, rows)


@kernel("float64(float64[:, :], float64[:], float64[:], float64[:], float64[:, :], boolean)")
def uniform_deceleration(inertia: Array, bias: Array, dx: Array, limit: Array,
                         to_joint: Array, mapped: bool) -> float:
    """A = |ẋ| min_j (L_j + sign(u_j) β_j)/|u_j| with u = Tᵀ D ẋ, β = Tᵀ b (the largest
    deceleration along ẋ of the uniform brake in the box, Braking's docstring; ``to_joint``
    Tᵀ read only when ``mapped``); inf at rest."""
    n = dx.shape[0]
    sq = 0.0
    for i in range(n):
        sq += dx[i] * dx[i]
    speed = math.sqrt(sq)
    if speed == 0.0:
        return math.inf
    u = times(inertia, dx)
    beta = bias
    if mapped:
        u, beta = times(to_joint, u), times(to_joint, bias)
    low = math.inf
    nan = False
    for j in range(n):
        size = abs(u[j])
        if size > 0.0:
            room = (limit[j] + (1.0 if u[j] > 0.0 else -1.0) * beta[j]) / size
            if room != room:
                nan = True
            elif room < low:
                low = room
    return (math.nan if nan else low) * speed


@kernel(f"float64(float64[:, :], float64[:], float64[:], {READ_ONLY}, float64, float64[:, :],"
        f" boolean, {READ_ONLY})")
def brake_ramp(inertia: Array, bias: Array, dx: Array, held: Array, per_speed: float,
               to_joint: Array, mapped: bool, rate: Array) -> float:
    """T = max_j |τ_b,j − τ_h,j| / ρ_j: the time the uniform brake τ_b = b − D ẋ/(2θA|ẋ|)
    (``per_speed`` = 1/(2θA)) takes to build from the held torque τ_h = ``held`` at the
    rate limit ρ (Braking.ramp), joint by joint (Tᵀ of the gap when ``mapped``); NaN if any
    is."""
    n = dx.shape[0]
    sq = 0.0
    for i in range(n):
        sq += dx[i] * dx[i]
    scale = 2.0 * per_speed * math.sqrt(sq)
    push = times(inertia, dx)
    gap = np.empty(n)
    for i in range(n):
        gap[i] = (bias[i] - push[i] / scale) - held[i]
    if mapped:
        gap = times(to_joint, gap)
    low = -math.inf
    for j in range(n):
        t = abs(gap[j]) / rate[j]
        if t != t or low != low:
            low = math.nan
        elif t > low:
            low = t
    return low
