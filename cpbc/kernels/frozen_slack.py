"""The safeguard's test of one torque under the frozen prediction, in two calls around the one
Pinocchio call between them (cpbc.controllers.safeguard.predicted_margins.PredictedMargins.
frozen_slack): ``frozen_test`` makes the prediction's rows (``frozen_rows``), the configurations
(S1) and (S2) test (``configuration_rows``) and F over them (``bounded_slack``: the sphere
clearances bounded from the sample where that settles them; ``predicted_slack`` where there are
none); where some clearance is left to compute it marks its row, the caller asks Pinocchio for
the marked rows' joint placements, and ``frozen_finish`` computes those clearances alone
(``spheres_at``) and ends F (``slack``); under a torque-rate limit ``frozen_ramp`` adds the
velocity margins while the torque ramps back. No formula is written here: these are the accept
path's kernels called in one go (``clipped_start`` is the prediction's start, with the
saturation into the step's box), over one buffer whose layout (``frozen_size``,
``frozen_parts``) is written once, below. What it saves is the Python between them (a calm
Panda step's first test made 2 kernel calls, 9 arrays and 2 Python calls more) and, where
rows need their clearances, the pairs a bound settles. For an arm whose chain is compiled
(cpbc.model.joint_chain) and under a torque-rate limit, ``frozen_chain_test`` makes all of it
in one call, the marked rows' placements inside (``joint_placements``).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, inner, kernel
from cpbc.kernels.braking_path import configuration_rows
from cpbc.kernels.clearance import SPHERES, Ints
from cpbc.kernels.joint_placements import joint_placements
from cpbc.kernels.plan_tables import COUNT, FIRST, KIND
from cpbc.kernels.sampled_guard import (
    all_but_spheres,
    bounded_slack,
    frozen_rows,
    frozen_start,
    predicted_slack,
    ramp_share,
    ramp_speeds,
    spheres_at,
)
from cpbc.kernels.shares import slack
from cpbc.kernels.torque_box import box_clip


@kernel("void(float64[:], float64[:], float64[:, :], float64[:, :], boolean, boolean,"
        " float64[:, :], float64[:], float64[:], float64[:], float64[:], float64, float64[:],"
        " float64[:], float64[:], float64[:])")
def clipped_start(lower: Array, upper: Array, to_joint: Array, from_joint: Array, mapped: bool,
                  clip: bool, inertia: Array, bias: Array, tau: Array, x: Array, dx: Array,
                  h: float, held: Array, acc: Array, smooth: Array, speed: Array) -> None:
    """``frozen_start`` under the torque the actuators would hold: τ clipped to the step's
    box (``box_clip``; τ itself without ``clip``), into ``held``."""
    n = x.shape[0]
    if clip:
        box_clip(lower, upper, to_joint, from_joint, mapped, tau, held)
    else:
        for i in range(n):
            held[i] = tau[i]
    frozen_start(inertia, bias, held, x, dx, h, np.empty((n, n)), acc, smooth, speed)


def frozen_size(r: int, n: int, points: int, nc: int, nv: int) -> int:
    """The floats of the buffer ``frozen_parts`` reads: r predictions of n coordinates,
    ``points`` points of the uniform brake's path after each (0 without (S2)), nc
    configuration and nv velocity margins."""
    return (2 + points) * r * (n + nc) + r * (4 * n + 2 * nv)


@inner("Tuple((float64[:, ::1], int64))(float64[::1], int64, int64, int64)")
def _block(work: Array, at: int, rows: int, cols: int) -> tuple[Array, int]:
    """The rows × cols block of ``work`` from ``at`` on, and where the next one starts."""
    end = at + rows * cols
    return work[at:end].reshape((rows, cols)), end


@inner("UniTuple(float64[:, ::1], 8)(float64[::1], int64, int64, int64, int64, int64)")
def frozen_parts(work: Array, r: int, n: int, points: int, nc: int,
                 nv: int) -> tuple[Array, Array, Array, Array, Array, Array, Array, Array]:
    """The test's arrays as views of ``work`` (``frozen_size`` floats): the configurations
    tested ((2 + points) r × n, ``configuration_rows``), the predicted ends, end rates,
    mid-period positions and rates (r × n each, ``frozen_rows``), the configuration margins
    at the configurations ((2 + points) r × nc), the velocity margins at the ends and at
    mid-period (r × nv each)."""
    tested = (2 + points) * r
    rows, at = _block(work, 0, tested, n)
    ends, at = _block(work, at, r, n)
    speeds, at = _block(work, at, r, n)
    mids, at = _block(work, at, r, n)
    mid_speeds, at = _block(work, at, r, n)
    config, at = _block(work, at, tested, nc)
    velocity, at = _block(work, at, r, nv)
    inside, _ = _block(work, at, r, nv)
    return rows, ends, speeds, mids, mid_speeds, config, velocity, inside


@kernel("UniTuple(float64, 2)(float64[:], float64[:], float64[:], float64[:], float64, float64,"
        " int64, float64[:], float64, float64, float64, int64, int64[:, :], int64[:, :],"
        " float64[:, :], int64[:, :], int64[:, :], float64[:, :], float64[:], float64[:],"
        f" float64[:], boolean, boolean, boolean, boolean, {READ_ONLY}, {READ_ONLY}, float64,"
        " int64, float64[::1], int64[:])")
def frozen_test(x: Array, dx: Array, acc: Array, after: Array, h: float, travel: float, r: int,
                start: Array, period: float, per_speed: float, ramp: float, points: int,
                config_plan: Ints, config_ints: Ints, config_floats: Array,
                velocity_plan: Ints, velocity_ints: Ints, velocity_floats: Array,
                end_floor: Array, mid_floor: Array, sigma_floor: Array, has_config: bool,
                has_stop: bool, spheres: bool, bounded: bool, sample_x: Array,
                sample_margins: Array, enough: float, nc: int, work: Array,
                slots: Ints) -> tuple[float, float]:
    """F of one torque under the frozen prediction (the acceleration ``acc`` at the sample,
    ``after`` the model's at the continuous-time end, r = 2 predictions with the corrector,
    else 1), its rows into ``work``: (F, 0), or (NaN, k) where k rows need their joint
    placements (``slots`` numbers them, −1 the others; ``frozen_finish`` ends F). With
    ``bounded`` (and sphere pairs among the margins) the sphere clearances are bounded from
    the ``sample_x`` and its margins where that settles them (``bounded_slack``, ``enough``
    as there); without, every row is marked. The brake's path has ``points`` points (0
    without (S2): ``start``, ``period``, ``per_speed`` and ``ramp`` then unread)."""
    n = x.shape[0]
    nv = end_floor.shape[0] - nc
    rows, ends, speeds, mids, mid_speeds, config, velocity, inside = frozen_parts(
        work, r, n, points, nc, nv)
    frozen_rows(x, dx, acc, after, h, travel, mids, ends, speeds, mid_speeds)
    no_past = np.zeros(0, dtype=np.bool_)
    if has_config:
        configuration_rows(mids, ends, speeds, start, period, per_speed, ramp, rows)
        if spheres and bounded:
            return bounded_slack(config_plan, config_ints, config_floats, velocity_plan,
                                 velocity_ints, velocity_floats, rows, ends, speeds, mids,
                                 mid_speeds, config, velocity, inside, end_floor, mid_floor,
                                 sigma_floor, no_past, has_stop, sample_x, sample_margins,
                                 enough, slots)
        if spheres:  # every clearance at every row
            all_but_spheres(config_plan, config_ints, config_floats, velocity_plan,
                            velocity_ints, velocity_floats, rows, ends, speeds, mids,
                            mid_speeds, config, velocity, inside, math.nan)
            for i in range(rows.shape[0]):
                slots[i] = i
            return math.nan, float(rows.shape[0])
    f = predicted_slack(config_plan, config_ints, config_floats, velocity_plan, velocity_ints,
                        velocity_floats, rows, np.zeros((0, 1, 1)), slots[:0], ends, speeds,
                        mids, mid_speeds, config, velocity, inside, end_floor, mid_floor,
                        sigma_floor, no_past, False, has_config, has_stop)
    return f, 0.0


@kernel("float64(int64[:, :], int64[:, :], float64[:, :], float64[::1], int64, int64, int64,"
        " int64, float64[:, :, :], int64[:], float64[:], float64[:], float64[:], boolean,"
        " boolean)")
def frozen_finish(config_plan: Ints, config_ints: Ints, config_floats: Array, work: Array,
                  r: int, n: int, points: int, nc: int, placements: Array, slots: Ints,
                  end_floor: Array, mid_floor: Array, sigma_floor: Array, has_config: bool,
                  has_stop: bool) -> float:
    """F where ``frozen_test`` marked rows: the clearances it left NaN at them, from their
    joint ``placements`` (numbered by ``slots``; ``spheres_at``), then ``slack`` over its
    buffer ``work``."""
    nv = end_floor.shape[0] - nc
    config, velocity, inside = frozen_parts(work, r, n, points, nc, nv)[5:]
    spheres_at(config_plan, config_ints, config_floats, placements, slots, config)
    return slack(config, velocity, inside, r, end_floor, mid_floor, sigma_floor,
                 np.zeros(0, dtype=np.bool_), False, has_config, has_stop)


@inner("float64(int64[:, :], int64[:, :], float64[:, :], float64[:, :], float64[:, :],"
       f" float64[:], float64, float64[:, :], float64[:, :], boolean, {READ_ONLY}, float64,"
       " float64[:])")
def _ramp_rows(velocity_plan: Ints, velocity_ints: Ints, velocity_floats: Array, ends: Array,
               speeds: Array, start: Array, h: float, inertia: Array, to_joint: Array,
               mapped: bool, rate: Array, share: float, floor: Array) -> float:
    """``frozen_ramp``'s share over the predictions' ``ends`` and end rates ``speeds``."""
    peaks = np.empty(speeds.shape)
    ramp_speeds(speeds, start, h, inertia, to_joint, mapped, rate, share, peaks)
    return ramp_share(velocity_plan, velocity_ints, velocity_floats, ends, peaks,
                      np.zeros((0, 1, 1)), np.empty((ends.shape[0], floor.shape[0])), floor)


@kernel("float64(int64[:, :], int64[:, :], float64[:, :], float64[::1], int64, int64, int64,"
        f" int64, float64[:], float64, float64[:, :], float64[:, :], boolean, {READ_ONLY},"
        " float64, float64[:])")
def frozen_ramp(velocity_plan: Ints, velocity_ints: Ints, velocity_floats: Array, work: Array,
                r: int, n: int, points: int, nc: int, start: Array, h: float, inertia: Array,
                to_joint: Array, mapped: bool, rate: Array, share: float,
                floor: Array) -> float:
    """Under a torque-rate limit, the velocity margins where the rates peak while the torque
    ramps back (``ramp_speeds``, ``ramp_share``; PredictedMargins.ramp_slack) at the ends
    ``frozen_test`` left in ``work``: min_j ψ_j/δ_j − 1."""
    nv = floor.shape[0]  # the velocity margins' cushions
    ends, speeds = frozen_parts(work, r, n, points, nc, nv)[1:3]
    return _ramp_rows(velocity_plan, velocity_ints, velocity_floats, ends, speeds, start, h,
                      inertia, to_joint, mapped, rate, share, floor)


@inner("void(float64[:, ::1], int64, float64[:, :])")
def _first_rows(config: Array, r: int, out: Array) -> None:
    """The configuration margins of the first prediction — its mid-period row, 0, and its
    end row, r (``frozen_parts``) — into the rows of ``out`` (2 × nc)."""
    for j in range(out.shape[1]):
        out[0, j], out[1, j] = config[0, j], config[r, j]


@inner("float64(int64[:, :], float64[::1], float64[:, :], int64, int64, int64, int64, boolean,"
       " float64[:])")
def first_positivity(config_plan: Ints, work: Array, before: Array, r: int, n: int,
                     points: int, nc: int, has_config: bool, cushion: Array) -> float:
    """(S0) — every margin above its cushion δ, ``slack`` with the cushions as floors —
    over the first of the r predictions whose margins F's test left in ``work``
    (``frozen_parts``): its sign is the sign (S0)'s own test of the torque gives
    (Brakes.positivity), which makes the same margins over that prediction alone. Where the
    sample's bound stood in for a sphere clearance there (``before``: the configuration
    margins of its mid-period and end rows before the marked clearances were made, NaN
    where one was to be made) and is below its cushion, the clearance itself is unknown:
    NaN, the test is to be made. A bound at or above its cushion leaves the sign as it is
    (the clearance is at least the bound). The ramp's share is not here (frozen_chain_test
    takes the lesser)."""
    nv = cushion.shape[0] - nc
    config, velocity, inside = frozen_parts(work, r, n, points, nc, nv)[5:]
    first = np.empty((2, nc if has_config else 0))
    if has_config:
        _first_rows(config, r, first)
        for p in range(config_plan.shape[0]):
            if config_plan[p, KIND] != SPHERES:
                continue
            at = config_plan[p, FIRST]
            for i in range(2):
                for c in range(at, at + config_plan[p, COUNT]):
                    bound = before[i, c]
                    if bound == bound and not bound >= cushion[c]:
                        return math.nan
    return slack(first, velocity[:1], inside[:1], 1, cushion, cushion[:first.shape[1]],
                 cushion, np.zeros(0, dtype=np.bool_), False, has_config, False)


@kernel("UniTuple(float64, 3)(float64[:], float64[:], float64[:], float64[:], float64, float64,"
        " int64, float64[:], float64, float64, float64, int64, int64[:, :], int64[:, :],"
        " float64[:, :], int64[:, :], int64[:, :], float64[:, :], float64[:], float64[:],"
        f" float64[:], boolean, boolean, boolean, {READ_ONLY}, {READ_ONLY}, float64, int64,"
        " float64[::1], int64[:], int64[:], int64[:], float64[:, :], float64[:, :, :],"
        " float64[:, :], int64[:], float64, boolean, float64[:], float64, float64[:, :],"
        f" float64[:, :], boolean, {READ_ONLY}, float64, float64[:], boolean, float64[:])")
def frozen_chain_test(x: Array, dx: Array, acc: Array, after: Array, h: float, travel: float,
                      r: int, start: Array, period: float, per_speed: float, ramp: float,
                      points: int, config_plan: Ints, config_ints: Ints, config_floats: Array,
                      velocity_plan: Ints, velocity_ints: Ints, velocity_floats: Array,
                      end_floor: Array, mid_floor: Array, sigma_floor: Array,
                      has_config: bool, has_stop: bool, bounded: bool, sample_x: Array,
                      sample_margins: Array, enough: float, nc: int, work: Array,
                      slots: Ints, parents: Ints, kinds: Ints, axes: Array,
                      rotations: Array, translations: Array, coordinates: Ints,
                      scale: float, has_ramp: bool, ramp_start: Array, ramp_period: float,
                      ramp_inertia: Array, to_joint: Array, mapped: bool, rate: Array,
                      share: float, ramp_floor: Array, has_cushion: bool,
                      cushion: Array) -> tuple[float, float, float]:
    """``frozen_test``, the marked rows' joint placements (``joint_placements``, the arm's
    chain: cpbc.model.joint_chain), ``frozen_finish`` and, with ``has_ramp``,
    ``frozen_ramp`` (the lesser) in one call, for an arm whose sphere pairs pack and whose
    chain is compiled: (F, the rows whose placements it made, P), F the same as the four
    calls and the placements between them give, bit for bit; what it saves is three calls
    from Python, the rows picked out and the placements' wrapper. With ``has_cushion``, P is
    (S0) of the same torque over the first prediction (``first_positivity``, the cushions
    ``cushion`` its floors), read from the margins F's test made, or NaN where they do not
    tell it; without, NaN."""
    f, marked = frozen_test(x, dx, acc, after, h, travel, r, start, period, per_speed, ramp,
                            points, config_plan, config_ints, config_floats, velocity_plan,
                            velocity_ints, velocity_floats, end_floor, mid_floor,
                            sigma_floor, has_config, has_stop, True, bounded, sample_x,
                            sample_margins, enough, nc, work, slots)
    n = x.shape[0]
    nv = end_floor.shape[0] - nc
    # the first prediction's configuration margins before the marked clearances are made:
    # where a sphere clearance is not NaN here, the sample's bound stands in for it
    before = np.empty((2, nc if has_config and has_cushion else 0))
    if before.shape[1]:
        _first_rows(frozen_parts(work, r, n, points, nc, nv)[5], r, before)
    if marked:
        k = int(marked)
        picked = np.empty((k, n))
        for i in range(slots.shape[0]):  # numbered from 0 in row order (_bound_spheres)
            if slots[i] >= 0:
                for j in range(n):
                    picked[slots[i], j] = work[i * n + j]
        placements = np.empty((k, 3, 4 * parents.shape[0]))
        joint_placements(parents, kinds, axes, rotations, translations, coordinates, scale,
                         picked, placements)
        f = frozen_finish(config_plan, config_ints, config_floats, work, r, n, points, nc,
                          placements, slots, end_floor, mid_floor, sigma_floor, has_config,
                          has_stop)
    kept = math.nan
    if has_cushion:
        kept = first_positivity(config_plan, work, before, r, n, points, nc, has_config,
                                cushion)
    if not has_ramp:
        return f, marked, kept
    found = frozen_ramp(velocity_plan, velocity_ints, velocity_floats, work, r, n, points,
                        nc, ramp_start, ramp_period, ramp_inertia, to_joint, mapped, rate,
                        share, ramp_floor)
    if kept == kept:  # the ramp's share of the first prediction alone, as (S0)'s test asks
        ends, speeds = frozen_parts(work, r, n, points, nc, nv)[1:3]
        first = _ramp_rows(velocity_plan, velocity_ints, velocity_floats, ends[:1],
                           speeds[:1], ramp_start, ramp_period, ramp_inertia, to_joint,
                           mapped, rate, share, ramp_floor)
        kept = first if first < kept else kept
    return (found if found < f else f), marked, kept  # min(f, found), as Python's
