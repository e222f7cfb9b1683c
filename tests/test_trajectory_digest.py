"""tools.trajectory_digest: one line per file that changes when a trajectory changes by a bit,
and not otherwise."""

from __future__ import annotations

from pathlib import Path

import pytest

from tools.trajectory_digest import digest, main

ROOT = Path(__file__).resolve().parents[1]
CH7 = ROOT / "scenarios" / "thesis_ch7.yaml"


def test_the_same_runs_give_the_same_digest_and_other_runs_another(tmp_path: Path) -> None:
    """The thesis's BPBC twice: the same digest; other starts, or a gain changed in the
    third decimal of one joint, another."""
    first = digest(str(CH7), 2, 0.1, 1)
    assert digest(str(CH7), 2, 0.1, 1) == first
    assert digest(str(CH7), 2, 0.1, 2)[0] != first[0]
    changed = tmp_path / "thesis_ch7.yaml"
    text = CH7.read_text(encoding="utf-8")
    assert text.count("kp: [2, 10]") == 2
    changed.write_text(text.replace("kp: [2, 10]", "kp: [2.001, 10]"), encoding="utf-8")
    assert digest(str(changed), 2, 0.1, 1)[0] != first[0]


def test_the_command_prints_a_line_per_file_and_refuses_bad_input(capsys) -> None:
    """A line per file; a file that is not there, or no starts, exit 2 with one line and
    nothing on standard output for it."""
    assert main([str(CH7), "--starts", "1", "--seconds", "0.05"]) == 0
    out = capsys.readouterr().out.split()
    assert out[0] == str(CH7) and len(out[1]) == 16 and out[2:] == ["acted", "0"]
    assert main(["no_such_scenario.yaml"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "no_such_scenario.yaml" in captured.err
    assert main([str(CH7), "--starts", "0"]) == 2
    assert "--starts" in capsys.readouterr().err


@pytest.mark.parametrize("seconds", ["0", "-1"])
def test_a_run_of_no_time_is_refused(seconds: str, capsys) -> None:
    assert main([str(CH7), "--seconds", seconds]) == 2
    assert "--seconds" in capsys.readouterr().err
