"""Running a scenario serially and in worker processes gives the same results."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from cpbc.resources import scenarios_dir
from cpbc.results import write_summaries
from cpbc.robot import describe, scenario_for
from cpbc.run import write_logs
from cpbc.scenario import Scenario, build, load_scenario
from cpbc.scenario.build import ScenarioSetup
from cpbc.scenario.load import load_any
from cpbc.scenario.runner import (
    default_workers,
    run_all,
    scenario_in_worker,
    worker_payload,
    worker_pool,
)
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
            folder.mkdir()
            write_logs(folder, setup, pooled)
            write_summaries(folder, [r.summary for r in pooled])
            write_run_outputs(folder, setup, pool=use)
    for a, b in zip(serial, pooled, strict=True):
        np.testing.assert_array_equal(a.trajectory.position, b.trajectory.position)
    drawn = {label: sorted(p.relative_to(f) for p in f.rglob("*.png"))
             for label, f in folders.items()}
    assert drawn["pool"] == drawn["serial"]
    assert {p.name for p in drawn["pool"]} >= {"rates.png", "torques.png", "path.png"}
    assert {p.parts[0] for p in drawn["pool"]} == {"rest", "moving"}


def _plain(value: object) -> object:
    """A setting as nested plain values, so that two settings compare with ==."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                if f.compare}
    if isinstance(value, np.ndarray):
        return ("array", value.shape, value.tolist())
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _settings(setup: ScenarioSetup) -> dict[str, object]:
    """What a run's physics depends on besides the law's own parameters."""
    return {
        "loop": _plain(setup.loop_settings), "plant": _plain(setup.plant_settings),
        "safeguard": _plain(setup.safeguard), "monitor": setup.monitor.names,
        "also_keep": [c.names for c in setup.also_keep],
        "criteria": _plain(setup.criteria), "rate_bounds": setup.rate_bounds,
        "target": setup.target.tolist(), "coordinates": setup.coordinate_names,
        "cases": [(c.name, c.position.tolist(), c.velocity.tolist()) for c in setup.cases],
        "controllers": [(e.name, e.controller.type_name, e.controller.constraints.names)
                        for e in setup.controllers],
    }


def _skeleton(name: str, folder: Path, duration: float, start: list[float] | None = None
              ) -> Path:
    """``python -m cpbc.robot NAME`` as printed (it leaves ``simulation.torque_limit`` out),
    from ``start`` if given."""
    data = scenario_for(describe(name), duration)
    assert "torque_limit" not in data["simulation"]
    if start is not None:
        data["cases"][0]["position"] = start
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _arm_scenarios() -> list[Path]:
    return sorted(p for p in scenarios_dir().glob("*.yaml")
                  if isinstance(load_any(p)[0], Scenario))


@pytest.mark.parametrize("source", [*(p.stem for p in _arm_scenarios()), "talos_arm", "ur10"])
def test_a_worker_rebuilds_every_setting_of_the_scenario(source: str, tmp_path: Path) -> None:
    """Every shipped arm scenario, and two skeletons that leave the torque limits to the
    model's effort limits, built here and as a worker rebuilds it: the same settings (the
    torque limits vanished in workers when the default hung on "was the key given?")."""
    path = (scenarios_dir() / f"{source}.yaml" if (scenarios_dir() / f"{source}.yaml").exists()
            else _skeleton(source, tmp_path, 1.0))
    scenario, file = load_scenario(path)
    rebuilt = scenario_in_worker(worker_payload(scenario))
    assert rebuilt == scenario
    here, there = build(scenario, file), build(rebuilt, file)
    assert _settings(there) == _settings(here)
    if source in ("talos_arm", "ur10"):
        np.testing.assert_array_equal(there.loop_settings.bounds.torque, there.arm.effort_limit)


def _timing_free(summary: dict[str, object]) -> dict[str, object]:
    return {k: v for k, v in summary.items() if k not in (
        "wall_time", "steps_per_second", "controller_time_max_us", "controller_time_mean_us")}


def test_in_process_and_worker_summaries_are_identical_with_the_motors_limits(
        tmp_path: Path) -> None:
    """The TALOS arm's skeleton from a tenth of each range, where PD + gravity asks for up to
    3.9 times what its motors give: run in this process and in worker processes, the
    summaries agree to the bit (but for the wall-clock fields) and the applied torque stays
    within the URDF's effort limits."""
    limits = describe("talos_arm").limits
    far = np.round(limits.lower + 0.1 * (limits.upper - limits.lower), 4).tolist()
    setup = build(*load_scenario(_skeleton("talos_arm", tmp_path, 0.3, far)))
    limit = setup.arm.effort_limit
    here = run_all(setup, workers=1)
    there = run_all(setup, workers=2)
    assert any(max(np.abs(r.summary.peak_commanded_torques) / limit) > 1 for r in here)
    for a, b in zip(here, there, strict=True):
        assert _timing_free(b.summary.as_dict()) == _timing_free(a.summary.as_dict())
        assert np.all(np.abs(b.summary.peak_torques) <= limit * (1 + 1e-12))
        assert b.summary.torque_limits == limit.tolist()
