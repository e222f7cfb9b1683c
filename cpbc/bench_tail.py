"""The guarded step's time distribution in closed loop (``python -m cpbc.bench --peers``'s
``guarded_tail_us``): what a hard control deadline asks of the law with its safeguard.

A median says what a step usually costs; a 1 kHz loop on a robot fails on its worst step.
This runs ``panda_cpbc_sphere`` (the Panda, URDF torque limits, joint and rate limits, a
ball and a table) from the verification campaign's seeded starts — most of them near a
boundary, so the safeguard intervenes, searches its brakes and rescues — and times every
guarded call, ``evaluate(x, ẋ)`` (the state's Pinocchio pass, the law and the guard), in the
MuJoCo loop, with Python's garbage collector off as the loop runs it. Before each run every
path of a step is taken once on a spare guard (Safeguard.warm), as cpbc.hardware does before
a motion: without it the worst steps of 10⁵ were runs' first acting steps, which took the
untaken paths' first calls (455 and 483 µs, each the second step of its run). Right before a
run's first timed step the driving guard is primed at its state (Controller.prime), as
cpbc.hardware does in a motion's first cycle: the loop's set-up left its data cold, and
runs' first steps were 8 of the 10 slowest. It reports the median, the 99th, 99.9th and
99.99th percentiles and the maximum over all steps, the same for the steps at which the
guard replaced the law's torque, and how many steps of each kind there were; and the same
quantiles of the thread's CPU time per call (``cpu``, ``acting_cpu``), which other
processes' preemption does not inflate: on a loaded machine the wall-clock tail is the
scheduler's, the CPU tail the guard's own work. Beside them, the guard's law alone at every
same state, timed just before the guarded call (``bare_law``): the machine's own tail for a
call that does a fixed small amount of work, against which a worst step read as a multiple
of the median is to be judged (on the project's VM, idle, the bare law's max was 16–58 × its
median over 10⁵ calls). Nothing is asserted: figures for the docs and for a deadline budget."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.controller import Evaluation, SafetyFilter
from cpbc.controllers.safeguard import Safeguard, SafeguardSettings
from cpbc.errors import ConstraintViolation, ParameterError
from cpbc.model.robot_model import ArmState
from cpbc.simulation import run_mujoco

if TYPE_CHECKING:
    from cpbc.scenario import ScenarioSetup

QUANTILES = {"p50": 50.0, "p99": 99.0, "p999": 99.9, "p9999": 99.99}


class TimedFilter(SafetyFilter):
    """A safety filter that times each of its guard's calls (ns) and marks the steps at
    which the guard acted; everything else is the guard's."""

    def __init__(self, guard: SafetyFilter) -> None:
        super().__init__(guard.model, guard.target, guard.constraints)
        self.guard = guard
        self.times: list[int] = []
        self.cpu: list[int] = []  # the thread's CPU time: no preemption by other processes
        self.acting: list[bool] = []
        self.bare: list[int] = []  # the guard's law alone at the same state, just before
        self.torques: list[bytes] = []  # what each call returned, to tell repeats apart
        self._prime = False  # the next call is a loop's first (restart)

    def restart(self) -> None:
        """A loop begins: the records emptied, and its first call primes the guard at its
        state before it is timed (Controller.prime), as cpbc.hardware does in a motion's
        first cycle (the loop's set-up leaves the caches cold)."""
        for record in (self.times, self.cpu, self.acting, self.bare, self.torques):
            record.clear()
        self._prime = True

    def state(self, x: Array, dx: Array) -> ArmState:
        return self.guard.state(x, dx)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        return self.guard.evaluate_state(state, margins)

    def evaluate(self, x: Array, dx: Array) -> tuple[Array, float]:
        guard = self.guard
        if self._prime:
            self._prime = False
            guard.prime(x, dx)
        law = getattr(guard, "law", None)
        if law is not None:  # the machine's own tail: the bare law's, in the same runs
            start = time.perf_counter_ns()
            law.evaluate(x, dx)
            self.bare.append(time.perf_counter_ns() - start)
        before = guard.acted
        start, start_cpu = time.perf_counter_ns(), time.thread_time_ns()
        out = guard.evaluate(x, dx)
        self.times.append(time.perf_counter_ns() - start)
        self.cpu.append(time.thread_time_ns() - start_cpu)
        self.acting.append(guard.acted != before)
        self.torques.append(np.asarray(out[0]).tobytes())
        self.acted, self.infeasible, self.rescues = guard.acted, guard.infeasible, guard.rescues
        return out

    def lyapunov(self, x: Array, dx: Array) -> float:
        return self.guard.lyapunov(x, dx)

    def holding(self, tau: Array, added: Array | None = None) -> None:
        self.guard.holding(tau, added)


