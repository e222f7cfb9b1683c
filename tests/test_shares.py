"""F of (S1) and (S2) from margins and floors (cpbc.kernels.shares): the division-free check
``keeps_floors`` says yes only where ``slack`` is ≥ 0, and says yes wherever every margin is
at or above a positive floor; a quotient's ≥ 1 is a comparison's."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.kernels.shares import keeps_floors, slack

NO_PAST = np.zeros(0, dtype=bool)


def _groups(rng: np.random.Generator, ends: int = 2, points: int = 1, nc: int = 5, nv: int = 3):
    rows = (2 + points) * ends
    floor = rng.uniform(0.01, 1.0, nc + nv)
    mid, sigma = rng.uniform(0.01, 1.0, nc), rng.uniform(0.01, 1.0, nc)
    config = np.empty((rows, nc))
    config[:ends] = mid * rng.uniform(1.0, 3.0, (ends, nc))
    config[ends:2 * ends] = floor[:nc] * rng.uniform(1.0, 3.0, (ends, nc))
    config[2 * ends:] = sigma * rng.uniform(1.0, 3.0, (rows - 2 * ends, nc))
    velocity = floor[nc:] * rng.uniform(1.0, 3.0, (ends, nv))
    inner = floor[nc:] * rng.uniform(1.0, 3.0, (ends, nv))
    return config, velocity, inner, ends, floor, mid, sigma


@pytest.mark.parametrize("seed", range(6))
def test_keeping_every_floor_is_told_without_dividing(seed: int) -> None:
    """Margins at or above their floors (some exactly on them): yes, and F ≥ 0; then one
    margin nudged below its floor by one ulp, made NaN, or one floor made 0 or NaN, in each
    group in turn: no (F then tells, and where a margin is below its floor it is < 0)."""
    rng = np.random.default_rng(seed)
    config, velocity, inner, ends, floor, mid, sigma = _groups(rng)
    nc = config.shape[1]
    config[ends, 0] = floor[0]  # exactly on its floor
    args = (ends, floor, mid, sigma)
    assert keeps_floors(config, velocity, inner, *args, True, True)
    assert slack(config, velocity, inner, *args, NO_PAST, False, True, True) >= 0.0
    for group, at, below in ((config, (0, 1), mid[1]), (config, (ends, 2), floor[2]),
                             (config, (2 * ends, 3), sigma[3]), (velocity, (1, 0), floor[nc]),
                             (inner, (0, 2), floor[nc + 2])):
        for bad in (np.nextafter(below, 0.0), np.nan):
            kept = group[at]
            group[at] = bad
            assert not keeps_floors(config, velocity, inner, *args, True, True)
            f = slack(config, velocity, inner, *args, NO_PAST, False, True, True)
            assert f < 0.0 or np.isnan(f) or bad != bad
            group[at] = kept
    for floors in (floor, mid, sigma):
        kept = floors[1]
        for bad in (0.0, np.nan, -0.5):
            floors[1] = bad
            assert not keeps_floors(config, velocity, inner, *args, True, True)
        floors[1] = kept
    assert keeps_floors(config, velocity, inner, *args, True, True)


def test_without_configuration_margins_or_stopping_points() -> None:
    """The groups ``slack`` skips are skipped: a stopping row below its floor does not
    count without (S2), nor configuration rows without configuration margins."""
    rng = np.random.default_rng(9)
    config, velocity, inner, ends, floor, mid, sigma = _groups(rng)
    config[2 * ends, 0] = 0.0
    assert not keeps_floors(config, velocity, inner, ends, floor, mid, sigma, True, True)
    assert keeps_floors(config, velocity, inner, ends, floor, mid, sigma, True, False)
    nc = config.shape[1]
    empty = np.zeros((0, 0))
    assert keeps_floors(empty, velocity, inner, ends, floor[nc:], mid[:0], sigma[:0], False,
                        False)


def test_a_quotient_at_least_one_is_a_comparison() -> None:
    """b / f ≥ 1 exactly where b ≥ f, for positive finite doubles, next to each other and
    far apart, subnormal ones too (cpbc.kernels.sampled_guard._bound_spheres reads its
    unit threshold so)."""
    rng = np.random.default_rng(4)
    f = np.concatenate([rng.uniform(1e-12, 1e6, 4000), 10.0 ** rng.uniform(-310, 300, 4000)])
    f = f[f > 0.0]
    for b in (f, np.nextafter(f, 0.0), np.nextafter(f, np.inf), f * rng.uniform(0.5, 2.0,
                                                                               len(f))):
        with np.errstate(over="ignore", under="ignore"):
            np.testing.assert_array_equal(b / f >= 1.0, b >= f)
