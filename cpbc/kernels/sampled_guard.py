"""The sampled-data safeguard's accept path (cpbc.controllers.safeguard): the frozen prediction
of one period under a held torque, the margins at the predicted states of the constraints whose
kinds have kernels and F of (S1) and (S2) (the uniform brake's deceleration, ramp and path to
rest are cpbc.kernels.braking_path, the torque box's kernels cpbc.kernels.torque_box).

Between these calls the guard makes its Pinocchio calls (the model's acceleration at the
predicted end, the joint placements at every predicted configuration); the rare paths (the
slide, the brakes' search, the rescue) stay Python. The constraint formulas are not repeated
here: the margins along a prediction are the set kernel's own (``linear_limit_terms``,
``rate_limit_margins``, ``sphere_clearances``) over the tables the guard packs once
(cpbc.constraints.packing, ``PackedSet``), row by row.
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, inner, kernel
from cpbc.kernels.barriers import (
    LINEAR,
    LINEAR_CONSTANTS,
    RATE,
    RATE_CONSTANTS,
    linear_limit_terms,
    rate_limit_margins,
)
from cpbc.kernels.clearance import (
    MOVED_ROUNDING,
    OBSTACLES,
    PAIR_INDEX,
    PAIR_TABLE,
    REACH,
    SPHERE_INDEX,
    SPHERE_LOCAL,
    SPHERES,
    Ints,
    sphere_clearances_in,
    sphere_clearances_of,
    travel,
)
from cpbc.kernels.plan_tables import COUNT, FIRST, KIND, float_table, int_table
from cpbc.kernels.shares import keeps_floors, slack
from cpbc.kernels.small_solves import nan_min, solve_spd
from cpbc.kernels.views import Bools

# --- step 2 of the package docstring: the prediction, dynamics frozen at the sample ---------


@kernel("void(float64[:, :], float64[:], float64[:], float64[:], float64[:], float64,"
        " float64[:, :], float64[:], float64[:], float64[:])")
def frozen_start(inertia: Array, bias: Array, tau: Array, x: Array, dx: Array, h: float,
                 work: Array, acc: Array, smooth: Array, speed: Array) -> None:
    """a = D⁻¹(τ − b) into ``acc``; the continuous-time end x + hẋ + ½h² a into ``smooth``
    and ẋ + h a into ``speed``: where the model's acceleration is asked for the corrector."""
    n = x.shape[0]
    rhs = np.empty(n)
    for i in range(n):
        rhs[i] = tau[i] - bias[i]
    solve_spd(inertia, rhs, work, acc)
    half = 0.5 * h * h
    for i in range(n):
        smooth[i] = (x[i] + h * dx[i]) + half * acc[i]
        speed[i] = dx[i] + h * acc[i]


@kernel("void(float64[:], float64[:], float64[:], float64[:], float64, float64,"
        " float64[:, :], float64[:, :], float64[:, :], float64[:, :])")
def frozen_rows(x: Array, dx: Array, acc: Array, after: Array, h: float, travel: float,
                mids: Array, ends: Array, speeds: Array, mid_speeds: Array) -> None:
    """The frozen prediction under a held acceleration a (row 0):

        x(h/2) = x + ½hẋ + ⅛h² a,   x(h) = x + hẋ + c h² a,   ẋ(h) = ẋ + h a,
        ẋ(h/2) = ẋ + ½h a

    (c = ``travel``: where the plant's own steps land); with a second row, the second-order
    prediction in continuous time beside it, the acceleration taken as linear from a to the
    model's ``after`` at the continuous-time end (Heun's; Δ = after − a):

        x(h/2) + h²Δ/48,   x + hẋ + ½h² a + h²Δ/6,   ẋ(h) + ½hΔ,   ẋ(h/2) + ⅛hΔ."""
    n = x.shape[0]
    second = mids.shape[0] > 1
    for i in range(n):
        coast = x[i] + h * dx[i]
        mid = (x[i] + (0.5 * h) * dx[i]) + (0.125 * h * h) * acc[i]
        end = coast + (travel * h * h) * acc[i]
        speed = dx[i] + h * acc[i]
        mid_speed = dx[i] + (0.5 * h) * acc[i]
        mids[0, i], ends[0, i], speeds[0, i], mid_speeds[0, i] = mid, end, speed, mid_speed
        if second:
            late = after[i] - acc[i]
            smooth = end if travel == 0.5 else coast + (0.5 * h * h) * acc[i]
            mids[1, i] = mid + (h * h / 48.0) * late
            ends[1, i] = smooth + (h * h / 6.0) * late
            speeds[1, i] = speed + (0.5 * h) * late
            mid_speeds[1, i] = mid_speed + (0.125 * h) * late


