"""The bound on the acceleration error of the model's smooth Coulomb friction over one period
(cpbc.controllers.safeguard.model_error's docstring, "The Coulomb friction's own error"), in
one call a guarded step: the accelerations the step's torque box reaches, the plant's force
error e_j per joint, and |D⁻¹| |T⁻ᵀ| max(e, F) in controller coordinates.

The sums run joint by joint in index order, as the loops of the other kernels do; numpy's
matrix products they replace add the same terms in an order of BLAS's choosing, so the bounds
agree to rounding (a few units in the last place).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, inner, kernel


@inner("float64(float64, float64, float64, float64, float64, float64, float64)")
def slide_error(level: float, smoothing: float, build_up: float, creep: float, low: float,
                high: float, deceleration: float) -> float:
    """e_j of one joint (cpbc.model.coulomb.DryFriction): the plant's dry friction is
    F_j sign(q̇_j) while the least speed ``low`` over the period is at least
    T_f α_j + v_c (``build_up`` T_f, ``creep`` v_c, ``deceleration`` α_j ≥ 0), and then
    differs from the model's F_j tanh(q̇_j/ε) by F_j (1 − tanh(s_j/ε)); otherwise by at
    most F_j (1 + tanh(S_j/ε)), S_j = ``high``."""
    if low >= build_up * deceleration + creep:
        return level * (1.0 - math.tanh(max(low, 0.0) / smoothing))
    return level * (1.0 + math.tanh(high / smoothing))


@kernel(f"void({READ_ONLY}, float64, float64, float64, {READ_ONLY}, {READ_ONLY}, {READ_ONLY},"
        " float64[:])")
def dry_force_error(levels: Array, smoothing: float, build_up: float, creep: float, low: Array,
                    high: Array, deceleration: Array, out: Array) -> None:
    """``slide_error`` of every joint into ``out``."""
    for j in range(levels.shape[0]):
        out[j] = slide_error(levels[j], smoothing, build_up, creep, low[j], high[j],
                             deceleration[j])


@inner(f"void({READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}, boolean, float64[:, :])")
def _to_accel(inverse: Array, t_inv: Array, mapped: bool, out: Array) -> None:
    """D⁻¹ T⁻ᵀ into ``out``: the controller-coordinate acceleration a joint torque gives
    (D⁻¹ itself for joint coordinates, ``mapped`` False)."""
    n = inverse.shape[0]
    for i in range(n):
        for j in range(n):
            if not mapped:
                out[i, j] = inverse[i, j]
                continue
            s = 0.0
            for k in range(n):
                s += inverse[i, k] * t_inv[j, k]
            out[i, j] = s


@inner(f"void({READ_ONLY_MATRIX}, float64[:, :], {READ_ONLY}, {READ_ONLY}, {READ_ONLY},"
       " float64[:], float64[:])")
def _reach(inverse: Array, to_accel: Array, bias: Array, lower: Array, upper: Array,
           centre: Array, radius: Array) -> None:
    """``reachable_accelerations`` with D⁻¹T⁻ᵀ given (``to_accel``)."""
    n = bias.shape[0]
    for i in range(n):
        c, b, r = 0.0, 0.0, 0.0
        for j in range(n):
            mid = 0.5 * (lower[j] + upper[j])
            if not math.isfinite(mid):
                mid = 0.0
            c += to_accel[i, j] * mid
            b += inverse[i, j] * bias[j]
            r += abs(to_accel[i, j]) * (0.5 * (upper[j] - lower[j]))
        centre[i] = c - b
        radius[i] = math.inf if r != r else r


@kernel(f"void({READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}, boolean, {READ_ONLY}, {READ_ONLY},"
        f" {READ_ONLY}, float64[:], float64[:])")
def reachable_accelerations(inverse: Array, t_inv: Array, mapped: bool, bias: Array,
                            lower: Array, upper: Array, centre: Array, radius: Array) -> None:
    """(centre, radius) of the model accelerations D⁻¹(T⁻ᵀ τ_q − b) of the joint torques
    lower ≤ τ_q ≤ upper, per controller coordinate: D⁻¹T⁻ᵀ m − D⁻¹ b and |D⁻¹T⁻ᵀ| r with m,
    r the box's middle and half-width (an infinite middle taken as 0; an infinite half-width
    gives an infinite radius)."""
    n = bias.shape[0]
    to_accel = np.empty((n, n))
    _to_accel(inverse, t_inv, mapped, to_accel)
    _reach(inverse, to_accel, bias, lower, upper, centre, radius)


@inner("float64(float64)")
def _sign(v: float) -> float:
    """numpy's sign: −1, 0 or 1, NaN for NaN."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return v if v != v else 0.0


@inner("float64(float64, float64)")
def _larger(a: float, b: float) -> float:
    """numpy's maximum of two: NaN if either is."""
    if a != a or b != b:
        return math.nan
    return a if a > b else b


@inner(f"float64({READ_ONLY_MATRIX}, boolean, {READ_ONLY}, int64, boolean)")
def _joint_entry(t_inv: Array, mapped: bool, v: Array, j: int, absolute: bool) -> float:
    """(T⁻¹ v)_j, or (|T⁻¹| v)_j when ``absolute``: v_j itself for joint coordinates."""
    if not mapped:
        return v[j]
    s = 0.0
    for k in range(v.shape[0]):
        s += (abs(t_inv[j, k]) if absolute else t_inv[j, k]) * v[k]
    return s


