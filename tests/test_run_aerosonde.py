"""The shipped ch5_aerosonde.yaml through the command line, cut short here (not in the file):
the summary reports climb rate, angle of attack and elevator against their bounds, the
figures and the replay are written, and the MuJoCo backend is refused (an ODE plant)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from cpbc.resources import scenarios_dir
from cpbc.results import LOG_FILE, load_log
from cpbc.run import main


def shipped(folder: Path, duration: float, cases: list[str], **simulation: object) -> Path:
    data = yaml.safe_load((scenarios_dir() / "ch5_aerosonde.yaml").read_text())
    data["simulation"].update(duration=duration, **simulation)
    data["cases"] = [c for c in data["cases"] if c["name"] in cases]
    path = folder / "ch5.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def fig55(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """Fig. 5.5's +100 m command, 30 s (20 s of climb), both laws."""
    folder = tmp_path_factory.mktemp("ch5")
    path = shipped(folder, 30.0, ["fig5.5"], timestep=0.1, control_period=0.1)
    assert main([str(path), "--out", str(folder / "out"), "--quiet"]) == 0
    rows = json.loads((folder / "out" / "summary.json").read_text())
    return folder / "out", {r["controller"]: r for r in rows}


def test_summary_reports_the_three_bounds(fig55) -> None:
    _, rows = fig55
    for row in rows.values():
        assert row["system"]["bounds"] == {"vz": 3.5, "alpha": 0.3, "elevator": 1.0}
        assert row["backend"] == "reference"
    barrier, plain = rows["constrained"], rows["traditional"]
    # the barrier law climbs at its plateau, well inside |v_z| < 3.5 and below the stall
    peaks, plain_peaks = barrier["system"]["peaks"], plain["system"]["peaks"]
    assert 1.5 < peaks["vz"] < 1.65 and peaks["alpha"] < 0.2
    # the traditional law overshoots the climb-rate bound and nearly stalls
    assert plain_peaks["vz"] > 6.5 and 0.29 < plain_peaks["alpha"] < 0.3
    # both demand more elevator than the actuator has at the step: the aircraft's limit,
    # reported, not a violation of the problem's constraint (the climb rate)
    assert plain["system"]["limits_reached"] == barrier["system"]["limits_reached"] == ["elevator"]
    assert plain["violated_constraint"] == "vz" and barrier["violated_constraint"] is None
    assert plain["status"] == "constraint_violated"
    assert barrier["status"] in ("converged", "not_settled")
    assert barrier["system"]["design_bounds"] == {
        "(5.68) k2 + c1 on |v_z|, law 'constrained' [m/s]": 3.5}


def test_figures_path_and_replay_are_written(fig55) -> None:
    out, _ = fig55
    assert (out / "fig5.5" / "timeseries.png").stat().st_size > 10_000
    assert (out / "fig5.5" / "path.png").stat().st_size > 10_000
    assert load_log(out / LOG_FILE, "fig5.5", "constrained")["state"].shape[1] == 7
    assert (out / "view.html").stat().st_size > 10_000


def test_the_mujoco_backend_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = shipped(tmp_path, 11.0, ["fig5.5"])
    out = tmp_path / "out"
    assert main([str(path), "--out", str(out), "--quiet", "--backend", "mujoco"]) == 2
    err = capsys.readouterr().err
    assert "--backend" in err and "only replays the path" in err and not out.exists()
    data = yaml.safe_load(path.read_text())
    data["simulation"]["backend"] = "mujoco"
    path.write_text(yaml.safe_dump(data))
    assert main([str(path), "--out", str(out), "--quiet"]) == 2
    assert "simulation.backend" in capsys.readouterr().err and not out.exists()


def test_an_inadmissible_command_ends_the_run_naming_it(tmp_path: Path) -> None:
    """A case the shipped file does not have: climbing under +400 m, the command turns to
    −100 m at 20 s while v_z ≈ 1.57 m/s: z2 = 1.57 + 1.5 tanh(≈ +115) ≈ 3.07 ≥ k2 = 2, so the
    constrained law refuses it (Theorem 5.5's unstated check); the traditional law flies on."""
    data = yaml.safe_load((scenarios_dir() / "ch5_aerosonde.yaml").read_text())
    data["simulation"].update(duration=25.0, timestep=0.1, control_period=0.1)
    data["cases"] = [{"name": "reversal", "state": [100, 0],
                      "commands": [{"time": 5, "altitude": 500}, {"time": 20, "altitude": 0}]}]
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main([str(path), "--out", str(tmp_path / "out"), "--quiet", "--no-plots"]) == 0
    rows = {r["controller"]: r for r in
            json.loads((tmp_path / "out" / "summary.json").read_text())}
    refused = rows["constrained"]
    assert refused["status"] == "constraint_violated" and refused["violated_constraint"] == "h_d"
    assert refused["end_time"] == pytest.approx(20.0, abs=0.11)  # the last sample before
    assert rows["traditional"]["end_time"] == pytest.approx(25.0)


def test_the_page_names_each_coordinates_unit(fig55) -> None:
    """The aircraft's replay coordinates mix slide joints (range, altitude: m) and a hinge
    (pitch: rad); the page labelled all three in rad."""
    out, _ = fig55
    page = (out / "view.html").read_text()
    assert '"label":"h [m]"' in page and '"label":"pitch [rad]"' in page
    assert '"label":"h [rad]"' not in page
