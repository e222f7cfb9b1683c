"""The sampled-data safeguard: it leaves the law alone far from ∂S, backs off in closed form near
it, keeps every constraint at 1 kHz, 500 Hz and 100 Hz on a small seeded sample where the bare
law does not, and is reported in the run summary."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from cpbc.constraints import ConstraintSet, joint_position_limit, joint_rate_limit
from cpbc.constraints.stopping import Braking
from cpbc.controllers import BPBC, Power, RecentredBarrier
from cpbc.controllers.hold import hold_corrected
from cpbc.controllers.linalg import solve_spd
from cpbc.controllers.safeguard import Safeguard, SafeguardSettings, guarded, viable
from cpbc.errors import CpbcError, ParameterError
from cpbc.model import RobotModel
from cpbc.model.input_bounds import InputBounds
from cpbc.reliability.campaign import (
    RecordingPlant,
    campaign_setup,
    checked_run,
    constrained,
    sample_states,
)
from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import run_all
from cpbc.simulation import LoopSettings, MujocoPlant, PlantSettings, run_mujoco
from tools.reliability.robustness import sampled_data_campaign


@pytest.fixture
def bpbc(absolute_model: RobotModel) -> BPBC:
    rates = ConstraintSet(2, velocity=[joint_rate_limit([0.3, 0.2], ["t1", "t2"])])
    return BPBC(absolute_model, np.array([np.pi, np.pi]), rates, [2, 10], [4, 20], 1, 1,
                Power(0.2))


def predicted(law: Safeguard, x: np.ndarray, dx: np.ndarray, tau: np.ndarray, t: float):
    """The safeguard's own frozen prediction of (x, ẋ) at time t under the held τ."""
    dyn = law.model.dynamics(x, dx)
    acc = solve_spd(dyn.inertia, tau - dyn.coriolis_force - dyn.gravity - dyn.dissipation)
    return x + t * dx + 0.5 * t * t * acc, dx + t * acc


def test_far_from_the_boundary_the_law_is_untouched(bpbc: BPBC) -> None:
    """Far from every bound the guard hands back the law's torque corrected for the hold
    (and, with the correction off, the law's own torque), without acting."""
    x, dx = np.array([0.3, 0.4]), np.array([0.01, -0.02])
    bare = Safeguard(bpbc, InputBounds(0.01), SafeguardSettings(hold_correction=False))
    np.testing.assert_array_equal(bare.torque(x, dx), bpbc.torque(x, dx))
    guard = Safeguard(bpbc, InputBounds(0.01))
    state = bpbc.state(x, dx)
    bias = state.coriolis_force + state.gravity + state.dissipation
    np.testing.assert_array_equal(
        guard.torque(x, dx), hold_corrected(bpbc.model, state, bias, bpbc.torque(x, dx), 0.01))
    assert (guard.calls, guard.acted, guard.infeasible) == (1, 0, 0)
    assert guard.lyapunov(x, dx) == bpbc.lyapunov(x, dx)


def test_back_off_meets_the_discrete_barrier_condition(recentred: RecentredBarrier) -> None:
    """Near the lower limit of joint 2 and moving towards it, the recentred law's torque
    (≈ 2 kN·m at 100 Hz) breaks (S1); the blended torque meets it, at the end of the period
    and half-way."""
    h = 0.01
    guard = Safeguard(recentred, InputBounds(h))
    x, dx = np.array([0.7, -1.29]), np.array([0.09, -0.3])
    raw = recentred.torque(x, dx)
    tau = guard.torque(x, dx)
    assert guard.acted == 1 and guard.infeasible == 0
    assert np.linalg.norm(tau) < 0.05 * np.linalg.norm(raw)
    cons = recentred.constraints
    now = cons.margins(x, dx)
    floor = guard.cushion + guard.keep * (now - guard.cushion)
    end = cons.margins(*predicted(guard, x, dx, tau, h))
    assert np.all(end >= floor * (1 - 1e-9))
    mid, _ = predicted(guard, x, dx, tau, h / 2)
    floor_mid = guard.cushion[:2] + guard.keep_half * (now[:2] - guard.cushion[:2])
    assert np.all(cons.configuration[0].value(mid) >= floor_mid * (1 - 1e-9))
    # the bare law's torque fails it
    assert np.any(cons.margins(*predicted(guard, x, dx, raw, h)) < floor)


def test_back_off_takes_the_smallest_blend_it_can_find(recentred: RecentredBarrier) -> None:
    """A blend a little closer to the law than the one chosen already fails (S1)."""
    h = 0.01
    guard = Safeguard(recentred, InputBounds(h))
    x, dx = np.array([0.7, -1.29]), np.array([0.09, -0.3])
    raw = recentred.torque(x, dx)
    tau = guard.torque(x, dx)
    assert guard.acted == 1
    stop = recentred.model.dynamics(x, dx)
    brake = (stop.coriolis_force + stop.gravity + stop.dissipation
             - guard.settings.braking * (stop.inertia @ dx) / h)
    beta = float(np.linalg.lstsq((brake - raw)[:, None], tau - raw, rcond=None)[0][0])
    assert 0 < beta < 1
    closer = (1 - 0.98 * beta) * raw + 0.98 * beta * brake
    now = recentred.constraints.margins(x, dx)
    floor = guard.cushion + guard.keep * (now - guard.cushion)
    end = recentred.constraints.margins(*predicted(guard, x, dx, closer, h))
    mid, _ = predicted(guard, x, dx, closer, h / 2)
    floor_mid = guard.cushion[:2] + guard.keep_half * (now[:2] - guard.cushion[:2])
    fails = np.any(end < floor) or np.any(
        recentred.constraints.configuration[0].value(mid) < floor_mid)
    assert fails