@kernel("void(float64[:, :], float64[:], float64[:], float64[:], float64, float64[:])")
def hold_torque(inertia: Array, tau: Array, acc: Array, after: Array, share: float,
                out: Array) -> None:
    """τ − s D Δa, Δa = ``after`` − a the drift of the acceleration over the period
    (cpbc.controllers.hold: the law's acceleration of the sample kept on average)."""
    n = tau.shape[0]
    for i in range(n):
        t = 0.0
        for j in range(n):
            t += inertia[i, j] * (after[j] - acc[j])
        out[i] = tau[i] - share * t


@kernel("void(float64[:, :], float64[:], float64, float64[:, :], float64[:, :], boolean,"
        f" {READ_ONLY}, float64, float64[:, :])")
def ramp_speeds(speeds: Array, start: Array, h: float, inertia: Array, to_joint: Array,
                mapped: bool, rate: Array, share: float, out: Array) -> None:
    """Where the rates peak while a held torque ramps back under a torque-rate limit
    (cpbc.controllers.safeguard.predicted_margins.RampTest), one row per prediction: the
    period's acceleration a = (ẋ₁ − ẋ₀)/h, its torque D a (Tᵀ D a in joints when
    ``mapped``), the ramp time T = max_j |(D a)_j| / ρ_j, and ẋ₁ + s T a into ``out``."""
    n = start.shape[0]
    acc = np.empty(n)
    push = np.empty(n)
    for r in range(speeds.shape[0]):
        for i in range(n):
            acc[i] = (speeds[r, i] - start[i]) / h
        for i in range(n):
            t = 0.0
            for j in range(n):
                t += inertia[i, j] * acc[j]
            push[i] = t
        lead = 0.0
        for i in range(n):
            t = push[i]
            if mapped:
                t = 0.0
                for j in range(n):
                    t += to_joint[i, j] * push[j]
            lead = max(lead, abs(t) / rate[i])
        for i in range(n):
            out[r, i] = speeds[r, i] + (share * lead) * acc[i]


@kernel("void(float64[:, :], float64[:], float64[:], float64[:])")
def project_halfspaces(grads: Array, need: Array, start: Array, out: Array) -> None:
    """``start`` moved onto the half-spaces {v : ∇φ_i · v ≥ r_i} (rows ``grads``, ``need``
    r_i) into ``out``: one orthogonal projection at a time onto the most violated (relative
    to |∇φ_i|), at most twice per constraint (cpbc.controllers.safeguard.braking's slide and
    escape). Rows with no gradient are never chosen; a NaN shortfall ends it, as numpy's
    argmax over the shortfalls would."""
    m, n = grads.shape
    norms = np.empty(m)
    for i in range(m):
        s = 0.0
        for j in range(n):
            s += grads[i, j] * grads[i, j]
        norms[i] = s
    for j in range(n):
        out[j] = start[j]
    for _ in range(2 * m):
        best, best_val, best_short = -1, -math.inf, 0.0
        for i in range(m):
            short, val = -math.inf, -math.inf
            if norms[i] > 1e-300:
                t = 0.0
                for j in range(n):
                    t += grads[i, j] * out[j]
                short = need[i] - t
                val = short / math.sqrt(norms[i])
            if val != val:  # argmax stops at the first NaN
                best, best_short = i, short
                break
            if best < 0 or val > best_val:
                best, best_val, best_short = i, val, short
        if best < 0 or not best_short > 0.0:
            break
        f = best_short / norms[best]
        for j in range(n):
            out[j] += f * grads[best, j]


