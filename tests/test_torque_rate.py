"""The motors' torque-rate limit (simulation.torque_rate_limit): the plant applies it as a
motor would, the safeguard chooses only within it, runs start from the gravity torque, the
summary reports the peak rate; checked from the logged joint torques of real MuJoCo runs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import campaign_run

from cpbc.constraints.brakes import TorqueBox
from cpbc.constraints.stopping import Braking
from cpbc.resources import scenarios_dir
from cpbc.run import main
from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import run_one

START = "    position: [-0.179, 0.172, -0.497, -2.085, 0.103, 2.233, 0.785]\n"


def _sphere(tmp_path: Path, rate: str | float | None, duration: float,
            velocity: list[float] | None = None) -> Path:
    """panda_cpbc_sphere (URDF torque limits 87/12 N·m, joint and half rate limits, a ball
    and a table) with a torque-rate limit, a duration and a start velocity."""
    text = (scenarios_dir() / "panda_cpbc_sphere.yaml").read_text()
    assert START in text and "  control_period: 0.001\n" in text
    if rate is not None:
        text = text.replace("  control_period: 0.001\n",
                            f"  control_period: 0.001\n  torque_rate_limit: {rate}\n")
    if velocity is not None:
        text = text.replace(START, START + f"    velocity: {velocity}\n")
    path = tmp_path / "rate.yaml"
    path.write_text(text.replace("duration: 5.0", f"duration: {duration}"))
    return path


def _logged_steps(setup, name: str):
    """One controller's run of the scenario's case: its trajectory and summary."""
    entry = next(e for e in setup.controllers if e.name == name)
    return run_one(setup, setup.cases[0], entry, "mujoco")


def _check_steps(traj, setup, rho: np.ndarray) -> float:
    """Every applied joint torque step, the first from the gravity torque at the start,
    against ρh; returns the largest |Δτ|/(ρh)."""
    h = setup.loop_settings.bounds.period
    held = setup.model.gravity(setup.cases[0].position)  # joint coordinates (T = I)
    torques = np.vstack((held, traj.joint_torque))
    assert setup.loop_settings.log_every == 1 and len(traj.joint_torque) == traj.control_steps
    return float(np.max(np.abs(np.diff(torques, axis=0)) / (rho * h)))


@pytest.mark.parametrize(("value", "says"), [
    (-5, "simulation.torque_rate_limit"),
    ("[1000, 1000]", "simulation.torque_rate_limit"),
    ("from_model", "declares no torque-rate limit"),
])
def test_a_bad_rate_limit_is_refused_naming_the_field(tmp_path, capsys, value, says) -> None:
    out = tmp_path / "out"
    assert main([str(_sphere(tmp_path, value, 0.01)), "--out", str(out), "--quiet",
                 "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
    assert not out.exists()


def test_the_plant_limits_an_unguarded_law_and_the_guard_never_asks_beyond_it(tmp_path) -> None:
    """PD + g knows nothing of the limit: its first command jumps from the gravity torque and
    the plant clips it (counted). The guarded CPBC chooses only within ρh of the held torque:
    the plant never clips it, every logged step is within ρh, and nothing is crossed."""
    setup = build(*load_scenario(_sphere(tmp_path, 1000, 0.4)))
    rho = setup.loop_settings.bounds.rate
    assert rho is not None and np.all(rho == 1000.0)
    pd = _logged_steps(setup, "PD+g")
    assert pd.summary.rate_limited_steps > 0
    assert _check_steps(pd.trajectory, setup, rho) <= 1 + 1e-9
    cpbc = _logged_steps(setup, "CPBC")
    assert cpbc.summary.rate_limited_steps == 0
    share = _check_steps(cpbc.trajectory, setup, rho)
    assert 0.99 < share <= 1 + 1e-9  # it ramps at the limit, and no faster
    assert max(cpbc.summary.peak_torque_rate) <= 1000.0 * (1 + 1e-9)
    assert cpbc.summary.torque_rate_limits == [1000.0] * 7
    assert cpbc.summary.status != "constraint_violated"
    assert min(cpbc.summary.min_margins.values()) > 0


def test_the_summary_reports_the_peak_rate_against_its_limit(tmp_path) -> None:
    out = tmp_path / "out"
    assert main([str(_sphere(tmp_path, 1000, 0.05)), "--out", str(out), "--quiet",
                 "--no-plots"]) == 0
    runs = {r["controller"]: r for r in json.loads((out / "summary.json").read_text())}
    assert runs["CPBC"]["torque_rate_limits"] == [1000.0] * 7
    assert len(runs["CPBC"]["peak_torque_rate"]) == 7
    assert runs["CPBC"]["rate_limited_steps"] == 0 < runs["PD+g"]["rate_limited_steps"]
    # without a limit the peak rate is still measured, the limits are null
    assert main([str(_sphere(tmp_path, None, 0.05)), "--out", str(tmp_path / "free"),
                 "--quiet", "--no-plots"]) == 0
    free = json.loads((tmp_path / "free" / "summary.json").read_text())
    assert all(r["torque_rate_limits"] is None and r["rate_limited_steps"] == 0 for r in free)
    assert max(free[0]["peak_torque_rate"]) > 1000.0  # PD + g's first step


@pytest.mark.parametrize(("rho", "moving"), [(1000.0, True), (435.0, False)])
def test_a_start_keeps_every_constraint_under_the_ramp(tmp_path, rho, moving) -> None:
    """The Panda under 1000 N·m/s moving at half its (halved) rate bounds toward the target,
    and under 435 N·m/s — at which the 87 N·m brake takes 200 ms to build — from rest: the
    start is accepted, and the guarded CPBC crosses nothing and never asks beyond the rate.
    The slow motors' run is 0.2 s: from 0.2 s on the guard needs its rescue there, whose
    searches take 24 s of CPU over the next 0.1 s (the guard's deadline, docs/reliability.md;
    a start moving at half the rate bound under 435 N·m/s keeps every constraint too, in 29 s).
    """
    setup0 = build(*load_scenario(_sphere(tmp_path, rho, 0.01)))
    bound = np.array(setup0.rate_bounds, dtype=float)
    toward = np.sign(setup0.target - setup0.cases[0].position)
    velocity = (0.5 * bound * toward).tolist() if moving else None
    setup = build(*load_scenario(_sphere(tmp_path, rho, 0.3 if moving else 0.2, velocity)))
    run = _logged_steps(setup, "CPBC")
    assert run.summary.status != "constraint_violated"
    assert min(run.summary.min_margins.values()) > 0
    assert run.summary.rate_limited_steps == 0
    assert _check_steps(run.trajectory, setup, np.full(7, rho)) <= 1 + 1e-9


def test_the_reachable_box_of_one_step() -> None:
    """TorqueBox.around: within ρh of the held torque and inside the box; a held torque
    beyond a limit reaches the limit's edge only."""
    box = TorqueBox(np.array([10.0, 10.0, 10.0]))
    step = box.around(np.array([0.0, 9.5, 12.0]), np.array([1.0, 1.0, 1.0]))
    lo, hi = step.bounds
    np.testing.assert_array_equal(lo, [-1.0, 8.5, 10.0])
    np.testing.assert_array_equal(hi, [1.0, 10.0, 10.0])
    np.testing.assert_array_equal(step.clip(np.array([5.0, -5.0, 0.0])), [1.0, 8.5, 10.0])
    # toward the bias: a bias inside the box scales the torque toward it, keeping direction
    inside = box.around(np.zeros(3), np.full(3, 2.0))
    scaled = inside.toward(np.zeros(3), np.array([4.0, 2.0, -1.0]))
    np.testing.assert_allclose(scaled, [2.0, 1.0, -0.5])