def test_viability_is_the_quarter_period_excursion(recentred: RecentredBarrier) -> None:
    cons = recentred.constraints
    x = np.array([0.0, 0.999])  # 1 mrad from the upper limit of joint 2
    assert viable(cons, x, np.array([0.0, 0.3]), 0.01)  # ¼·10 ms·0.3 = 0.75 mrad
    assert not viable(cons, x, np.array([0.0, 0.5]), 0.01)  # 1.25 mrad
    assert viable(cons, x, np.array([0.0, -0.5]), 0.01)  # moving away
    assert viable(cons, x, np.array([0.0, 0.5]), 0.001)


def test_torque_limit_is_inside_the_prediction(recentred: RecentredBarrier) -> None:
    """With motors too weak to brake, even the brake fails (S1): counted as infeasible."""
    guard = Safeguard(recentred, InputBounds(0.01, np.array([1e-3, 1e-3])))
    x, dx = np.array([0.7, -1.295]), np.array([0.09, -0.3])
    guard.torque(x, dx)
    assert guard.acted == 1 and guard.infeasible == 1


def _lambda_of(t: np.ndarray) -> float:
    """The braking factor of a candidate τ = bias − λ·stop with bias = 0, stop = 1."""
    return -float(t[0])


def test_braking_search_finds_a_factor_between_stop_and_reverse(
    recentred: RecentredBarrier,
) -> None:
    """Stopping (λ = 1) and reversing (λ = 2) both fail; some λ between passes."""
    guard = Safeguard(recentred, InputBounds(0.01))
    seen: list[float] = []

    def slack(t: np.ndarray) -> float:
        lam = _lambda_of(t)
        seen.append(lam)
        return 0.01 - (lam - 1.5) ** 2  # passes for λ in (1.4, 1.6)

    lam, f = guard.brakes.search_braking(np.zeros(1), np.ones(1), slack,
                                         slack(-np.ones(1)), slack(-2 * np.ones(1)))
    assert f >= 0 and 1.4 < lam < 1.6
    assert len(seen) <= 2 + guard.settings.brake_search


def test_braking_search_returns_the_best_when_none_passes(recentred: RecentredBarrier) -> None:
    guard = Safeguard(recentred, InputBounds(0.01))

    def slack(t: np.ndarray) -> float:
        return -0.5 - (_lambda_of(t) - 1.3) ** 2  # best at λ = 1.3, never ≥ 0

    lam, f = guard.brakes.search_braking(np.zeros(1), np.ones(1), slack,
                                         slack(-np.ones(1)), slack(-2 * np.ones(1)))
    assert f < 0 and abs(lam - 1.3) < 0.1  # five golden-section steps on [1, 2]
    assert f == pytest.approx(slack(-lam * np.ones(1)))
    off = Safeguard(recentred, InputBounds(0.01), SafeguardSettings(brake_search=0))
    lam0, _ = off.brakes.search_braking(np.zeros(1), np.ones(1), slack,
                                        slack(-np.ones(1)), slack(-2 * np.ones(1)))
    assert lam0 == 1.0  # no search: the better of stopping and reversing


def test_fallback_is_the_calmest_brake_that_keeps_the_cushion(
    recentred: RecentredBarrier,
) -> None:
    """With no torque meeting (S1) the fallback keeps the margins above the cushion (S0)
    with the smallest braking factor (least reversal of the motion) it can find."""
    guard = Safeguard(recentred, InputBounds(0.01))

    def positivity(t: np.ndarray) -> float:
        return _lambda_of(t) - 1.4  # (S0) holds for λ ≥ 1.4

    lam = _lambda_of(guard.brakes.fallback(np.zeros(1), np.ones(1), positivity))
    assert 1.4 <= lam < 1.45
    assert _lambda_of(guard.brakes.fallback(np.zeros(1), np.ones(1), lambda t: 1.0)) == 1.0


@pytest.mark.parametrize("d1, v1, d2, v2", [(1.5e-4, 0.04, 2e-4, 0.05),
                                            (1e-4, 0.03, 1e-4, 0.3)])
def test_escape_pushes_off_one_limit_and_stops_the_joint_leaving_another(
    recentred: RecentredBarrier, d1: float, v1: float, d2: float, v2: float
) -> None:
    """Joint 1 heads into its upper limit, joint 2 leaves its lower one, both closer than
    their cushion at 100 Hz: no uniform brake meets (S1) or (S0) — reversing all of the
    motion sends joint 2 back at its limit. The escape pushes joint 1 off (its margin grows
    over the period and dips mid-period by no more than the decay share) and only stops
    joint 2 (judged by the closed-form prediction: one step of 10 ms)."""
    # the law's torque held as it is (with the hold correction it meets (S1) here)
    guard = Safeguard(recentred, InputBounds(0.01),
                      SafeguardSettings(max_step=0.01, hold_correction=False))
    cons = recentred.constraints
    x, dx = np.array([1.4 - d1, -1.3 + d2]), np.array([v1, v2])
    assert viable(cons, x, dx, 0.01)
    now = cons.margins(x, dx)
    assert np.all(now[:2] < guard.cushion[:2])
    tau = guard.torque(x, dx)
    assert guard.infeasible == 1
    x_mid, _ = predicted(guard, x, dx, tau, 0.005)
    x_end, dx_end = predicted(guard, x, dx, tau, 0.01)
    mid, end = cons.margins(x_mid, dx), cons.margins(x_end, dx_end)
    assert mid[0] >= guard.keep_half * now[0] * (1 - 1e-9)
    assert end[0] > 2 * now[0] and end[1] > now[1]
    assert dx_end[0] < 0 and abs(dx_end[1]) < 1e-6 * v2
    assert np.all(end[2:] > 0)


