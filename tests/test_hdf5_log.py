"""trajectories.h5: one standard HDF5 file per run folder that h5py reads without cpbc, the
lines docs/getting-started.md gives for it, and run folders of earlier versions
(trajectory.npz) that still replay."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

from cpbc.results import LOG_FILE, load_log
from cpbc.results.delta_planes import CODED, encode
from cpbc.results.saved_run import load_run
from cpbc.run import main

PAGE = Path(__file__).resolve().parents[1] / "docs" / "getting-started.md"
SIGNALS = ("time", "position", "velocity", "torque", "joint_torque", "margins", "lyapunov")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A 20 ms CPBC run of the planar arm with limits, written where the docs read it
    (runs/thesis_ch6 under the folder returned)."""
    root = tmp_path_factory.mktemp("h5")
    scenario = root / "tiny.yaml"
    scenario.write_text(yaml.safe_dump({
        "name": "tiny", "simulation": {"duration": 0.02}, "target": [0.5, 0.5],
        "cases": [{"name": "rest", "position": [0, 0]}],
        "constraints": [
            {"type": "joint_rate_limit", "name": "r", "bounds": [0.3, 0.2]},
            {"type": "joint_position_limit", "name": "p", "lower": [-3, -3], "upper": [3, 3]}],
        "controllers": [{"type": "cpbc", "name": "CPBC", "kp": 1, "kd": 1},
                        {"type": "pd", "name": "PD", "kp": 1, "kd": 1}],
    }, sort_keys=False))
    assert main([str(scenario), "--out", str(root / "runs" / "thesis_ch6"), "--quiet",
                 "--no-plots", "--workers", "1"]) == 0
    return root


def test_one_file_a_group_per_run_with_units_names_and_summary(run: Path) -> None:
    folder = run / "runs" / "thesis_ch6"
    assert not list(folder.rglob("*.npz"))
    summaries = json.loads((folder / "summary.json").read_text())
    with h5py.File(folder / LOG_FILE, "r") as f:
        assert f.attrs["format"] == "cpbc-trajectories/1" and f.attrs["scenario"] == "tiny"
        assert list(f) == ["rest"] and list(f["rest"]) == ["CPBC", "PD"]
        g = f["rest/CPBC"]
        assert set(SIGNALS) <= set(g)
        assert g["time"].dtype == np.float64 and g["time"].attrs["units"] == "s"
        for name in SIGNALS[1:]:
            assert g[name].dtype == np.float32, name
            assert g[name].compression == "gzip" and g[name].shuffle, name
        assert list(g["velocity"].attrs["units"]) == ["rad/s", "rad/s"]
        assert list(g["joint_torque"].attrs["units"]) == ["N m", "N m"]
        margins = g["margins"].attrs
        assert len(margins["names"]) == g["margins"].shape[1] == len(margins["types"])
        assert {str(t): str(u) for t, u in zip(margins["types"], margins["units"],
                                               strict=True)} == {"rate": "rad/s",
                                                                 "position": "rad"}
        assert json.loads(g.attrs["summary"]) == summaries[0]
        assert g.attrs["status"] == summaries[0]["status"] and g.attrs["outcome"] == "completed"
    log = load_log(folder / LOG_FILE, "rest", "PD")
    assert list(log["coordinate_names"]) == list(log["position_names"])
    assert log["velocity"].shape == (len(log["time"]), 2)


def test_the_docs_lines_read_a_run_with_h5py_alone(run: Path, monkeypatch) -> None:
    block = re.search(r"```python\n(import h5py\n.*?)```", PAGE.read_text(), re.S)
    assert block, "docs/getting-started.md lacks the h5py lines for trajectories.h5"
    assert len(block.group(1).strip().splitlines()) == 3
    monkeypatch.chdir(run)
    scope: dict[str, object] = {}
    exec(block.group(1), scope)  # the page's own lines, on the run written here
    expected = load_log(run / "runs" / "thesis_ch6" / LOG_FILE, "rest", "CPBC")
    np.testing.assert_array_equal(scope["velocity"], expected["velocity"])
    assert scope["names"] == list(expected["coordinate_names"])


def _as_earlier_version(folder: Path) -> None:
    """Rewrite a run folder as cpbc wrote it before trajectories.h5: a trajectory.npz of
    coded float members per run."""
    for s in json.loads((folder / "summary.json").read_text()):
        log = load_log(folder / LOG_FILE, s["case"], s["controller"])
        members = {("margin_names", "margin_types", "coordinate_names")[i]:
                   np.array(list(log[k]), dtype=str)
                   for i, k in enumerate(("margin_names", "margin_types", "coordinate_names"))}
        members |= {k + CODED: encode(log[k]) for k in (*SIGNALS, "target")}
        members["outcome"] = np.array(log["outcome"])
        (folder / s["case"] / s["controller"]).mkdir(parents=True)
        np.savez_compressed(folder / s["case"] / s["controller"] / "trajectory.npz", **members)
    (folder / LOG_FILE).unlink()


def test_a_folder_of_an_earlier_version_replays_the_same(run: Path, tmp_path: Path) -> None:
    old = tmp_path / "old"
    shutil.copytree(run / "runs" / "thesis_ch6", old)
    _as_earlier_version(old)
    new, earlier = load_run(run / "runs" / "thesis_ch6"), load_run(old)
    for a, b in zip(new.case("rest").runs, earlier.case("rest").runs, strict=True):
        assert (a.controller, a.margin_names, a.margin_types, a.outcome) == (
            b.controller, b.margin_names, b.margin_types, b.outcome)
        np.testing.assert_array_equal(a.margins, b.margins)
        np.testing.assert_array_equal(a.time, b.time)
