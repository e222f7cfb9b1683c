"""Files of a scenario run: summary.csv and summary.json (one record per run, an arm's or a
Part I system's: cpbc.results.metrics.RunSummary), and the staging of the run folder (the
logs: cpbc.results.hdf5_log)."""

from __future__ import annotations

import contextlib
import csv
import errno
import json
import math
import secrets
import shutil
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from cpbc.errors import CpbcError
from cpbc.results.metrics import RunSummary
from cpbc.results.saved_run import FIGURES

CSV_COLUMNS = (
    "controller", "controller_type", "case", "backend", "status", "end_time", "final_error",
    "settle_time", "peak_joint_rates", "rate_bounds", "peak_torques", "peak_commanded_torques",
    "torque_limits", "peak_torque_norm", "torque_bound", "worst_margins",
    "crossed_constraints", "max_lyapunov_increase", "max_contacts", "saturated_steps",
    "safeguard_steps", "safeguard_share", "safeguard_infeasible", "rescues", "out_of_tests",
    "rejected_samples",
    "wall_time", "steps_per_second", "cause", "stall_kind", "task_error_final",
    "task_error_rms", "task_error_max", "reach_time", "tracking_error_applied_rms",
    "path_lag_final", "path_lag_max", "governor", "blocked_by", "blocked_at",
    "peak_torque_rate", "torque_rate_limits", "rate_limited_steps", "controller_time_max_us",
    "controller_time_mean_us", "violated_constraint",
)
#: Lists the files a run wrote into its folder, one relative path a line; a later run into
#: the same folder replaces these and nothing else.
MANIFEST = ".cpbc-files"
#: What earlier versions wrote (folders without a manifest), as glob patterns.
_LEGACY = ("summary.json", "summary.csv", "scene.mjb", "scene.mjb.gz", "scene.json", "view.html",
           "*/view.html", "*/*/trajectory.npz", "trajectories.h5",
           *(f"*/{name}.png" for name in FIGURES))


def _csv_row(s: RunSummary) -> dict[str, object]:
    """A run's row; a number that does not apply (a Part I run's V: NaN) is left empty."""
    row = {k: getattr(s, k) for k in CSV_COLUMNS if hasattr(s, k)}
    row = {k: "" if isinstance(v, float) and not math.isfinite(v) else v
           for k, v in row.items()}
    row["worst_margins"] = "; ".join(
        f"{w.type} {w.value:.6g} {w.unit} ({w.constraint})".replace("  ", " ")
        for w in s.worst_margins())
    row["safeguard_share"] = f"{s.safeguard_share:.6g}"
    for k in ("task_error_final", "task_error_rms", "task_error_max"):
        pair = getattr(s, k)
        row[k] = "" if pair is None else f"{pair['position']:.6g} m {pair['angle']:.6g} rad"
    for k in ("governor", "blocked_at"):
        items = getattr(s, k)
        row[k] = "" if items is None else " ".join(f"{n}={v:.6g}" for n, v in items.items())
    for k in ("peak_joint_rates", "rate_bounds", "peak_torques", "peak_commanded_torques",
              "torque_limits", "crossed_constraints", "peak_torque_rate",
              "torque_rate_limits"):
        row[k] = " ".join("-" if v is None else (f"{v:.6g}" if isinstance(v, float) else str(v))
                          for v in getattr(s, k) or [])
    return row