@pytest.mark.parametrize(
    "kwargs", [{"decay_rate": 0}, {"braking": -1}, {"cushion": 1.0}, {"substeps": 0},
               {"backoffs": 0}, {"decay_rate": float("nan")}, {"brake_search": -1},
               {"time_budget": -1e-4}, {"test_budget": 0}, {"rescue_budget": 0},
               {"plant_step": float("inf")}, {"velocity_cushion": -0.1}],
)
def test_settings_are_checked(kwargs: dict) -> None:
    """A ValueError naming the setting (ParameterError), as a Python caller expects."""
    with pytest.raises(ParameterError) as caught:
        SafeguardSettings(**kwargs)
    (name,) = kwargs
    assert isinstance(caught.value, ValueError) and caught.value.parameter == name
    assert str(caught.value).startswith(f"safeguard {name} must be")


@pytest.mark.parametrize("error", [-1.0, float("nan"), [1.0, 2.0, 3.0], [0.5, float("inf")]])
def test_a_declared_model_error_is_checked(bpbc: BPBC, error: object) -> None:
    """ā: one number or one per coordinate, finite and ≥ 0 — else a ValueError naming
    model_error (a short vector stopped numpy's broadcast; a negative or NaN one passed)."""
    with pytest.raises(ParameterError, match=r"^model_error must be one number or one per "
                       r"coordinate \(2\)") as caught:
        guarded(bpbc, InputBounds(0.002, 50.0), SafeguardSettings(), model_error=error)
    assert caught.value.parameter == "model_error"


@pytest.mark.parametrize(("tau", "added", "named"), [
    ([float("nan"), 0.0], None, "tau"), ([1.0], None, "tau"), ([0.0, 0.0], [0.0, float("inf")],
                                                                "added"),
    ([0.0, 0.0], [0.0, 0.0, 0.0], "added")])
def test_a_bad_held_torque_is_named_and_the_guard_is_as_it_was(bpbc: BPBC, tau, added,
                                                               named) -> None:
    """Safeguard.holding (a robot's loop tells the guard its torque every cycle): a torque
    that is not n finite numbers is refused by name and the next step is the one the guard
    would have made. Before, a short one was taken, and the step's box was read past its
    end (uninitialised bounds)."""
    bounds = InputBounds(0.002, 50.0, 2000.0)
    x, dx = np.array([0.3, 0.4]), np.array([0.29, 0.1])
    law, twin = Safeguard(bpbc, bounds), Safeguard(bpbc, bounds)
    np.testing.assert_array_equal(law.torque(x, dx), twin.torque(x, dx))
    with pytest.raises(ParameterError, match=rf"^{named} must be 2 finite numbers") as caught:
        law.holding(np.array(tau), None if added is None else np.array(added))
    assert caught.value.parameter == named
    later = x + 0.002 * dx
    np.testing.assert_array_equal(law.torque(later, dx), twin.torque(later, dx))


def test_period_is_checked(bpbc: BPBC) -> None:
    with pytest.raises(CpbcError, match="period"):
        Safeguard(bpbc, InputBounds(0.0))


def test_sub_stepped_prediction_agrees_with_the_frozen_one(bpbc: BPBC) -> None:
    x, dx = np.array([0.3, 0.4]), np.array([0.29, 0.1])
    a = Safeguard(bpbc, InputBounds(0.002)).torque(x, dx)
    b = Safeguard(bpbc, InputBounds(0.002), SafeguardSettings(substeps=4)).torque(x, dx)
    np.testing.assert_allclose(a, b, rtol=1e-6)


def test_the_safeguard_imports_no_simulator() -> None:
    code = "import sys, cpbc.controllers.safeguard; print('mujoco' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60)
    assert out.stdout.strip() == "False"


# -- in the loop -------------------------------------------------------------------------------
@pytest.mark.parametrize("period", [0.001, 0.002, 0.01])
# expected here: the bare law diverges from some states at 100 Hz (its logged margins
# overflow), and the guard meets candidate torques predicting astronomic speeds (judged failing)
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_small_campaign_no_violation_with_the_safeguard(period: float) -> None:
    """20 seeded states near and away from ∂S, sampled-data admissible at 100 Hz, MuJoCo's
    default integrator: the bare re-centred law breaks a constraint from some of them, the
    guarded one from none."""
    setup = campaign_setup("planar_recentred")
    states = [s for s in sample_states(setup, 40, seed=3)
              if viable(setup.monitor, s.position, s.velocity, 0.01)][:20]
    assert len(states) == 20
    records = sampled_data_campaign(
        setup, "planar_recentred", states, [period], 0.3, SafeguardSettings())
    bare = [r for r in records if not r["safeguard"]]
    guarded = [r for r in records if r["safeguard"]]
    assert len(bare) == len(guarded) == 20
    assert sum(r["violated"] for r in bare) > 0
    assert sum(r["violated"] for r in guarded) == 0
    assert sum(r["acted"] for r in guarded) > 0


