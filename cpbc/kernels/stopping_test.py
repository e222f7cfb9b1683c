"""The first-order stopping test in compiled code (cpbc.constraints.stopping.stopping_terms):
for each configuration margin φ_i with gradient ∇φ_i and curvature κ_i = ẋᵀ∇²φ_i ẋ at a
state, its approach speed, the largest deceleration the torque box gives it, and its stopping
margin. The aimed brake reads them at every period it is held (the rescue's checks, a held
brake), where numpy's solve and the masks around it cost ~20 µs a call on the Panda (the whole
stopping_terms: 47 µs then, 32 now, median of 1 000 calls); ``aimed_stop`` makes the whole
brake from them in one call."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, kernel
from cpbc.kernels.bounded_lsq import bounded_least_squares
from cpbc.kernels.small_solves import cholesky, cholesky_solve, solve_lu, times
from cpbc.kernels.torque_box import acceleration_map


@kernel(f"void(float64[:], float64[:, :], float64[:], float64[:, :], {READ_ONLY}, "
        f"{READ_ONLY}, float64[:, :], boolean, {READ_ONLY}, float64[:], float64[:], "
        f"float64[:])")
def stopping_rows(phi: Array, grads: Array, curvature: Array, inertia: Array, bias: Array,
                  dx: Array, inverse: Array, mapped: bool, limit: Array, margins: Array,
                  speed: Array, decel: Array) -> None:
    """Per margin i (stopping.py's docstring): w = T⁻¹ D⁻¹ ∇φ_iᵀ (``inverse`` T⁻¹ read only
    when ``mapped``), the largest deceleration a_i = Σ_j |w_j| L_j − ∇φ_i · D⁻¹ b + κ_i — a
    joint without a limit (L_j = ∞) adds ∞ only where it moves φ_i —, the approach
    v_i = −∇φ_i · ẋ and the margin s_i = φ_i − v_i²/(2a_i) where v_i > 0 (−∞ where
    a_i ≤ 0, NaN a_i included), else φ_i; into ``margins``, ``speed``, ``decel``."""
    n = inertia.shape[0]
    work = np.empty((n, n))
    y = np.empty(n)
    spd = cholesky(inertia, work)  # D = L Lᵀ once for every row (solve_spd's steps)
    for i in range(phi.shape[0]):
        if spd:  # D⁻¹ ∇φ_iᵀ
            cholesky_solve(work, grads[i], y)
        else:  # the factor is not read again: its buffer holds the elimination's, as there
            solve_lu(inertia, grads[i], work, y)
        w = times(inverse, y) if mapped else y
        reach = 0.0
        down = 0.0
        for j in range(n):
            if w[j] != 0.0:
                reach += abs(w[j]) * limit[j]
            down += y[j] * bias[j]
        a = reach - down + curvature[i]
        v = 0.0
        for j in range(n):
            v -= grads[i, j] * dx[j]
        speed[i], decel[i] = v, a
        if v > 0.0:
            margins[i] = phi[i] - (v * v / (2.0 * a) if a > 0.0 else math.inf)
        else:
            margins[i] = phi[i]


@kernel(f"boolean({READ_ONLY}, {READ_ONLY}, {READ_ONLY_MATRIX}, {READ_ONLY}, float64, float64, "
        "float64[:], float64[:])")
def aim_row(margins: Array, speed: Array, grads: Array, dx: Array, h: float, weight: float,
            row: Array, wanted: Array) -> bool:
    """The aimed brake's extra row (cpbc.constraints.brakes.aimed_brake): of the margins
    approached (v_i > 0), the one of least stopping margin s_i — the first of equals, a NaN
    before any number, as numpy's argmin —, its gradient scaled to length ``weight`` into
    ``row`` and the rate it asks the approach for, row · (−ẋ)/h, into ``wanted[0]``; False
    (both untouched) where none is approached or its gradient is 0. The sums run in order,
    as numpy's dot of two n-vectors does here: the brake is the same to the bit."""
    best = -1
    for i in range(margins.shape[0]):
        if speed[i] > 0.0:
            if best < 0 or margins[i] < margins[best] or (
                    margins[i] != margins[i] and margins[best] == margins[best]):
                best = i
    if best < 0:
        return False
    n = grads.shape[1]
    square = 0.0
    for j in range(n):
        square += grads[best, j] * grads[best, j]
    norm = math.sqrt(square)
    if norm == 0.0:
        return False
    scale = weight / norm
    rate = 0.0
    for j in range(n):
        row[j] = scale * grads[best, j]
        rate += row[j] * -dx[j]
    wanted[0] = rate / h
    return True


