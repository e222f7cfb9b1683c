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
