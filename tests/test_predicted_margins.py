"""The guarded margins along a prediction (cpbc.controllers.safeguard.predicted_margins): F of
(S1) and (S2), the same F where the sphere clearances are bounded from the sample instead of
computed (cpbc.kernels.sampled_guard.bounded_slack), and the same F again from the frozen
prediction's compiled test (cpbc.kernels.frozen_slack)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from cpbc.bench_arms import panda
from cpbc.controllers.safeguard import Safeguard, SafeguardSettings
from cpbc.controllers.safeguard.predicted_margins import PredictedMargins, Sample
from cpbc.controllers.safeguard.prediction import Frozen
from cpbc.model.input_bounds import InputBounds
from cpbc.model.joint_chain import JointChain


def _guard(rate: float | None = None) -> tuple[Safeguard, list[tuple[np.ndarray, np.ndarray]]]:
    """The Panda benchmark's guard at 1 kHz (with ``rate`` N·m/s a torque-rate limit) and its
    states."""
    setup = panda()
    rates = None if rate is None else np.full(7, rate)
    return Safeguard(setup.controllers["cpbc"], InputBounds(0.001, setup.torque_limit, rates),
                     SafeguardSettings()), setup.states


def _tests(rate: float | None = None):
    """Each of the Panda benchmark's states (52 of 64 with a link within 10 cm of an
    obstacle), at its rates and at three times them, with the law's torque and pushed off
    it: the guard's margins along the prediction, its floors, and F without bounds."""
    guard, states = _guard(rate)
    law = guard.law
    along, rng = guard.acceptance.along, np.random.default_rng(3)
    for x, dx in states:
        for speed in (1.0, 3.0):
            state = guard.state(x, speed * dx)
            out = law.evaluate_state(state, margins=True)
            assert out.margins is not None
            step = guard.step_tests(state, out.torque, out.margins)
            floor, mid, stop, predict = step.floor, step.floor_mid, step.stop, step.predict
            for push in (0.0, 10.0, 100.0):
                tau = out.torque + push * rng.standard_normal(7)
                rows = predict(tau)
                exact = along.slack(rows, floor, mid, stop, None)
                yield (along, rows, floor, mid, stop, Sample(state.x, step.now), exact, predict,
                       tau, guard.acceptance.ramp)


@contextmanager
def _counting(placed: list[int]) -> Iterator[None]:
    """The rows the block asks the joint placements at (JointChain.placements, compiled,
    which the guarded margins read for the sphere clearances) appended to ``placed``: each
    is still computed (a count, not a stub)."""
    asked, rows = JointChain.placements, [0]

    def count(chain: JointChain, at: np.ndarray) -> np.ndarray:
        rows[0] += len(at)
        return asked(chain, at)

    JointChain.placements = count  # type: ignore[method-assign]
    try:
        yield
    finally:
        JointChain.placements = asked  # type: ignore[method-assign]
        placed.append(rows[0])


@contextmanager
def _counting_in_one_call(placed: list[int]) -> Iterator[None]:
    """As :func:`_counting`, and the rows the frozen test's one call (frozen_chain_test,
    under a rate limit for an arm whose chain is compiled) makes the joint placements at,
    which it says: their sum appended to ``placed``."""
    import cpbc.controllers.safeguard.predicted_margins as module

    tested, rows, apart = module.frozen_chain_test, [0], list[int]()

    def count(*args: object) -> tuple[float, float, float]:
        f, marked, kept = tested(*args)
        rows[0] += int(marked)
        return f, marked, kept

    module.frozen_chain_test = count  # type: ignore[assignment]
    try:
        with _counting(apart):
            yield
    finally:
        module.frozen_chain_test = tested
        placed.append(rows[0] + sum(apart))


