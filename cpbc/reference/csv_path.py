"""A reference read from a CSV file: a header ``t,x,y,z`` then rows of numbers, t [s]
starting at 0 and strictly increasing, positions [m]; linear between rows. Every defect is
a ParameterError naming ``reference.path.csv`` with the file, the row and the fix."""

from __future__ import annotations

import csv
from pathlib import Path as FilePath

import numpy as np

from cpbc.errors import ParameterError
from cpbc.reference.paths import Polyline

FIELD = "reference.path.csv"
COLUMNS = ("t", "x", "y", "z")


def _fail(path: FilePath, msg: str) -> ParameterError:
    return ParameterError(FIELD, f"{path}: {msg}")


def read_csv_path(path: FilePath) -> Polyline:
    """The polyline of the file (module docstring)."""
    try:
        with path.open(newline="") as fh:
            rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
    except (OSError, UnicodeDecodeError) as exc:
        raise _fail(path, f"cannot be read ({exc.__class__.__name__}: {exc})") from None
    if not rows or tuple(c.strip().lower() for c in rows[0]) != COLUMNS:
        raise _fail(path, "the first line must be the header t,x,y,z")
    values = []
    for k, row in enumerate(rows[1:], start=2):
        if len(row) != 4:
            raise _fail(path, f"line {k} has {len(row)} columns, needs 4 (t, x, y, z)")
        try:
            values.append([float(c) for c in row])
        except ValueError:
            raise _fail(path, f"line {k} is not 4 numbers: {row}") from None
    data = np.asarray(values, dtype=float)
    if len(data) < 2:
        raise _fail(path, "needs at least 2 rows of samples")
    if not np.all(np.isfinite(data)):
        raise _fail(path, "holds a non-finite number (nan or inf)")
    t = data[:, 0]
    if t[0] != 0.0:
        raise _fail(path, f"time must start at 0, got {t[0]}")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise _fail(path, f"time must increase strictly; line {bad[0] + 3} does not")
    return Polyline(t, data[:, 1:])