def test_loop_reports_the_safeguard_and_can_switch_it_off(recentred: RecentredBarrier,
                                                          planar_path) -> None:
    plant = MujocoPlant.from_file(planar_path, PlantSettings(0.001, "Euler"))
    x0, dx0 = np.array([0.7, -1.29]), np.array([0.09, -0.3])
    coords = recentred.model.coordinates
    on = run_mujoco(plant, guarded(recentred, InputBounds(0.01), SafeguardSettings()), coords,
                    x0, dx0,
                    LoopSettings(0.2, InputBounds(0.01)))
    off = run_mujoco(plant, guarded(recentred, InputBounds(0.01), None), coords, x0, dx0,
                     LoopSettings(0.2, InputBounds(0.01)))
    assert guarded(recentred, InputBounds(0.01), None) is recentred
    assert on.outcome == "completed" and on.safeguard_steps > 0
    assert off.safeguard_steps == 0


@pytest.mark.parametrize("period", [0.001, 0.01])
def test_also_keeps_a_constraint_the_law_only_monitors(bpbc: BPBC, planar_path,
                                                       period: float) -> None:
    """BPBC bounds rates only; heading at a joint limit it does not know of, it crosses it.
    Told to keep that limit too, the safeguard brakes the arm short of it."""
    wall = joint_position_limit(np.array([-1.0, -10.0]), np.array([0.3, 10.0]), ["t1", "t2"])
    settings = PlantSettings(0.001, "Euler")
    plant = RecordingPlant(MujocoPlant.from_file(planar_path, settings).model, settings)
    coords = bpbc.model.coordinates
    x0, dx0 = np.array([0.2, 0.2]), np.array([0.29, 0.15])
    low = {}
    for keep in ((), (wall,)):
        law = guarded(bpbc, InputBounds(period), SafeguardSettings(), also_keep=keep)
        traj = run_mujoco(plant, law,
                          coords, x0, dx0, LoopSettings(1.0, InputBounds(period)))
        assert traj.outcome == "completed"
        xs, dxs = plant.fine_states(coords.matrix)
        low[len(keep)] = float(wall.values_along(xs).min())
        assert np.all(bpbc.constraints.margins_along(xs, dxs) > 0)
        assert (traj.safeguard_steps > 0) == bool(keep)
    assert low[0] < 0 < low[1]


def test_an_extra_constraint_already_broken_does_not_break_the_guard(bpbc: BPBC) -> None:
    wall = joint_position_limit(np.array([-1.0, -10.0]), np.array([0.3, 10.0]), ["t1", "t2"])
    guard = Safeguard(bpbc, InputBounds(0.01), also_keep=(wall,))
    tau = guard.torque(np.array([0.31, 0.2]), np.array([0.1, 0.0]))  # past the wall
    assert np.all(np.isfinite(tau)) and guard.acted == 1
    kept = Safeguard(bpbc, InputBounds(0.01), also_keep=bpbc.constraints.configuration)
    assert len(kept.guarded) == 2
    same_names = joint_position_limit(np.array([-1.0, -10.0]), np.array([0.3, 10.0]),
                                      ["t1", "t2"])
    twice = Safeguard(bpbc, InputBounds(0.01), also_keep=(wall, same_names))  # one copy is kept
    assert len(twice.guarded) == 2 + 2


def test_past_a_limit_only_the_guard_keeps_the_arm_is_let_back_not_held() -> None:
    """BPBC-KE knows only its energy bound; the guard keeps the joint ranges. From a state no
    torque in the 2 N m box could stop (joint 2 at 0.997 of its 1.0 limit, 0.35 rad/s in)
    the arm went past the limit; the guard then asked the broken margin to turn positive
    within one period, failed every step and held the arm at rest beyond the limit for good
    (3001 of 3001 steps), while the law's torque led back. Now a broken margin must merely
    not shrink: the law leads the arm back inside and the guard lets go."""
    from pathlib import Path

    path = Path(__file__).resolve().parent.parent / "tools/campaigns/planar_laws_box.yaml"
    setup = build(*load_scenario(path))
    entry = next(e for e in setup.controllers if e.name == "BPBC-KE")
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    settings = replace(setup.loop_settings, duration=2.0, noise=None)
    x0, dx0 = np.array([0.28472, 0.99670]), np.array([0.03659, 0.34515])
    check = checked_run(plant, setup, entry, x0, dx0, settings, safeguard=setup.safeguard)
    traj = check.trajectory
    limit = setup.monitor.configuration[0]
    assert np.max(traj.position[:, 1]) > 1.0  # it did go past: no torque could stop it
    assert np.all(limit.value(traj.position[-1]) > 0)  # and is back inside
    assert traj.safeguard_steps < 0.25 * traj.control_steps


def test_scenarios_keep_their_monitored_constraints_unless_told_not_to() -> None:
    setup = campaign_setup("ur5_bpbc")
    assert setup.also_keep == setup.monitor.configuration
    names = [n for c in setup.also_keep for n in c.names]
    assert "position[elbow_joint]" in names and "clearance[wrist_3_link|floor]" in names
    spec, file = load_scenario("ur5_bpbc")
    off = spec.model_copy(update={"simulation": spec.simulation.model_copy(
        update={"safeguard_monitored": False})})
    assert build(off, file).also_keep == ()


def test_summary_and_scenario_key(tmp_path) -> None:
    setup = campaign_setup("planar_recentred")
    setup.cases = [replace(setup.cases[0], position=np.array([0.7, -1.29]),
                           velocity=np.array([0.09, -0.3]))]
    setup.controllers = [c for c in setup.controllers if c.name == "recentred"]
    setup.loop_settings = replace(setup.loop_settings, duration=0.2,
        bounds=replace(setup.loop_settings.bounds, period=0.01))
    (on,) = run_all(setup)
    assert on.summary.safeguard_steps > 0
    assert on.summary.as_dict()["safeguard_steps"] == on.summary.safeguard_steps
    setup.safeguard = None
    (off,) = run_all(setup)
    assert off.summary.safeguard_steps == 0


