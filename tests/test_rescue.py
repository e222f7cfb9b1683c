"""The safeguard's rescue and its one-period prediction on the Panda figure-8 with a kinetic-energy
bound (panda_figure8_ke): the table's clearance only the guard keeps, MuJoCo implicitfast at one
physics step per 1 ms control period."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cpbc.constraints.brakes import Rollout, TorqueBox, brakes, model_advance
from cpbc.controllers.rescue import Rescue
from cpbc.controllers.safeguard import SafeguardSettings
from cpbc.controllers.safeguard.prediction import predictor, travel_share
from cpbc.errors import CpbcError
from cpbc.reliability.campaign import RecordingPlant, checked_run, kept_constraints
from cpbc.reliability.verification import draw_state, in_braking_set, stopping_brake
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
    box = TorqueBox.of(setup.model, setup.loop_settings.bounds.torque)
    tau = box.clip(bias + state.inertia @ np.linspace(-40.0, 40.0, setup.model.n))
    plant = setup.make_plant()
    coords = setup.model.coordinates
    plant.reset(coords.to_joint(s.position), coords.to_joint(s.velocity))
    plant.apply(box.joint(tau))
    plant.step(1)
    landed = coords.matrix @ plant.data.qpos
    ends = {}
    for c in (travel_share(H, setup.plant_settings.timestep), 0.5):
        predict = predictor(setup.model, state, bias, H, 1, box, True, c)
        ends[c] = predict(tau)[1][0]
    assert np.max(np.abs(ends[1.0] - landed)) < 1e-10
    assert np.max(np.abs(ends[0.5] - landed)) > 1e-6


def test_a_committed_brake_is_held_only_in_the_next_period(figure8):
    """The commitment lasts while the brake is held period after period; a step in between
    (the guard's own torque passed) ends it, and the next failure searches afresh."""
    setup, _, kept = figure8
    s = draw_state(setup, 19)
    box = TorqueBox.of(setup.model, setup.loop_settings.bounds.torque)
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


def test_a_committed_brake_is_held_again_only_if_it_still_stops_the_arm_from_the_state_now(
        figure8):
    """Without a budget the committed brake is checked again from the state measured in the
    next period: held when the model still stops the arm from there (no new search), refused
    when it no longer does, though its one-period prediction passes (``holds``) — the plant
    has left the rollout that committed it (the UR5 rate campaign's seed 49 held one for 40
    periods while its friction took the wrist through the floor's clearance)."""
    setup, _, kept = figure8
    s = draw_state(setup, 19)
    box = TorqueBox.of(setup.model, setup.loop_settings.bounds.torque)

    def at(scale):
        state = setup.model.state(s.position, scale * s.velocity)
        bias = state.coriolis_force + state.gravity + state.dissipation
        return state, bias, kept.margins(state.x, state.dx)

    def holds(_tau, _floor):
        return True

    cushion = np.full(len(kept.names), 1e-5)
    rescue = Rescue(setup.model, kept, box, cushion, H, 1)
    state, bias, now = at(1.0)
    assert rescue.torque(state, bias, now, holds, 10) is not None
    committed = rescue.committed
    assert rescue.torque(state, bias, now, holds, 11) is not None  # still stops the arm: held
    assert rescue.committed == committed and rescue.searches == 1
    # 30 % faster no brake stops the arm inside S (a fresh search finds none)
    state, bias, now = at(1.3)
    assert Rescue(setup.model, kept, box, cushion, H, 1).torque(state, bias, now, holds,
                                                                 12) is None
    assert rescue.torque(state, bias, now, holds, 12) is None


def test_the_guard_keeps_the_clearance_of_the_figure8_from_a_stoppable_state(figure8):
    """Seed 19 at 1 kHz: the uniform brake stops it in the true plant. The guard's rescue held
    a least-squares brake committed 300 periods earlier, which from there no longer stops the
    arm, and the hand went 4.3 mm through the table's clearance at t = 0.43 s."""
    setup, entry, kept = figure8
    s = draw_state(setup, 19)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    assert stopping_brake(setup, kept, s.position, s.velocity, H, plant) is not None
    settings = replace(setup.loop_settings, duration=0.5,
        bounds=replace(setup.loop_settings.bounds, period=H), log_every=1)
    assert setup.reference is not None
    check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                        safeguard=setup.safeguard, phase=setup.reference.phase(entry.name, 19))
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.rescues > 0  # the rescue did hold brakes on the way


