"""Running a scenario serially and in worker processes gives the same results."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from cpbc.resources import scenarios_dir
from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import default_workers, run_all


def test_parallel_runs_equal_serial_runs(tmp_path: Path) -> None:
    raw = yaml.safe_load((scenarios_dir() / "thesis_ch7.yaml").read_text())
    raw["simulation"]["duration"] = 0.5
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(raw))
    scenario, file = load_scenario(path)
    setup = build(scenario, file)
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


def test_default_workers_never_exceeds_runs_or_cores() -> None:
    assert default_workers(1) == 1
    assert 1 <= default_workers(100) <= 100