@pytest.mark.parametrize("rate", [None, 1000.0])
def test_bounds_from_the_sample_leave_F_as_it_is(rate: float | None) -> None:
    """With every F asked exactly (``enough`` ∞) the bounds change no bit of it; for the
    first test (``enough`` 1) F is the same where it is < 0 and a value in [0, F] where it
    is not. Both signs occur, and F with few joint placements and with many (without a rate
    limit, with none at all)."""
    signs, placed = set(), list[int]()
    for along, rows, floor, mid, stop, sample, exact, _, _, _ in _tests(rate):
        with _counting(placed):
            assert along.slack(rows, floor, mid, stop, None, sample, math.inf) == exact
            first = along.slack(rows, floor, mid, stop, None, sample, 1.0)
        if exact < 0:
            assert first == exact
        else:
            assert 0.0 <= first <= exact
        signs.add(exact >= 0)
    assert signs == {True, False}
    assert min(placed) < max(placed)  # tests that ask few placements and tests that ask many
    assert rate is not None or min(placed) == 0  # without a rate limit, some ask none


@pytest.mark.parametrize("rate", [None, 1000.0])
def test_the_frozen_test_is_the_same_F_bit_for_bit(rate: float | None) -> None:
    """The frozen prediction's test in compiled calls (PredictedMargins.frozen_slack) gives F
    as the rows and ``slack`` give it (under a torque-rate limit with ``ramp_slack``), to
    the bit, exact and from the sample's bounds with ``enough`` ∞, with and without (S2)'s
    stopping points; with ``enough`` 1 the same where
    F < 0, else a value in [0, F] (it computes only the clearances a bound leaves open, where
    the rows' path computes a marked row whole); and it makes the joint placements at the
    same rows (inside its one call: frozen_chain_test). Both signs occur, and tests with no
    placements."""
    signs, placed, fused, tests = set(), list[int](), list[int](), 0
    for along, rows, floor, mid, stop, sample, exact, predict, tau, ramp in _tests(rate):
        assert isinstance(predict, Frozen) and along.fuses and (ramp is None) == (rate is None)
        acc, after = predict.start(tau)
        for s in (stop, None):
            for given, enough in ((None, math.inf), (sample, math.inf), (sample, 1.0)):
                with _counting(placed):
                    expected = along.slack(rows, floor, mid, s, None, given, enough)
                exact = along.slack(rows, floor, mid, s, None)
                if ramp is not None:  # as Acceptance.check takes it on the rows
                    expected = min(expected, along.ramp_slack(rows, ramp))
                    exact = min(exact, along.ramp_slack(rows, ramp))
                with _counting_in_one_call(fused):
                    found = along.frozen_slack(predict, acc, after, floor, mid, s, given,
                                               enough, ramp)
                if enough == math.inf or expected < 0.0:
                    assert found == expected or (math.isnan(found) and math.isnan(expected))
                else:  # a sign: in [0, F] as the rows' is (bounds may stand in for more)
                    assert 0.0 <= found <= exact
                assert sum(fused) == sum(placed)
                tests += 1
        signs.add(exact >= 0)
    assert signs == {True, False}
    assert len(fused) == tests and min(fused) == 0 < max(fused)  # some ask none, some a few


def test_the_frozen_test_without_configuration_margins() -> None:
    """A guard with rate limits alone (no configuration margin, so no (S1) configuration
    floors and no (S2)): the compiled test's F is the rows' to the bit."""
    from cpbc.constraints.constraint_set import ConstraintSet

    setup = panda()
    law = setup.controllers["cpbc"]
    rates = ConstraintSet(law.model.n, (), law.constraints.velocity)
    along = PredictedMargins(rates, law.model)
    guard = Safeguard(law, InputBounds(0.001, setup.torque_limit), SafeguardSettings())
    x, dx = setup.states[3]
    state = guard.state(x, 3.0 * dx)
    bias = state.coriolis_force + state.gravity
    predict = guard.predictor(state, bias)
    assert isinstance(predict, Frozen)
    now = rates.margins(state.x, state.dx)
    floor = 0.5 * now
    for push in (0.0, 30.0, 300.0):
        tau = law.torque(x, dx) + push
        acc, after = predict.start(tau)
        expected = along.slack(predict(tau), floor, None, None, None)
        assert along.frozen_slack(predict, acc, after, floor, None, None) == expected


