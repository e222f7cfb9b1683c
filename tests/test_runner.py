"""Running a scenario serially and in worker processes gives the same results."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from cpbc.resources import scenarios_dir
from cpbc.results import write_summaries, write_trajectory
from cpbc.scenario import build, load_scenario
from cpbc.scenario.build import ScenarioSetup
from cpbc.scenario.runner import default_workers, run_all, worker_pool
from cpbc.viewer.outputs import write_run_outputs


def _short_ch7(tmp_path: Path) -> ScenarioSetup:
    raw = yaml.safe_load((scenarios_dir() / "thesis_ch7.yaml").read_text())
    raw["simulation"]["duration"] = 0.5
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(raw))
    scenario, file = load_scenario(path)
    return build(scenario, file)


def test_parallel_runs_equal_serial_runs(tmp_path: Path) -> None:
    setup = _short_ch7(tmp_path)
    serial = run_all(setup, workers=1)
    parallel = run_all(setup, workers=2)
    assert [(r.case, r.controller) for r in serial] == [(r.case, r.controller) for r in parallel]
    assert [(r.case, r.controller) for r in serial] == [
        ("rest", "PD"), ("rest", "BPBC"), ("moving", "PD"), ("moving", "BPBC")
    ]
    for a, b in zip(serial, parallel, strict=True):
        np.testing.assert_array_equal(a.trajectory.position, b.trajectory.position)
        assert a.summary.status == b.summary.status
        assert a.summary.min_margins == b.summary.min_margins


def test_shared_runs_equal_serial_runs_whether_or_not_workers_help(
    tmp_path: Path, monkeypatch
) -> None:
    """run_shared keeps short scenarios in this process and shares long ones; either way
    the results are the serial ones, in case-major order."""
    from cpbc.scenario import runner

    setup = _short_ch7(tmp_path)
    serial = run_all(setup, workers=1)
    with runner.LazyPool(1) as lazy:
        kept = runner.run_shared(setup, lazy.get, 1)  # 0.5 s runs: not worth sharing
    assert lazy.started is None  # so no worker process was even started
    with worker_pool(1) as pool:
        runner.run_shared(setup, lambda: pool, 1)
        # the worker has never built the setup, so it ran no pair
        assert pool.submit(runner.setups_built).result() == 0
        monkeypatch.setattr(runner, "OFFLOAD_AFTER", 0.0)  # every run looks long: share
        shared = runner.run_shared(setup, lambda: pool, 1)
        assert pool.submit(runner.setups_built).result() == 1
    for results in (kept, shared):
        assert [(r.case, r.controller) for r in results] == [
            (r.case, r.controller) for r in serial]
        for a, b in zip(serial, results, strict=True):
            np.testing.assert_array_equal(a.trajectory.position, b.trajectory.position)
            assert a.summary.min_margins == b.summary.min_margins


def test_default_workers_never_exceeds_runs_or_cores() -> None:
    assert default_workers(1) == 1
    assert 1 <= default_workers(100) <= 100


def test_a_shared_pool_runs_and_then_draws_the_figures(tmp_path: Path) -> None:
    setup = _short_ch7(tmp_path)
    serial = run_all(setup, workers=1)
    folders = {}
    with worker_pool(2) as pool:
        pooled = run_all(setup, pool=pool)
        for label, use in (("pool", pool), ("serial", None)):
            folder = folders[label] = tmp_path / label
            for r in pooled:
                (folder / r.case / r.controller).mkdir(parents=True)
                write_trajectory(folder / r.case / r.controller / "trajectory.npz",
                                 r.trajectory, r.margins, setup.monitor.names, r.lyapunov,
                                 setup.target, setup.coordinate_names)
            write_summaries(folder, [r.summary for r in pooled])
            write_run_outputs(folder, setup, pool=use)
    for a, b in zip(serial, pooled, strict=True):
        np.testing.assert_array_equal(a.trajectory.position, b.trajectory.position)
    drawn = {label: sorted(p.relative_to(f) for p in f.rglob("*.png"))
             for label, f in folders.items()}
    assert drawn["pool"] == drawn["serial"]
    assert {p.name for p in drawn["pool"]} >= {"rates.png", "torques.png", "path.png"}
    assert {p.parts[0] for p in drawn["pool"]} == {"rest", "moving"}
