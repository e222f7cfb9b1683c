"""Shared pieces of the scenario specs: the size limits, and (re-exported from cpbc.spec, where
the kinds declared below the scenario layer read them) the numbers, the names, the files a
run writes and the ``Strict`` base of every spec."""

from __future__ import annotations

from cpbc.spec.fields import Gain, NonNegative, Number, Positive, Strict, Vector
from cpbc.spec.names import CASE_FILES, RUN_FILES, CaseName, RunName, SafeName

__all__ = ["CASE_FILES", "MAX_CASES", "MAX_RUNS", "RUN_FILES", "CaseName", "Gain",
           "NonNegative", "Number", "Positive", "RunName", "SafeName", "Strict", "Vector"]

#: The most cases a scenario holds, and the most runs (cases × controllers): each case
#: draws its figures and each run logs its trajectory and joins the page; more is a
#: campaign, for cpbc.reliability, or several scenarios.
MAX_CASES = 500
MAX_RUNS = 1000