@inner(f"void(float64[:, :], {READ_ONLY_MATRIX}, boolean, {READ_ONLY}, float64, float64,"
       f" float64, {READ_ONLY}, {READ_ONLY}, {READ_ONLY}, boolean, float64, float64[:])")
def _bound(to_accel: Array, t_inv: Array, mapped: bool, levels: Array, smoothing: float,
           build_up: float, creep: float, dx: Array, centre: Array, radius: Array,
           bounded: bool, period: float, out: Array) -> None:
    """``friction_error`` with D⁻¹T⁻ᵀ given (``to_accel``)."""
    n = dx.shape[0]
    held = np.empty(n)
    for j in range(n):
        coarse = own = 0.0
        for k in range(n):
            joint_inv = to_accel[j, k] if not mapped else 0.0  # (T⁻¹ D⁻¹ T⁻ᵀ)_jk
            for m in range(n if mapped else 0):
                joint_inv += t_inv[j, m] * to_accel[m, k]
            coarse += abs(joint_inv) * (2.0 * levels[k])
            if k == j:
                own = abs(joint_inv)
        dq = _joint_entry(t_inv, mapped, dx, j, False)
        speed = abs(dq)
        alpha = reach = math.inf
        if bounded:
            c = _joint_entry(t_inv, mapped, centre, j, False)
            r = _joint_entry(t_inv, mapped, radius, j, True)
            reach = abs(c) + r + coarse
        spread = period * reach if period > 0.0 else 0.0
        if bounded:
            # sliding, the joint's own friction is the plant's F_j sign(q̇_j) and the
            # model's at least F_j tanh(s_j/ε): its own share of α_j is at most
            # (T⁻¹D⁻¹T⁻ᵀ)_jj F_j (1 − tanh(s_j/ε)), not the coarse 2 F_j
            low = _larger(speed - spread, 0.0)
            alpha = (_larger(-_sign(dq) * c + r, 0.0) + coarse
                     - own * levels[j] * (1.0 + math.tanh(low / smoothing)))
        e = slide_error(levels[j], smoothing, build_up, creep, speed - spread, speed + spread,
                        alpha)
        # never below F_j (model_error's docstring: the shortfall alone at speed let a rate
        # through at 500 Hz)
        held[j] = _larger(e, levels[j])
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += abs(to_accel[i, j]) * held[j]
        out[i] = s


@kernel(f"void({READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}, boolean, {READ_ONLY}, float64, float64,"
        f" float64, {READ_ONLY}, {READ_ONLY}, {READ_ONLY}, boolean, float64, float64[:])")
def friction_error(inverse: Array, t_inv: Array, mapped: bool, levels: Array,
                   smoothing: float, build_up: float, creep: float, dx: Array, centre: Array,
                   radius: Array, bounded: bool, period: float, out: Array) -> None:
    """|D⁻¹| |T⁻ᵀ| max(e, F) per controller coordinate into ``out`` (model_error's
    docstring), ``inverse`` D⁻¹, ``t_inv`` T⁻¹ (read when ``mapped``), ``levels`` F,
    ``smoothing`` ε, ``build_up`` T_f and ``creep`` v_c of the plant's friction.

    With ``bounded`` the torques that may be held give the model accelerations
    ``centre`` ± ``radius`` (controller coordinates; ``reachable_accelerations``), carried to
    joint coordinates as T⁻¹c ± |T⁻¹| r. To them the plant's friction adds at most
    |T⁻¹D⁻¹T⁻ᵀ|·2F (joint coordinates, the coarse bound): joint j's rate moves by at most
    h (|c_j| + r_j + coarse_j) over the period h = ``period`` (0: the rate at the start
    only), so its speed stays at least s_j. Whether it slides is asked of the deceleration
    it would have if it slid (model_error's docstring: were its friction short of F_j, it
    would decelerate less, and the rule then says it slides), where its own friction differs
    from the model's by F_j (1 − tanh(s_j/ε)) at most: α_j = max(−sign(q̇_j) c_j + r_j, 0)
    + coarse_j − (T⁻¹D⁻¹T⁻ᵀ)_jj F_j (1 + tanh(s_j/ε)). Without ``bounded`` no joint is
    taken to slide (α_j = ∞), and over a period a rate may reach any speed."""
    n = dx.shape[0]
    to_accel = np.empty((n, n))
    _to_accel(inverse, t_inv, mapped, to_accel)
    _bound(to_accel, t_inv, mapped, levels, smoothing, build_up, creep, dx, centre, radius,
           bounded, period, out)


@kernel(f"void({READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}, boolean, {READ_ONLY}, float64, float64,"
        f" float64, {READ_ONLY}, {READ_ONLY}, {READ_ONLY}, {READ_ONLY}, float64, float64[:])")
def held_friction_error(inverse: Array, t_inv: Array, mapped: bool, levels: Array,
                        smoothing: float, build_up: float, creep: float, dx: Array,
                        bias: Array, lower: Array, upper: Array, period: float,
                        out: Array) -> None:
    """``friction_error`` for the accelerations of the joint torques lower ≤ τ_q ≤ upper
    that may be held over the period (``reachable_accelerations`` at the bias b): what a
    guarded step asks, in one call."""
    n = dx.shape[0]
    to_accel = np.empty((n, n))
    _to_accel(inverse, t_inv, mapped, to_accel)
    centre, radius = np.empty(n), np.empty(n)
    _reach(inverse, to_accel, bias, lower, upper, centre, radius)
    _bound(to_accel, t_inv, mapped, levels, smoothing, build_up, creep, dx, centre, radius,
           True, period, out)
