"""Results layer: metrics and status judged from data, and the files a run writes."""

from cpbc.results.io import staged_output, write_summaries, write_trajectory
from cpbc.results.metrics import STATUSES, RunSummary, SettleCriteria, summarise

__all__ = [
    "STATUSES",
    "RunSummary",
    "SettleCriteria",
    "staged_output",
    "summarise",
    "write_summaries",
    "write_trajectory",
]