# --- step 3: the margins along the prediction, and F of (S1), (S2) --------------------------


@kernel(f"void({READ_ONLY}, {READ_ONLY}, float64, float64, float64[:], float64[:],"
        " float64[:])")
def floors(margins: Array, cushion: Array, keep: float, keep_half: float, now: Array,
           end_floor: Array, mid_floor: Array) -> None:
    """The margins at the sample into ``now``, NaN counted as −∞ (a prediction gone wild),
    and the floors of (S1) from them and the cushions δ: δ_i + e^{−κh}(m_i − δ_i) for every
    margin at the period's end, δ_i + e^{−κh/2}(φ_i − δ_i) for the configuration ones at
    mid-period (as many as ``mid_floor`` holds)."""
    for i in range(margins.shape[0]):
        m = margins[i]
        now[i] = m if m == m else -math.inf
    for i in range(now.shape[0]):
        end_floor[i] = cushion[i] + keep * (now[i] - cushion[i])
    for i in range(mid_floor.shape[0]):
        mid_floor[i] = cushion[i] + keep_half * (now[i] - cushion[i])



@kernel("void(int64[:, :], int64[:, :], float64[:, :], float64[:, :], float64[:, :],"
        " float64[:, :, :], int64[:], float64[:, :])")
def margins_along(plan: Ints, ints: Ints, floats: Array, xs: Array, dxs: Array, ys: Array,
                  slots: Ints, out: Array) -> None:
    """The margins of every packed constraint (``plan``, cpbc.kernels.barrier_set) at every
    row of ``xs`` (and ``dxs`` for the rates; ``ys`` the joint placements of each row, for
    the sphere pairs) into their columns of ``out``, the constraint kinds' own kernels row by
    row. Columns of constraints that do not pack are left as they are. A non-empty
    ``slots`` gives the entry of ``ys`` that holds each row's placements, −1 for a row whose
    sphere pairs are not asked for (their columns are left as they are too)."""
    for r in range(plan.shape[0]):
        kind, at, k = plan[r, KIND], plan[r, FIRST], plan[r, COUNT]
        if kind == LINEAR:
            constants = float_table(plan, floats, r, LINEAR_CONSTANTS)
            part = np.empty(xs.shape[1])
            for i in range(xs.shape[0]):
                linear_limit_terms(constants, xs[i], out[i, at:at + k], part)
        elif kind == RATE:
            constants = float_table(plan, floats, r, RATE_CONSTANTS)
            for i in range(dxs.shape[0]):
                rate_limit_margins(constants, dxs[i], out[i, at:at + k])
        elif kind == SPHERES and (slots.shape[0] == 0 or slots.max() >= 0):
            index = int_table(plan, ints, r, SPHERE_INDEX)[:, 0]
            pairs = int_table(plan, ints, r, PAIR_INDEX)
            local = float_table(plan, floats, r, SPHERE_LOCAL)
            obstacles = float_table(plan, floats, r, OBSTACLES)
            table = float_table(plan, floats, r, PAIR_TABLE)
            work = np.empty(3 * index.shape[0] + 7 * pairs.shape[0])  # once for every row
            for i in range(xs.shape[0]):
                y = i if slots.shape[0] == 0 else slots[i]
                if y >= 0:
                    sphere_clearances_in(ys[y], index, local, obstacles, pairs, table, work,
                                         out[i, at:at + k])