def test_the_compiled_margins_along_rows_are_the_sets() -> None:
    """The rescue's margins along its rollout (PredictedMargins.margins_along: the packed
    kernels with the compiled joint placements, JointChain) are the constraint set's own
    (ConstraintSet.margins_along, from Pinocchio's placements) at the bench's states, to
    rounding (the two forward kinematics sum in other orders: 1.4e-14 apart at most here,
    where with Pinocchio's placements on both sides they were equal to the bit), and NaN
    rows where a state is not finite; so are its configuration margins alone (the slide's
    stopping point)."""
    setup = panda()
    law = setup.controllers["cpbc"]
    guard = Safeguard(law, InputBounds(0.001, setup.torque_limit), SafeguardSettings())
    along, guarded = guard.acceptance.along, guard.guarded
    xs = np.array([x for x, _ in setup.states])
    dxs = np.array([3.0 * dx for _, dx in setup.states])

    def same(found: np.ndarray, expected: np.ndarray) -> None:
        np.testing.assert_allclose(found, expected, rtol=1e-12, atol=1e-12)

    same(along.margins_along(xs, dxs), guarded.margins_along(xs, dxs))
    xs[5, 2], dxs[9, 0] = np.nan, np.inf
    found = along.margins_along(xs, dxs)
    assert np.isnan(found[[5, 9]]).all() and not np.isnan(found[[4, 6, 8, 10]]).any()
    same(found, guarded.margins_along(xs, dxs))
    config = along.configuration_margins(xs)
    for i, x in enumerate(xs):
        if i != 5:
            same(config[i], guarded.configuration_margins(x))
    assert np.isnan(config[5]).all() and not np.isnan(config[9]).any()


@pytest.mark.parametrize("rate", [None, 1000.0])
def test_positivity_read_from_F_has_the_sign_of_its_own_test(rate: float | None) -> None:
    """(S0) over the first prediction read from F's compiled test of the same torque
    (PredictedMargins.frozen_positivity, what a spent step's reaches ask: Brakes.spent) has
    the sign of (S0)'s own test (Brakes.positivity's: the first prediction alone, the
    cushions its floors) wherever it is told, with and without the sample's bounds and
    (S2)'s points; F itself is unchanged. It is told in most tests, on both sides of 0,
    and left NaN where a bound below its cushion stood in for a clearance (the cushions
    are 0.007–0.8 mm here: a few tests, with F's floors below them)."""
    guard, _ = _guard(rate)
    cushion, nc = guard.brakes.cushion, guard.guarded.n_configuration
    told, untold, signs = 0, 0, set()
    for along, _, floor, mid, stop, sample, _, predict, tau, ramp in _tests(rate):
        first = predict.first()
        acc, after = predict.start(tau)
        acc1, after1 = first.start(tau)
        own = along.frozen_slack(first, acc1, after1, cushion, cushion[:nc], None, sample, 1.0,
                                 ramp)
        assert own == along.frozen_slack(first, acc1, after1, cushion, cushion[:nc], None,
                                         None, math.inf, ramp) or own >= 0.0
        # F's floors as a step whose margins are below their cushions has them (S1 keeps a
        # share of each): bounds below the cushions then stand in for clearances
        low = (0.05 * floor, 0.05 * mid)
        for s, (end, middle) in itertools.product((stop, None), ((floor, mid), low)):
            for given, enough in ((None, math.inf), (sample, 1.0)):
                f, kept = along.frozen_positivity(predict, acc, after, end, middle, s, given,
                                                  enough, ramp, cushion)
                assert f == along.frozen_slack(predict, acc, after, end, middle, s, given,
                                               enough, ramp)
                if math.isnan(kept):
                    untold += 1
                    continue
                assert (kept >= 0.0) == (own >= 0.0)
                told += 1
                signs.add(kept >= 0.0)
    assert signs == {True, False}
    assert told > 3 * untold
    assert untold > 0 or rate is not None  # 8 of 3 072 untold without the rate limit