@kernel(f"void(float64[:, :], {READ_ONLY}, {READ_ONLY}, float64, float64[:, :], float64[:], "
        "boolean, float64[:], float64[:], float64[:, :], float64[:, :], boolean, float64[:])")
def nearest_stop(inertia: Array, bias: Array, dx: Array, h: float, row: Array, wanted: Array,
                 aimed: bool, lower: Array, upper: Array, to_joint: Array, from_joint: Array,
                 mapped: bool, out: Array) -> None:
    """The torque in the box ``lower`` ≤ τ_q ≤ ``upper`` (Tᵀ ``to_joint``, T⁻ᵀ ``from_joint``
    where ``mapped``) nearest in acceleration to ẍ = −ẋ/h (least squares,
    ``bounded_least_squares``, with A = D⁻¹T⁻ᵀ, ``acceleration_map``), with ``aimed`` the
    1 × n ``row`` · ẍ = ``wanted[0]`` on top, into ``out`` (cpbc.constraints.brakes: the
    least-squares brake, the aimed one). Its products are BLAS's, as numpy's are (numba's
    np.dot on contiguous arrays calls dgemv and dgemm: the same bits as numpy's on 20 000
    random 7-joint cases here), and the row's rate on the free acceleration is the sum in
    order numpy's 1 × n product makes (a 1-row dgemv is not: 10 625 of 20 000 differ)."""
    n = inertia.shape[0]
    a = acceleration_map(inertia, from_joint, mapped)
    b = np.ascontiguousarray(bias)
    free = np.dot(a, np.dot(np.ascontiguousarray(to_joint), b) if mapped else b)
    k = n + 1 if aimed else n
    stacked, target = np.empty((k, n)), np.empty(k)
    stacked[:n] = a
    for i in range(n):
        target[i] = free[i] - dx[i] / h
    if aimed:
        stacked[n] = np.dot(np.ascontiguousarray(row), a)[0]
        rate = 0.0
        for j in range(n):
            rate += row[0, j] * free[j]
        target[n] = wanted[0] + rate
    tau_q = np.empty(n)
    bounded_least_squares(stacked, target, lower, upper, tau_q)
    if mapped:
        out[:] = np.dot(np.ascontiguousarray(from_joint), tau_q)
    else:
        out[:] = tau_q


@kernel(f"void(float64[:], float64[:, :], float64[:], float64[:, :], {READ_ONLY}, {READ_ONLY}, "
        f"float64[:, :], boolean, {READ_ONLY}, float64, float64, float64[:], float64[:], "
        "float64[:, :], float64[:, :], boolean, float64[:])")
def aimed_stop(phi: Array, grads: Array, curvature: Array, inertia: Array, bias: Array,
               dx: Array, inverse: Array, mapped: bool, limit: Array, h: float, weight: float,
               lower: Array, upper: Array, to_joint: Array, from_joint: Array,
               mapped_box: bool, out: Array) -> None:
    """The aimed brake (cpbc.constraints.brakes.aimed_brake) in one call: ``stopping_rows``,
    ``aim_row``, then ``nearest_stop`` with the aimed row on top where there is one, into
    ``out``."""
    n, m = inertia.shape[0], phi.shape[0]
    margins, speed, decel = np.empty(m), np.empty(m), np.empty(m)
    stopping_rows(phi, grads, curvature, inertia, bias, dx, inverse, mapped, limit, margins,
                  speed, decel)
    row, wanted = np.empty((1, n)), np.empty(1)
    aimed = aim_row(margins, speed, grads, dx, h, weight, row[0], wanted)
    nearest_stop(inertia, bias, dx, h, row, wanted, aimed, lower, upper, to_joint, from_joint,
                 mapped_box, out)