def test_the_brake_ramp_time_is_the_slowest_joints(joint_model) -> None:
    """Braking.ramp: the time the uniform brake b − θA D ẋ/|ẋ| takes to build from the held
    torque, joint by joint at ρ, the slowest joint setting it."""
    limit = np.array([50.0, 20.0])
    x, dx = np.array([0.2, 0.4]), np.array([1.0, -0.5])
    st = joint_model.state(x, dx)
    bias = st.coriolis_force + st.gravity + st.dissipation
    braking = Braking.of(joint_model, limit, rate=np.array([100.0, 40.0]))
    per_speed = braking.per_speed(st.inertia, bias, dx)
    brake = bias - st.inertia @ dx / (2 * per_speed * np.linalg.norm(dx))
    held = np.array([3.0, -2.0])
    expected = max(abs(brake[0] - held[0]) / 100.0, abs(brake[1] - held[1]) / 40.0)
    assert braking.ramp(st.inertia, bias, dx, held, per_speed) == pytest.approx(expected)
    assert Braking.of(joint_model, limit).ramp(st.inertia, bias, dx, held, per_speed) == 0.0


def test_a_robot_that_adds_gravity_bounds_the_command_not_the_torque(tmp_path) -> None:
    """A Franka adds its own gravity compensation g_r to every command and bounds the
    command τ − g_r by 87/12 N·m. Told what the robot adds (holding(τ_h, added)), the guard
    keeps every command inside that box and within ρh of the last, from commands held at
    the box's edges (random signs) on the campaign's starts near the boundaries; told
    nothing, it bounds τ itself: held torques beyond that box are pulled back into it at
    once (a step over ρh) or commands fall outside the robot's box."""
    from cpbc.reliability.campaign import sample_states

    setup = build(*load_scenario(_sphere(tmp_path, 1000, 0.01)))
    entry = next(e for e in setup.controllers if e.name == "CPBC")
    limit = setup.loop_settings.bounds.torque
    assert limit is not None
    rng = np.random.default_rng(0)
    broken = {True: 0, False: 0}
    for s in sample_states(setup, 40, seed=3):
        added = setup.model.gravity(s.position)  # what the robot adds at this state
        command = (limit - 0.5) * rng.choice((-1.0, 1.0), size=7)  # held near the edges
        for told in (True, False):
            guard = setup.controller(entry)
            guard.holding(command + added, added if told else None)
            sent = guard.torque(s.position, s.velocity) - added
            over_rate = np.any(np.abs(sent - command) > 1.0 + 1e-9)  # ρh = 1 N·m
            outside = np.any(np.abs(sent) > limit * (1 + 1e-9))
            broken[told] += int(over_rate or outside)
    assert broken[True] == 0 < broken[False]