def _rescue_at(figure8, seed, budget):
    setup, _, kept = figure8
    s = draw_state(setup, seed)
    box = TorqueBox.of(setup.model, setup.loop_settings.bounds.torque)
    rescue = Rescue(setup.model, kept, box, np.full(len(kept.names), 1e-5), H, 1, budget=budget)
    state = setup.model.state(s.position, s.velocity)
    bias = state.coriolis_force + state.gravity + state.dissipation
    return rescue, state, bias, kept.margins(s.position, s.velocity)


def test_a_rollout_run_in_pieces_ends_as_one_run_to_its_end(figure8):
    """A check spread over control periods (the rescue's budget) decides as the same check
    run at once: same outcome, periods and least margin."""
    setup, _, kept = figure8
    s = draw_state(setup, 19)
    box = TorqueBox.of(setup.model, setup.loop_settings.bounds.torque)
    table = brakes(box, kept, setup.model)
    outcomes = []
    for piece in (None, 3):
        advance = model_advance(setup.model, box, s.position, s.velocity, H, 1)
        check = Rollout(table["least_squares"], setup.model, kept.margins_along, advance,
                        s.position, s.velocity, H, horizon=2.0)
        stop, calls = check.run(piece), 1
        while stop is None:
            assert check.held == 3 * calls  # exactly the budget each call
            stop, calls = check.run(piece), calls + 1
        outcomes.append((stop, calls))
    (whole, one), (pieces, many) = outcomes
    assert one == 1 and many > 1 and whole.periods > 3
    assert whole == pieces


def _holds(_tau, _floor):
    return True


def test_under_a_budget_a_search_commits_only_to_a_check_that_ended_at_rest(figure8):
    """Under a budget of B model periods a search commits to a brake only where its check
    brought the arm to rest within them: never before (a brake held before its check had
    seen the arm to rest kept fewer runs, cpbc.controllers.rescue). Too small a budget
    commits to nothing; one as long as the unbounded search's check commits to its brake,
    at rest by the same step."""
    unbounded, state, bias, now = _rescue_at(figure8, 19, budget=None)
    assert unbounded.torque(state, bias, now, _holds, 10) is not None
    assert unbounded.rest_at is not None
    periods = unbounded.rest_at - 10
    assert periods > 3
    short, *_ = _rescue_at(figure8, 19, budget=periods - 1)
    assert short.torque(state, bias, now, _holds, 10) is None and short.committed is None
    enough, *_ = _rescue_at(figure8, 19, budget=periods)
    assert enough.torque(state, bias, now, _holds, 10) is not None
    assert (enough.committed, enough.rest_at) == (unbounded.committed, unbounded.rest_at)


def test_under_a_budget_the_search_from_a_motions_first_state_runs_to_rest(figure8):
    """At the motion's first step (the guard's step 1) the search runs until rest whatever
    the budget, and commits to the unbounded search's brake; the committed brake is then
    live — held without a search — until the step its check came to rest at."""
    first, state, bias, now = _rescue_at(figure8, 19, budget=1)
    unbounded, *_ = _rescue_at(figure8, 19, budget=None)
    assert unbounded.torque(state, bias, now, _holds, 1) is not None
    assert first.torque(state, bias, now, _holds, 1) is not None
    assert (first.committed, first.rest_at) == (unbounded.committed, unbounded.rest_at)
    assert first.rest_at is not None
    for step in range(2, first.rest_at + 1):
        assert first.live(step)
        assert first.held_brake(state, bias, (lambda tau: tau,), _holds, step) is not None
    assert not first.live(first.rest_at + 1)
    assert first.searches == 1


def test_a_budget_below_one_period_is_refused(figure8):
    with pytest.raises(ValueError, match="budget"):
        _rescue_at(figure8, 19, budget=0)
    with pytest.raises(CpbcError, match="rescue_budget"):
        SafeguardSettings(rescue_budget=0)


UR5_RATE = "tools/campaigns/ur5_bpbc_rate.yaml"


