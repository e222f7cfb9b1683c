"""CPU seconds ``cpbc.run`` takes to refuse the largest inputs tests/test_cli_limits.py sends
it: an alias bomb, a million-entry target (over the file-size limit), a 450 000-entry target
(just under it, parsed whole), 5 000 cases, 1 200 runs. The tests assert *where* each is
refused (before the step whose cost grows with the input); this prints how long it took on
this machine, median and range over ``--runs`` repetitions in this process.

    PYTHONPATH=. python scripts/refusal_time.py [--runs 3]
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import yaml

from cpbc.run import main as run_main
from tools.reliability.bad_input import BASE

_TARGET = "target:\n- 1.0\n- 1.5\n"


def _base_text(change: dict[str, object] | None = None) -> str:
    data = copy.deepcopy(BASE)
    data["controllers"] = data["controllers"][:2]
    data.update(change or {})
    return yaml.safe_dump(data, sort_keys=False)


def _alias_bomb() -> str:
    lines = ["a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 10)]
    return "\n".join(lines) + "\n"


INPUTS: dict[str, Callable[[], str]] = {
    "alias bomb": _alias_bomb,
    "target, 10⁶ entries": lambda: _base_text().replace(
        _TARGET, f"target: [{', '.join(['1'] * 10**6)}]\n"),
    "target, 450 000 entries": lambda: _base_text().replace(
        _TARGET, f"target: [{','.join(['1'] * 450_000)}]\n"),
    "5 000 cases": lambda: _base_text(
        {"cases": [{"name": f"c{i}", "position": [0, 0]} for i in range(5000)]}),
    "1 200 runs": lambda: _base_text(
        {"cases": [{"name": f"c{i}", "position": [0, 0]} for i in range(400)],
         "controllers": [{"type": "pd", "name": f"PD{k}", "kp": 4, "kd": 20}
                         for k in range(3)]}),
}


def refusal_seconds(text: str, folder: Path) -> float:
    """CPU seconds of one refused ``cpbc.run`` on ``text`` (which must be refused)."""
    scenario = folder / "scenario.yaml"
    scenario.write_text(text)
    start = time.process_time()
    with contextlib.redirect_stderr(io.StringIO()):
        code = run_main([str(scenario), "--out", str(folder / "out"), "--quiet",
                         "--no-plots", "--workers", "1"])
    seconds = time.process_time() - start
    if code != 2:
        raise SystemExit(f"expected a refusal (exit 2), got exit {code}")
    return seconds


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=3, help="repetitions of each input")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for name, make in INPUTS.items():
            text = make()
            v = [refusal_seconds(text, Path(tmp)) for _ in range(args.runs)]
            print(f"{name:<24} cpu {statistics.median(v):.2f} s ({min(v):.2f}–{max(v):.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
