"""The documentation: the generated scenario reference is current and complete, the README
stays short and gives CI's test command, and every code block marked runnable runs.

A block is marked runnable by an HTML comment on the line before its opening fence (GitHub
and mkdocs both render the comment as nothing):

* ``<!-- runnable -->`` before a ``bash`` block: the block runs in bash (``set -euo
  pipefail``), ``python`` being this interpreter;
* ``<!-- runnable -->`` before a ``python`` block: the block runs as a script;
* ``<!-- runnable: file NAME -->`` before any block: its text is written to ``NAME``.

A page's runnable blocks run in order in one temporary folder, with this repository's cpbc
first on the path. Mark only blocks that finish in seconds.
"""

from __future__ import annotations

import inspect
import os
import re
import subprocess
import sys
import typing
from pathlib import Path

import pytest
from pydantic import BaseModel

from cpbc.scenario import schema
from cpbc.scenario.schema.kinds import KINDS
from tools import scenario_reference

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
MARKER = re.compile(r"^<!-- runnable(?:: file (?P<file>[\w./-]+))? -->$")
FENCE = re.compile(r"^(?P<fence>```+)(?P<lang>[\w-]*)")


def runnable_blocks(text: str) -> list[tuple[str, str | None, str]]:
    """(language, file name or None, code) of each block marked runnable, in order."""
    lines = text.splitlines()
    blocks = []
    for i, line in enumerate(lines[:-1]):
        marker = MARKER.match(line.strip())
        if marker is None:
            continue
        opening = FENCE.match(lines[i + 1])
        assert opening, f"a runnable marker must precede a fenced block (line {i + 1})"
        body = []
        for inner in lines[i + 2:]:
            if inner.startswith(opening["fence"]):
                break
            body.append(inner)
        else:
            raise AssertionError(f"unclosed block after line {i + 1}")
        blocks.append((opening["lang"], marker["file"], "\n".join(body) + "\n"))
    return blocks


def test_scenario_reference_is_current() -> None:
    assert scenario_reference.PAGE.read_text(encoding="utf-8") == scenario_reference.render(), (
        "docs/scenario-reference.md is stale: python -m tools.scenario_reference")


def _models_in(annotation: object) -> list[type[BaseModel]]:
    """The pydantic models an annotation names, however nested (unions, lists, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models_in(arg)]


def test_every_scenario_field_is_described() -> None:
    # the schema's own models and every registered kind's spec (declared in its constraint's
    # or law's module), with the models their fields nest
    models = [cls for _, cls in inspect.getmembers(schema, inspect.isclass)
              if issubclass(cls, BaseModel) and cls.__module__.startswith("cpbc.")]
    models += [k.spec for k in (*KINDS.constraints, *KINDS.laws)]
    for cls in list(models):
        models += [m for f in cls.model_fields.values() for m in _models_in(f.annotation)]
    models = list(dict.fromkeys(models))
    assert len(models) > 40 and any(m.__name__ == "PrimitiveSpec" for m in models)
    missing = [f"{cls.__name__}.{name}" for cls in models
               for name, field in cls.model_fields.items() if not field.description]
    assert not missing, f"fields without a description: {missing}"


def test_readme_is_short_and_gives_ci_its_test_command() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 200
    install, tests = "bash scripts/install.sh --test", ".venv/bin/python -m pytest"
    assert f"{install} && {tests}" in readme
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert install in ci and tests in ci


def test_the_marker_is_found() -> None:
    text = ("x\n<!-- runnable: file a.yaml -->\n```yaml\nname: a\n```\n"
            "<!-- runnable -->\n```bash\necho hi\n```\n")
    assert runnable_blocks(text) == [("yaml", "a.yaml", "name: a\n"), ("bash", None, "echo hi\n")]


@pytest.mark.parametrize("page", [p for p in PAGES if runnable_blocks(p.read_text("utf-8"))],
                         ids=lambda p: p.name)
def test_runnable_blocks_run(page: Path, tmp_path: Path) -> None:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    # a wrapper, not a symlink: a symlinked venv interpreter would lose its venv
    wrapper = bin_dir / "python"
    wrapper.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n', encoding="utf-8")
    wrapper.chmod(0o755)
    work = tmp_path / "work"
    work.mkdir()
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
           "MPLBACKEND": "Agg"}
    for n, (lang, name, code) in enumerate(runnable_blocks(page.read_text(encoding="utf-8"))):
        if name is not None:
            (work / name).write_text(code, encoding="utf-8")
            continue
        if lang in ("bash", "sh", "console"):
            argv = ["bash", "-c", "set -euo pipefail\n" + code]
        elif lang == "python":
            script = work / f"block{n}.py"
            script.write_text(code, encoding="utf-8")
            argv = [sys.executable, str(script)]
        else:
            raise AssertionError(f"{page.name}: cannot run a {lang!r} block")
        done = subprocess.run(argv, cwd=work, env=env, capture_output=True, text=True,
                              timeout=300)
        assert done.returncode == 0, (
            f"{page.name}, block {n} ({lang}) exited {done.returncode}:\n{code}\n"
            f"{done.stdout[-2000:]}\n{done.stderr[-2000:]}")