@pytest.mark.parametrize("rate", [1000.0, 500.0])
def test_the_ur5s_wrist_keeps_the_floor_from_seed_49_of_the_rate_campaign(rate):
    """The UR5 with friction and a 1000 N·m/s rate limit from seed 49, which a brake stops in
    the plant: the rescue held a brake whose first rollout stopped above the floor for 40
    periods while the plant's friction took the wrist through the floor's clearance (by 0.15
    mm at 1 kHz, 0.03 mm at 500 Hz); checked again from each measured state, it is left in
    time and every margin stays positive."""
    path = Path(__file__).resolve().parents[1] / UR5_RATE
    setup = build(*load_scenario(str(path)))
    entry = next(e for e in setup.controllers if e.name == "BPBC")
    period = 1.0 / rate
    kept = kept_constraints(setup, entry, period, setup.safeguard)
    s = draw_state(setup, 49)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    assert stopping_brake(setup, kept, s.position, s.velocity, period, plant) is not None
    settings = replace(setup.loop_settings, duration=0.5, log_every=1,
                       bounds=replace(setup.loop_settings.bounds, period=period))
    check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                        safeguard=setup.safeguard)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.rescues > 0


def test_a_committed_brake_under_a_rate_limit_is_held_without_the_velocity_lookahead(
        load_dict):
    """The xArm7 on its table (tools/campaigns/xarm7_cpbc_table.yaml) at 250 Hz under the
    robot's budgets (6 tests, B = 8) and a 500 N·m/s torque-rate limit, from seed 57, a start
    inside V heading for the pole: the first step's search commits to the aimed brake. Its
    one-period test at the second step passes on every margin (F = 3.2) but fails the
    guard's velocity lookahead (F = −996: the rates while the torque ramps back), which its
    check's ramped braking answers; held on without it, the clearance keeps 0.6 mm, as
    unbounded. With the lookahead the commitment ended there, no brake stopped the arm within
    8 periods and the uniform brake, untested, let link 7 cross the clearance by 2.9 µm."""
    import yaml

    campaign = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    data = yaml.safe_load((campaign / "xarm7_cpbc_table.yaml").read_text())
    data["simulation"].update(torque_rate_limit=500, safeguard_test_budget=6,
                              safeguard_rescue_budget=8)
    setup = load_dict(data)
    period = 1 / 250
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    kept = kept_constraints(setup, entry, period, setup.safeguard)
    s = draw_state(setup, 57)
    settings = replace(setup.loop_settings, duration=0.1, log_every=1,
                       bounds=replace(setup.loop_settings.bounds, period=period))
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                        safeguard=setup.safeguard)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.min_margin > 5e-4 and check.trajectory.rescues >= 4


class _Crossed(Exception):
    """The run crossed a constraint (the known defect below), apart from a failed set-up."""


@pytest.mark.xfail(strict=True, raises=_Crossed, reason="found 2026-11-30, not mended "
                   "(docs/reliability.md, 'The same set-up under cpbc.verify'): infeasible "
                   "from its first step, the guard has only the rescue, whose checks run in "
                   "the nominal model, and the fallback; a larger declared friction error "
                   "changes nothing")
def test_the_kinova_under_dry_friction_keeps_its_rates_from_seed_16_at_500_hz():
    """The Kinova Jaco2 with 0.3 N·m of Coulomb friction on its light base joint, 200 N·m/s,
    at 500 Hz (tools/campaigns/kinova_friction_hold.yaml), from seed 16: a start inside V that
    the least-squares brake, ramped, stops in the plant. The guard is infeasible from its
    first step; the rescue, checking in the nominal model, finds no brake there, holds the
    least-squares brake from the third step to the fifteenth, and from the sixteenth no
    torque keeps (S0) with the ramp's lookahead: joint 2 ends 4.5 mrad/s through its rate
    bound at 58 ms. When this passes, the xfail goes and the reliability.md entry with it; a
    set-up that no longer holds (the state not stoppable, not in V) fails as itself."""
    path = Path(__file__).resolve().parents[1] / "tools/campaigns/kinova_friction_hold.yaml"
    setup = build(*load_scenario(str(path)))
    entry = setup.controllers[0]
    period = 1.0 / 500.0
    kept = kept_constraints(setup, entry, period, setup.safeguard)
    s = draw_state(setup, 16)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    assert stopping_brake(setup, kept, s.position, s.velocity, period, plant) is not None
    assert in_braking_set(setup, kept, s.position, s.velocity, period)
    settings = replace(setup.loop_settings, duration=0.1, log_every=1,
                       bounds=replace(setup.loop_settings.bounds, period=period))
    check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                        safeguard=setup.safeguard)
    if check.violated:
        raise _Crossed(f"{check.constraint} {check.min_margin:.3g}")
