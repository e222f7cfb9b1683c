"""Files of a scenario run: trajectory.npz per run, summary.csv and summary.json per scenario."""

from __future__ import annotations

import csv
import json
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from cpbc.constraints.base import Array
from cpbc.errors import CpbcError
from cpbc.results.metrics import RunSummary
from cpbc.simulation.trajectory import Trajectory

CSV_COLUMNS = (
    "controller", "controller_type", "case", "backend", "status", "end_time", "final_error",
    "settle_time", "peak_joint_rates", "rate_bounds", "peak_torques", "peak_torque_norm",
    "torque_bound", "min_margin", "min_margin_constraint", "crossed_constraints",
    "max_lyapunov_increase", "max_contacts", "saturated_steps", "safeguard_steps",
    "safeguard_infeasible", "rejected_samples", "wall_time", "steps_per_second",
)


def write_trajectory(
    path: Path,
    traj: Trajectory,
    margins: Array,
    margin_names: Sequence[str],
    lyapunov: Array,
    target: Array,
    coordinate_names: Sequence[str],
) -> None:
    """All logged signals of one run, in one .npz — uncompressed: float logs shrink by only
    about a fifth, and compressing took most of a run's writing time."""
    np.savez(
        path,
        time=traj.time,
        position=traj.position,
        velocity=traj.velocity,
        torque=traj.torque,
        joint_torque=traj.joint_torque,
        margins=margins,
        margin_names=np.array(list(margin_names), dtype=str),
        lyapunov=lyapunov,
        target=target,
        coordinate_names=np.array(list(coordinate_names), dtype=str),
        outcome=np.array(traj.outcome),
    )


def _csv_row(s: RunSummary) -> dict[str, object]:
    finite = {k: v for k, v in s.min_margins.items() if v == v}
    worst = min(finite, key=finite.__getitem__) if finite else ""
    row = {k: getattr(s, k) for k in CSV_COLUMNS if hasattr(s, k)}
    row["min_margin"] = finite.get(worst, "")
    row["min_margin_constraint"] = worst
    for k in ("peak_joint_rates", "rate_bounds", "peak_torques", "crossed_constraints"):
        row[k] = " ".join("-" if v is None else (f"{v:.6g}" if isinstance(v, float) else str(v))
                          for v in getattr(s, k))
    return row


def write_summaries(folder: Path, summaries: Sequence[RunSummary]) -> None:
    """summary.json (a list of run objects) and summary.csv (one row per run)."""
    (folder / "summary.json").write_text(
        json.dumps([s.as_dict() for s in summaries], indent=2, allow_nan=False)
    )
    with (folder / "summary.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(CSV_COLUMNS))
        writer.writeheader()
        for s in summaries:
            writer.writerow(_csv_row(s))


@contextmanager
def staged_output(out: Path) -> Iterator[Path]:
    """Write into a scratch folder next to ``out``; move it into place only on success.

    Nothing half-written is left behind: on any error the scratch folder is removed and an
    existing ``out`` is untouched. An existing ``out`` is replaced only if it is an earlier
    cpbc output (it holds a summary.json) or empty; anything else is refused.
    """
    if out.exists() and not (
        out.is_dir() and ((out / "summary.json").is_file() or not any(out.iterdir()))
    ):
        raise CpbcError(
            f"--out {out} exists and is not an earlier cpbc output (no summary.json); "
            "choose another folder"
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        yield scratch
    except BaseException:
        shutil.rmtree(scratch, ignore_errors=True)
        raise
    if out.exists():
        shutil.rmtree(out)
    scratch.rename(out)
