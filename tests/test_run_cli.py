"""The command line: ``python -m cpbc.run SCENARIO``. A good scenario writes summary.json,
summary.csv and trajectories.h5 (a group per case and controller); bad input exits with code
2, a message naming the field and no traceback, and leaves nothing behind."""

from __future__ import annotations

import csv
import dataclasses
import json
import re
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

from cpbc.resources import scenarios_dir
from cpbc.results import LOG_FILE, load_log, write_summaries
from cpbc.run import main
from cpbc.scenario import build
from cpbc.scenario.load import load_scenario
from cpbc.scenario.runner import run_all
from tools.reliability.bad_input import BASE

SUMMARY_KEYS = {
    "controller", "case", "status", "final_error", "settle_time", "peak_joint_rates",
    "peak_torques", "min_margins", "steps_per_second",
}


def short_ch7(folder: Path, duration: float = 1.0) -> Path:
    """thesis_ch7 cut to ``duration`` seconds, written into ``folder``."""
    data = yaml.safe_load((scenarios_dir() / "thesis_ch7.yaml").read_text())
    data["simulation"]["duration"] = duration
    path = folder / "ch7_short.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def tiny(folder: Path, **changes: object) -> Path:
    """A 10 ms PD-only scenario on the planar arm, with top-level keys replaced."""
    data: dict = {
        "name": "tiny",
        "simulation": {"duration": 0.01},
        "target": [0.5, 0.5],
        "cases": [{"name": "rest", "position": [0, 0]}],
        "controllers": [{"type": "pd", "name": "PD", "kp": 1, "kd": 1}],
    }
    data.update(changes)
    path = folder / "tiny.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def ch7_run(tmp_path_factory) -> tuple[int, Path, dict]:
    """One 1 s run of thesis_ch7 shared by the tests of its outputs."""
    folder = tmp_path_factory.mktemp("ch7")
    out = folder / "out"
    code = main([str(short_ch7(folder)), "--out", str(out), "--quiet"])
    setup_data = yaml.safe_load((folder / "ch7_short.yaml").read_text())
    return code, out, setup_data


def test_good_scenario_exits_zero_and_writes_results(ch7_run):
    code, out, data = ch7_run
    assert code == 0
    assert (out / "summary.json").is_file()
    assert (out / "summary.csv").is_file()
    cases = [c["name"] for c in data["cases"]]
    controllers = [c["name"] for c in data["controllers"]]
    with h5py.File(out / LOG_FILE, "r") as log:  # one group per case, one per run in it
        assert list(log) == cases
        assert all(list(log[case]) == controllers for case in cases)
    assert not list(out.rglob("*.npz"))
    # nothing else was left next to the output (the scratch folder was moved into place)
    assert sorted(p.name for p in out.parent.iterdir()) == ["ch7_short.yaml", "out"]


def test_summary_json_lists_every_run(ch7_run):
    _, out, data = ch7_run
    runs = json.loads((out / "summary.json").read_text())
    assert isinstance(runs, list)
    pairs = {(r["case"], r["controller"]) for r in runs}
    expected = {(c["name"], k["name"]) for c in data["cases"] for k in data["controllers"]}
    assert pairs == expected
    assert len(runs) == len(expected)
    for r in runs:
        assert SUMMARY_KEYS <= set(r), SUMMARY_KEYS - set(r)
        assert r["status"] in ("converged", "stalled", "not_settled", "constraint_violated",
                               "diverged")
        assert len(r["peak_joint_rates"]) == len(r["peak_torques"]) == 2
        assert set(r["min_margins"]) == {"rate[theta1]", "rate[theta2]"}
        assert r["steps_per_second"] > 0


