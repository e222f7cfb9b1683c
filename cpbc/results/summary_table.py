"""The printed summary of a scenario run: one table for every run's record
(cpbc.results.metrics.RunSummary), an arm's or a Part I system's, with the columns that apply
to the runs shown: an arm's rates, torques, V and safeguard; a Part I system's peaks against
its bounds."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from rich.markup import escape
from rich.table import Table

from cpbc.results.metrics import RunSummary

STATUS_STYLE = {
    "converged": "green",
    "reached": "green",
    "tracked": "green",
    "blocked": "yellow",
    "unreachable": "yellow",
    "stalled": "yellow",
    "held": "yellow",
    "not_settled": "yellow",
    "constraint_violated": "red",
    "diverged": "red",
}


def _fmt(values: Sequence[float | None], digits: int = 3) -> str:
    return ", ".join("-" if v is None else f"{v:.{digits}g}" for v in values)


WIDE = 3  # more coordinates than this: the table shows the one nearest its bound


def _rates(s: RunSummary, names: Sequence[str]) -> str:
    if len(names) > WIDE:
        return _widest_rate(s, names)
    parts = []
    for peak, bound in zip(s.peak_joint_rates, s.rate_bounds, strict=True):
        if bound is None:
            parts.append(f"{peak:.3g}")
        else:
            mark = "≤" if peak < bound else "[red]>[/red]"
            parts.append(f"{peak:.4g}{mark}{bound:.4g}")
    return ", ".join(parts)


def _widest_rate(s: RunSummary, names: Sequence[str]) -> str:
    """For a many-joint arm: the coordinate whose peak rate came nearest its bound (or the
    fastest, without bounds), and how many went past theirs."""
    bounded = [(peak / bound, i, bound) for i, (peak, bound) in
               enumerate(zip(s.peak_joint_rates, s.rate_bounds, strict=True)) if bound]
    if not bounded:
        i = max(range(len(names)), key=lambda k: s.peak_joint_rates[k])
        return f"{s.peak_joint_rates[i]:.3g} ({escape(names[i])})"
    _, i, bound = max(bounded)  # indices differ: ties never compare the bounds
    peak = s.peak_joint_rates[i]
    over = sum(r >= 1.0 for r, _, _ in bounded)
    mark = "≤" if peak < bound else "[red]>[/red]"
    tail = f"; [red]{over} of {len(bounded)} over[/red]" if over else f"; all {len(bounded)} within"
    return f"{peak:.4g}{mark}{bound:.4g} ({escape(names[i])}){tail}"


def _torques(s: RunSummary, names: Sequence[str]) -> str:
    """Peak applied torques; against the plant's limits, per joint, when it has them."""
    limits = s.torque_limits
    if limits is None:
        if len(names) <= WIDE:
            return _fmt(s.peak_torques)
        i = max(range(len(s.peak_torques)), key=lambda k: s.peak_torques[k])
        return f"{s.peak_torques[i]:.3g} ({escape(names[i])})"
    peaks = s.peak_joint_torques
    lims = [math.inf if lim is None else lim for lim in limits]  # None: this joint has none
    at = [k for k, (p, lim) in enumerate(zip(peaks, lims, strict=True)) if p >= lim]
    if len(names) <= WIDE:
        return ", ".join(f"{p:.3g}{'=' if k in at else '<'}{lim:.3g}"
                         for k, (p, lim) in enumerate(zip(peaks, lims, strict=True)))
    i = max(range(len(peaks)), key=lambda k: peaks[k] / lims[k])
    tail = f"; [yellow]{len(at)} of {len(peaks)} at the limit[/yellow]" if at else ""
    return f"{peaks[i]:.3g}{'=' if i in at else '<'}{lims[i]:.3g} (joint {i + 1}){tail}"


def _torque_rate(s: RunSummary) -> str:
    """The peak joint torque rate against the motors' rate limit, when they have one."""
    if s.torque_rate_limits is None or not s.peak_torque_rate:
        return ""
    ratios = [p / lim for p, lim in zip(s.peak_torque_rate, s.torque_rate_limits, strict=True)]
    i = max(range(len(ratios)), key=lambda k: ratios[k])
    mark = "≤" if ratios[i] <= 1.0 + 1e-9 else "[red]>[/red]"
    return (f"torque rate {s.peak_torque_rate[i]:.4g}{mark}{s.torque_rate_limits[i]:.4g} "
            f"N·m/s (joint {i + 1})")