def _joint_accel(law, x, dx, tau):
    state = law.model.state(x, dx)
    return solve_spd(state.inertia, tau - state.coriolis_force - state.gravity
                     - state.dissipation), state


def test_every_guarded_torque_fits_the_torque_box_with_its_direction_kept(
    recentred: RecentredBarrier,
) -> None:
    """With actuator limits, the torque the safeguard returns lies in the box, and where the
    law's torque or a brake had to shrink, the acceleration keeps its direction: it is
    scaled toward C ẋ + g + f, never clipped joint by joint."""
    limit = np.array([3.0, 1.0])
    # the law's own torque, not its hold-corrected one, is what is compared below
    guard = Safeguard(recentred, InputBounds(0.01, limit),
                      SafeguardSettings(hold_correction=False))
    rng = np.random.default_rng(7)
    shrunk = 0
    for _ in range(200):
        x = rng.uniform([-0.95, -1.25], [1.35, 0.95])
        dx = rng.uniform(-0.55, 0.55, 2)
        acted = guard.acted
        tau = guard.torque(x, dx)
        assert np.all(np.abs(tau) <= limit * (1 + 1e-12))  # joint coordinates
        raw = recentred.torque(x, dx)
        if np.any(np.abs(raw) > limit) and guard.acted == acted:  # the law's torque, scaled
            shrunk += 1
            a, _ = _joint_accel(recentred, x, dx, tau)
            a_raw, _ = _joint_accel(recentred, x, dx, raw)
            cos = a @ a_raw / (np.linalg.norm(a) * np.linalg.norm(a_raw))
            assert cos == pytest.approx(1.0, abs=1e-9)
            assert np.linalg.norm(a) <= np.linalg.norm(a_raw) * (1 + 1e-12)
    assert shrunk > 20 and guard.scaled > 0


def test_a_brake_that_does_not_fit_slows_every_joint(joint_model: RobotModel) -> None:
    """The one-period brake b − D ẋ/h of a joint-1 swing is outside the box. Clipped joint
    by joint it would speed the joints up (the coupling through D); scaled into the box it
    decelerates every joint."""
    names = ["q1", "q2"]
    cons = ConstraintSet(2, [joint_position_limit(np.array([-3.0, -1.0]),
                                                  np.array([3.0, 1.0]), names)])
    law = RecentredBarrier(joint_model, np.zeros(2), cons, 5, 2)
    limit = np.array([2.9, 5.8])
    h = 0.01
    guard = Safeguard(law, InputBounds(h, limit))
    x, dx = np.array([0.0, 0.45]), np.array([-0.44, -0.03])
    brake = guard.brakes.brake(*_bias_and_stop(law, x, dx, h), 1.0)
    assert np.all(np.abs(brake) <= limit * (1 + 1e-12))
    a, _ = _joint_accel(law, x, dx, brake)
    assert np.all(np.abs(dx + h * a) < np.abs(dx))  # every joint slower
    clipped = np.clip(_bias_and_stop(law, x, dx, h)[0] - _bias_and_stop(law, x, dx, h)[1],
                      -limit, limit)
    a_clip, _ = _joint_accel(law, x, dx, clipped)
    assert np.any(np.abs(dx + h * a_clip) > np.abs(dx))  # what clipping would have done
    assert np.all(np.abs(guard.torque(x, dx)) <= limit * (1 + 1e-12))


def _bias_and_stop(law, x, dx, h):
    state = law.model.state(x, dx)
    bias = state.coriolis_force + state.gravity + state.dissipation
    return bias, state.inertia @ dx / h


def test_the_braking_margins_keep_states_the_one_period_test_lets_go() -> None:
    """Panda of panda_cpbc_sphere, URDF torque limits in plant and guard, 1 kHz: from a
    seeded state near the rate bounds (campaign seed 11, draw 136), in the braking set V,
    CPBC drives the hand toward the table faster than the box can brake. The one-period
    test (S1) on the margins alone notices too late and the hand crosses the table's 1 cm
    margin; with the braking margins σ the guard slows it in time. Both hold the law's
    torque, as when this was found: with the hold correction the state is kept even
    without σ."""
    off = SafeguardSettings(hold_correction=False)
    setup = replace(campaign_setup("panda_cpbc_sphere"), safeguard=off)
    limit = setup.loop_settings.bounds.torque
    assert limit is not None and limit.max() == 87.0
    entry = constrained(setup)[0]
    braking = Braking.of(setup.model, limit)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    settings = replace(setup.loop_settings, duration=0.7, noise=None)
    for s in sample_states(setup, 137, seed=11)[136:]:
        sigma, _ = braking.margins(setup.monitor, setup.model, s.position, s.velocity)
        assert np.all(sigma > 0)
        kept = checked_run(plant, setup, entry, s.position, s.velocity, settings,
                           safeguard=off)
        assert not kept.violated and kept.trajectory.safeguard_steps > 0
        guard = setup.controller(entry)
        assert isinstance(guard, Safeguard)
        guard.acceptance.braking = None  # the same guard without σ
        law = replace(entry, controller=guard)
        lost = checked_run(plant, setup, law, s.position, s.velocity, settings,
                           safeguard=None)
        assert lost.violated and lost.constraint == "clearance[panda_hand|table]"