@pytest.mark.parametrize("rate", [None, 5000.0])
def test_the_frozen_test_in_other_coordinates_with_a_box(rate: float | None) -> None:
    """The thesis's arm in absolute link angles (a map to the joints), its joint and
    relative limits and rate limits (every one packed), a torque box the torques are pushed
    far out of (the clip through the map) and, with ``rate``, a torque-rate limit: the
    compiled test's F is the rows' to the bit, on both sides of 0."""
    from cpbc.bench import planar_2link
    from cpbc.constraints.constraint_set import ConstraintSet
    from cpbc.constraints.linear_limit import LinearLimit, joint_position_limit
    from cpbc.constraints.rate_limit import joint_rate_limit
    from cpbc.controllers.cpbc import CPBC
    from cpbc.controllers.shaping import Power

    setup = planar_2link()
    model = setup.controllers["cpbc"].model
    names = ["theta1", "theta2"]
    constraints = ConstraintSet(2, [joint_position_limit([-0.5, -0.5], [3.5, 3.5], names),
                                    LinearLimit([[-1, 1]], [-3.0], [3.0], ["relative"])],
                                [joint_rate_limit([0.3, 0.2], names)])
    law = CPBC(model, np.array([np.pi, 2.0]), constraints, 4.0, 20.0, Power(0.2))
    bounds = InputBounds(0.001, np.array([30.0, 20.0]),
                         None if rate is None else np.full(2, rate))
    guard = Safeguard(law, bounds, SafeguardSettings())
    along, rng, signs = guard.acceptance.along, np.random.default_rng(11), set()
    assert along.fuses and not model.coordinates.is_identity
    for x, dx in setup.states[:24]:
        state = guard.state(x, 1.5 * dx)
        out = law.evaluate_state(state, margins=True)
        assert out.margins is not None
        step = guard.step_tests(state, out.torque, out.margins)
        predict, ramp = step.predict, guard.acceptance.ramp
        assert isinstance(predict, Frozen)
        for push in (0.0, 20.0, 200.0):
            tau = out.torque + push * rng.standard_normal(2)
            rows = predict(tau)
            expected = along.slack(rows, step.floor, step.floor_mid, step.stop, None)
            if ramp is not None:
                expected = min(expected, along.ramp_slack(rows, ramp))
            acc, after = predict.start(tau)
            found = along.frozen_slack(predict, acc, after, step.floor, step.floor_mid,
                                       step.stop, None, math.inf, ramp)
            assert found == expected
            signs.add(found >= 0.0)
    assert signs == {True, False}


@pytest.mark.parametrize("rate", [None, 1000.0])
def test_the_first_prediction_alone_is_the_corrected_ones_first_row(rate: float | None) -> None:
    """Frozen.first (what the fallback's (S0) judges on, Brakes.positivity): the closed form
    without the corrector's row is that row of the corrected prediction to the bit, and the
    compiled test on it gives the F its rows give (both signs occur)."""
    signs = set()
    for along, _, floor, mid, stop, _, _, predict, tau, ramp in _tests(rate):
        assert isinstance(predict, Frozen) and predict.corrector
        first = predict.first()
        assert isinstance(first, Frozen) and first.rows == 1 and first.first() is first
        both, alone = predict(tau), first(tau)
        for whole, one in zip(both[:3], alone[:3], strict=True):
            np.testing.assert_array_equal(whole[:1], one)
        rows = alone
        expected = along.slack(rows, floor, mid, stop, None)
        if ramp is not None:
            expected = min(expected, along.ramp_slack(rows, ramp))
        acc, after = first.start(tau)
        found = along.frozen_slack(first, acc, after, floor, mid, stop, None, math.inf, ramp)
        assert found == expected
        signs.add(found >= 0.0)
    assert signs == {True, False}
