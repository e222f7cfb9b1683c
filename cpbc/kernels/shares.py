"""F of the safeguard's (S1) and (S2) from the margins along a prediction and their floors
(cpbc.controllers.safeguard, step 3): the least share m/floor of every group the guard holds
(``slack``), and whether every margin keeps its floor, told without dividing
(``keeps_floors``: all a first test needs where F ≥ 0, the calm step's usual answer).
"""

from __future__ import annotations

import math

from cpbc.arrays import Array
from cpbc.kernels import kernel
from cpbc.kernels.small_solves import nan_min
from cpbc.kernels.views import Bools


@kernel("float64(float64, float64)")
def _least(low: float, value: float) -> float:
    """Python's min(low, value): a NaN value is passed over, a NaN low kept."""
    return value if value < low else low


@kernel("float64(float64[:, :], int64, int64, int64, float64[:], boolean[:], boolean)")
def _least_share(m: Array, first: int, last: int, col: int, floor: Array, past: Bools,
                 has_past: bool) -> float:
    """min over rows [first, last) of m/floor per margin (≥ 1: the margin keeps its floor),
    NaN margins counted as −∞; where ``past`` (the margin broken already) 1 + (m −
    floor)/|floor| instead. ``col``: the column of m's first margin in ``floor``/``past``."""
    low = math.inf
    for i in range(first, last):
        for j in range(m.shape[1]):
            v = m[i, j]
            if v != v:
                v = -math.inf
            f = floor[col + j]
            if has_past and past[col + j]:
                share = 1.0 + (v - f) / max(abs(f), 1e-12)
            else:
                share = v / f
            low = nan_min(low, share)
    return low


@kernel("float64(float64[:, :], float64[:, :], float64[:, :], int64, float64[:], float64[:],"
        " float64[:], boolean[:], boolean, boolean, boolean)")
def slack(config: Array, velocity: Array, inner: Array, ends: int, end_floor: Array,
          mid_floor: Array, sigma_floor: Array, past: Bools, has_past: bool, has_config: bool,
          has_stop: bool) -> float:
    """F = min_i m_i/floor_i − 1 (≥ 0: every margin keeps its floor; the package docstring,
    (S1) and (S2)) over the margins along one prediction of ``ends`` rows: ``config`` the
    configuration margins at the mid-period rows, the ends and (``has_stop``) the uniform
    brake's stopping points, ``velocity`` the velocity margins at the ends, ``inner`` those
    inside the period (held to their end floor). ``end_floor`` covers every margin, the
    configuration ones first; ``mid_floor`` and ``sigma_floor`` the configuration ones.
    ``past`` marks margins broken already: compared by difference, their braking margin not
    held. Groups combine as the Python they replace did (a NaN group is passed over)."""
    nc = config.shape[1] if has_config else 0
    low = math.inf
    if inner.shape[1] > 0:
        low = _least_share(inner, 0, inner.shape[0], nc, end_floor, past, has_past)
    end = _least_share(velocity, 0, velocity.shape[0], nc, end_floor, past, has_past)
    if not has_config:
        return _least(low, end) - 1.0
    end = nan_min(end, _least_share(config, ends, 2 * ends, 0, end_floor, past, has_past))
    low = _least(_least(low, end),
                 _least_share(config, 0, ends, 0, mid_floor, past, has_past))
    if has_stop:
        braking = math.inf
        for i in range(2 * ends, config.shape[0]):  # every stopping row (configuration_rows)
            for j in range(nc):
                v = config[i, j]
                if v != v:
                    v = -math.inf
                braking = nan_min(braking, math.inf if has_past and past[j]
                                 else v / sigma_floor[j])
        low = _least(low, braking)
    return low - 1.0


@kernel("boolean(float64[:, :], int64, int64, int64, float64[:])", inline=True)
def _keeps(m: Array, first: int, last: int, col: int, floor: Array) -> bool:
    """Every margin of rows [first, last) at or above its floor, every floor > 0, none NaN:
    then each share m/floor is ≥ 1 as ``_least_share`` rounds it (a correctly rounded
    quotient of m ≥ f > 0 is ≥ 1), without a division."""
    for i in range(first, last):
        for j in range(m.shape[1]):
            f = floor[col + j]
            if not (f > 0.0 and m[i, j] >= f):
                return False
    return True


@kernel("boolean(float64[:, :], float64[:, :], float64[:, :], int64, float64[:], float64[:],"
        " float64[:], boolean, boolean)")
def keeps_floors(config: Array, velocity: Array, inner: Array, ends: int, end_floor: Array,
                 mid_floor: Array, sigma_floor: Array, has_config: bool,
                 has_stop: bool) -> bool:
    """Whether every group ``slack`` reads keeps its floors (``_keeps``; no margin broken
    already): then ``slack`` is ≥ 0. False says nothing: ``slack`` then tells."""
    nc = config.shape[1] if has_config else 0
    if inner.shape[1] > 0 and not _keeps(inner, 0, inner.shape[0], nc, end_floor):
        return False
    if not _keeps(velocity, 0, velocity.shape[0], nc, end_floor):
        return False
    if not has_config:
        return True
    if not (_keeps(config, ends, 2 * ends, 0, end_floor)
            and _keeps(config, 0, ends, 0, mid_floor)):
        return False
    return not has_stop or _keeps(config, 2 * ends, config.shape[0], 0, sigma_floor)
