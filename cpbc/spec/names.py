"""The names of a scenario's cases and runs: they become folder names of the output, so one
path component each, and none the name of a file the run writes beside them."""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated

from pydantic import AfterValidator, Field

# Names become folder names of the output: one path component, no "." or "..", short
# enough for any file system (a name is at most 255 bytes).
SafeName = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$", max_length=100)]
#: What a run writes at the top of its output folder (cpbc.results.io, cpbc.results.saved_run,
#: cpbc.viewer) and into each case's folder (the figures of cpbc.results.plots and
#: cpbc.results.system_plots): a case, or a controller, of one of these names would collide.
RUN_FILES = frozenset({"summary.json", "summary.csv", "scene.mjb", "scene.mjb.gz",
                       "scene.json", "view.html"})
CASE_FILES = frozenset({"positions.png", "rates.png", "torques.png", "lyapunov.png",
                        "margins.png", "path.png", "timeseries.png", "task_error.png",
                        "governor.png",
                        "view.html"})


def _not_in(reserved: frozenset[str], what: str) -> Callable[[str], str]:
    def check(name: str) -> str:
        if name in reserved:
            raise ValueError(f"'{name}' is the name of a file the run writes {what}; "
                             "rename it")
        return name

    return check


CaseName = Annotated[SafeName, AfterValidator(_not_in(RUN_FILES, "into the output folder"))]
RunName = Annotated[SafeName, AfterValidator(_not_in(CASE_FILES, "into each case's folder"))]