@pytest.mark.parametrize("period", [0.001, 0.01])
def test_within_the_urdf_torque_limits_no_state_of_the_braking_set_is_lost(period: float
                                                                         ) -> None:
    """The Panda of panda_cpbc_sphere with the URDF's torque limits (87 / 12 N·m) in the plant
    and the guard: of 30 seeded states, most pushed near ∂S, the guarded CPBC keeps every one
    of the braking set V inside S at every physics step, while states outside V (the brake
    that slows every joint together cannot stop them in time) are lost — the sample reaches
    the edge of what the actuators allow."""
    setup = campaign_setup("panda_cpbc_sphere")
    limit = setup.loop_settings.bounds.torque
    assert limit is not None and limit.max() == 87.0
    entry = constrained(setup)[0]
    braking = Braking.of(setup.model, limit)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    settings = replace(setup.loop_settings, duration=0.3,
        bounds=replace(setup.loop_settings.bounds, period=period), noise=None)
    inside, outside_lost, acted = 0, 0, 0
    for s in sample_states(setup, 30, seed=11):
        sigma, _ = braking.margins(setup.monitor, setup.model, s.position, s.velocity)
        check = checked_run(plant, setup, entry, s.position, s.velocity, settings,
                            safeguard=SafeguardSettings())
        if np.all(sigma > 0):
            inside += 1
            acted += check.trajectory.safeguard_steps
            assert not check.violated, (s, check.constraint, check.min_margin)
        else:
            outside_lost += check.violated
    assert inside >= 15 and outside_lost >= 3 and acted > 0


def test_a_run_the_guard_holds_at_a_boundary_is_held_not_stalled(bpbc: BPBC,
                                                                  planar_path) -> None:
    """BPBC heads for θ₁ = π through a joint limit at 0.3 rad that only the safeguard keeps:
    the guard stops link 1 short of it and lets link 2 go on to its target (its torque less
    the push into the wall), and from then on replaces the law's torque on most steps. The
    run is judged `held` — the guard, not a spurious equilibrium of the law, keeps the arm
    there — and without the wall the same law converges."""
    from cpbc.results.metrics import SettleCriteria, judge_status

    wall = joint_position_limit(np.array([-1.0, -10.0]), np.array([0.3, 10.0]), ["t1", "t2"])
    settings = PlantSettings(0.001, "Euler")
    plant = MujocoPlant.from_file(planar_path, settings)
    coords = bpbc.model.coordinates
    x0, dx0 = np.array([0.2, 0.2]), np.zeros(2)
    walled = guarded(bpbc, InputBounds(0.001), SafeguardSettings(), also_keep=(wall,))
    held = run_mujoco(plant, walled,
                      coords, x0, dx0, LoopSettings(60.0, InputBounds(0.001)))
    assert judge_status(held, bpbc.target, SettleCriteria())[0] == "held"
    assert held.guarded_steps is not None and held.guarded_steps[-12000:].mean() > 0.5
    assert abs(held.position[-1, 1] - np.pi) < 0.01  # link 2 went on to its target
    assert 0 < 0.3 - held.position[-1, 0] < 0.01  # link 1 rests against the wall
    free = run_mujoco(plant, guarded(bpbc, InputBounds(0.001), SafeguardSettings()), coords,
                      x0, dx0,
                      LoopSettings(60.0, InputBounds(0.001)))
    assert free.guarded_steps is not None and not free.guarded_steps.any()
    assert judge_status(free, bpbc.target, SettleCriteria())[0] == "converged"


def test_the_slide_removes_only_the_push_into_the_boundary(bpbc: BPBC) -> None:
    """At rest against a wall on θ₁ that only the guard keeps, BPBC's torque accelerates
    link 1 into the wall: the guard's slide keeps the law's acceleration of link 2 as it is,
    turns link 1's round so that its margin grows as (S1) asks, and passes (S1)."""
    wall = joint_position_limit(np.array([-1.0, -10.0]), np.array([0.3, 10.0]), ["t1", "t2"])
    guard = Safeguard(bpbc, InputBounds(0.001), also_keep=(wall,))
    x, dx = np.array([0.3 - 9e-4, 0.5]), np.zeros(2)  # just inside its cushion
    state = guard.state(x, dx)
    out = bpbc.evaluate_state(state, margins=True)
    bias = state.coriolis_force + state.gravity
    law_acc = solve_spd(state.inertia, out.torque - bias)
    assert law_acc[0] > 0  # into the wall (θ₁ ≤ 0.3)
    now, floor, floor_mid = guard.sample_floors(x, out.margins)
    floor, floor_mid = np.maximum(floor, 1e-300), np.maximum(floor_mid, 1e-300)
    slack = guard.acceptance.check(guard.predictor(state, bias), floor, floor_mid)
    assert slack(out.torque) < 0
    slid = guard.brakes.slide(state, bias, out.torque, now, floor, floor_mid, None)
    acc = solve_spd(state.inertia, slid - bias)
    assert acc[0] < 0 and acc[1] == pytest.approx(law_acc[1], rel=1e-9)
    assert slack(slid) >= 0
    tau = guard.torque(x, dx)
    assert slack(tau) >= 0 and not np.allclose(tau, bias)  # not a brake to rest


