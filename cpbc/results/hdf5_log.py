"""Every run's logged signals in one HDF5 file per run folder, ``trajectories.h5``.

A standard container that h5py, pandas (through h5py), MATLAB (``h5read``), Julia (HDF5.jl)
and the ``h5dump`` tool open without cpbc. Layout::

    /                      attrs: format ("cpbc-trajectories/1"), scenario
    /<case>/<controller>/  one group per run; attrs: outcome, summary (the run's object of
                           summary.json as a JSON string) and its scalar and numeric-list
                           entries (status, final_error, …) as attributes of their own
        time               (N,) float64, attrs units="s"
        <signal>           (N,) or (N, k); attrs units (one per column) and names (idem)

An arm's run holds ``position``, ``velocity``, ``torque`` (asked for, controller
coordinates), ``joint_torque`` (applied, per joint), ``margins`` (attrs ``types`` too:
cpbc.results.margin_types), ``lyapunov`` and ``target``; a Part I system's run holds
``state`` and ``input``. The signals are single precision (7 significant digits), time and
the target double; every dataset of more than one value is stored a column a chunk with
HDF5's shuffle filter and deflate, which together take the place of a hand-written coding.
Summaries are computed from the double-precision logs before they are written, so their
peaks are the file's, rounded.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.margins import BY_KEY, OTHER
from cpbc.simulation.trajectory import SystemTrajectory, Trajectory

#: The file's name in a run folder.
LOG_FILE = "trajectories.h5"
FORMAT = "cpbc-trajectories/1"
_FILTERS: dict[str, Any] = {"compression": "gzip", "compression_opts": 6, "shuffle": True}
_CHUNK_ROWS = 65536  # 256 kB of a float32 column (HDF5's chunk cache holds 1 MB)


@dataclass(frozen=True)
class ArmLabels:
    """What the columns of an arm's signals are: names, and which are lengths (prismatic:
    m, m/s, N) rather than angles (rad, rad/s, N m)."""

    coordinate_names: Sequence[str]
    coordinate_lengths: Sequence[bool]
    joint_names: Sequence[str]
    joint_lengths: Sequence[bool]
    margin_names: Sequence[str]
    margin_types: Sequence[str]


@contextmanager
def log_file(path: Path, scenario: str) -> Iterator[h5py.File]:
    """A new ``trajectories.h5`` at ``path``, open for writing runs into."""
    with h5py.File(path, "w", track_order=True) as f:
        f.attrs["format"] = FORMAT
        f.attrs["scenario"] = scenario
        yield f


def _dataset(group: h5py.Group, name: str, data: Array, units: str | Sequence[str],
             names: Sequence[str] = ()) -> h5py.Dataset:
    data = np.asarray(data)
    if data.size > 1:  # a column a chunk: a smooth signal's bytes deflate best on their own
        chunks = (min(len(data), _CHUNK_ROWS), *(1,) * (data.ndim - 1))
        ds = group.create_dataset(name, data=data, chunks=chunks, **_FILTERS)
    else:
        ds = group.create_dataset(name, data=data)
    if isinstance(units, str):
        ds.attrs["units"] = units
    elif len(units):
        ds.attrs["units"] = _text(units)
    if len(names):
        ds.attrs["names"] = _text(names)
    return ds


def _text(values: Sequence[str]) -> Array:
    """Strings as an HDF5 array of variable-length UTF-8 strings."""
    return np.array([str(v) for v in values], dtype=h5py.string_dtype())


def _summary_attrs(group: h5py.Group, summary: Mapping[str, object]) -> None:
    """The summary as one JSON attribute, and its scalars and lists of numbers as their own."""
    group.attrs["summary"] = json.dumps(summary, allow_nan=False)
    for key, value in summary.items():
        if key in group.attrs or value is None:
            continue
        if isinstance(value, (str, bool, int, float)):
            group.attrs[key] = value
        elif (isinstance(value, list) and value
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
            group.attrs[key] = np.asarray(value, dtype=float)


def _run_group(log: h5py.File, case: str, controller: str, outcome: str,
               summary: Mapping[str, object]) -> h5py.Group:
    parent = log[case] if case in log else log.create_group(case, track_order=True)
    group = parent.create_group(controller, track_order=True)  # in the scenario's order
    group.attrs["outcome"] = outcome
    _summary_attrs(group, summary)
    return group


def _units(lengths: Sequence[bool], length: str, angle: str) -> list[str]:
    return [length if is_length else angle for is_length in lengths]


def _single(a: Array) -> Array:
    return np.asarray(a, dtype=np.float32)


def write_trajectory(log: h5py.File, case: str, controller: str, traj: Trajectory,
                     margins: Array, lyapunov: Array, target: Array, labels: ArmLabels,
                     summary: Mapping[str, object], task_error: Array | None = None,
                     reference: Mapping[str, Array] | None = None) -> None:
    """One arm's run into ``log`` as the group ``/<case>/<controller>``; a goal run's
    ``task_error`` (position, angle per sample) too, and a reference run's per-sample
    ``path_time`` s_v [s], ``applied`` and ``requested`` points [m] and ``blocked`` flag."""
    g = _run_group(log, case, controller, traj.outcome, summary)
    coords, lengths = labels.coordinate_names, labels.coordinate_lengths
    _dataset(g, "time", traj.time, "s")
    _dataset(g, "position", _single(traj.position), _units(lengths, "m", "rad"), coords)
    _dataset(g, "velocity", _single(traj.velocity), _units(lengths, "m/s", "rad/s"), coords)
    _dataset(g, "torque", _single(traj.torque), _units(lengths, "N", "N m"), coords)
    _dataset(g, "joint_torque", _single(traj.joint_torque),
             _units(labels.joint_lengths, "N", "N m"), labels.joint_names)
    types = list(labels.margin_types) or [OTHER.key] * len(labels.margin_names)
    m = _dataset(g, "margins", _single(margins), [BY_KEY[t].unit for t in types],
                 labels.margin_names)
    if types:
        m.attrs["types"] = _text(types)
    _dataset(g, "lyapunov", _single(lyapunov), "")
    _dataset(g, "target", target, _units(lengths, "m", "rad"), coords)
    if task_error is not None:
        _dataset(g, "task_error", _single(task_error), ["m", "rad"], ["position", "angle"])
    for name, data in (reference or {}).items():
        units = {"path_time": "s", "path_lag": "s", "blocked": ""}.get(name, ["m", "m", "m"])
        labels_ = ["x", "y", "z"] if name in ("applied", "requested") else ()
        _dataset(g, name, np.asarray(data, dtype=np.uint8 if name == "blocked" else float),
                 units, labels_)


def write_signals(log: h5py.File, case: str, controller: str,
                  signals: Mapping[str, tuple[Array, str | Sequence[str], Sequence[str]]]
                  ) -> None:
    """More per-sample signals into the run ``/<case>/<controller>`` that
    :func:`write_trajectory` wrote: each as (data, units, column names), in double
    precision (a robot's commands and timings are read back to the last bit)."""
    g = log[f"{case}/{controller}"]
    for name, (data, units, names) in signals.items():
        _dataset(g, name, np.asarray(data), units, names)


def _unit_of(name: str) -> str:
    """The unit in a name's brackets ("tau [N m]" → "N m"); empty without."""
    found = re.search(r"\[([^\]]*)\]", name)
    return found.group(1) if found else ""


def write_system_trajectory(log: h5py.File, case: str, law: str, traj: SystemTrajectory,
                            state_names: Sequence[str], input_name: str,
                            summary: Mapping[str, object]) -> None:
    """One Part I run into ``log`` as the group ``/<case>/<law>``: time, state, input."""
    g = _run_group(log, case, law, traj.outcome, summary)
    _dataset(g, "time", traj.time, "s")
    _dataset(g, "state", _single(traj.state), [_unit_of(n) for n in state_names], state_names)
    _dataset(g, "input", _single(traj.input), _unit_of(input_name), [input_name])


def _strings(values: Any) -> tuple[str, ...]:
    return tuple(v.decode() if isinstance(v, bytes) else str(v) for v in np.atleast_1d(values))


def read_run(log: h5py.File, case: str, controller: str) -> dict[str, Any]:
    """A run read back by name: every dataset, its ``names`` and ``types`` attributes as
    ``<dataset>_names`` and ``<dataset>_types`` (an arm's also as ``coordinate_names``,
    ``margin_names`` and ``margin_types``, the names its logs had before), and ``outcome``.

    Raises:
        KeyError: the file holds no such run.
    """
    g = log[f"{case}/{controller}"]
    out: dict[str, Any] = {name: ds[()] for name, ds in g.items()}
    for name, ds in g.items():
        for attr in ("names", "types"):
            if attr in ds.attrs:
                out[f"{name}_{attr}"] = _strings(ds.attrs[attr])
    if "position" in g:
        out["coordinate_names"] = out.get("position_names", ())
    if "margins" in g:
        out["margin_names"] = out.get("margins_names", ())
        out["margin_types"] = out.get("margins_types", ())
    out["outcome"] = str(g.attrs["outcome"])
    return out


def load_log(path: Path | str, case: str, controller: str) -> dict[str, Any]:
    """``read_run`` of a ``trajectories.h5`` at ``path``."""
    with h5py.File(path, "r") as f:
        return read_run(f, case, controller)