def quantiles(times_ns: Sequence[int]) -> dict[str, float]:
    """p50 … p9999 and max of ``times_ns`` [µs] (empty: NaN)."""
    if not len(times_ns):
        return {**{k: float("nan") for k in QUANTILES}, "max": float("nan")}
    us = np.asarray(times_ns, dtype=float) / 1e3
    return {**{k: float(np.percentile(us, q)) for k, q in QUANTILES.items()},
            "max": float(us.max())}


class TimedPass:
    """One pass of the tail's closed-loop runs: every timed step's wall and CPU time, whether
    the guard acted, the bare law's time, and the torque it returned (bytes), run by run."""

    def __init__(self) -> None:
        self.times: list[list[int]] = []
        self.cpu: list[int] = []
        self.acting: list[bool] = []
        self.bare: list[int] = []
        self.torques: list[list[bytes]] = []
        self.counts = {"runs": 0, "rescues": 0, "infeasible": 0, "out_of_tests": 0}

    @property
    def steps(self) -> int:
        return sum(map(len, self.times))

    def flat_times(self) -> list[int]:
        return [t for run in self.times for t in run]


def _run_all(setup: ScenarioSetup, steps: int, seconds: float, seed: int,
             runs: int | None = None) -> TimedPass:
    """The campaign's seeded starts run one after another until ``steps`` steps are timed
    (or, given, exactly ``runs`` runs: the same starts again)."""
    from cpbc.reliability.campaign import state_sampler

    entry = next(e for e in setup.controllers if not e.controller.constraints.empty)
    settings = replace(setup.loop_settings, duration=seconds)
    plant = setup.make_plant()
    out = TimedPass()
    starts = state_sampler(setup, seed)  # drawn until the steps are timed: some runs end early
    for _ in range(2 * steps if runs is None else runs):  # a bound, for runs that end at once
        if runs is None and out.steps >= steps:
            break
        s = starts.draw()
        spare = setup.controller(entry)  # every path of a step, as before a robot's motion
        if isinstance(spare, Safeguard):
            with contextlib.suppress(ConstraintViolation):
                spare.warm(s.position, s.velocity)
        guard = setup.controller(entry)
        assert isinstance(guard, SafetyFilter)
        timed = TimedFilter(guard)
        timed.evaluate(s.position, s.velocity)  # warm this run's paths, not timed
        timed.restart()
        run_mujoco(plant, timed, setup.model.coordinates, s.position, s.velocity, settings)
        out.times.append(timed.times)
        out.torques.append(timed.torques)
        out.cpu.extend(timed.cpu)
        out.acting.extend(timed.acting)
        out.bare.extend(timed.bare)
        for key in ("rescues", "infeasible", "out_of_tests"):
            out.counts[key] += getattr(guard, key)
        out.counts["runs"] += 1
    return out


def _same_prefix(first: Sequence[bytes], other: Sequence[bytes]) -> int:
    """How many steps from a run's start two passes made by the same torques."""
    n = min(len(first), len(other))
    return next((i for i in range(n) if first[i] != other[i]), n)


def least_of_repeats(passes: Sequence[TimedPass]) -> list[int]:
    """The least time of each step over the passes, for the steps every pass made by the
    same torques as the first, every step before it in its run included: the same
    computation from the same state (the loop is deterministic but for what a time budget
    cuts). The step's own work: the host's interruptions are taken out wherever they missed
    one repeat of it."""
    first = passes[0]
    least: list[int] = []
    for r, (times, torques) in enumerate(zip(first.times, first.torques, strict=True)):
        best = np.asarray(times, dtype=np.int64)
        common = len(times)
        for other in passes[1:]:
            k = _same_prefix(torques, other.torques[r])
            common = min(common, k)
            best[:k] = np.minimum(best[:k], np.asarray(other.times[r][:k], dtype=np.int64))
        least.extend(best[:common].tolist())
    return least


