"""The benchmark's command line: the JSON the issue specifies, with every controller timed."""

from __future__ import annotations

import json

from cpbc.bench import main


def test_bench_json_has_every_controller(capsys) -> None:
    assert main(["--json", "--repeats", "1", "--loop-seconds", "0.02"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["robot"] == "planar_2link"
    types = {"pd", "pd_gravity", "cpbc", "cpbc_ke", "recentred", "bpbc", "bpbc_ke"}
    assert set(out["torque_us"]) == types
    assert set(out["closed_loop_steps_per_second"]) == types
    assert set(out["closed_loop_bare_law_steps_per_second"]) == types - {"pd", "pd_gravity"}
    assert all(v > 0 for v in out["torque_us"].values())
    assert out["cpbc_over_pd_gravity"] > 0
    assert out["governor_us"] > 0  # timed there, never asserted against a wall clock


def test_bench_peers_times_guarded_law_and_cbf_qp_on_the_same_states(capsys) -> None:
    assert main(["--json", "--peers", "--repeats", "1", "--loop-seconds", "0.02"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"cpbc", "cpbc_guarded", "cbf_qp"} <= set(out["torque_us"])
    assert all(out["torque_us"][k] > 0 for k in ("cpbc_guarded", "cbf_qp"))
    # the guarded step against its bare law, timed in the same blocks (its own entry: the
    # table's cpbc is the one timed beside PD + g)
    beside = out["guarded_over_bare"]
    assert "cpbc_bare" not in out["torque_us"]
    assert beside["ratio_min"] <= beside["ratio"] <= beside["ratio_max"]
    assert beside["guarded_us"] > beside["bare_us"] > 0  # the guard runs the law, and more


def test_bench_refuses_a_tail_repeated_fewer_than_once(capsys, tmp_path) -> None:
    """--tail-repeats 0 is refused before anything is timed or written: exit 2, the flag
    named."""
    out = tmp_path / "speed.md"
    assert main(["--robot", "panda", "--peers", "--tail-repeats", "0", "--markdown",
                 str(out)]) == 2
    assert "--tail-repeats 0" in capsys.readouterr().err and not out.exists()


def test_bench_check_fails_when_the_kernels_are_not_compiled() -> None:
    """--check fails when a kernel is not compiled in nopython mode: here none is (the
    kernels run as plain Python under NUMBA_DISABLE_JIT=1), however fast CPBC may be."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    done = subprocess.run(
        [sys.executable, "-m", "cpbc.bench", "--check", "--repeats", "1", "--loop-seconds",
         "0.01"], cwd=Path(__file__).resolve().parents[1], env=env, capture_output=True,
        text=True, timeout=600)
    assert done.returncode == 1
    assert "kernel: no compiled kernels" in done.stderr


def test_the_benchs_safeguard_is_set_for_its_plant_as_a_scenario_sets_it() -> None:
    """The Panda's bench plant steps implicitfast at 1 ms, as panda_cpbc_sphere does: its
    guard predicts that plant's step and holds no hold correction, as cpbc.scenario.build
    sets it for the scenario (it assumed a continuous-time plant before, and paid a model
    pass a step for the correction); the planar arm's RK4 plant is continuous time."""
    from cpbc.bench import ROBOTS
    from cpbc.scenario import build, load_scenario

    panda, planar = ROBOTS["panda"](), ROBOTS["planar_2link"]()
    scenario = build(*load_scenario("panda_cpbc_sphere"))
    assert scenario.safeguard is not None
    assert panda.safeguard().plant_step == scenario.safeguard.plant_step == 0.001
    assert planar.safeguard().plant_step is None


def test_the_tails_are_the_robot_s_step_first_then_without_its_rate_limit_then_unbounded(
        capsys) -> None:
    """``guarded_tail_us`` — the key the deadline's targets are read on — is the guard as
    cpbc.hardware bounds it on a Franka: the robot's budgets and libfranka's 1000 N·m/s;
    beside it the same bounds without the rate limit and simulation's guard, unbounded.
    Each prints, the targets beside the first alone."""
    from cpbc.bench import _print_tail
    from cpbc.bench_tail import TAILS, bench_tails
    from cpbc.hardware.robot_run import ROBOT_TEST_BUDGET, ROBOT_TIME_SHARE

    tails = bench_tails(200, 1)
    assert list(tails) == [key for key, _ in TAILS]
    robot, no_rate, unbounded = (tails[key] for key, _ in TAILS)
    assert robot["rate_limit"] == 1000.0 and no_rate["rate_limit"] is None
    for bounded in (robot, no_rate):
        assert bounded["time_budget_us"] == 1e6 * ROBOT_TIME_SHARE * 1e-3
        assert bounded["test_budget"] == ROBOT_TEST_BUDGET
    assert unbounded["time_budget_us"] is None and unbounded["rate_limit"] is None
    for key, how in TAILS:
        _print_tail(tails[key], how, key == TAILS[0][0])
    lines = capsys.readouterr().out.splitlines()
    steps = [line for line in lines if line.startswith("guarded step")]
    assert len(steps) == 3 and "1000 N·m/s" in steps[0]
    assert ["target ≤ 5" in line for line in steps] == [True, False, False]