def write_summaries(folder: Path, summaries: Sequence[RunSummary]) -> None:
    """summary.json (a list of run objects) and summary.csv (one row per run; a Part I run
    fills the columns that apply to it, its own quantities are in summary.json's
    ``system``)."""
    (folder / "summary.json").write_text(
        json.dumps([s.as_dict() for s in summaries], indent=2, allow_nan=False)
    )
    with (folder / "summary.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(CSV_COLUMNS))
        writer.writeheader()
        for s in summaries:
            writer.writerow(_csv_row(s))


def earlier_output(out: Path) -> set[Path]:
    """The files an earlier run wrote into ``out`` (relative paths); empty for a new or
    empty folder.

    Raises:
        CpbcError: ``out`` is a file, or a folder holding files but no earlier cpbc output.
    """
    if not out.exists():
        return set()
    if not out.is_dir():
        raise CpbcError(f"--out {out} is a file; choose a folder")
    if (out / MANIFEST).is_file():
        listed = (out / MANIFEST).read_text(encoding="utf-8").splitlines()
        return {Path(p) for p in listed if p and not Path(p).is_absolute() and ".." not in p}
    if (out / "summary.json").is_file():
        return {p.relative_to(out) for pattern in _LEGACY for p in out.glob(pattern)
                if p.is_file()}
    if any(out.iterdir()):
        raise CpbcError(
            f"--out {out} exists and is not an earlier cpbc output (no summary.json); "
            "choose another folder"
        )
    return set()


def _place(scratch: Path, out: Path, earlier: set[Path]) -> None:
    """Replace the earlier run's files in ``out`` by the scratch folder's; every other file
    in ``out`` (the user's) stays. Refuses, before touching anything, to overwrite one."""
    new = sorted(p.relative_to(scratch) for p in scratch.rglob("*") if p.is_file())
    taken = [p for p in new if p not in earlier and (out / p).exists()]
    if taken:
        raise CpbcError(
            f"{out / taken[0]} was not written by cpbc, and this run would overwrite it; "
            "move it out of the folder or choose another --out"
        )
    for p in sorted(earlier, key=lambda q: -len(q.parts)):
        target = out / p
        if target.is_file():
            target.unlink()
        for parent in target.parents:  # folders the earlier run made, once empty
            if parent == out or not parent.is_relative_to(out):
                break
            if parent.is_dir() and not any(parent.iterdir()):
                parent.rmdir()
    for p in new:
        (out / p).parent.mkdir(parents=True, exist_ok=True)
        (scratch / p).replace(out / p)
    (out / MANIFEST).write_text("".join(f"{p.as_posix()}\n" for p in new), encoding="utf-8")


def _unwritable(out: Path, exc: OSError) -> CpbcError:
    """An output folder the system refused (read-only, missing, name too long, full disk),
    as a one-line error naming --out."""
    return CpbcError(f"--out {out}: cannot write the results there ({exc.strerror or exc}); "
                     "choose a writable folder with --out")


def _missing_folders(out: Path) -> list[Path]:
    """The folders of ``out``'s path that do not exist yet, deepest first (a run that
    fails removes those it made)."""
    missing = []
    for folder in out.absolute().parents:
        try:
            if folder.exists():
                break
        except OSError:  # a name too long: nothing of it was made
            break
        missing.append(folder)
    return missing


def _scratch_folder(out: Path) -> Path:
    """An empty folder next to ``out`` with a new name, made as any folder is: its mode
    from the umask (tempfile.mkdtemp's would be private, 0700, and so would the run folder
    it becomes)."""
    for _ in range(100):
        scratch = out.parent / f".{out.name[:64]}.{secrets.token_hex(4)}"
        try:
            scratch.mkdir()
        except FileExistsError:
            continue
        return scratch
    raise FileExistsError(errno.EEXIST, "no free scratch folder name", str(out.parent))


def _remove_made(folders: Sequence[Path]) -> None:
    for folder in folders:  # deepest first; only if still empty
        with contextlib.suppress(OSError):
            folder.rmdir()


@contextmanager
def staged_output(out: Path) -> Iterator[Path]:
    """Write into a scratch folder next to ``out``; move it into place only on success.

    Nothing half-written is left behind: on any error the scratch folder (and the missing
    parent folders of ``out`` it made) are removed and an existing ``out`` is untouched.
    Into an earlier cpbc output, the earlier run's files (listed in its ``.cpbc-files``) are
    replaced and files the user added are kept; a run that would overwrite one of those is
    refused. A folder holding files but no earlier cpbc output is refused, and so is one the
    system will not let this process write (a CpbcError naming --out).
    """
    made = _missing_folders(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        earlier = earlier_output(out)  # after: a name too long shows only in a folder
        scratch = _scratch_folder(out)
    except (OSError, CpbcError) as exc:
        _remove_made(made)
        if isinstance(exc, OSError):
            raise _unwritable(out, exc) from None
        raise
    try:
        yield scratch
        _finish(scratch, out, earlier)
    except OSError as exc:
        raise _unwritable(out, exc) from None
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
        if not out.exists():
            _remove_made(made)


def _finish(scratch: Path, out: Path, earlier: set[Path]) -> None:
    if not out.exists():
        (scratch / MANIFEST).write_text("".join(
            f"{p.relative_to(scratch).as_posix()}\n"
            for p in sorted(scratch.rglob("*")) if p.is_file()), encoding="utf-8")
        scratch.rename(out)
        return
    _place(scratch, out, earlier)
