"""Input outside the scenario schema: output folders the system refuses, names that collide
with the run's files, YAML that expands without bound, scenarios too large to run. Each ends
with exit code 2, a one-line message naming what to change, no traceback and nothing left
behind, before the step whose cost grows with the input."""

from __future__ import annotations

import copy
import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from rich.console import Console
from rich.progress import Progress

from cpbc.progress_bars import run_progress
from cpbc.results import LOG_FILE, load_log
from cpbc.run import main
from cpbc.scenario.load import MAX_FILE_BYTES
from tools.reliability.bad_input import BASE


def _ctrl_c_heard() -> None:
    """In the child before it starts: Ctrl-C as a terminal's foreground job hears it. A
    pytest started in the background by a shell without job control ignores SIGINT, and its
    children would inherit that (Python then installs no KeyboardInterrupt handler)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _scenario(folder: Path, change: dict[str, object] | None = None) -> Path:
    data = copy.deepcopy(BASE)
    data["controllers"] = data["controllers"][:2]
    data.update(change or {})
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _refused(capsys: pytest.CaptureFixture[str], args: list[str], *named: str) -> str:
    """The CLI's answer: exit 2, no traceback, one line (a schema error's line under the
    "invalid scenario:" heading) naming each of ``named``."""
    code = main([*args, "--quiet", "--no-plots", "--workers", "1"])
    message = capsys.readouterr().err.strip()
    assert code == 2, message
    assert "Traceback" not in message
    assert len(message.removeprefix("error: invalid scenario:\n").splitlines()) == 1, message
    for n in named:
        assert n in message, message
    return message


def _left(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name != "scenario.yaml")


@pytest.mark.parametrize("out", ["/proc/cpbc-out", "/proc/cpbc/deeper/out"])
def test_output_folder_on_a_read_only_file_system_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], out: str) -> None:
    scenario = _scenario(tmp_path)
    _refused(capsys, [str(scenario), "--out", out], "--out", out)


@pytest.mark.parametrize("where", ["leaf", "parent"])
def test_over_long_output_folder_name_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], where: str) -> None:
    scenario = _scenario(tmp_path)
    out = tmp_path / ("a" * 300) if where == "leaf" else tmp_path / ("a" * 300) / "out"
    _refused(capsys, [str(scenario), "--out", str(out)], "--out", "File name too long")
    assert _left(tmp_path) == []


def test_missing_parents_of_the_output_folder_are_made(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = _scenario(tmp_path)
    out = tmp_path / "new" / "deeper" / "out"
    assert main([str(scenario), "--out", str(out), "--quiet", "--no-plots",
                 "--workers", "1"]) == 0
    assert (out / "summary.json").is_file()


def test_missing_parents_made_for_a_refused_run_are_removed(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = _scenario(tmp_path)
    out = tmp_path / "new" / "deeper" / ("a" * 300)
    _refused(capsys, [str(scenario), "--out", str(out)], "--out")
    assert _left(tmp_path) == []


def test_read_only_working_directory_is_refused_naming_out(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    scenario = _scenario(tmp_path)
    monkeypatch.chdir("/proc")  # where the default runs/<name> cannot be made, even by root
    _refused(capsys, [str(scenario)], "--out runs/base", "writable folder")


@pytest.mark.parametrize(("field", "change"), [
    ("cases[0].name", {"cases": [{"name": "view.html", "position": [0, 0]}]}),
    ("cases[0].name", {"cases": [{"name": "summary.json", "position": [0, 0]}]}),
    ("cases[0].name", {"cases": [{"name": "c" * 300, "position": [0, 0]}]}),
    ("controllers[0].name", {"controllers": [{"type": "pd", "name": "positions.png",
                                              "kp": 4, "kd": 20}]}),
    ("controllers[0].name", {"controllers": [{"type": "pd", "name": "view.html",
                                              "kp": 4, "kd": 20}]}),
])
def test_names_that_collide_with_the_run_files_are_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], field: str,
        change: dict[str, object]) -> None:
    scenario = _scenario(tmp_path, change)
    _refused(capsys, [str(scenario), "--out", str(tmp_path / "out")], field)
    assert _left(tmp_path) == []


def test_names_near_the_run_files_still_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = _scenario(tmp_path, {
        "cases": [{"name": "view", "position": [0, 0]}],
        "controllers": [{"type": "pd", "name": "positions", "kp": 4, "kd": 20}]})
    out = tmp_path / "out"
    assert main([str(scenario), "--out", str(out), "--quiet", "--no-plots",
                 "--workers", "1"]) == 0
    assert load_log(out / LOG_FILE, "view", "positions")["time"].size


def _refused_early(capsys: pytest.CaptureFixture[str], scenario: Path, *named: str) -> None:
    """Refused with a message naming ``named`` and nothing left behind. How early it is
    refused is asserted by what the message names (the size check's own words, or a limit
    met although the robot's file is missing); how fast is measured by
    scripts/refusal_time.py, not asserted here."""
    _refused(capsys, [str(scenario), "--out", str(scenario.parent / "out")], *named)
    assert _left(scenario.parent) == []


def _without_the_robot(data: dict[str, object]) -> dict[str, object]:
    """``data`` naming a robot file that does not exist: a refusal for anything else came
    before the robot was read (reading it would have refused naming the file)."""
    return {**data, "robot": {**BASE["robot"], "model": "missing_arm.xml"}}


def test_yaml_alias_bomb_is_refused_at_once(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = ["a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]"]  # 9**10 values once expanded
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 10)]
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text("\n".join(lines) + "\n")
    # the node count's refusal, on the line where the count passed the limit: before the
    # aliases were expanded into 3.5 × 10⁹ Python objects, which no test would outlive
    _refused_early(capsys, scenario, "1,000,000 values", "aliases expanded", "from line 7")


def test_yaml_that_contains_itself_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text("name: x\ntarget: &a [1, *a]\n")
    _refused_early(capsys, scenario, "line 2", "recursive")


def test_million_entry_target_is_refused_before_it_is_parsed(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = _scenario(tmp_path).read_text().replace("target:\n- 1.0\n- 1.5\n",
                                                   f"target: [{', '.join(['1'] * 10**6)}]\n")
    (tmp_path / "scenario.yaml").write_text(text)
    # the file-size check's words: the file was not parsed (it is refused by its size alone)
    _refused_early(capsys, tmp_path / "scenario.yaml", "1 MB", "split it")


def test_target_at_the_size_limit_is_refused_naming_its_length(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = _scenario(tmp_path).read_text().replace("target:\n- 1.0\n- 1.5\n",
                                                   f"target: [{','.join(['1'] * 450_000)}]\n")
    (tmp_path / "scenario.yaml").write_text(text)
    assert MAX_FILE_BYTES * 0.9 < len(text) <= MAX_FILE_BYTES  # parsed whole, not refused unread
    _refused_early(capsys, tmp_path / "scenario.yaml", "target", "got 450000")


def test_more_cases_than_the_limit_are_refused_naming_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cases = [{"name": f"c{i}", "position": [0, 0]} for i in range(5000)]
    scenario = _scenario(tmp_path, _without_the_robot({"cases": cases}))
    _refused_early(capsys, scenario, "cases", "5000 entries", "500 allowed")


def test_more_runs_than_the_limit_are_refused_naming_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cases = [{"name": f"c{i}", "position": [0, 0]} for i in range(400)]
    controllers = [{"type": "pd", "name": f"PD{k}", "kp": 4, "kd": 20} for k in range(3)]
    scenario = _scenario(tmp_path, _without_the_robot({"cases": cases,
                                                       "controllers": controllers}))
    _refused_early(capsys, scenario, "cases", "1200 runs", "1000")


def test_a_missing_robot_file_is_what_the_limits_tests_would_otherwise_see(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The witness of _without_the_robot: within the limits, the missing file is refused."""
    scenario = _scenario(tmp_path, _without_the_robot({}))
    _refused_early(capsys, scenario, "robot.model", "missing_arm.xml")


def test_progress_shows_the_runs_under_way_not_every_run() -> None:
    bar = Progress(console=Console(file=io.StringIO()))
    report = run_progress(bar, 500)
    for i in range(500):
        report(f"c{i} / PD", 0.5)
        report(f"c{i} / PD", 1.0)
    assert len(bar.tasks) == 1  # the runs done
    assert bar.tasks[0].completed == 500


@pytest.mark.parametrize("how", ["SIGTERM", "Ctrl-C"])
def test_interrupted_run_removes_its_scratch_folder(tmp_path: Path, how: str) -> None:
    scenario = _scenario(tmp_path, {"simulation": {**BASE["simulation"], "duration": 300},
                                    "controllers": BASE["controllers"][:1]})
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-c", "from cpbc.run import cli; cli()", str(scenario), "--out",
         str(out), "--workers", "2"],  # with the figure helpers, forked at the start
        cwd=Path(__file__).parents[1], start_new_session=True, preexec_fn=_ctrl_c_heard,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # waits for the scratch folder however slow the machine; a run that ends first fails
        while not any(p.name.startswith(".out.") for p in tmp_path.iterdir()):
            if proc.poll() is not None:
                pytest.fail(f"the run ended before its scratch folder appeared: "
                            f"{proc.communicate()[1]}")
            time.sleep(0.05)
        time.sleep(0.5)  # the run under way
        if how == "SIGTERM":
            proc.terminate()
        else:
            os.killpg(proc.pid, signal.SIGINT)  # as the terminal sends it: to every process
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    assert "Traceback" not in err, err
    assert "interrupted; nothing written" in err
    assert _left(tmp_path) == []


def test_run_folder_mode_follows_the_umask(tmp_path: Path) -> None:
    scenario = _scenario(tmp_path)
    out = tmp_path / "out"
    old = os.umask(0o022)
    try:
        assert main([str(scenario), "--out", str(out), "--quiet", "--no-plots",
                     "--workers", "1"]) == 0
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == 0o755
    assert (out / "trajectories.h5").stat().st_mode & 0o777 == 0o644
