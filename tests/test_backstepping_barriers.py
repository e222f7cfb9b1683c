"""Barrier terms of §3.1/§3.3/§3.5: Γ = z/β'(z) and Γ' against finite differences, Lemma 3.12."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cpbc.backstepping import (
    DesignError,
    LogBarrier,
    QuadraticTerm,
    RationalBarrier,
)

BARRIERS = [
    RationalBarrier(0.3, 0.7, 2.0),
    RationalBarrier(1.0, 1.0, 0.5),
    LogBarrier(0.051, 0.07),
    QuadraticTerm(3.0),
]


def _interior(b, n: int = 41) -> np.ndarray:
    lo = max(b.lower, -1.0)
    hi = min(b.upper, 1.0)
    return np.linspace(lo, hi, n + 2)[1:-1] * 0.999


@pytest.mark.parametrize("barrier", BARRIERS, ids=repr)
def test_gamma_is_z_over_barrier_slope(barrier) -> None:
    for z in _interior(barrier):
        h = 1e-7 * max(barrier.upper - barrier.lower, 1.0) if math.isfinite(barrier.upper) else 1e-6
        h = min(h, 1e-4 * (min(z - barrier.lower, barrier.upper - z)))
        slope = (barrier.value(z + h) - barrier.value(z - h)) / (2 * h)
        if abs(z) > 1e-3:
            assert barrier.gamma(z) == pytest.approx(z / slope, rel=1e-5)
        assert barrier.gamma(z) > 0
        dg = (barrier.gamma(z + h) - barrier.gamma(z - h)) / (2 * h)
        assert barrier.dgamma(z) == pytest.approx(dg, rel=1e-5, abs=1e-9)


def test_rational_gamma_is_the_thesis_form() -> None:
    """(3.10) as printed (with k outside the bracket) and Lemma 3.3's y-form agree with ours."""
    a, b, k = 0.3, 0.7, 2.0
    bar = RationalBarrier(a, b, k)
    for z in _interior(bar):
        p = (a + z) * (b - z)
        printed = p * p / (k * (2 * p - z * ((b - z) - (a + z))))
        y = 2 - z / (a + z) + z / (b - z)
        assert bar.gamma(z) == pytest.approx(printed, rel=1e-12)
        assert bar.gamma(z) == pytest.approx(p / (k * y), rel=1e-12)


@pytest.mark.parametrize("a,b", [(0.3, 0.7), (1.0, 1.0), (0.05, 2.0)])
def test_lemma_3_12_bounds_gamma(a: float, b: float) -> None:
    """Y/k bounds Γ; it is the supremum only for a = b (it pairs max p with min y, which
    occur at different z otherwise), so for a ≠ b the bound (3.105) is conservative."""
    bar = RationalBarrier(a, b, 1.7)
    zs = np.linspace(-a, b, 4001)[1:-1]
    worst = max(bar.gamma(float(z)) for z in zs)
    assert worst <= bar.gamma_max * (1 + 1e-12)
    if a == b:
        assert worst == pytest.approx(bar.gamma_max, rel=1e-6)
    else:
        assert worst < 0.99 * bar.gamma_max


def test_log_barrier_values() -> None:
    bar = LogBarrier(0.5, 0.25)
    assert bar.gamma_max == pytest.approx(1.0)
    assert bar.value(0.0) == 0.0
    assert bar.value(0.5) == math.inf and bar.value(-0.6) == math.inf
    assert not bar.contains(0.5) and bar.contains(0.4999)


@pytest.mark.parametrize(
    "make", [lambda: RationalBarrier(0.0, 1, 1), lambda: LogBarrier(-1, 1),
             lambda: LogBarrier(1, math.nan), lambda: QuadraticTerm(0.0)]
)
def test_invalid_constants_are_refused(make) -> None:
    with pytest.raises(DesignError, match="must be finite and > 0"):
        make()
