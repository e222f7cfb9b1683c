"""Results layer: metrics and status judged from data, and the files a run writes.

The file writers (h5py, about 0.1 s to import) load on first use of their names, so that
building a scenario, which reads ``SettleCriteria`` from here, does not import them.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from cpbc.results.metrics import STATUSES, RunSummary, SettleCriteria, summarise

if TYPE_CHECKING:
    from cpbc.results.hdf5_log import (
        LOG_FILE,
        ArmLabels,
        load_log,
        log_file,
        write_system_trajectory,
        write_trajectory,
    )
    from cpbc.results.io import staged_output, write_summaries

_WRITERS = {
    "LOG_FILE": "cpbc.results.hdf5_log",
    "ArmLabels": "cpbc.results.hdf5_log",
    "load_log": "cpbc.results.hdf5_log",
    "log_file": "cpbc.results.hdf5_log",
    "write_trajectory": "cpbc.results.hdf5_log",
    "write_system_trajectory": "cpbc.results.hdf5_log",
    "staged_output": "cpbc.results.io",
    "write_summaries": "cpbc.results.io",
}


def __getattr__(name: str) -> Any:
    if name in _WRITERS:
        return getattr(importlib.import_module(_WRITERS[name]), name)
    raise AttributeError(f"module 'cpbc.results' has no attribute {name!r}")


__all__ = [
    "LOG_FILE",
    "STATUSES",
    "ArmLabels",
    "RunSummary",
    "SettleCriteria",
    "load_log",
    "log_file",
    "staged_output",
    "summarise",
    "write_summaries",
    "write_system_trajectory",
    "write_trajectory",
]