@pytest.mark.parametrize("scenario, seed, rate", [
    ("panda_cpbc_ke_box", 198, 1000.0),  # implicitfast: the frozen prediction is its step
    ("tools/campaigns/z1_bpbc_ke.yaml", 228, 500.0),  # RK4, two physics steps per period
])
def test_margins_are_held_under_the_plants_own_integrator(scenario: str, seed: int,
                                                          rate: float) -> None:
    """Seeded viable states (cpbc.verify's draws) from which the kinetic-energy bound was
    crossed while the guard trusted one prediction only: the frozen one under RK4 (the Z1
    at 500 Hz, −1.7e-5 J), the second-order one under implicitfast (the Panda, −3e-8 J).
    Held under both predictions, each stays inside at every physics step."""
    from pathlib import Path

    from cpbc.reliability.campaign import kept_constraints
    from cpbc.reliability.verification import classify, draw_state

    path = Path(__file__).resolve().parent.parent / scenario
    setup = build(*load_scenario(path if path.suffix == ".yaml" else scenario))
    entry = constrained(setup)[0]
    s = draw_state(setup, seed)
    kept = kept_constraints(setup, entry, 1 / rate, setup.safeguard)
    assert classify(setup, kept, s.position, s.velocity, 1 / rate) == "stoppable"
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    settings = replace(setup.loop_settings, duration=0.5,
        bounds=replace(setup.loop_settings.bounds, period=1 / rate), noise=None)
    for corrector, kept in ((True, True), (False, scenario.startswith("panda"))):
        check = checked_run(plant, setup, entry, s.position, s.velocity, settings,
                            safeguard=SafeguardSettings(corrector=corrector,
                                                        hold_correction=False))
        assert check.violated != kept, (corrector, check.constraint, check.min_margin)


def test_a_law_riding_a_rate_bound_slows_down_as_in_continuous_time(tmp_path) -> None:
    """The Kinova Jaco2 on a 1.5 rad reach at half its rate limits, CPBC α = 0.2: in
    continuous time the law rides the rate bound (headroom 8e-5 rad/s) and settles at 8.0 s.
    Near the bound its authority (D + ρΠ with ρ/ψ huge) is below the hold error: holding the
    law's torque, the margin was worn down to the cushion, the guard trimmed 69 % of the
    steps and the arm coasted 1.5 rad past its target at the bound. Holding its acceleration
    (the hold correction) it settles as in continuous time, the guard never acting."""
    spec = {
        "name": "jaco_reach", "robot": {"model": "kinova"},
        "simulation": {"duration": 12.0, "timestep": 0.001},
        "target": [0.8, 3.6, 3.9, 0.0, 3.1416, 0.0],
        "cases": [{"name": "start", "position": [-0.6, 3.0, 2.6, -0.1, 3.0, -0.1]}],
        "constraints": [
            {"type": "joint_position_limit", "name": "ranges", "lower": "from_model",
             "upper": "from_model",
             "joints": ["j2s6s200_joint_2", "j2s6s200_joint_3", "j2s6s200_joint_5"]},
            {"type": "joint_rate_limit", "name": "rates", "bounds": "from_model", "scale": 0.5},
        ],
        "controllers": [{"type": "cpbc", "name": "CPBC", "omega_n": 6.0, "zeta": 1.0,
                         "shaping": {"type": "power", "alpha": 0.2}}],
    }
    from cpbc.scenario import Scenario

    setup = build(Scenario.model_validate(spec), tmp_path / "s.yaml")
    assert setup.safeguard is not None and setup.safeguard.hold_correction
    (result,) = run_all(setup)
    s = result.summary
    assert s.status == "converged" and s.settle_time is not None and s.settle_time < 8.5, (
        s.status, s.settle_time, s.safeguard_share)
    assert not s.crossed_constraints and s.safeguard_share < 0.05
    # holding the torque instead, as before: the defect this fixes
    spec["simulation"]["safeguard_hold_correction"] = False
    (held_torque,) = run_all(build(Scenario.model_validate(spec), tmp_path / "s.yaml"))
    assert held_torque.summary.status == "not_settled"
    assert held_torque.summary.safeguard_share > 0.5


def test_the_hold_correction_keeps_the_acceleration_of_the_sample() -> None:
    """Over one period of the Panda model's own motion (RK4 in 20 steps), the mean
    acceleration under the corrected torque is the law's acceleration at the sample to
    O(h²); under the law's torque it is off by ½Δa = O(h)."""
    from cpbc.model.loading import load_arm

    model = RobotModel(load_arm("panda").model, name="panda")
    rng = np.random.default_rng(3)

    def mean_acc(x: np.ndarray, dx: np.ndarray, t: np.ndarray, h: float) -> np.ndarray:
        q, v, k, f = x.copy(), dx.copy(), 20, model.forward_dynamics
        dt = h / k
        for _ in range(k):
            k1v, k1q = f(q, v, t), v
            k2v, k2q = f(q + 0.5 * dt * k1q, v + 0.5 * dt * k1v, t), v + 0.5 * dt * k1v
            k3v, k3q = f(q + 0.5 * dt * k2q, v + 0.5 * dt * k2v, t), v + 0.5 * dt * k2v
            k4v, k4q = f(q + dt * k3q, v + dt * k3v, t), v + dt * k3v
            q = q + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v = v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        return (v - dx) / h

    for _ in range(5):
        x, dx = rng.uniform(-1.0, 1.0, model.n), rng.uniform(-1.5, 1.5, model.n)
        state = model.state(x, dx)
        bias = state.coriolis_force + state.gravity + state.dissipation
        tau = bias + rng.normal(0.0, 5.0, model.n)
        a0 = solve_spd(state.inertia, tau - bias)
        errors = []
        for h in (0.004, 0.002):
            plain = np.abs(mean_acc(x, dx, tau, h) - a0).max()
            held = np.abs(mean_acc(x, dx, hold_corrected(model, state, bias, tau, h), h)
                          - a0).max()
            errors.append((plain, held))
        (plain4, held4), (plain2, held2) = errors
        assert held2 < 0.25 * plain2 and 1.6 < plain4 / plain2 < 2.4, errors
        assert held4 / held2 > 3.0, errors  # second order: halving h quarters it