@kernel("float64(int64[:, :], int64[:, :], float64[:, :], int64[:, :], int64[:, :], float64[:, :],"
        " float64[:, :], float64[:, :, :], int64[:], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:, :], float64[:, :], float64[:, :], float64[:, :], float64[:],"
        " float64[:], float64[:], boolean[:], boolean, boolean, boolean)")
def predicted_slack(config_plan: Ints, config_ints: Ints, config_floats: Array,
                    velocity_plan: Ints, velocity_ints: Ints, velocity_floats: Array,
                    rows: Array, placements: Array, slots: Ints, ends: Array, speeds: Array,
                    inner_x: Array, inner_v: Array, config: Array, velocity: Array,
                    inner: Array, end_floor: Array, mid_floor: Array, sigma_floor: Array,
                    past: Bools, has_past: bool, has_config: bool, has_stop: bool) -> float:
    """F of one prediction in one call: the packed velocity margins at the ends and inside
    the period, the packed configuration margins at ``rows`` (``configuration_rows``, with
    their joint ``placements``; the sphere pairs only at the rows ``slots`` gives, all with
    none, ``margins_along``) into their columns (the other columns filled already), then
    ``slack``."""
    everywhere = slots[:0]
    margins_along(velocity_plan, velocity_ints, velocity_floats, ends, speeds, placements,
                  everywhere, velocity)
    if inner.shape[1] > 0:
        margins_along(velocity_plan, velocity_ints, velocity_floats, inner_x, inner_v,
                      placements, everywhere, inner)
    if has_config:
        margins_along(config_plan, config_ints, config_floats, rows, rows, placements, slots,
                      config)
    return slack(config, velocity, inner, ends.shape[0], end_floor, mid_floor, sigma_floor,
                 past, has_past, has_config, has_stop)


@inner("int64(int64[:, :], float64[:, :], float64[:, :], int64, float64[:], float64[:],"
       " float64[:], float64[:], float64[:], float64, int64[:], float64[:, :])")
def _bound_spheres(plan: Ints, floats: Array, rows: Array, ends: int, end_floor: Array,
                   mid_floor: Array, sigma_floor: Array, x: Array, now: Array,
                   threshold: float, slots: Ints, config: Array) -> int:
    """Each sphere constraint's bound from its margin ``now`` at ``x``, φ − ``travel`` −
    MOVED_ROUNDING, into its column of ``config`` at each row where it is > 0 with a share
    ≥ ``threshold`` of its floor (the mid-period rows', the ends', then the stopping points'
    σ floor, as ``slack`` reads them); where one is not, NaN there (its clearance is to be
    computed: ``spheres_at``) and the row is marked in ``slots`` (numbered from 0, in order;
    −1 the others). The row's travel by the largest reach of every constraint is tried
    first (one sum a row), the constraint's own where that is not enough. Returns how many
    rows are marked."""
    n = x.shape[0]
    widest = np.empty(n)
    unit = threshold == 1.0  # bound/f ≥ 1 is bound ≥ f for f > 0: no division
    for i in range(rows.shape[0]):
        slots[i] = -1
    for r in range(plan.shape[0]):
        if plan[r, KIND] != SPHERES:
            continue
        at, k = plan[r, FIRST], plan[r, COUNT]
        reach = float_table(plan, floats, r, REACH)
        for j in range(n):
            widest[j] = reach[:, j].max()
        for i in range(rows.shape[0]):
            floor = mid_floor if i < ends else end_floor if i < 2 * ends else sigma_floor
            q = rows[i]
            far = travel(widest, x, q)
            for c in range(k):
                f = floor[at + c]
                bound = now[at + c] - far - MOVED_ROUNDING
                if not (bound > 0.0 and (bound >= f if unit else bound / f >= threshold)):
                    bound = now[at + c] - travel(reach[c], x, q) - MOVED_ROUNDING
                if f > 0.0 and bound > 0.0 and (bound >= f if unit else bound / f >= threshold):
                    config[i, at + c] = bound
                else:
                    config[i, at + c] = math.nan
                    slots[i] = 0
    marked = 0
    for i in range(rows.shape[0]):
        if slots[i] == 0:
            slots[i] = marked
            marked += 1
    return marked


