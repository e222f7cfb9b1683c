"""Results layer: metrics and status judged from data, and the files a run writes."""

from cpbc.results.hdf5_log import (
    LOG_FILE,
    ArmLabels,
    load_log,
    log_file,
    write_system_trajectory,
    write_trajectory,
)
from cpbc.results.io import staged_output, write_summaries
from cpbc.results.metrics import STATUSES, RunSummary, SettleCriteria, summarise

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
