"""The torque box's kernels (cpbc.constraints.brakes.TorqueBox): the interval one step of a
torque-rate limit reaches, a torque clipped into the box, and a torque scaled toward the bias
until it fits."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, inner, kernel
from cpbc.kernels.bounded_lsq import bounded_least_squares
from cpbc.kernels.small_solves import inverse_spd, nan_max, nan_min, times


@kernel(f"void(float64[:], float64[:], {READ_ONLY}, {READ_ONLY}, float64[:], float64[:])")
def box_around(lower: Array, upper: Array, held: Array, step: Array, low: Array,
               high: Array) -> None:
    """The joint-torque interval one step reaches from the held joint torques ``held``
    under a rate step ρh (``step``) within lower ≤ τ_q ≤ upper, into ``low`` and ``high``:
    min(max(lower, held − ρh), upper) and max(min(upper, held + ρh), lower) — the one nearest
    to the box where the held torque lies outside it; NaN where any term is (numpy's
    minimum and maximum)."""
    for j in range(held.shape[0]):
        a, b = held[j] - step[j], held[j] + step[j]
        low[j] = nan_min(nan_max(lower[j], a), upper[j])
        high[j] = nan_max(nan_min(upper[j], b), lower[j])


@kernel("void(float64[:], float64[:], float64[:, :], float64[:, :], boolean, float64[:],"
        " float64[:])")
def box_clip(lower: Array, upper: Array, to_joint: Array, from_joint: Array, mapped: bool,
             tau: Array, out: Array) -> None:
    """τ with each joint torque clipped to its interval: T⁻ᵀ clip(Tᵀτ, lower, upper) (τ_q
    itself for joint coordinates, ``mapped`` False)."""
    tau_q = times(to_joint, tau) if mapped else tau
    clipped = np.empty(tau.shape[0])
    for j in range(tau.shape[0]):
        t = tau_q[j]
        clipped[j] = lower[j] if t < lower[j] else (upper[j] if t > upper[j] else t)
    if mapped:
        clipped = times(from_joint, clipped)
    out[:] = clipped


@kernel("int64(float64[:], float64[:], float64[:, :], float64[:, :], boolean, float64[:],"
        " float64[:], float64[:])")
def box_toward(lower: Array, upper: Array, to_joint: Array, from_joint: Array, mapped: bool,
               bias: Array, tau: Array, out: Array) -> int:
    """b + t (τ − b) with the largest t ∈ [0, 1] that fits the box lower ≤ Tᵀτ ≤ upper, into
    ``out``; returns 0 when τ fits as it is (``out`` untouched), 1 when scaled, 2 when b alone
    does not fit and τ is clipped instead (``box_clip``)."""
    n = tau.shape[0]
    tau_q = times(to_joint, tau) if mapped else tau
    fits = True
    for j in range(n):
        if not lower[j] <= tau_q[j] <= upper[j]:
            fits = False
    if fits:
        return 0
    b_q = times(to_joint, bias) if mapped else bias
    for j in range(n):
        if b_q[j] < lower[j] or b_q[j] > upper[j]:  # (a NaN bias scales, as before)
            box_clip(lower, upper, to_joint, from_joint, mapped, tau, out)
            return 2
    low = math.inf
    nan = False
    for j in range(n):
        d = tau_q[j] - b_q[j]
        room = (upper[j] - b_q[j]) / d if d > 0 else ((lower[j] - b_q[j]) / d if d < 0
                                                        else math.inf)
        if room != room:
            nan = True
        elif room < low:
            low = room
    t = 1.0 if nan or not low < 1.0 else low
    for i in range(n):
        out[i] = bias[i] + t * (tau[i] - bias[i])
    return 1


@inner("float64[:, ::1](float64[:, :], float64[:, :], boolean)")
def acceleration_map(inertia: Array, from_joint: Array, mapped: bool) -> Array:
    """A = D⁻¹T⁻ᵀ (``from_joint``; D⁻¹ in joint coordinates, ``mapped`` False): the
    acceleration a joint torque τ_q gives, ẍ = A τ_q − D⁻¹b (``inverse_spd``; the product
    BLAS's, on contiguous arrays, as numpy's is)."""
    n = inertia.shape[0]
    inv = np.empty((n, n))
    inverse_spd(np.ascontiguousarray(inertia), inv)
    if mapped:
        return np.dot(inv, np.ascontiguousarray(from_joint))
    return inv


@kernel(f"boolean(float64[:], float64[:], float64[:, :], float64[:, :], boolean, {READ_ONLY},"
        " float64[:])")
def box_nearest(lower: Array, upper: Array, inertia: Array, from_joint: Array, mapped: bool,
                tau_q: Array, out: Array) -> bool:
    """False where the joint torques τ_q fit lower ≤ τ_q ≤ upper (``out`` untouched), else
    True with the joint torques in the box whose acceleration is nearest to τ_q's,
    min ‖A(τ_q' − τ_q)‖ with A = D⁻¹T⁻ᵀ (``from_joint``; D⁻¹ in joint coordinates,
    ``mapped`` False), into ``out`` (``acceleration_map``, ``bounded_least_squares``;
    cpbc.constraints.brakes.TorqueBox.nearest)."""
    n = tau_q.shape[0]
    for j in range(n):
        if not (tau_q[j] >= lower[j] and tau_q[j] <= upper[j]):
            break
    else:
        return False
    accel = acceleration_map(inertia, from_joint, mapped)
    bounded_least_squares(accel, np.dot(accel, tau_q), lower, upper, out)
    return True