@inner("void(int64[:, :], float64[:, :], float64)")
def sphere_columns(plan: Ints, config: Array, value: float) -> None:
    """The sphere constraints' columns of ``config`` set to ``value`` at every row."""
    for r in range(plan.shape[0]):
        if plan[r, KIND] == SPHERES:
            first = plan[r, FIRST]
            config[:, first:first + plan[r, COUNT]] = value


@inner("void(int64[:, :], int64[:, :], float64[:, :], int64[:, :], int64[:, :],"
       " float64[:, :], float64[:, :], float64[:, :], float64[:, :], float64[:, :],"
       " float64[:, :], float64[:, :], float64[:, :], float64[:, :], float64)")
def all_but_spheres(config_plan: Ints, config_ints: Ints, config_floats: Array,
                     velocity_plan: Ints, velocity_ints: Ints, velocity_floats: Array,
                     rows: Array, ends: Array, speeds: Array, inner_x: Array, inner_v: Array,
                     config: Array, velocity: Array, inner: Array, spheres: float) -> None:
    """Every packed margin but the sphere clearances, whose columns are set to ``spheres``
    (∞: left out of F; NaN: every one to compute, ``spheres_at``)."""
    everywhere = np.zeros(0, dtype=np.int64)
    none = np.zeros((0, 1, 1))
    margins_along(velocity_plan, velocity_ints, velocity_floats, ends, speeds, none,
                  everywhere, velocity)
    if inner.shape[1] > 0:
        margins_along(velocity_plan, velocity_ints, velocity_floats, inner_x, inner_v, none,
                      everywhere, inner)
    skip = np.full(rows.shape[0], -1, dtype=np.int64)  # no sphere pair's
    margins_along(config_plan, config_ints, config_floats, rows, rows, none, skip, config)
    sphere_columns(config_plan, config, spheres)


@kernel("UniTuple(float64, 2)(int64[:, :], int64[:, :], float64[:, :], int64[:, :],"
        " int64[:, :], float64[:, :], float64[:, :], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:, :], float64[:, :], float64[:, :], float64[:, :],"
        f" float64[:], float64[:], float64[:], boolean[:], boolean, {READ_ONLY}, {READ_ONLY},"
        " float64, int64[:])")
def bounded_slack(config_plan: Ints, config_ints: Ints, config_floats: Array,
                  velocity_plan: Ints, velocity_ints: Ints, velocity_floats: Array,
                  rows: Array, ends: Array, speeds: Array, inner_x: Array, inner_v: Array,
                  config: Array, velocity: Array, inner: Array, end_floor: Array,
                  mid_floor: Array, sigma_floor: Array, no_past: Bools, has_stop: bool,
                  x: Array, now: Array, enough: float, slots: Ints) -> tuple[float, float]:
    """``predicted_slack`` (no margin broken already: ``no_past`` empty) that asks for the
    sphere clearances only where a bound from the sample does not settle them, and so for
    no joint placements at the rows where all are: every other margin first, and G, their
    least share m/floor (F + 1 without the spheres; ``all_but_spheres``); then
    ``_bound_spheres`` with the threshold min(G, ``enough``), from the margins ``now`` at
    the sample ``x`` (NaN as −∞). Returns (min(G, ``enough``) − 1, 0) when no row needs
    its clearances, else (NaN, the rows that do), with ``slots`` numbering them and the
    clearances to compute NaN in ``config``: ``predicted_slack`` finishes F with those rows'
    placements, or ``spheres_at`` and ``slack`` with those clearances alone (the bounds
    stand in at the others).

    A bound stands in only where the clearance is ≥ it, and only with a share ≥ the
    threshold T; the groups of ``slack`` keep their NaN (only finite shares stand in for
    finite ones), and F + 1 is their least value: with every sphere share ≥ T,
    T ≤ F + 1 ≤ G. With ``enough`` = ∞ (T = G) F is exact. With ``enough`` = 1 it is exact
    where it is < 0 (G < 1), else a value in [0, F]: its sign is F's. A NaN G (a NaN rate
    inside the period, which ``slack`` keeps) is F's."""
    all_but_spheres(config_plan, config_ints, config_floats, velocity_plan, velocity_ints,
                    velocity_floats, rows, ends, speeds, inner_x, inner_v, config, velocity,
                    inner, math.inf)
    n = ends.shape[0]
    if enough <= 1.0 and keeps_floors(config, velocity, inner, n, end_floor, mid_floor,
                                      sigma_floor, True, has_stop):
        rest = enough  # G ≥ 1 ≥ enough, told without a division: min(G, enough) is enough
    else:
        rest = slack(config, velocity, inner, n, end_floor, mid_floor, sigma_floor, no_past,
                     False, True, has_stop) + 1.0
    threshold = enough if rest > enough else rest  # NaN stays
    marked = _bound_spheres(config_plan, config_floats, rows, n, end_floor, mid_floor,
                            sigma_floor, x, now, threshold, slots, config)
    if marked:
        return math.nan, float(marked)
    return threshold - 1.0, 0.0


