"""The safeguard's budget of tests a step: counted where the guard tests a torque, and past
it the step holds the last torque that passed, else the uniform brake."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import campaign_run

from cpbc.controllers import RecentredBarrier
from cpbc.controllers.safeguard import Safeguard, SafeguardSettings, viable
from cpbc.controllers.safeguard.step_budget import OutOfTests, StepBudget
from cpbc.errors import CpbcError
from cpbc.model.input_bounds import InputBounds
from cpbc.reliability.campaign import campaign_setup, sample_states
from tools.reliability.robustness import sampled_data_campaign

H = 0.01
# near joint 2's lower limit and moving towards it: the law's torque fails (S1)
X, DX = np.array([0.7, -1.29]), np.array([0.09, -0.3])


def test_the_budget_counts_its_tests_and_keeps_the_last_that_passed() -> None:
    budget = StepBudget(3)
    slack = budget.counted(lambda t: float(t[0]))
    first, second = np.array([1.0]), np.array([-1.0])
    assert slack(first) == 1.0 and slack(second) == -1.0
    assert budget.passed is first and budget.used == 2
    slack(second)
    with pytest.raises(OutOfTests):
        slack(first)
    budget.begin()
    assert budget.used == 0 and budget.passed is None
    unbounded = StepBudget(None)
    f = lambda t: 0.0  # noqa: E731
    assert unbounded.counted(f) is f


def test_under_a_time_budget_a_test_begins_only_where_one_as_long_still_fits() -> None:
    """A test after the first begins only where the step's longest test so far, begun now,
    ends within the budget: after a 0.6 s test, a 1 s budget with 0.4 s left refuses the
    next; after a 0.1 s test it makes it; after a 0.6 s test that is not exact (the first
    test's sign) it makes it too. A refused torque after a 0.6 s test ends the step before the
    next candidate's work; after a 0.1 s one it does not. The first test is made whatever its
    time."""
    import time

    def slow(seconds: float):
        def slack(t: np.ndarray) -> float:
            time.sleep(seconds)
            return float(t[0])
        return slack

    for first, allowed in ((0.6, False), (0.1, True)):
        budget = StepBudget(None, 1.0)
        budget.start()
        budget.begin()
        slack = budget.counted(slow(first))
        assert slack(np.array([1.0])) == 1.0 and budget.longest >= first
        quick = budget.counted(lambda t: float(t[0]))
        if allowed:
            assert quick(np.array([-1.0])) == -1.0 and budget.used == 2
        else:
            with pytest.raises(OutOfTests):
                quick(np.array([-1.0]))
            assert budget.used == 1 and budget.passed is not None
    sign = StepBudget(None, 1.0)  # a test that is not exact does not set the estimate
    sign.start()
    sign.begin()
    assert sign.counted(slow(0.6), exact=False)(np.array([1.0])) == 1.0
    assert sign.longest == 0.0
    assert sign.counted(lambda t: float(t[0]))(np.array([-1.0])) == -1.0
    for first, stops in ((0.6, True), (0.1, False)):  # a refused torque, no room for another
        refused = StepBudget(None, 1.0)
        refused.start()
        refused.begin()
        fails = refused.counted(slow(first))
        if stops:
            with pytest.raises(OutOfTests):
                fails(np.array([-1.0]))
        else:
            assert fails(np.array([-1.0])) == -1.0
        assert refused.used == 1 and refused.passed is None
    spent = StepBudget(None, 1e-9)
    spent.start()
    spent.begin()
    assert spent.counted(lambda t: float(t[0]))(np.array([2.0])) == 2.0  # the first, always


def test_a_making_begins_only_where_one_as_long_as_its_kind_s_last_still_fits() -> None:
    """Under a 0.5 s budget a slide made in 0.6 s is made (no slide made before: taken to be
    made as fast as the step's longest test, none yet); at the next step none begins, since
    one as long would not end within the budget, and the block is not entered; after
    MADE_KEPT steps that asked for one (refused, or made quickly) the slow slide is
    forgotten. Under a 1 s budget, a kind not made yet
    after a 0.4 s test is taken to take as long as that test: 0.4 s gone and 0.8 s more do
    not fit. A making's time is its kind's, not the next candidate's: the test after a 0.3 s
    slide does not set the step's longest to 0.3 s. Without a time budget nothing is
    gated."""
    import time

    from cpbc.controllers.safeguard.step_budget import MADE_KEPT

    budget = StepBudget(None, 0.5)
    entered = []

    def step() -> None:
        budget.start()
        budget.begin()

    step()
    with budget.making("slide"):
        time.sleep(0.6)
    step()
    with pytest.raises(OutOfTests), budget.making("slide"):
        entered.append("slide")
    assert entered == []
    for _ in range(MADE_KEPT - 1):  # refused: one as long still does not fit
        step()
        with pytest.raises(OutOfTests), budget.making("slide"):
            entered.append("slide")
    step()
    with budget.making("slide"):  # the slow one forgotten: taken as fast as the longest test
        entered.append("quick")
    step()
    with budget.making("slide"):  # foretold by the quick one
        entered.append("slide")
    assert entered == ["quick", "slide"]
    apart = StepBudget(None, 10.0)  # a making is its kind's record, not the next test's
    apart.start()
    apart.begin()
    with apart.making("slide"):
        time.sleep(0.3)
    apart.counted(lambda t: 1.0)(np.array([1.0]))
    assert apart.longest < 0.3
    unseen = StepBudget(None, 1.0)
    unseen.start()
    unseen.begin()
    unseen.counted(lambda t: (time.sleep(0.4), 1.0)[1])(np.array([1.0]))
    with pytest.raises(OutOfTests), unseen.making("escape"):
        entered.append("escape")
    free = StepBudget(6)
    with free.making("slide"):
        time.sleep(0.01)
    with free.making("slide"):
        entered.append("free")
    assert entered[-1] == "free"


def test_what_is_made_ahead_is_untested_by_the_budget_and_ends_the_step_where_time_is_out(
        ) -> None:
    """Inside ``ahead`` no bound applies (a tenth test of a budget of one is made); after it
    the step ends where a candidate as long as the step's longest would not end within the
    budget (0.4 s test, 0.3 s ahead, 1 s), and goes on where one would (0.1 s, 0.1 s)."""
    import time

    one = StepBudget(1)
    one.counted(lambda t: -1.0)(np.array([1.0]))
    with one.ahead():
        for _ in range(10):
            one.counted(lambda t: 1.0)(np.array([1.0]))
    for test, made, ends in ((0.4, 0.3, True), (0.1, 0.1, False)):
        budget = StepBudget(None, 1.0)
        budget.start()
        budget.begin()
        budget.counted(lambda t, s=test: (time.sleep(s), -1.0)[1])(np.array([1.0]))
        if ends:
            with pytest.raises(OutOfTests), budget.ahead():
                time.sleep(made)
        else:
            with budget.ahead():
                time.sleep(made)


def test_the_brakes_made_ahead_set_the_step_s_longest_candidate() -> None:
    """Under a 1 s budget: the law's test a sign (0.05 s, not exact: the step's longest stays
    0), then ahead a brake tested in 0.4 s and 0.2 s more of making. The ahead test's time is
    the step's longest, so at 0.65 s a candidate as long would end past the budget and the
    step ends after the block (with the longest left at 0, it went on to its next candidate
    with 0.35 s left, and a slide begun so ran past a robot's budget). Its test is not
    counted and passes nothing on. Without a time budget, nothing is timed."""
    import time

    budget = StepBudget(None, 1.0)
    budget.start()
    budget.begin()
    budget.counted(lambda t: (time.sleep(0.05), -1.0)[1], exact=False)(np.array([1.0]))
    assert budget.longest == 0.0
    with pytest.raises(OutOfTests), budget.ahead():
        brake = budget.counted(lambda t: (time.sleep(0.4), 1.0)[1], exact=False)
        assert brake(np.array([2.0])) == 1.0
        time.sleep(0.2)
    assert 0.4 <= budget.longest < 0.6
    assert budget.used == 1 and budget.passed is None
    free = StepBudget(None)
    with free.ahead():
        assert free.counted(lambda t: 1.0)(np.array([1.0])) == 1.0
    assert free.longest == 0.0 and free.used == 0


def test_a_budget_below_one_test_is_refused() -> None:
    with pytest.raises(ValueError, match="tests"):
        StepBudget(0)
    with pytest.raises(CpbcError, match="test_budget"):
        SafeguardSettings(test_budget=0)


def _slack_at(guard: Safeguard, tau: np.ndarray) -> float:
    """F of (S1) for ``tau`` at (X, DX), tested by a guard without a budget."""
    free = Safeguard(guard.law, InputBounds(H))
    state = free.state(X, DX)
    out = free.law.evaluate_state(state, margins=True)
    bias = state.coriolis_force + state.gravity + state.dissipation
    _, floor, mid = free.sample_floors(state.x, out.margins)
    return free.acceptance.check(free.predictor(state, bias), floor, mid)(tau)


def test_step_tests_give_F_at_a_state_without_counting_against_the_step(
        recentred: RecentredBarrier) -> None:
    """Safeguard.step_tests: F of any torque at a state, as a step makes it — the law's
    torque fails where the guarded step acts, the unbounded guard's torque passes, and F is
    the one a guard without a budget computes — with no test counted against a budget of
    one (four tests, none refused) and no count of the guard moved."""
    guard = Safeguard(recentred, InputBounds(H), SafeguardSettings(test_budget=1))
    state = guard.state(X, DX)
    out = recentred.evaluate_state(state, margins=True)
    assert out.margins is not None
    step = guard.step_tests(state, out.torque, out.margins)
    best = Safeguard(recentred, InputBounds(H)).torque(X, DX)
    f_law = step.slack(out.torque)
    assert f_law < 0.0 <= step.slack(best)
    assert f_law == _slack_at(guard, out.torque) == step.slack(out.torque)
    assert (guard.calls, guard.acted, guard.out_of_tests) == (0, 0, 0)
    guard.torque(X, DX)  # the guarded step after it: its own budget, untouched
    assert (guard.calls, guard.acted, guard.out_of_tests) == (1, 1, 1)


def test_one_test_a_step_holds_the_uniform_brake_where_the_law_fails(
        recentred: RecentredBarrier) -> None:
    """With one test a step the law's torque is the only one tested: where it fails, the
    step holds b − λ₀ D ẋ/h and counts the step as out of tests."""
    guard = Safeguard(recentred, InputBounds(H), SafeguardSettings(test_budget=1))
    tau = guard.torque(X, DX)
    dyn = recentred.model.dynamics(X, DX)
    brake = dyn.coriolis_force + dyn.gravity + dyn.dissipation - dyn.inertia @ DX / H
    np.testing.assert_allclose(tau, brake, rtol=1e-12)
    assert (guard.acted, guard.out_of_tests) == (1, 1)


def test_past_the_budget_the_step_holds_the_last_torque_that_passed(
        recentred: RecentredBarrier) -> None:
    """With two tests the law's torque fails and the slide passes: the blend between them
    has no test left, so the slide is held — a torque that passed (S1), further from the
    law than the unbounded guard's blend."""
    bounded = Safeguard(recentred, InputBounds(H), SafeguardSettings(test_budget=2))
    free = Safeguard(recentred, InputBounds(H))
    tau, best = bounded.torque(X, DX), free.torque(X, DX)
    assert bounded.out_of_tests == 1 and free.out_of_tests == 0
    assert _slack_at(bounded, tau) >= 0.0
    assert not np.allclose(tau, best)
    law = recentred.torque(X, DX)
    assert np.linalg.norm(tau - law) > np.linalg.norm(best - law)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_a_small_campaign_keeps_every_constraint_on_a_budget() -> None:
    """The seeded states of the safeguard's small campaign at 1 kHz with three tests a
    step: steps run out of tests, and no run breaks a constraint."""
    setup = campaign_setup("planar_recentred")
    states = [s for s in sample_states(setup, 40, seed=3)
              if viable(setup.monitor, s.position, s.velocity, 0.01)][:20]
    records = sampled_data_campaign(setup, "planar_recentred", states, [0.001], 0.3,
                                    SafeguardSettings(test_budget=3))
    guarded = [r for r in records if r["safeguard"]]
    assert len(guarded) == 20
    assert sum(r["violated"] for r in guarded) == 0
    assert sum(r["out_of_tests"] for r in guarded) > 0


def _fr3_seed_0(rescue_budget: int | None):
    """The FR3 rate campaign as a robot runs it (6 tests a step), with the rescue's budget
    ``rescue_budget``, run from seed 0 at 1 kHz: a state a rate-limited brake stops in the
    true plant (conftest.campaign_run)."""
    from cpbc.scenario import build, load_scenario

    campaign = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    setup = build(*load_scenario(campaign / "fr3_sphere_rate_robot.yaml"))
    assert setup.safeguard is not None and setup.safeguard.test_budget == 6
    guard = replace(setup.safeguard, rescue_budget=rescue_budget)
    return campaign_run(replace(setup, safeguard=guard), 0, 0.5, "CPBC").check


def test_where_no_torque_passes_within_the_budget_an_unbounded_rescue_answers() -> None:
    """Seed 0's chain runs out of tests with no torque passed and none of the rescue's
    brakes passing one test either: the uniform brake, untested, carried joint 5 2.8 mrad
    past its limit; the rescue's search, without a budget of its own, keeps it."""
    check = _fr3_seed_0(None)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.out_of_tests > 0 and check.trajectory.rescues > 0


def test_a_bounded_rescue_answers_a_spent_step_with_a_brake_decided_whole() -> None:
    """Under the robot's bounded rescue seed 0 starts outside V: its first step's tests are
    spent, and the rescue's search from the motion's first state runs until rest whatever
    the budget (Rescue.answers); the spent steps after it hold that brake while it is
    committed. The uniform brake, untested, carried joint 5 2.8 mrad past its limit; a
    brake committed before its check ended kept fewer runs (docs/reliability.md)."""
    check = _fr3_seed_0(8)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.out_of_tests > 0 and check.trajectory.rescues > 0


def test_a_budget_in_time_stops_the_tests_once_it_is_spent(
        recentred: RecentredBarrier) -> None:
    """A time budget of a nanosecond is spent once the law's torque is tested (that test is
    always made): near the target the law's torque passes and is held; where it fails
    (S1) the step holds what a step out of tests holds, as with one test a step. A budget of
    ten seconds leaves the step as it is without one."""
    x, dx = np.array([1.1, -0.9]), np.array([0.01, -0.01])  # near the target: law passes
    free = Safeguard(recentred, InputBounds(H))
    spent = Safeguard(recentred, InputBounds(H), SafeguardSettings(time_budget=1e-9))
    np.testing.assert_array_equal(spent.torque(x, dx), free.torque(x, dx))
    assert spent.out_of_tests == 0
    one = Safeguard(recentred, InputBounds(H), SafeguardSettings(test_budget=1))
    np.testing.assert_array_equal(spent.torque(X, DX), one.torque(X, DX))
    assert spent.out_of_tests == 1
    ample = Safeguard(recentred, InputBounds(H), SafeguardSettings(time_budget=10.0))
    np.testing.assert_array_equal(ample.torque(X, DX), free.torque(X, DX))
    assert ample.out_of_tests == 0
    with pytest.raises(CpbcError, match="time_budget"):
        SafeguardSettings(time_budget=0.0)
    with pytest.raises(ValueError, match="seconds"):
        StepBudget(None, -1.0)


def test_past_its_time_a_step_holds_the_uniform_brake_without_a_further_test() -> None:
    """On the FR3 as a robot runs it, seed 23's state fails the law's test: a step out of
    tests (one test a step) asks the rescue's bounded search, a step out of time does not and
    holds the uniform brake b − D ẋ/h in the step's box at once (its (S0) passing there) — a
    step that ends within its time and the one test under way. Each guard's first step is the
    arm at rest there (the law's torque passes): at a motion's first step the rescue's search
    would answer instead."""
    from dataclasses import replace
    from pathlib import Path

    from cpbc.reliability.verification import draw_state
    from cpbc.scenario import build, load_scenario

    campaign = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    setup = build(*load_scenario(campaign / "fr3_sphere_rate_robot.yaml"))
    assert setup.safeguard is not None
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    s = draw_state(setup, 23)
    rest = np.zeros_like(s.velocity)

    def guard(**budgets: float | None) -> Safeguard:
        made = replace(setup, safeguard=replace(setup.safeguard, **budgets)).controller(entry)
        assert isinstance(made, Safeguard)
        made.torque(s.position, rest)
        assert made.acted == 0
        return made

    timed, counted = guard(test_budget=None, time_budget=1e-9), guard(test_budget=1)
    tau_timed = timed.torque(s.position, s.velocity)
    tau_counted = counted.torque(s.position, s.velocity)
    assert (timed.out_of_tests, counted.out_of_tests) == (1, 1)
    rescue_timed, rescue_counted = timed.brakes.rescue, counted.brakes.rescue
    assert rescue_timed is not None and rescue_counted is not None
    assert (rescue_timed.searches, rescue_counted.searches) == (0, 1)
    assert np.all(np.isfinite(tau_counted))
    twin = guard()
    state = twin.state(s.position, s.velocity)
    twin.box.begin(state)  # the second step's box, around the torque the first one held
    bias = state.coriolis_force + state.gravity + state.dissipation
    uniform = twin.brakes.brake(bias, state.inertia @ state.dx / twin.period,
                                twin.settings.braking)
    np.testing.assert_allclose(tau_timed, uniform, rtol=0, atol=1e-12)


def test_out_of_time_under_a_rate_limit_a_step_holds_what_it_made_ahead() -> None:
    """On the FR3 as a robot runs it (1000 N·m/s), seed 23's state fails the law's test. Under
    a 50 ms budget, with the slide slowed to 60 ms, the step makes what a spent step holds
    before its candidates (the uniform brake's reach nearer to passing F that keeps (S0),
    Brakes.spent), then the
    slide, which runs the budget out, and holds the torque made ahead. At the next step, one
    slide as long would not fit: none is begun, and the step holds what it made ahead again.
    Made after the budget ran out, that brake's tests ran up to 95 µs past it on the
    Panda."""
    import time

    from cpbc.reliability.verification import draw_state
    from cpbc.scenario import build, load_scenario

    campaign = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    setup = build(*load_scenario(campaign / "fr3_sphere_rate_robot.yaml"))
    assert setup.safeguard is not None
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    s = draw_state(setup, 23)
    guard = replace(setup, safeguard=replace(setup.safeguard, test_budget=None,
                                             time_budget=0.05)).controller(entry)
    assert isinstance(guard, Safeguard) and guard.box.rate_limited
    guard.torque(s.position, np.zeros_like(s.velocity))  # at rest: the law's torque passes
    assert guard.acted == 0
    brakes = guard.brakes
    slide, spent = brakes.slide, brakes.spent
    slides, made = [], []

    def slowed(*args):
        slides.append(1)
        time.sleep(0.06)
        return slide(*args)

    def recorded(*args):
        made.append(spent(*args))
        return made[-1]

    brakes.slide = slowed  # type: ignore[method-assign]
    brakes.spent = recorded  # type: ignore[method-assign]
    held = [guard.torque(s.position, s.velocity) for _ in range(2)]
    assert len(slides) == 1 and len(made) == 2
    assert guard.out_of_tests == 2 and guard.acted == 2
    for tau, ahead in zip(held, made, strict=True):
        np.testing.assert_array_equal(tau, ahead)


def test_under_a_time_budget_the_candidates_take_up_the_brake_s_reaches_made_ahead(
        monkeypatch) -> None:
    """On the FR3 as a robot runs it (1000 N·m/s), from seed 23's state, whose law's torque
    fails and whose chain of candidates gets to the brakes: under a time budget (10 s, never
    reached) the step makes the calmest brake's two reaches and their F once, ahead of its
    candidates, and the chain takes them up; without one the chain makes the brake itself,
    the line only where the nearest fails. Made twice, they were ~90 µs more on the Panda's
    acting steps."""
    from cpbc.controllers.safeguard.braking import Reaches
    from cpbc.reliability.verification import draw_state
    from cpbc.scenario import build, load_scenario

    campaign = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    setup = build(*load_scenario(campaign / "fr3_sphere_rate_robot.yaml"))
    assert setup.safeguard is not None
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    s = draw_state(setup, 23)
    taken: list[Reaches] = []
    first_passing = Reaches.first_passing

    def taken_up(self: Reaches) -> tuple[np.ndarray, float]:
        taken.append(self)
        return first_passing(self)

    monkeypatch.setattr(Reaches, "first_passing", taken_up)
    for seconds, made_as in ((10.0, ["reaches"]), (None, ["calmest"])):
        guard = replace(setup, safeguard=replace(setup.safeguard, test_budget=None,
                                                 time_budget=seconds)).controller(entry)
        assert isinstance(guard, Safeguard)
        guard.torque(s.position, np.zeros_like(s.velocity))  # at rest: the law's passes
        made = list[str]()
        for name in ("calmest", "reaches"):  # both reaches at once, or the nearest first
            method = getattr(guard.brakes, name)

            def counted(*args, _c=method, _n=name, _m=made, **kwargs):
                _m.append(_n)
                return _c(*args, **kwargs)

            setattr(guard.brakes, name, counted)
        taken.clear()
        guard.torque(s.position, s.velocity)
        assert guard.acted == 1 and guard.out_of_tests == 0
        assert made == made_as and len(taken) == 1


def test_tests_in_an_uncut_block_count_and_none_is_cut() -> None:
    """Inside ``uncut`` a test counts and keeps what passed, past the budget of tests or of
    time alike; a refused one ends the step at the block's end where a candidate as long as
    the step's longest no longer fits the time left (after a 0.6 s test, 0.4 s left of 1 s),
    and not where one does (after 0.1 s) or where the torque passed."""
    import time

    counted = StepBudget(1)
    counted.counted(lambda t: float(t[0]))(np.array([-1.0]))
    with counted.uncut():
        assert counted.counted(lambda t: float(t[0]))(np.array([2.0])) == 2.0
    assert counted.used == 2 and counted.passed is not None
    with pytest.raises(OutOfTests):  # the count is spent outside the block as before
        counted.counted(lambda t: float(t[0]))(np.array([3.0]))

    def slow(t: np.ndarray) -> float:
        time.sleep(0.6)
        return float(t[0])

    for first, outcome, ends in ((0.6, -1.0, True), (0.6, 1.0, False), (0.1, -1.0, False)):
        budget = StepBudget(None, 1.0)
        budget.start()
        budget.begin()
        budget.counted(slow if first == 0.6 else (lambda t: (time.sleep(0.1), 1.0)[1]))(
            np.array([1.0]))  # a torque passed, a test as long as ``first`` made
        if ends:
            with pytest.raises(OutOfTests), budget.uncut():
                budget.counted(slow)(np.array([outcome]))
        else:
            with budget.uncut():
                budget.counted(lambda t: float(t[0]))(np.array([outcome]))
        assert budget.used == 2


def test_a_committed_brake_is_made_once_a_step_whatever_the_time_left() -> None:
    """On the FR3 as a robot runs it (seed 0, outside V), the first step's search commits to
    a brake that the next step holds as soon as the law's torque fails its test: one brake
    and one test, under a time budget that the brake's making spends (the brake slowed to
    5 ms, the budget 2 ms) as under none. Cut off by the budget there, the brake was made,
    dropped and made again by the step out of tests — the bounded tail's worst steps on the
    Panda (docs/speed.md)."""
    import time
    from dataclasses import replace
    from pathlib import Path

    from cpbc.reliability.verification import draw_state
    from cpbc.scenario import build, load_scenario

    campaign = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    setup = build(*load_scenario(campaign / "fr3_sphere_rate_robot.yaml"))
    assert setup.safeguard is not None
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    s = draw_state(setup, 0)
    held = []
    for seconds in (None, 0.002):
        made = replace(setup, safeguard=replace(setup.safeguard, rescue_budget=8,
                                                time_budget=seconds)).controller(entry)
        assert isinstance(made, Safeguard) and made.brakes.rescue is not None
        rescue = made.brakes.rescue
        made.torque(s.position, s.velocity)  # the motion's first step: searched, committed
        assert rescue.committed is not None and made.rescues == 1
        name, brake, calls = rescue.committed, rescue.table[rescue.committed], []

        def slowed(*args, brake=brake, calls=calls):
            calls.append(1)
            time.sleep(0.005)
            return brake(*args)

        rescue.table[name] = slowed
        held.append(made.torque(s.position, s.velocity))
        assert made.rescues == 2 and len(calls) == 1, (seconds, len(calls))
    np.testing.assert_array_equal(*held)


def test_under_a_rate_limit_the_committed_brake_held_is_the_torque_tested() -> None:
    """On the FR3 as a robot runs it (seed 0, 1000 N·m/s) the second step holds the brake its
    first step's search committed to, reached into the step's rate box nearest in
    acceleration (StepBox.fit): the torque its one-period test saw, bit for bit. The
    prediction clips a torque to the rate box joint by joint; tested as given, the brake was
    tested clipped and held fitted, a torque no test had seen: 2 N·m away on a joint (the
    whole width of the ±1 N·m box) at this state."""
    from dataclasses import replace
    from pathlib import Path

    from cpbc.reliability.verification import draw_state
    from cpbc.scenario import build, load_scenario

    campaign = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    setup = build(*load_scenario(campaign / "fr3_sphere_rate_robot.yaml"))
    assert setup.safeguard is not None and setup.loop_settings.bounds.rate is not None
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    guard = replace(setup, safeguard=replace(setup.safeguard, rescue_budget=8)
                    ).controller(entry)
    assert isinstance(guard, Safeguard) and guard.box.rate_limited
    s = draw_state(setup, 0)
    guard.torque(s.position, s.velocity)  # the motion's first step: searched, committed
    tested = []
    check = guard.acceptance.check

    class Recording:  # every torque a test is asked of, in order
        def __init__(self, slack) -> None:
            self.slack = slack

        def __call__(self, t: np.ndarray) -> float:
            tested.append(np.array(t))
            return self.slack(t)

        def sign(self, t: np.ndarray) -> float:
            tested.append(np.array(t))
            return self.slack.sign(t)

    guard.acceptance.check = (  # type: ignore[method-assign]
        lambda *args, **kwargs: Recording(check(*args, **kwargs)))
    held = guard.torque(s.position, s.velocity)
    assert guard.rescues == 2
    np.testing.assert_array_equal(held, tested[-1])


def _as_a_robot_runs_it(load_dict, campaign_file: str, seed: int, seconds: float,
                        on_path: bool = False, **simulation: float):
    """The run of ``campaign_file``'s first constrained law from seed ``seed`` for
    ``seconds``, with the robot's budgets of 6 tests a step and 8 model periods of rescue
    and the ``simulation`` fields given, as cpbc.verify runs it (conftest.campaign_run)."""
    import yaml

    campaign = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    data = yaml.safe_load((campaign / campaign_file).read_text())
    data["simulation"].update(safeguard_test_budget=6, safeguard_rescue_budget=8, **simulation)
    return campaign_run(load_dict(data), seed, seconds, on_path=on_path).check


def test_a_spent_step_under_a_rate_limit_holds_no_brake_that_fails_S0(load_dict) -> None:
    """panda_goal_pose_rate (the task-space law toward a hand pose under a 1000 N·m/s
    torque-rate limit) under the robot's budgets, 6 tests and B = 8, from seed 35: a start
    inside V with joint 2 on its rate bound and joint 6 at its position limit. From the
    seventh step no candidate passes within the budget and no rescue brake stops the arm
    within 8 periods; the uniform brake, reached into the ±1 N·m box by its nearest
    acceleration and held untested, drove joint 2 through its rate bound by 5.2 mrad/s at
    8 ms. Tested against (S0) and replaced by the brake along the line where it fails, as the
    unbounded guard's fallback does (Brakes.spent), the run keeps every constraint."""
    check = _as_a_robot_runs_it(load_dict, "panda_goal_pose_rate.yaml", 35, 0.2)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.out_of_tests >= 2


def test_a_spent_step_holds_the_brake_S2_promised_not_one_tested_for_a_period(
        load_dict) -> None:
    """The figure eight under a 1000 N·m/s torque-rate limit
    (tools/campaigns/panda_figure8_ke_rate.yaml) with the robot's budgets, 6 tests and B = 8,
    from seed 58, a start inside V, the path from its beginning (cpbc.verify starts it at the
    seed's own phase): the law's torque fails at two steps of three and 6 tests
    reach no further than the slide and the brakes along the line. A spent step that held the
    first of the rescue's least-squares and aimed brakes to pass one period's test took the
    hand through the table's clearance from 176 ms on; holding the uniform brake, the one the
    step before's (S2) was tested with (as a step out of time does), the run keeps it. (It
    comes 0.11 mm into the clearance's 1 mm cushion at 239 ms, under torques that passed
    (S1), which lets a margin decay inside its cushion: the unbounded guard's run comes to
    1.005 mm; before the spent step's reach was chosen by F, 1.6 mm.)"""
    check = _as_a_robot_runs_it(load_dict, "panda_figure8_ke_rate.yaml", 58, 0.25)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.out_of_tests > 0



def test_the_brake_s_reaches_are_ordered_by_F_and_the_candidates_take_the_first_passing(
        ) -> None:
    """The two reaches of the calmest brake as the figure eight's seed 19 made them at its
    first spent steps (F of the nearest acceleration's, of the line's): a spent step tries
    the one nearer to passing first (Brakes.spent), while the chain of candidates, which
    takes them up, keeps its order — the nearest where it passes, else the line where it
    passes, else the nearest, whose λ the search then moves."""
    from cpbc.controllers.safeguard.braking import Reaches

    nearest, line = np.array([1.0]), np.array([2.0])
    first = Reaches(nearest, -61.0, line, 0.024)
    assert first.by_f() == (line, nearest)
    assert first.first_passing() == (line, 0.024)
    later = Reaches(nearest, -980.0, line, -590.0)
    assert later.by_f() == (line, nearest)
    assert later.first_passing() == (nearest, -980.0)
    both_pass = Reaches(nearest, 0.5, line, 0.9)
    assert both_pass.by_f() == (line, nearest)
    assert both_pass.first_passing() == (nearest, 0.5)
    assert Reaches(nearest, -1.0).by_f() == (nearest,)  # no rate limit: one reach


def test_a_spent_step_holds_the_reach_of_the_brake_nearer_to_passing(load_dict) -> None:
    """The figure eight under a 1000 N·m/s torque-rate limit with the robot's budgets and
    the tightest time budget, seed 19 from its phase of the path (a start inside V): from
    397 ms no candidate passes within the budget. Reached by its nearest acceleration, the
    uniform brake stopped the wrist first while the shoulder and elbow carried the hand
    0.15 mm through the table's clearance at 452 ms; at the first spent step the brake
    along the line — the path the step before's (S2) was tested on — passes F, and held
    where its F is the nearer to passing (Brakes.spent) the run keeps the clearance."""
    check = _as_a_robot_runs_it(load_dict, "panda_figure8_ke_rate.yaml", 19, 0.5,
                                on_path=True, safeguard_time_budget=1e-9)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.out_of_tests > 50  # the brake was the spent steps' to choose


def test_a_reach_that_passes_over_floors_above_the_cushions_is_held_untested(
        load_dict, monkeypatch) -> None:
    """The figure eight's seed 19 run as above (the robot's budgets, the tightest time
    budget, 0.45 s): at each of its 270 steps whose reaches were made ahead, Brakes.spent
    given (S1)'s floors holds what it holds without them — where they are at or above the
    cushions and a reach passes F, that reach, with no (S0) test (154 steps); tested, (S0)
    holds it, as F ≥ 0 over those floors implies. Elsewhere it tests as before (116)."""
    from cpbc.controllers.safeguard.braking import Brakes, _first_prediction

    spent, positivity = Brakes.spent, Brakes.positivity
    tests, untested, tested = [0], [0], [0]

    def counted(self, *args, **kwargs):
        tests[0] += 1
        return positivity(self, *args, **kwargs)

    def both_ways(self, bias, stop, predict, sample, reaches, floors=None):
        before = tests[0]
        held = spent(self, bias, stop, predict, sample, reaches, floors)
        if reaches is None:
            return held
        made_none = tests[0] == before
        np.testing.assert_array_equal(held, spent(self, bias, stop, predict, sample,
                                                  reaches, None))
        if made_none:
            untested[0] += 1
            assert positivity(self, _first_prediction(predict), sample)(held) >= 0.0
        else:
            tested[0] += 1
        return held

    monkeypatch.setattr(Brakes, "positivity", counted)
    monkeypatch.setattr(Brakes, "spent", both_ways)
    check = _as_a_robot_runs_it(load_dict, "panda_figure8_ke_rate.yaml", 19, 0.45,
                                on_path=True, safeguard_time_budget=1e-9)
    assert not check.violated, (check.constraint, check.min_margin)
    assert untested[0] > 0 and tested[0] > 0, (untested, tested)


def test_a_committed_brake_whose_nearest_reach_fails_is_held_clipped_where_that_passes(
        load_dict) -> None:
    """The figure eight's seed 127 from its phase of the path, under the robot's budgets
    and the tightest time budget: a start outside V with joint 7 1.3 mrad from its limit at
    0.82 rad/s. The first step's search commits to a brake; at the next, reached into the
    ±1 N·m box by its nearest acceleration the brake fails its one-period test, and the
    uniform brake held instead took joint 7 0.33 mrad past its limit at 2 ms. Clipped into
    the box joint by joint — as the unbounded rescue holds it, and as the test predicts it —
    it passes, and held so the run keeps the limit (Brakes.committed)."""
    check = _as_a_robot_runs_it(load_dict, "panda_figure8_ke_rate.yaml", 127, 0.02,
                                on_path=True, safeguard_time_budget=1e-9)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.rescues >= 2


def test_a_tracker_reports_its_guards_spent_steps(load_dict) -> None:
    """The figure eight (a path, its law a reference tracker around the safeguard) under
    the tightest time budget, seed 19 from its phase of the path: the run's trajectory
    counts the steps that spent the budget, as it counts the guard's acting steps. The
    tracker passed on the guard's acting, infeasible and rescue counts and left this one
    at 0."""
    traj = _as_a_robot_runs_it(load_dict, "panda_figure8_ke_rate.yaml", 19, 0.05,
                               on_path=True, safeguard_time_budget=1e-9).trajectory
    assert 0 < traj.out_of_tests <= traj.safeguard_steps
