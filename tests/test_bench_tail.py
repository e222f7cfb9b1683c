"""The guarded step's closed-loop time distribution (cpbc.bench_tail): what it times, counts
and records, on a few short runs of panda_cpbc_sphere (no time is asserted: a bench's
figures are printed, not tested)."""

from __future__ import annotations

import math

import pytest

from cpbc.bench_tail import QUANTILES, TimedPass, guarded_tail, least_of_repeats, quantiles
from cpbc.errors import ParameterError


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


def _pass(times: list[list[int]], torques: list[list[bytes]]) -> TimedPass:
    made = TimedPass()
    made.times, made.torques = times, torques
    return made


def test_a_step_s_own_time_is_its_least_over_the_repeats_that_made_it_the_same_way() -> None:
    """Two runs, three passes: each step's least time over the passes whose torques agree
    with the first's up to it; a pass that changed a run's torque at its third step leaves
    the run's steps from there out (not the same computation), and so does a pass whose run
    ended sooner."""
    a, b, c, d = b"a", b"b", b"c", b"d"
    first = _pass([[10, 20, 30, 40], [5, 6]], [[a, b, c, d], [a, b]])
    second = _pass([[12, 15, 31, 39], [4, 9]], [[a, b, c, d], [a, b]])
    third = _pass([[11, 25, 1, 1], [7]], [[a, b, d, d], [a]])
    assert least_of_repeats([first]) == [10, 20, 30, 40, 5, 6]
    assert least_of_repeats([first, second]) == [10, 15, 30, 39, 4, 6]
    assert least_of_repeats([first, second, third]) == [10, 15, 4]


def test_repeated_runs_time_each_step_again_and_keep_its_least() -> None:
    """Without a time budget the loop is deterministic: a second pass makes every step the
    same way, and each step's own time is at most its first pass's, so every quantile of
    ``own`` is too. No repeat is refused by name."""
    tail = guarded_tail(300, seconds=0.1, rate_limit=1000.0, rescue_budget=8, test_budget=2,
                        repeats=2)
    assert tail["repeats"] == 2 and tail["own_steps"] == tail["steps"]
    own = tail["own"]
    assert isinstance(own, dict)
    for key in (*QUANTILES, "max"):
        assert 0.0 < own[key] <= tail[key]  # type: ignore[operator]
    assert tail["own_max_over_p50"] == pytest.approx(own["max"] / own["p50"])
    with pytest.raises(ParameterError, match="repeats"):
        guarded_tail(10, repeats=0)


def test_a_restarted_timer_primes_its_guard_once_before_its_first_timed_step(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """After ``restart`` the records are empty and the next call primes the guard at its
    state before timing it (Safeguard.prime, as a robot's first cycle does); later calls do
    not, and priming moves no count."""
    import numpy as np

    from cpbc.bench_tail import TimedFilter
    from cpbc.reliability.campaign import campaign_setup
    setup = campaign_setup("panda_cpbc_sphere", integrator="Euler")
    entry = next(e for e in setup.controllers if not e.controller.constraints.empty)
    guard = setup.controller(entry)
    primed: list[np.ndarray] = []
    real = guard.prime
    monkeypatch.setattr(guard, "prime", lambda x, dx: (primed.append(x), real(x, dx)))
    timed = TimedFilter(guard)
    case = setup.cases[0]
    x, dx = np.asarray(case.position, dtype=float), np.asarray(case.velocity, dtype=float)
    timed.evaluate(x, dx)
    assert primed == [] and len(timed.times) == len(timed.torques) == 1
    timed.restart()
    assert timed.times == timed.cpu == timed.acting == timed.bare == timed.torques == []
    timed.evaluate(x, dx)
    timed.evaluate(x, dx)
    assert len(primed) == 1 and np.array_equal(primed[0], x)
    assert guard.calls == 3 and len(timed.times) == 2