def test_summary_csv_has_one_row_per_run(ch7_run):
    _, out, _ = ch7_run
    with (out / "summary.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    runs = json.loads((out / "summary.json").read_text())
    assert [(r["case"], r["controller"]) for r in rows] == [
        (r["case"], r["controller"]) for r in runs
    ]
    for row, run in zip(rows, runs, strict=True):
        assert float(row["final_error"]) == pytest.approx(run["final_error"], rel=1e-12)
        peaks = [float(v) for v in row["peak_joint_rates"].split()]
        np.testing.assert_allclose(peaks, run["peak_joint_rates"], rtol=1e-5)


def single(x: object) -> np.ndarray:
    """A summary number as the trajectory file stores it (single precision)."""
    return np.asarray(x, dtype=np.float32)


def test_summary_agrees_with_the_trajectories(ch7_run):
    """The summary is computed in double precision before the file is written in single:
    its peaks, rounded to single precision, are exactly the file's."""
    _, out, data = ch7_run
    target = np.array([np.pi, np.pi])
    bounds = np.array(data["constraints"][0]["bounds"], dtype=float)
    coordinates = np.array([[1.0, 0.0], [1.0, 1.0]])  # absolute link angles θ = T q
    for r in json.loads((out / "summary.json").read_text()):
        npz = load_log(out / LOG_FILE, r["case"], r["controller"])
        vel, pos, tau = npz["velocity"], npz["position"], npz["torque"]
        applied_q = npz["joint_torque"]
        margins, names = npz["margins"], list(npz["margin_names"])
        types = list(npz["margin_types"])
        np.testing.assert_allclose(npz["target"], target, rtol=1e-15)
        assert list(npz["coordinate_names"]) == ["theta1", "theta2"]
        time = npz["time"]
        assert vel.dtype == np.float32 and time.dtype == np.float64
        assert time[0] == 0.0 and time[-1] == pytest.approx(1.0)
        np.testing.assert_array_equal(single(r["peak_joint_rates"]), np.abs(vel).max(axis=0))
        np.testing.assert_array_equal(single(r["peak_commanded_torques"]),
                                      np.abs(tau).max(axis=0))
        # applied joint torques τ_q = Tᵀ τ (no limit here), back in θ: equal to the asked ones
        np.testing.assert_array_equal(single(r["peak_joint_torques"]),
                                      np.abs(applied_q).max(axis=0))
        np.testing.assert_allclose(r["peak_torques"], r["peak_commanded_torques"], rtol=1e-12)
        np.testing.assert_allclose(applied_q, tau @ coordinates, rtol=1e-6, atol=1e-6)
        assert r["torque_limits"] is None
        assert r["final_error"] == pytest.approx(np.abs(pos[-1] - target).max(), rel=1e-6)
        # the logged margins are the rate headroom B − |θ̇| (rad/s), not ½(B² − θ̇²)
        assert names == ["rate[theta1]", "rate[theta2]"]
        assert types == ["rate", "rate"]
        assert r["margin_types"] == dict.fromkeys(names, "rate")
        np.testing.assert_allclose(margins, bounds - np.abs(vel), rtol=1e-6, atol=1e-6)
        for k, name in enumerate(names):
            assert single(r["min_margins"][name]) == margins[:, k].min()
        (worst,) = r["worst_margins"]
        assert worst["type"] == "rate" and worst["unit"] == "rad/s"
        assert worst["value"] == min(r["min_margins"].values())


def test_bpbc_keeps_its_rates_inside_the_bounds(ch7_run):
    """The rate bounds are invariant under Theorem 7.7 at every instant, so 1 s suffices."""
    _, out, data = ch7_run
    bounds = np.array(data["constraints"][0]["bounds"], dtype=float)
    runs = [r for r in json.loads((out / "summary.json").read_text()) if r["controller"] == "BPBC"]
    assert runs
    for r in runs:
        assert np.all(np.array(r["peak_joint_rates"]) < bounds)
        assert all(m > 0 for m in r["min_margins"].values())
        assert r["status"] != "constraint_violated"


def test_stdout_has_the_summary_table(tmp_path, capsys):
    assert main([str(tiny(tmp_path)), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert "cpbc summary" in captured.out
    assert "PD" in captured.out
    assert "Traceback" not in captured.err


def test_a_second_run_replaces_the_previous_output(tmp_path):
    out = tmp_path / "out"
    first = tiny(tmp_path, cases=[{"name": "first", "position": [0, 0]}])
    assert main([str(first), "--out", str(out), "--quiet"]) == 0
    second = tiny(tmp_path, cases=[{"name": "second", "position": [0.1, 0]}])
    assert main([str(second), "--out", str(out), "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        ".cpbc-files", "scene.json", "scene.mjb.gz", "second", "summary.csv", "summary.json",
        "trajectories.h5", "view.html",
    ]
    assert [r["case"] for r in json.loads((out / "summary.json").read_text())] == ["second"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "tiny.yaml"]


# == bad input ==================================================================================
BAD_INPUTS = {
    "unknown_key": ({"colour": "red"}, "colour"),
    "zero_gain": ({"controllers": [{"type": "pd", "kp": 0, "kd": 1}]}, "kp"),
    "wrong_target_length": ({"target": [1, 2, 3]}, "target"),
    "negative_duration": ({"simulation": {"duration": -1}}, "duration"),
    "control_period": (
        {"simulation": {"duration": 0.01, "control_period": 0.0015}}, "control_period"
    ),
    "inadmissible_start": (
        {
            "constraints": [{"type": "joint_rate_limit", "name": "r", "bounds": [0.3, 0.2]}],
            "cases": [{"name": "fast", "position": [0, 0], "velocity": [0.5, 0]}],
        },
        "cases[0]",
    ),
    "malicious_expression": ({"target": ["__import__('os')", 0]}, "target"),
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_exits_2_naming_the_field(case, tmp_path, monkeypatch, capsys):
    changes, field = BAD_INPUTS[case]
    sandbox = tmp_path / "cwd"
    sandbox.mkdir()
    monkeypatch.chdir(sandbox)
    path = tiny(sandbox, **changes)
    assert main([str(path), "--quiet"]) == 2  # default output folder runs/tiny
    assert main([str(path), "--out", str(sandbox / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert field in err
    assert "Traceback" not in err
    # no output folder, no scratch folder, nothing at all besides the scenario file
    assert [p.name for p in sandbox.iterdir()] == ["tiny.yaml"]


def test_missing_scenario_file_exits_2(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["no_such_scenario.yaml"]) == 2
    err = capsys.readouterr().err
    assert "no_such_scenario" in err and "thesis_ch7" in err
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_bad_input_leaves_an_existing_output_untouched(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text("[]")
    assert main([str(tiny(tmp_path, target=[1])), "--out", str(out), "--quiet"]) == 2
    assert [p.name for p in out.iterdir()] == ["summary.json"]
    assert (out / "summary.json").read_text() == "[]"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "tiny.yaml"]


def test_subprocess_bad_input_exits_2_without_traceback(tmp_path):
    path = tiny(tmp_path, target=[1, 2, 3])
    proc = subprocess.run(
        [sys.executable, "-m", "cpbc.run", str(path)],
        cwd=tmp_path, capture_output=True, text=True, timeout=60, check=False,
    )
    assert proc.returncode == 2
    assert "target" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["tiny.yaml"]


def test_subprocess_run_ends_with_everything_written_and_printed(tmp_path):
    """``python -m cpbc.run`` leaves without the interpreter's teardown (cpbc.run.cli): the
    summary must still reach a pipe to its last line, and every file its folder."""
    path = tiny(tmp_path)
    proc = subprocess.run(
        [sys.executable, "-m", "cpbc.run", str(path), "--out", "out", "--quiet"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.rstrip().endswith("results written to out/")
    out = tmp_path / "out"
    assert {"summary.json", "summary.csv", "view.html", "scene.json"} <= {
        p.name for p in out.iterdir()}
    assert sorted(p.name for p in (out / "rest").glob("*.png")) == sorted(
        f"{name}.png" for name in ("positions", "rates", "torques", "lyapunov", "path"))


def test_error_message_keeps_bracketed_constraint_names(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    changes, _ = BAD_INPUTS["inadmissible_start"]
    assert main([str(tiny(tmp_path, **changes)), "--quiet"]) == 2
    assert "'rate[joint1]'" in capsys.readouterr().err


def test_summary_table_keeps_bracketed_constraint_names(tmp_path, capsys):
    path = tiny(
        tmp_path,
        constraints=[{"type": "joint_rate_limit", "name": "r", "bounds": [0.3, 0.2]}],
    )
    assert main([str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert "rate[joint" in capsys.readouterr().out


# == output paths come from names in the scenario: they must stay inside the output ================
def test_scenario_name_dotdot_does_not_delete_the_working_directory(tmp_path, monkeypatch):
    sandbox = tmp_path / "cwd"  # confined: whatever the bug deletes lies inside tmp_path
    sandbox.mkdir()
    (sandbox / "precious.txt").write_text("keep")
    monkeypatch.chdir(sandbox)
    assert Path.cwd() == sandbox.resolve()
    path = tiny(sandbox, name="..")
    assert main([str(path), "--quiet"]) == 2
    assert (tmp_path / "cwd" / "precious.txt").read_text() == "keep"


def test_scenario_name_dot_does_not_replace_all_runs(tmp_path, monkeypatch):
    sandbox = tmp_path / "cwd"
    (sandbox / "runs" / "other").mkdir(parents=True)
    (sandbox / "runs" / "other" / "summary.json").write_text("[]")
    monkeypatch.chdir(sandbox)
    main([str(tiny(sandbox, name=".")), "--quiet"])
    assert (tmp_path / "cwd" / "runs" / "other" / "summary.json").is_file()


def test_case_names_cannot_write_outside_the_output(tmp_path):
    sandbox = tmp_path / "cwd"
    sandbox.mkdir()
    path = tiny(sandbox, cases=[{"name": "../escaped", "position": [0, 0]}])
    main([str(path), "--out", str(sandbox / "out"), "--quiet"])
    assert sorted(p.name for p in sandbox.iterdir()) in (["out", "tiny.yaml"], ["tiny.yaml"])


def test_existing_folder_that_is_not_a_cpbc_output_is_not_wiped(tmp_path):
    sandbox = tmp_path / "cwd"
    (sandbox / "mine").mkdir(parents=True)
    (sandbox / "mine" / "notes.txt").write_text("keep")
    main([str(tiny(sandbox)), "--out", str(sandbox / "mine"), "--quiet"])
    assert (sandbox / "mine" / "notes.txt").read_text() == "keep"


# == re-running into an earlier output keeps what the user added =================================
def test_a_rerun_keeps_the_files_the_user_added(tmp_path, capsys):
    out = tmp_path / "out"
    first = tiny(tmp_path, cases=[{"name": "first", "position": [0, 0]}])
    assert main([str(first), "--out", str(out), "--quiet", "--no-plots"]) == 0
    written = (out / ".cpbc-files").read_text().splitlines()
    assert "summary.json" in written and LOG_FILE in written
    (out / "notes.md").write_text("mine")
    (out / "first").mkdir()  # (a run without figures writes no case folder)
    (out / "first" / "sketch.txt").write_text("also mine")
    second = tiny(tmp_path, cases=[{"name": "second", "position": [0.1, 0]}])
    assert main([str(second), "--out", str(out), "--quiet", "--no-plots"]) == 0
    assert (out / "notes.md").read_text() == "mine"
    assert (out / "first" / "sketch.txt").read_text() == "also mine"
    # the earlier run's own files are gone, the new run's are in place
    assert not (out / "first" / "PD").exists()
    with h5py.File(out / LOG_FILE, "r") as log:
        assert list(log) == ["second"]
    assert [r["case"] for r in json.loads((out / "summary.json").read_text())] == ["second"]
    assert "notes.md" not in (out / ".cpbc-files").read_text()


def test_a_rerun_that_would_overwrite_a_user_file_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    first = tiny(tmp_path, cases=[{"name": "first", "position": [0, 0]}])
    assert main([str(first), "--out", str(out), "--quiet", "--no-plots"]) == 0
    mine = out / LOG_FILE  # a file of the user's, where the next run writes (not listed)
    mine.write_text("my own file where the next run writes")
    listed = (out / ".cpbc-files").read_text().splitlines()
    (out / ".cpbc-files").write_text("".join(f"{p}\n" for p in listed if p != LOG_FILE))
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    second = tiny(tmp_path, cases=[{"name": "second", "position": [0.1, 0]}])
    assert main([str(second), "--out", str(out), "--quiet", "--no-plots"]) == 2
    err = " ".join(capsys.readouterr().err.split())  # as one line, however it was wrapped
    assert LOG_FILE in err and "was not written by cpbc" in err
    assert "choose another --out" in err
    assert mine.read_text() == "my own file where the next run writes"
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "tiny.yaml"]


def test_an_output_of_an_earlier_version_keeps_unknown_files(tmp_path):
    """Folders written before the manifest: cpbc's files are known by name."""
    out = tmp_path / "out"
    (out / "old" / "PD").mkdir(parents=True)
    (out / "summary.json").write_text("[]")
    (out / "old" / "PD" / "trajectory.npz").write_bytes(b"")
    (out / "old" / "rates.png").write_bytes(b"")
    (out / "old" / "my_plot.png").write_bytes(b"mine")
    assert main([str(tiny(tmp_path)), "--out", str(out), "--quiet", "--no-plots"]) == 0
    assert (out / "old" / "my_plot.png").read_bytes() == b"mine"
    assert not (out / "old" / "rates.png").exists()
    assert not (out / "old" / "PD").exists()


# == the table: margins by type, applied torques against limits, the safeguard's share ===========
def test_table_reports_margins_by_type_in_their_units(tmp_path, capsys):
    path = tiny(
        tmp_path, simulation={"duration": 0.2},
        constraints=[
            {"type": "joint_rate_limit", "name": "r", "bounds": [0.3, 0.2]},
            {"type": "joint_position_limit", "name": "p", "lower": [-3, -3], "upper": [3, 3]},
            {"type": "kinetic_energy_limit", "name": "ke", "limit": 5.0},
        ],
        controllers=[{"type": "cpbc", "name": "CPBC", "kp": 1, "kd": 1}],
    )
    assert main([str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    table = capsys.readouterr().out
    for kind, unit in (("position", "rad"), ("rate", "rad/s"), ("energy", "J")):
        assert re.search(rf"{kind} [-0-9.e]+ {re.escape(unit)}\b", table), (kind, table)
    (run,) = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert {w["type"]: w["unit"] for w in run["worst_margins"]} == {
        "position": "rad", "rate": "rad/s", "energy": "J"}
    # starting at rest at x = 0: 3 rad from the position limits, the whole energy budget
    npz = load_log(tmp_path / "out" / LOG_FILE, "rest", "CPBC")
    m, names = npz["margins"], list(npz["margin_names"])
    assert m[0, names.index("position[joint1]")] == pytest.approx(3.0)
    assert m[0, names.index("ke")] == pytest.approx(5.0)


def test_applied_torque_is_reported_against_the_plant_limit(tmp_path, capsys):
    path = tiny(tmp_path, simulation={"duration": 0.05, "torque_limit": 0.2},
                controllers=[{"type": "pd", "name": "PD", "kp": 10, "kd": 1}])
    assert main([str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    table = capsys.readouterr().out
    (run,) = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert run["torque_limits"] == [0.2, 0.2]
    assert max(run["peak_commanded_torques"]) > 0.2  # PD asked for more …
    assert max(run["peak_joint_torques"]) == pytest.approx(0.2)  # … than the motors gave
    assert run["saturated_steps"] > 0
    assert "0.2=0.2" in table and "torque saturated" in table


def test_status_says_when_the_safeguard_drove_most_of_the_run(ch7_run):
    from dataclasses import replace

    from cpbc.results.metrics import RunSummary
    from cpbc.results.summary_table import run_notes, safeguard_cell

    _, out, _ = ch7_run
    fields = {k: v for k, v in json.loads((out / "summary.json").read_text())[0].items()
              if k in RunSummary.__dataclass_fields__}
    s = RunSummary(**fields)
    half = s.control_steps // 2
    busy = replace(s, safeguard_steps=half + 1)  # just over half of the steps
    share = (half + 1) / s.control_steps
    assert f"safeguard acted on {share:.0%} of steps" in run_notes(busy)
    assert safeguard_cell(busy) == f"{share:.1%} ({half + 1} steps)"
    calm = replace(s, safeguard_steps=half)
    assert "safeguard" not in run_notes(calm)
    assert safeguard_cell(calm) == f"{half / s.control_steps:.1%} ({half} steps)"


def test_summary_csv_names_the_violated_constraint(tmp_path: Path) -> None:
    path = tmp_path / "base.yaml"
    path.write_text(yaml.safe_dump(BASE, sort_keys=False))
    scenario, file = load_scenario(path)
    setup = build(scenario, file)
    summaries = [r.summary for r in run_all(setup)]
    summaries[1] = dataclasses.replace(summaries[1], status="constraint_violated",
                                       violated_constraint="obstacle")
    write_summaries(tmp_path, summaries)
    with (tmp_path / "summary.csv").open(newline="") as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
    assert reader.fieldnames is not None and reader.fieldnames[-1] == "violated_constraint"
    assert [r["violated_constraint"] for r in rows] == ["", "obstacle", "", ""]


def test_status_says_when_the_run_crossed_what_it_only_monitored(ch7_run, capsys):
    """thesis_ch7's PD monitors the rate bounds (it enforces nothing) and crosses both: its
    status cell says so next to ``converged``; BPBC enforces them and its cell has no such
    note."""
    from cpbc.results.metrics import RunSummary
    from cpbc.results.summary_table import status_text

    _, out, _ = ch7_run
    runs = [RunSummary(**{k: v for k, v in r.items() if k in RunSummary.__dataclass_fields__})
            for r in json.loads((out / "summary.json").read_text())]
    pd = [s for s in runs if s.controller == "PD"]
    assert pd and all(s.crossed_constraints == ["rate[theta1]", "rate[theta2]"] for s in pd)
    assert all("crossed monitored rate[theta1], rate[theta2]" in status_text(s) for s in pd)
    bpbc = [s for s in runs if s.controller == "BPBC"]
    assert bpbc and all("crossed" not in status_text(s) for s in bpbc)
