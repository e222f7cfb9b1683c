"""A state handed to a law's public calls: lists, float32 and int vectors are taken as the
float64 vectors the compiled kernels need; the wrong length is a ParameterError naming x or
dx, and the law, guarded or not, is as it was."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.controllers.safeguard import Safeguard
from cpbc.errors import ParameterError
from cpbc.model.measured_state import measured
from cpbc.reliability.verification import draw_state
from cpbc.scenario import build, load_scenario


@pytest.fixture(scope="module")
def panda():
    """The shipped Panda reach past a ball: PD + g and the guarded CPBC, and a state."""
    setup = build(*load_scenario("panda_cpbc_sphere"))
    return setup, draw_state(setup, 3)


def test_the_usual_vectors_pass_as_they_are() -> None:
    x, dx = np.zeros(3), np.ones(3)
    got = measured(x, dx, 3)
    assert got[0] is x and got[1] is dx


@pytest.mark.parametrize("kind", [list, np.float32, np.float64])
def test_lists_and_other_floats_give_the_float64_torque(panda, kind) -> None:
    setup, s = panda
    for entry in setup.controllers:
        law = setup.controller(entry)
        want = setup.controller(entry).torque(s.position, s.velocity)
        if kind is list:
            x, dx = list(s.position), list(s.velocity)
        else:
            x, dx = s.position.astype(kind), s.velocity.astype(kind)
        got = law.torque(x, dx)
        tol = 0.0 if kind is not np.float32 else 1e-2  # float32 rounds the state
        np.testing.assert_allclose(got, want, rtol=0, atol=tol * np.abs(want).max())


@pytest.mark.parametrize(("x_at", "dx_at", "named", "says"), [
    (slice(0, 6), slice(None), "x", "7 finite numbers .* got shape"),
    (slice(None), slice(0, 8), "dx", "7 finite numbers .* got shape"),
])
def test_a_bad_state_names_its_argument_and_leaves_the_law_as_it_was(
        panda, x_at, dx_at, named, says) -> None:
    setup, s = panda

    def part(v: np.ndarray, at: slice) -> np.ndarray:
        return np.resize(v, 8)[at] if at.stop == 8 else v[at]

    x, dx = part(s.position, x_at), part(s.velocity, dx_at)
    for entry in setup.controllers:
        law = setup.controller(entry)
        for call in (law.torque, law.evaluate, law.lyapunov):
            with pytest.raises(ParameterError, match=says) as caught:
                call(x, dx)
            assert caught.value.parameter == named and str(caught.value).startswith(named + " ")
        if isinstance(law, Safeguard):  # no count moved, and its next step is a fresh guard's
            assert (law.acted, law.infeasible, law.rescues) == (0, 0, 0)
        fresh = setup.controller(entry)
        np.testing.assert_array_equal(law.torque(s.position, s.velocity),
                                      fresh.torque(s.position, s.velocity))


def test_a_non_number_is_named() -> None:
    with pytest.raises(ParameterError, match=r"x must be 2 finite numbers .* got \['a', 'b'\]"):
        measured(["a", "b"], [0.0, 0.0], 2)  # type: ignore[arg-type]


def _no_rate_limits(setup):
    """The scenario's CPBC with its configuration constraints only (no velocity margin to
    refuse a NaN rate), guarded with and without a torque-rate limit of 1000 N·m/s."""
    from cpbc.constraints.constraint_set import ConstraintSet
    from cpbc.controllers.cpbc import CPBC
    from cpbc.controllers.safeguard import SafeguardSettings, guarded
    from cpbc.model.input_bounds import InputBounds

    base = next(setup.controller(e) for e in setup.controllers
                if setup.controller(e).type_name == "safeguard").law
    law = CPBC(base.model, base.target,
               ConstraintSet(base.model.n, base.constraints.configuration, []),
               base.kp, base.kd, base.shaping)
    limit = np.full(base.model.n, 80.0)
    return [law] + [guarded(law, InputBounds(0.001, limit, rate), SafeguardSettings())
                    for rate in (None, 1000.0)]


@pytest.mark.parametrize("value", [np.nan, np.inf])
@pytest.mark.parametrize("named", ["x", "dx"])
def test_a_state_not_finite_is_named_and_leaves_the_law_as_it_was(panda, value, named):
    """A NaN or ∞ in x or ẋ: NonFiniteState, a ValueError naming the argument and the
    index, and a ConstraintViolation; no count moves and the next torque is the one the
    law would have given without the bad call (a rate-limited guard's held torque kept).
    Before, a law without velocity constraints returned NaN for a NaN rate, and its guard
    under a rate limit a finite ramp, counted as acting."""
    from cpbc.errors import ConstraintViolation, NonFiniteState

    setup, s = panda
    laws = [setup.controller(e) for e in setup.controllers] + _no_rate_limits(setup)
    twins = [setup.controller(e) for e in setup.controllers] + _no_rate_limits(setup)
    x, dx = s.position.copy(), s.velocity.copy()
    (x if named == "x" else dx)[3] = value
    for law, twin in zip(laws, twins, strict=True):
        first, _ = law.torque(s.position, s.velocity), twin.torque(s.position, s.velocity)
        np.testing.assert_array_equal(first, _)
        for call in (law.torque, law.evaluate):
            with pytest.raises(NonFiniteState, match=rf"^{named} must be 7 finite numbers "
                               rf".* got {value} at index 3") as caught:
                call(x, dx)
            assert isinstance(caught.value, ValueError)
            assert isinstance(caught.value, ConstraintViolation)
            assert caught.value.parameter == named
        if isinstance(law, Safeguard):
            assert (law.calls, law.acted, law.infeasible) == (twin.calls, twin.acted,
                                                              twin.infeasible)
        after = s.position + 0.001 * s.velocity
        np.testing.assert_array_equal(law.torque(after, s.velocity),
                                      twin.torque(after, s.velocity))