def _kept_from_inside_v(seed: int, horizon: float, campaign: str = "panda_goal_pose_rate",
                        controller: str = "TS-CPBC", on_path: bool = False) -> None:
    """``controller`` of tools/campaigns/``campaign``.yaml from the campaign's state ``seed``
    (``on_path``: the scenario tracks a path, from the seed's phase of it) — a start inside
    V that a rate-limited brake stops — keeps every constraint for ``horizon`` seconds."""
    from cpbc.reliability.verification import in_braking_set, stopping_brake

    folder = Path(__file__).resolve().parents[1] / "tools" / "campaigns"
    setup = build(*load_scenario(folder / f"{campaign}.yaml"))
    assert (setup.reference is not None) == on_path
    run = campaign_run(setup, seed, horizon, controller, on_path)
    assert in_braking_set(setup, run.kept, run.position, run.velocity, 0.001)
    assert stopping_brake(setup, run.kept, run.position, run.velocity, 0.001) is not None
    assert not run.check.violated, (run.check.constraint, run.check.min_margin)
    assert run.check.trajectory.end_time == pytest.approx(horizon)


def test_a_joint_riding_its_rate_bound_is_slowed_by_the_brake_along_the_line() -> None:
    """panda_goal_pose under a 1000 N·m/s rate limit, seed 100 (a stoppable start inside V):
    joint 4 rides its rate bound for 140 ms while the uniform brake, fitted into the ±1 N·m
    box by its nearest acceleration, fails (S1) by far; when the law's torque failed too,
    the step fell to the fallback, which took joint 4 through its bound by 5.6 mrad/s at
    148 ms. The brake reached along the line from the held torque slows it, and the run
    keeps every constraint."""
    _kept_from_inside_v(100, 0.2)


@pytest.mark.parametrize("seed, horizon", [(58, 0.24), (89, 0.47)])
def test_the_brake_path_that_turns_keeps_a_clearance_the_arm_skims(seed, horizon) -> None:
    """panda_figure8_ke under a 1000 N·m/s rate limit, the first law, seeds 58 and 89
    (stoppable starts inside V): the law drives the hand and link 6 along the table 0.3–4 mm
    above it, accelerating at 200–300 rad/s² (100–130 across the motion) while the brake
    would take ≈ 90 ms to build. (S2) tested only the end of a straight path 1.2–1.8 rad
    long, 3–5 cm above the table, while the path the arm takes — on along the motion and
    turning with the held acceleration as the torque ramps — went under it: the arm crossed
    the clearance by 2.1 mm at 226 ms (seed 58) and 0.7 mm at 462 ms (seed 89). With the
    path's margins held where it turns (kernels.braking_path.configuration_rows) the runs
    keep every constraint."""
    _kept_from_inside_v(seed, horizon, "panda_figure8_ke_rate", "TS-CPBC-KE-x1", on_path=True)


