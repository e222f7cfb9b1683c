"""Results layer: metrics and status judged from data, and the files a run writes."""

from cpbc.results.io import staged_output, write_summaries, write_trajectory
from cpbc.results.metrics import STATUSES, RunSummary, SettleCriteria, summarise
from cpbc.results.packed import load_npz, write_npz

__all__ = [
    "STATUSES",
    "RunSummary",
    "SettleCriteria",
    "load_npz",
    "staged_output",
    "summarise",
    "write_npz",
    "write_summaries",
    "write_trajectory",
]