def joint_dynamics_note(friction: Mapping[str, object] | None,
                        armature: Sequence[float] | None) -> str:
    """The friction and rotor inertia the model used, when it had any: the largest Coulomb
    and viscous coefficients, whether the law compensated the Coulomb friction, the largest
    armature ("" for none)."""
    parts = []
    friction = friction or {}
    coulomb, viscous = friction.get("coulomb"), friction.get("viscous")
    if isinstance(coulomb, list) and coulomb and max(coulomb) > 0:
        compensated = friction.get("compensation") is not None
        parts.append(f"Coulomb friction ≤ {max(coulomb):.3g} N·m"
                     f" ({'compensated' if compensated else 'not compensated'})")
    if isinstance(viscous, list) and viscous and max(viscous) > 0:
        parts.append(f"viscous ≤ {max(viscous):.3g} N·m·s/rad")
    if armature and max(armature) > 0:
        parts.append(f"armature ≤ {max(armature):.3g} kg·m²")
    return ", ".join(parts)


def _margins(s: RunSummary) -> str:
    """Per constraint type, the constraint nearest its bound, in the type's unit."""
    parts = []
    for w in s.worst_margins():
        colour = "red" if w.value <= 0 else ("green" if w.constraint in s.enforced_constraints
                                             else "")
        value = f"{w.value:.3g} {w.unit}".strip()
        value = f"[{colour}]{value}[/{colour}]" if colour else value
        parts.append(f"{w.type} {value} {escape(f'({w.constraint})')}")
    return "\n".join(parts) or "-"


def _peaks(s: RunSummary) -> str:
    """A Part I run's constrained quantities: peak |value| against the bound."""
    if s.system is None:
        return ""
    parts = []
    for name, peak in s.system.peaks.items():
        bound = s.system.bounds[name]
        mark = "<" if peak < bound else "[red]≥[/red]"
        parts.append(f"{escape(name)} {peak:.4g}{mark}{bound:.4g}")
    return "\n".join(parts)


def _others(s: RunSummary) -> str:
    """A Part I run's components that are not constrained (the wheel's speed, say)."""
    if s.system is None:
        return ""
    peaks = s.system.peaks
    return ", ".join(f"{escape(k)} {v:.4g}" for k, v in s.system.peak_abs.items()
                     if k not in peaks)


def _arm_cells(s: RunSummary, names: Sequence[str]) -> list[str]:
    """An arm's rates and torques; empty cells for a Part I run."""
    if s.system is not None:
        return ["", ""]
    bound = "" if s.torque_bound is None else f" ({s.torque_bound:.4g})"
    return [_rates(s, names),
            f"{_torques(s, names)} / {s.peak_torque_norm:.4g}{bound}"]


def summary_table(summaries: Sequence[RunSummary], coordinate_names: Sequence[str] = (),
                  contacts: bool = False) -> Table:
    """The table ``python -m cpbc.run`` prints: a row per run; ``coordinate_names`` are an
    arm's, ``contacts`` adds the arm's contact count."""
    arms = any(s.system is None for s in summaries)
    systems = any(s.system is not None for s in summaries)
    t = Table(title="cpbc summary" if arms else "cpbc summary (Part I system)",
              show_lines=False)
    wide = len(coordinate_names) > WIDE
    rates = ("peak |rate|, nearest its bound" if wide
             else f"peak |rate| ({', '.join(coordinate_names)})")
    columns = ["case", "controller", "status", "final err", "settle [s]"]
    if arms:
        columns += [rates, "peak |τ| applied (vs limit) / ‖τ‖ asked (bound)"]
    columns.append("nearest its bound, per type")
    columns += ["contacts"] if contacts else []
    columns += ["peak |·| vs bound", "other peaks |·|"] if systems else []
    columns += ["V rise", "safeguard"] if arms else []
    for col in (*columns, "steps/s"):
        t.add_column(col)
    for s in summaries:
        style = STATUS_STYLE[s.status]
        cells = [escape(s.case), escape(s.controller),
                 f"[{style}]{escape(status_text(s))}[/{style}]", _final_error(s),
                 "-" if s.settle_time is None else f"{s.settle_time:.3g}"]
        cells += _arm_cells(s, coordinate_names) if arms else []
        cells.append(_margins(s))
        if contacts:
            cells.append(f"[red]{s.max_contacts}[/red]" if s.max_contacts else "0")
        cells += [_peaks(s), _others(s)] if systems else []
        if arms:
            rise = s.max_lyapunov_increase
            cells += ["-" if math.isnan(rise) else f"{rise:.2g}", safeguard_cell(s)]
        # a reference's samples are not its steps: its rate says nothing
        cells.append(_rate_cell(s))
        t.add_row(*cells)
    return t