@inner("void(int64[:, :], int64[:, :], float64[:, :], float64[:, :, :], int64[:],"
       " float64[:, :])")
def spheres_at(plan: Ints, ints: Ints, floats: Array, placements: Array, slots: Ints,
               config: Array) -> None:
    """The sphere clearances left NaN in ``config`` (``_bound_spheres``: those their bound
    does not settle), at each row ``slots`` marks, from its joint ``placements``
    (``sphere_clearances_of``: only their pairs)."""
    for r in range(plan.shape[0]):
        if plan[r, KIND] != SPHERES:
            continue
        at, k = plan[r, FIRST], plan[r, COUNT]
        index = int_table(plan, ints, r, SPHERE_INDEX)[:, 0]
        pairs = int_table(plan, ints, r, PAIR_INDEX)
        local = float_table(plan, floats, r, SPHERE_LOCAL)
        obstacles = float_table(plan, floats, r, OBSTACLES)
        table = float_table(plan, floats, r, PAIR_TABLE)
        work = np.empty(3 * index.shape[0] + 7 * pairs.shape[0])
        need = np.empty(k, dtype=np.bool_)
        for i in range(config.shape[0]):
            if slots[i] < 0:
                continue
            for c in range(k):
                need[c] = config[i, at + c] != config[i, at + c]
            sphere_clearances_of(placements[slots[i]], index, local, obstacles, pairs, table,
                                 work, need, config[i, at:at + k])


@kernel("float64(int64[:, :], int64[:, :], float64[:, :], float64[:, :], float64[:, :],"
        f" float64[:, :, :], float64[:, :], {READ_ONLY})")
def ramp_share(plan: Ints, ints: Ints, floats: Array, ends: Array, peaks: Array,
               placements: Array, margins: Array, floor: Array) -> float:
    """min_j ψ_j/δ_j − 1 of the velocity margins at the rows (x₁, ẋ peak) of ``ramp_speeds``
    (cpbc.controllers.safeguard.predicted_margins.RampTest): the packed ones into their
    columns of ``margins`` (``margins_along``; the other columns filled already), NaN margins
    counted as −∞, ``floor`` the cushions δ_j."""
    margins_along(plan, ints, floats, ends, peaks, placements, np.zeros(0, dtype=np.int64),
                  margins)
    low = math.inf
    for r in range(margins.shape[0]):
        for j in range(margins.shape[1]):
            v = margins[r, j]
            if v != v:
                v = -math.inf
            low = nan_min(low, v / floor[j])
    return low - 1.0
