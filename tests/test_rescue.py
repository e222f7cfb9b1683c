"""The safeguard's rescue and its one-period prediction on the Panda figure-8 with a kinetic-energy
bound (panda_figure8_ke): the table's clearance only the guard keeps, MuJoCo implicitfast at one
physics step per 1 ms control period."""

from dataclasses import replace

import numpy as np
import pytest

from cpbc.constraints.brakes import TorqueBox
from cpbc.controllers.rescue import Rescue
from cpbc.controllers.safeguard.prediction import predictor, travel_share
from cpbc.reliability.campaign import RecordingPlant, checked_run, kept_constraints
from cpbc.reliability.verification import draw_state, stopping_brake
from cpbc.scenario import build, load_scenario

H = 0.001


@pytest.fixture(scope="module")
def figure8():
    setup = build(*load_scenario("panda_figure8_ke"))
    entry = setup.controllers[0]  # TS-CPBC-KE-x1
    return setup, entry, kept_constraints(setup, entry, H, setup.safeguard)


def test_travel_share_is_where_the_plants_steps_land():
    assert travel_share(0.001, None) == 0.5  # continuous time
    assert travel_share(0.001, 0.001) == 1.0  # one semi-implicit Euler step a period
    assert travel_share(0.002, 0.001) == 0.75
    assert travel_share(0.01, 0.001) == pytest.approx(0.55)


def test_the_prediction_ends_where_a_one_step_plant_lands(figure8):
    """At one MuJoCo step a period the closed-form end x + hẋ + h²a is the plant's, to
    rounding; the continuous-time ½h²a misses it by ½h²a (micrometres at the hand, which wore
    the clearance below its cushion)."""
    setup, _, _ = figure8
    s = draw_state(setup, 62)
    state = setup.model.state(s.position, s.velocity)
    bias = state.coriolis_force + state.gravity + state.dissipation
    box = TorqueBox.of(setup.model, setup.loop_settings.torque_limit)
    tau = box.clip(bias + state.inertia @ np.linspace(-40.0, 40.0, setup.model.n))
    plant = setup.make_plant()
    coords = setup.model.coordinates
    plant.reset(coords.to_joint(s.position), coords.to_joint(s.velocity))
    plant.apply(box.joint(tau))
    plant.step(1)
    landed = coords.matrix @ plant.data.qpos
    ends = {}
    for c in (travel_share(H, setup.plant_settings.timestep), 0.5):
        predict = predictor(setup.model, state, bias, H, 1, box.clip, True, c)
        ends[c] = predict(tau)[1][0]
    assert np.max(np.abs(ends[1.0] - landed)) < 1e-10
    assert np.max(np.abs(ends[0.5] - landed)) > 1e-6


def test_a_committed_brake_is_held_only_in_the_next_period(figure8):
    """The commitment lasts while the brake is held period after period; a step in between
    (the guard's own torque passed) ends it, and the next failure searches afresh."""
    setup, _, kept = figure8
    s = draw_state(setup, 19)
    box = TorqueBox.of(setup.model, setup.loop_settings.torque_limit)
    rescue = Rescue(setup.model, kept, box, np.full(len(kept.names), 1e-5), H, 1)
    state = setup.model.state(s.position, s.velocity)
    bias = state.coriolis_force + state.gravity + state.dissipation
    now = kept.margins(s.position, s.velocity)

    def holds(_tau, _floor):
        return True

    assert rescue.torque(state, bias, now, holds, 10) is not None
    assert rescue.committed is not None and rescue.searches == 1
    rescue.torque(state, bias, now, holds, 11)  # the next period: held again
    assert rescue.searches == 1
    rescue.torque(state, bias, now, holds, 40)  # after periods of the guard's own torque
    assert rescue.searches == 2


def test_the_guard_keeps_the_clearance_of_the_figure8_from_a_stoppable_state(figure8):
    """Seed 19 at 1 kHz: the uniform brake stops it in the true plant. The guard's rescue held
    a least-squares brake committed 300 periods earlier, which from there no longer stops the
    arm, and the hand went 4.3 mm through the table's clearance at t = 0.43 s."""
    setup, entry, kept = figure8
    s = draw_state(setup, 19)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    assert stopping_brake(setup, kept, s.position, s.velocity, H, plant) is not None
    settings = replace(setup.loop_settings, duration=0.5, control_period=H, log_every=1)
    assert setup.reference is not None
    check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                        safeguard=setup.safeguard, phase=setup.reference.phase(entry.name, 19))
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.rescues > 0  # the rescue did hold brakes on the way