def _rate_cell(s: RunSummary) -> str:
    """Steps per second, and the controller's slowest call (against a control deadline)."""
    if s.steps_per_second is None:
        return "-"
    slowest = s.controller_time_max_us
    tail = "" if slowest is None else (f"\n({slowest / 1e3:.3g} ms)" if slowest >= 1e3
                                       else f"\n({slowest:.0f} µs)")
    return f"{s.steps_per_second:,.0f}{tail}"


def _final_error(s: RunSummary) -> str:
    """The joint error, or a goal run's task error (position, angle) and reach time."""
    if s.task_error_final is None:
        return f"{s.final_error:.3g}"
    e = s.task_error_final
    if s.path_lag_max is not None and s.task_error_rms is not None:  # a reference run
        rms = s.task_error_rms
        return (f"rms {rms['position'] * 1000:.3g} mm, {rms['angle']:.2g} rad; end "
                f"{e['position'] * 1000:.3g} mm; lag ≤ {s.path_lag_max:.3g} s")
    reach = "" if s.reach_time is None else f" @{s.reach_time:.3g}s"
    return f"{e['position'] * 1000:.3g} mm, {e['angle']:.2g} rad{reach}"


def status_text(s: RunSummary) -> str:
    """A run's status line: the status, what stopped it and when, and the notes."""
    at = s.end_time
    if s.system is not None and s.system.crossed_at is not None:
        at = s.system.crossed_at  # the first sample at the bound, not the run's end
    status = s.status + (f" ({s.stall_kind})" if s.stall_kind else "") + (
        f" by {s.blocked_by} @{s.blocked_at['time']:.4g}s" if s.status == "blocked"
        and s.blocked_by and s.blocked_at else "") + (
        f" @{at:.3g}s: {s.violated_constraint}" if s.violated_constraint else "")
    if s.status == "diverged":
        status += f" @{s.end_time:.3g}s"
    return status + run_notes(s) + (f"; cause: {s.cause}" if s.cause else "")


#: Above this share of steps, the safeguard, not the law, drove the run: the status says so.
SAFEGUARD_NOTE = 0.5


def run_notes(s: RunSummary) -> str:
    """What went on outside the proof: constraints crossed that the law only monitored,
    saturated torque, a safeguard that did most of the work, refused noisy measurements, a
    Part I plant's limits reached."""
    notes = []
    monitored = monitored_crossings(s)
    if monitored:
        notes.append(f"crossed monitored {monitored}")
    if s.saturated_steps:
        notes.append(f"torque saturated in {s.saturated_steps} steps")
    if s.rate_limited_steps:
        notes.append(f"torque rate clipped by the motors in {s.rate_limited_steps} steps")
    rate = _torque_rate(s)
    if rate:
        notes.append(rate)
    joints = joint_dynamics_note(s.friction, s.armature)
    if joints:
        notes.append(f"model with {joints}")
    if s.safeguard_share > SAFEGUARD_NOTE:
        notes.append(f"safeguard acted on {s.safeguard_share:.0%} of steps")
    if s.rejected_samples:
        notes.append(f"{s.rejected_samples} noisy samples outside S refused")
    if s.system is not None and s.system.limits_reached:
        notes.append(f"reached the plant's limit: {', '.join(s.system.limits_reached)}")
    return "".join(f"; {n}" for n in notes)


#: Up to this many crossed constraints are named one by one; more are counted by type.
NAMED_CROSSINGS = 3


def monitored_crossings(s: RunSummary) -> str:
    """The constraints the run crossed that its law did not enforce (it only monitored
    them): by name, or counted by type when many ("7 rate, 1 clearance"); empty when none.
    A run that ends at its target while crossing them must not read as a clean one."""
    enforced = set(s.enforced_constraints)
    crossed = [n for n in s.crossed_constraints if n not in enforced]
    if len(crossed) <= NAMED_CROSSINGS:
        return ", ".join(crossed)
    by_type: dict[str, int] = {}
    for n in crossed:
        kind = s.margin_types.get(n, "other")
        by_type[kind] = by_type.get(kind, 0) + 1
    return ", ".join(f"{k} {kind}" for kind, k in by_type.items())


def safeguard_cell(s: RunSummary) -> str:
    """Share of the control steps at which the sampled-data safeguard changed the law's
    torque."""
    if not s.safeguard_steps:
        return "-" if s.enforced_constraints else ""
    late = f", {s.safeguard_infeasible} infeasible" if s.safeguard_infeasible else ""
    late += f", {s.rescues} rescued" if s.rescues else ""
    late += f", {s.out_of_tests} out of tests" if s.out_of_tests else ""
    share = f"{s.safeguard_share:.1%}" if s.safeguard_share >= 0.001 else "<0.1%"
    return f"{share} ({s.safeguard_steps} steps{late})"
