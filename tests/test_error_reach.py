"""What an acceleration error takes off the margins over a time (cpbc.constraints.error_reach):
its growth with t, the guard's one-period losses as its value at h, and the rescue's checks
that hold it over the time they brake (cpbc.controllers.rescue)."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.constraints.brakes import TorqueBox
from cpbc.constraints.error_reach import ErrorReach
from cpbc.controllers.rescue import Rescue
from cpbc.controllers.safeguard.model_error import margin_losses
from cpbc.reliability.campaign import kept_constraints
from cpbc.reliability.verification import draw_state
from cpbc.scenario import build, load_scenario

H = 0.001


@pytest.fixture(scope="module")
def figure8():
    setup = build(*load_scenario("panda_figure8_ke"))
    entry = setup.controllers[0]
    kept = kept_constraints(setup, entry, H, setup.safeguard)
    s = draw_state(setup, 19)
    return setup, kept, setup.model.state(s.position, s.velocity)


def test_the_reach_grows_as_t_squared_in_position_and_t_in_rate(figure8) -> None:
    _, kept, state = figure8
    bound = np.full(state.x.size, 2.0)
    reach = ErrorReach.at(kept, state, bound)
    nc = kept.n_configuration
    one, two = reach.losses(0.01), reach.losses(0.02)
    np.testing.assert_allclose(two[:nc], 4.0 * one[:nc])
    assert np.all(reach.configuration > 0.0) and np.all(reach.push >= 0.0)
    np.testing.assert_allclose(two[nc:] - 2.0 * one[nc:], 2e-4 * reach.drift)
    np.testing.assert_array_equal(ErrorReach.at(kept, state, 2.0 * bound).configuration,
                                  2.0 * reach.configuration)


def test_the_guards_one_period_losses_are_the_reach_at_h(figure8) -> None:
    _, kept, state = figure8
    bound = np.linspace(0.5, 3.0, state.x.size)
    end, mid = margin_losses(kept, state, bound, H, 0.75)
    reach = ErrorReach.at(kept, state, bound)
    np.testing.assert_array_equal(end, reach.losses(H, 0.75))
    np.testing.assert_allclose(mid, 0.125 * H * H * reach.configuration)


def test_a_rescue_check_holds_the_error_over_the_time_it_brakes(figure8) -> None:
    """From the figure-8's seed 19 a brake stops the arm in the model; with an error bound
    whose reach over that braking exceeds the margins no brake passes its check, and with a
    negligible one a brake passes again."""
    setup, kept, state = figure8
    box = TorqueBox.of(setup.model, setup.loop_settings.bounds.torque)
    bias = state.coriolis_force + state.gravity + state.dissipation
    now = kept.margins(state.x, state.dx)

    def holds(_tau, _floor) -> bool:
        return True

    def rescue() -> Rescue:
        return Rescue(setup.model, kept, box, np.full(len(kept.names), 1e-5), H, 1)

    assert rescue().torque(state, bias, now, holds, 10) is not None
    huge = np.full(state.x.size, 1e3)
    assert rescue().torque(state, bias, now, holds, 10, error=huge) is None
    small = np.full(state.x.size, 1e-6)
    assert rescue().torque(state, bias, now, holds, 10, error=small) is not None