@pytest.mark.parametrize("scenario, seed", [
    ("panda_cpbc_sphere", 0),  # rate[panda_joint5] crossed by 3.8e-4 rad/s mid-period
    ("tools/campaigns/z1_bpbc_ke.yaml", 23),  # the kinetic energy, likewise
])
def test_velocity_margins_are_held_inside_the_period(scenario: str, seed: int) -> None:
    """At 100 Hz, holding the hold-corrected torque, these campaign states crossed a velocity
    bound between two samples while the margin at every sample (and the predicted one at
    every period's end) was positive: the acceleration turned within the period. The guard
    now holds the velocity margins at every predicted sub-step as well."""
    from pathlib import Path

    from cpbc.reliability.campaign import kept_constraints
    from cpbc.reliability.verification import classify, draw_state

    path = Path(__file__).resolve().parent.parent / scenario
    setup = build(*load_scenario(path if path.suffix == ".yaml" else scenario))
    entry = constrained(setup)[0]
    s = draw_state(setup, seed)
    kept = kept_constraints(setup, entry, 0.01, setup.safeguard)
    assert classify(setup, kept, s.position, s.velocity, 0.01) == "stoppable"
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    settings = replace(setup.loop_settings, duration=0.5,
        bounds=replace(setup.loop_settings.bounds, period=0.01), noise=None)
    assert setup.safeguard is not None and setup.safeguard.hold_correction
    check = checked_run(plant, setup, entry, s.position, s.velocity, settings,
                        safeguard=setup.safeguard)
    assert not check.violated, (check.constraint, check.min_margin)


def test_lyapunov_runs_no_guard_and_moves_no_count(bpbc: BPBC) -> None:
    """V of the guarded law is the law's: asking for it runs no guard (every count stays),
    so a noisy run, whose loop asks for the true state's V beside every guarded call, guards
    each control step once (it guarded twice: 30 002 calls over 15 001 steps on
    planar_cpbc_ke)."""
    guard = Safeguard(bpbc, InputBounds(0.001))
    x, dx = np.array([0.3, 0.4]), np.array([0.25, -0.15])  # near the rate bounds: it acts
    guard.torque(x, dx)
    counts = (guard.calls, guard.acted, guard.infeasible, guard.scaled, guard.uncorrected)
    assert guard.lyapunov(x, dx) == bpbc.lyapunov(x, dx)
    assert (guard.calls, guard.acted, guard.infeasible, guard.scaled,
            guard.uncorrected) == counts

    scenario, path = load_scenario("planar_cpbc_ke")
    spec = scenario.model_dump(exclude_unset=True)
    spec["simulation"].update(duration=0.5, noise={"position": 1e-4, "velocity": 1e-3,
                                                   "seed": 1})
    from cpbc.scenario import Scenario

    setup = build(Scenario.model_validate(spec), path)
    (entry,) = constrained(setup)
    law = setup.controller(entry)
    assert isinstance(law, Safeguard)
    case = setup.cases[0]
    traj = run_mujoco(setup.make_plant(), law, setup.model.coordinates, case.position,
                      case.velocity, setup.loop_settings)
    assert traj.control_steps == 501 and law.calls == traj.control_steps


def test_warm_takes_every_path_of_a_step_whatever_the_law_does() -> None:
    """At the FR3's calm start (the law's torque passes) ``warm`` still takes the slide, the
    brakes' search and the rescue's search, under a rate limit and a budget of one test a
    step, and gives the budget back."""
    from pathlib import Path
    scenario = Path(__file__).resolve().parent / "scenarios" / "fr3_reach_ball.yaml"
    setup = build(*load_scenario(scenario))
    assert setup.safeguard is not None
    setup = replace(setup, safeguard=replace(setup.safeguard, test_budget=1))
    guard = setup.controller(setup.controllers[0])
    assert isinstance(guard, Safeguard) and guard.brakes.rescue is not None
    x, dx = setup.cases[0].position, setup.cases[0].velocity
    guard.warm(x, dx + 0.3)
    assert guard.brakes.rescue.searches == 2  # its own, and a spent first step's
    assert guard.budget.tests == 1 and guard.box.holding is not None
    fresh = setup.controller(setup.controllers[0])
    fresh.torque(x, dx)
    assert fresh.acted == 0  # the path warm forced is not the calm start's own


def test_prime_touches_a_step_and_moves_nothing() -> None:
    """``prime`` at a state the arm is not at (under the FR3's rate limit) leaves the guard
    as it was — no count, no held torque —, so a run after it holds the torques of an
    unprimed guard's to the bit, acting at 78 steps; outside S it raises, still moving
    nothing."""
    from pathlib import Path

    from cpbc.errors import ConstraintViolation
    scenario = Path(__file__).resolve().parent / "scenarios" / "fr3_reach_ball.yaml"
    setup = build(*load_scenario(scenario))
    x = np.array(setup.cases[0].position, dtype=float)
    dx = np.zeros(7)
    x[3], dx[3] = -0.6, 1.1  # toward joint 4's upper limit, fast: the guard brakes
    plain, primed = (setup.controller(setup.controllers[0]) for _ in range(2))
    assert isinstance(primed, Safeguard) and isinstance(plain, Safeguard)
    primed.prime(x - 0.05, dx + 0.2)
    with pytest.raises(ConstraintViolation):
        primed.prime(x, dx + 0.5)  # past joint 4's rate bound
    assert primed.calls == 0 and primed.box.holding is None
    settings = replace(setup.loop_settings, duration=0.3)
    runs = [run_mujoco(setup.make_plant(), guard, setup.model.coordinates, x, dx, settings)
            for guard in (plain, primed)]
    assert np.array_equal(runs[0].torque, runs[1].torque)
    assert plain.acted == primed.acted == 78 and plain.calls == primed.calls
