"""The guarded step's closed-loop time distribution (cpbc.bench_tail): what it times, counts
and records, on a few short runs of panda_cpbc_sphere (no time is asserted: a bench's
figures are printed, not tested)."""

from __future__ import annotations

import math

import pytest

from cpbc.bench_tail import QUANTILES, guarded_tail, quantiles


def test_quantiles_of_nothing_are_nan_and_of_a_list_ordered() -> None:
    empty = quantiles([])
    assert set(empty) == {*QUANTILES, "max"} and all(math.isnan(v) for v in empty.values())
    found = quantiles([1000, 2000, 3000, 100_000])
    assert found["p50"] == pytest.approx(2.5) and found["max"] == pytest.approx(100.0)
    values = [found[k] for k in (*QUANTILES, "max")]
    assert values == sorted(values)


@pytest.mark.parametrize("rate", [None, 1000.0])
def test_the_tail_times_every_step_of_runs_where_the_guard_acts(rate: float | None) -> None:
    """At least the steps asked for, each timed on both clocks beside the bare law; the
    campaign's starts near a boundary make the guard act; the bounds it ran under are
    recorded, and under a budget of tests the step runs out of them somewhere."""
    tail = guarded_tail(400, seconds=0.1, rate_limit=rate, rescue_budget=8, test_budget=2)
    assert tail["steps"] >= 400 and tail["runs"] >= 4
    assert 0 < tail["acting_steps"] < tail["steps"]
    assert tail["out_of_tests"] > 0
    for key in ("bare_law", "acting", "cpu", "acting_cpu"):
        values = [tail[key][k] for k in (*QUANTILES, "max")]  # type: ignore[index]
        assert values == sorted(values) and values[0] > 0.0
    assert tail["max_over_p50"] == pytest.approx(tail["max"] / tail["p50"])  # type: ignore[operator]
    assert (tail["rate_limit"], tail["rescue_budget"], tail["test_budget"]) == (rate, 8, 2)
    assert tail["time_budget_us"] is None