def guarded_tail(steps: int = 100_000, seconds: float = 0.5, seed: int = 0,
                 scenario: str = "panda_cpbc_sphere", integrator: str | None = "Euler",
                 rate_limit: float | None = None,
                 rescue_budget: int | None = None,
                 test_budget: int | None = None,
                 time_budget: float | None = None,
                 repeats: int = 1) -> dict[str, object]:
    """The guarded law of ``scenario`` (its first constrained one; ``integrator``: the
    plant's, MuJoCo's default semi-implicit Euler unless given, None for the scenario's)
    timed over at least ``steps`` control steps of
    ``seconds``-long runs from the campaign's seeded starts (``rate_limit``: a torque-rate
    limit [N·m/s] for plant and guard, or the scenario's none; ``rescue_budget``,
    ``test_budget`` and ``time_budget`` [s]: the safeguard's bounds on a step, or the
    scenario's none). With ``repeats`` > 1 the same runs are made that many times in all,
    and ``own`` gives the quantiles of each step's least time over them, over the
    ``own_steps`` steps every pass made the same way (:func:`least_of_repeats`); the other
    figures are the first pass's."""
    from cpbc.reliability.campaign import campaign_setup

    if repeats < 1:
        raise ParameterError("repeats", f"repeats must be ≥ 1, got {repeats}")
    setup = campaign_setup(scenario, integrator=integrator)
    if rate_limit is not None:
        limit = np.full(setup.model.n, float(rate_limit))
        bounds = replace(setup.loop_settings.bounds, rate=limit)
        setup = replace(setup, loop_settings=replace(setup.loop_settings, bounds=bounds))
    if setup.safeguard is not None and rescue_budget is not None:
        setup = replace(setup, safeguard=replace(setup.safeguard, rescue_budget=rescue_budget))
    if setup.safeguard is not None and test_budget is not None:
        setup = replace(setup, safeguard=replace(setup.safeguard, test_budget=test_budget))
    if setup.safeguard is not None and time_budget is not None:
        setup = replace(setup, safeguard=replace(setup.safeguard, time_budget=time_budget))
    guard_settings = setup.safeguard or SafeguardSettings()
    first = _run_all(setup, steps, seconds, seed)
    times, acting, cpu = first.flat_times(), first.acting, first.cpu
    acted = [t for t, a in zip(times, acting, strict=True) if a]
    every, law = quantiles(times), quantiles(first.bare)
    found: dict[str, object] = {
        **every, "steps": len(times), "acting_steps": len(acted),
        "bare_law": law, "bare_law_max_over_p50": law["max"] / law["p50"],
        "acting": quantiles(acted), "cpu": quantiles(cpu),
        "acting_cpu": quantiles([t for t, a in zip(cpu, acting, strict=True) if a]),
        "max_over_p50": every["max"] / every["p50"],
        **first.counts, "rate_limit": rate_limit, "rescue_budget": guard_settings.rescue_budget,
        "test_budget": guard_settings.test_budget, "time_budget_us":
            None if time_budget is None else 1e6 * time_budget,
        "setup": f"{scenario}'s guarded law, {seconds:g} s runs from the "
                 f"campaign's starts (seed {seed}), 1 kHz, garbage collector off"}
    if repeats > 1:
        passes = [first, *(_run_all(setup, steps, seconds, seed, runs=first.counts["runs"])
                           for _ in range(repeats - 1))]
        own = least_of_repeats(passes)
        mine = quantiles(own)
        found.update(repeats=repeats, own=mine, own_steps=len(own),
                     own_max_over_p50=mine["max"] / mine["p50"])
    return found


#: The guarded step's tails in closed loop (cpbc.bench_tail), by key: the first is the step
#: with a deadline that the targets (max ≤ 5 × p50, p99.99 ≤ 250 µs) are read on.
TAILS = (("guarded_tail_us", "as on a Franka"),
         ("guarded_tail_no_rate_us", "the same bounds without a torque-rate limit"),
         ("guarded_tail_unbounded_us", "simulation's guard: no time budget"))


def bench_tails(steps: int, repeats: int) -> dict[str, dict[str, object]]:
    """The tails ``python -m cpbc.bench --robot panda --peers`` reports, keyed as :data:`TAILS`:
    bounded as cpbc.hardware bounds the guard on a robot at 1 kHz (the tail's runs are the
    Panda's at 1 kHz: a deadline of one period) under the Franka's own torque-rate limit
    (libfranka's 1000 N·m/s a joint, every candidate reached into the step's rate box, as
    cpbc.hardware runs the arm) — the step the deadline is about —, then the same bounds
    without the rate limit, then simulation's guard, which has no time budget (its tail is
    the rescue's search: milliseconds, by design)."""
    from cpbc.hardware.franka import FR3_LIMITS
    from cpbc.hardware.robot_run import (
        ROBOT_RESCUE_BUDGET,
        ROBOT_TEST_BUDGET,
        ROBOT_TIME_SHARE,
    )

    found = {}
    for key, rate in (("guarded_tail_us", float(FR3_LIMITS.torque_rate.max())),
                      ("guarded_tail_no_rate_us", None)):
        found[key] = guarded_tail(
            steps, rate_limit=rate, rescue_budget=ROBOT_RESCUE_BUDGET,
            test_budget=ROBOT_TEST_BUDGET, time_budget=ROBOT_TIME_SHARE * 1e-3,
            repeats=repeats)
    found["guarded_tail_unbounded_us"] = guarded_tail(steps, repeats=repeats)
    return found