def test_eight_points_of_the_brake_path_keep_a_clearance_four_let_through() -> None:
    """panda_figure8_ke under a 1000 N·m/s rate limit, the first law, seed 19 (a stoppable
    start inside V): the guard rescues the arm off the table and lets the law on again, over
    and over, the hand 0.5–2 mm above the table. With (S2) holding the clearance at 4 points
    of the uniform brake's turning path, from 453 ms the law's torque passed while the
    clearance between those points dipped under its floor; from 470 ms no torque kept (S1),
    no rescue brake stopped the arm, and the hand crossed the table by 0.79 mm at 500 ms
    (after 811dfc8's round-off; before it the same run kept 0.5 mm). 8 points of the path
    (predicted_margins.SEGMENT_POINTS) keep 0.58 mm; 16 keep the same."""
    _kept_from_inside_v(19, 0.5, "panda_figure8_ke_rate", "TS-CPBC-KE-x1", on_path=True)


def test_a_refused_step_takes_back_the_held_acceleration_before_it_spins_a_riding_joint_up(
) -> None:
    """panda_goal_pose under a 1000 N·m/s rate limit, seed 35 (a stoppable start inside V on
    two boundaries: joint 6 at its lower position limit, joint 2 at its rate bound): the law
    pushes joint 6 off its limit at up to 74 rad/s² while joint 2 slows at 1 rad/s². At the
    seventh step no torque in the ±1 N·m box keeps (S1) — joint 6's rate margin shrinks
    faster than κ allows — and the fallback's brake, reached by its nearest acceleration,
    took joint 2 to +4.3 rad/s² and through its bound by 5.4 mrad/s at 8 ms. Reached along
    the line from the held torque, or as the held acceleration taken back, the fallback
    keeps (S0), and the run keeps every constraint (Brakes.fallback)."""
    _kept_from_inside_v(35, 0.1)


def test_a_start_whose_gravity_exceeds_a_motor_s_limit_is_held_at_the_limit() -> None:
    """Baxter's left arm (tools/campaigns/baxter_cpbc_rate.yaml: 50 N·m at the shoulder,
    500 N·m/s) from seed 52 of its campaign, where gravity pulls the shoulder 4 % past its
    motor's limit. The motors hold at most their limit at the start: no command of the
    guarded run is clipped by the plant and no applied torque leaves the box. (Held at the
    gravity torque itself, the plant clipped 8 of the guard's commands, each within the
    box, and applied up to 1.49 N·m beyond the limit over 3 steps.) A guard told nothing
    starts from the same held torque: its first torque lies within ρh of gravity clipped
    into the box."""
    from dataclasses import replace

    from cpbc.controllers.safeguard import Safeguard
    from cpbc.reliability.campaign import RecordingPlant, checked_run, kept_constraints
    from cpbc.reliability.verification import draw_state

    path = Path(__file__).resolve().parents[1] / "tools/campaigns/baxter_cpbc_rate.yaml"
    setup = build(*load_scenario(path))
    entry = setup.controllers[0]
    limit = np.asarray(setup.loop_settings.bounds.torque)
    s = draw_state(setup, 52)
    gravity = setup.model.gravity(s.position)
    assert np.max(np.abs(gravity) / limit) > 1.03
    settings = replace(setup.loop_settings, duration=0.1, log_every=1)
    period = settings.bounds.period
    kept = kept_constraints(setup, entry, period, setup.safeguard)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    traj = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                       safeguard=setup.safeguard).trajectory
    assert traj.rate_limited_steps == 0
    assert np.all(np.abs(traj.joint_torque) <= limit * (1 + 1e-12))
    guard = setup.controller(entry)
    assert isinstance(guard, Safeguard) and guard.box.rate_limited
    first = guard.torque(s.position, s.velocity)
    held = np.clip(gravity, -limit, limit)
    step = np.asarray(setup.loop_settings.bounds.step)
    assert np.all(np.abs(first - held) <= step * (1 + 1e-9))
    assert np.all(np.abs(first) <= limit)
