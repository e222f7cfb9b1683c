"""Render the campaign data (docs/robustness_data.json) as docs/ROBUSTNESS.md."""

from __future__ import annotations

import statistics
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Sequence
from typing import cast

Data = dict[str, object]


def _table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        lines.append("| " + " | ".join(str(c) for c in r) + " |")
    return "\n".join(lines)


def _hz(period: float) -> str:
    return f"{1 / period:,.0f} Hz"


def _ms(period: float | None) -> str:
    return "< 1 ms" if period is None else f"{period * 1e3:g} ms"


def _g(v: object, digits: int = 3) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def _after_touch(row: Data) -> str:
    """' (75 after a touch: floor 62, joint stop elbow_joint 13)' or ''."""
    if not row["with_contact"]:
        return ""
    what = row.get("touched") or {}
    detail = ": " + ", ".join(f"{k} {v}" for k, v in sorted(what.items(),
                                                          key=lambda kv: -kv[1]))
    return f" ({row['with_contact']} after a touch{detail if what else ''})"


# -- sections ------------------------------------------------------------------------------
def _sampled(data: Data) -> tuple[str, dict[float, list[int]]]:
    totals: dict[float, list[int]] = defaultdict(lambda: [0, 0, 0, 0])
    rows = []
    for scenario, d in data.items():
        by = {(r["controller"], r["period"], r["safeguard"]): r for r in d["rows"]}
        for ctrl, period in sorted({(c, p) for c, p, _ in by}, key=lambda k: (k[0], k[1])):
            off, on = by[ctrl, period, False], by[ctrl, period, True]
            t = totals[period]
            t[0] += on["runs"]
            t[1] += off["violated"]
            t[2] += on["violated"]
            t[3] += on["with_contact"]
            share = on["acted_steps"] / max(on["steps"], 1)
            rows.append([
                scenario, ctrl, _hz(period), on["runs"],
                f"**{off['violated']}**" + _after_touch(off),
                f"**{on['violated']}**" + _after_touch(on),
                f"{on['runs_acted']} runs, {100 * share:.2g} % of steps",
                on["infeasible_steps"],
                ", ".join(f"{k} {v}" for k, v in off["constraints"].items()) or "–",
            ])
    text = _table(
        ["scenario", "law", "control", "states", "violated without safeguard",
         "violated with safeguard", "safeguard acted", "infeasible steps",
         "what broke without it"], rows)
    nonviable_rows = []
    for scenario, d in data.items():
        for r in sorted(d["nonviable_rows"], key=lambda r: (r["controller"], r["period"],
                                                            r["safeguard"])):
            if r["safeguard"]:
                off = next(x for x in d["nonviable_rows"] if x["controller"] == r["controller"]
                           and x["period"] == r["period"] and not x["safeguard"])
                nonviable_rows.append([scenario, r["controller"], _hz(r["period"]), r["runs"],
                                       off["violated"], r["violated"]])
    extra = ""
    if nonviable_rows:
        extra = "\n\n" + _table(["scenario", "law", "control", "non-viable states run",
                                  "violated without", "violated with"], nonviable_rows)
    return text + extra, totals


def _longest(trail: Sequence[Data], ok: Callable[[Data], bool]) -> float | None:
    best = None
    for r in sorted(trail, key=lambda r: r["period"]):
        if not ok(r):
            break
        best = r["period"]
    return best


def _periods(data: Data) -> str:
    rows = []
    for scenario, recs in data.items():
        longest = {r["controller"]: r["longest_safe"] for r in recs if "longest_safe" in r}
        for ctrl, best in longest.items():
            trail = [r for r in recs if r.get("controller") == ctrl and "period" in r]
            cases = _longest(trail, lambda r: not r["cases_violated"])
            states = _longest(trail, lambda r: r["states_violated"] == 0)
            first_bad = next((r for r in trail if not r["safe"]), None)
            why = "–"
            if first_bad is not None:
                parts = []
                if first_bad["cases_violated"]:
                    parts.append("scenario case " + ", ".join(first_bad["cases_violated"]))
                if first_bad["states_violated"]:
                    parts.append(f"{first_bad['states_violated']}/{first_bad['states']} "
                                 "sampled states")
                why = f"{_ms(first_bad['period'])}: " + "; ".join(parts)
            worst = trail[-1] if trail else None
            at_worst = (f"{worst['states_violated']}/{worst['states']}"
                        if worst is not None else "–")
            contact = sum(r["contact"] for r in trail)
            rows.append([scenario, ctrl, f"**{_ms(best)}**", _ms(cases), _ms(states), why,
                         at_worst, contact or "–"])
    return _table(["scenario", "law", "longest safe period (bare law)",
                   "from the scenario's cases", "from sampled states",
                   "first failing period: what failed", "sampled states violated at "
                   "the longest period tried", "runs with a physical contact (not counted)"],
                  rows)


def _status_counts(rs: Sequence[Data]) -> str:
    c = Counter(str(r["status"]) for r in rs)
    order = ["converged", "stalled", "held", "not_settled", "constraint_violated", "diverged",
             "crashed"]
    order += sorted(set(c) - set(order))
    return ", ".join(f"{c[k]} {k}" for k in order if c[k])


def _mismatch(data: Data) -> tuple[str, list[str]]:
    rows = []
    ke_notes = []
    for scenario, recs in data.items():
        if "/" in scenario:
            continue
        groups: dict[tuple, list[Data]] = defaultdict(list)
        for r in recs:
            groups[r["controller"], r["level"], r["safeguard"], bool(r.get("declared"))].append(r)
        for (ctrl, level, guarded, declared), rs in groups.items():
            true_v = sum(r["true_violation"] for r in rs)
            enf_v = sum(r["enforced_violation"] for r in rs)
            err = statistics.median(float(r["final_error"]) for r in rs)
            ke = [float(r["ke_peak_over_limit"]) for r in rs
                  if r["ke_peak_over_limit"] == r["ke_peak_over_limit"]]
            acted = sum(int(r["acted"]) for r in rs)
            rows.append([
                scenario, ctrl, level, "on" if guarded else "off",
                "yes" if declared else "no", len(rs),
                enf_v if rs[0]["enforces"] else "–", true_v, _status_counts(rs), _g(err),
                _g(max(ke)) if ke else "–", acted if guarded and rs[0]["enforces"] else "–",
            ])
            if rs[0]["type"] in ("cpbc_ke", "bpbc_ke"):
                ke_notes.append(
                    f"{scenario} {ctrl} ({level}, safeguard {'on' if guarded else 'off'}"
                    f"{', error declared' if declared else ''}): "
                    f"true energy peak {max(ke):.4g} × Ω, {enf_v}/{len(rs)} runs over the "
                    f"bound, {_status_counts(rs)}")
    return _table(["scenario", "law", "plant perturbation", "safeguard", "error declared", "runs",
                   "enforced constraints violated", "any constraint violated (plant)",
                   "status", "median final error [rad]", "peak KE / Ω (plant)",
                   "safeguard steps"], rows), ke_notes


def _tightness(data: Data) -> str:
    """The declared error's acceleration bound against the drawn plants' true error."""
    rows = []
    for key, recs in data.items():
        if not key.endswith("/tightness"):
            continue
        for r in cast(list[Data], recs):
            rows.append([key.split("/")[0], r["level"], r["states"], _g(r["max_ratio"]),
                         _g(r["median_ratio"]),
                         ", ".join(_g(v) for v in cast(list[float], r["max_error"])),
                         ", ".join(_g(v) for v in cast(list[float], r["median_bound"]))])
    if not rows:
        return ""
    return _table(["scenario", "plants drawn inside", "states", "largest true error / bound",
                   "median true error / bound", "largest true error per joint [rad/s²]",
                   "median bound per joint [rad/s²]"], rows)


def _noise(data: Data) -> str:
    rows = []
    for scenario, recs in data.items():
        groups: dict[tuple, list[Data]] = defaultdict(list)
        for r in recs:
            groups[r["controller"], r["level"], r.get("bound_sigmas")].append(r)
        for (ctrl, level, sigmas), rs in groups.items():
            rows.append([
                scenario, ctrl, f"{level} (σ {rs[0]['sigma_position']:g} rad, "
                f"{rs[0]['sigma_velocity']:g} rad/s)",
                "–" if sigmas is None else f"{sigmas:g} σ"
                + ("" if all(r.get("declarable", True) for r in rs) else " (no room)"),
                "–" if sigmas is None else sum(int(cast(int, r.get("beyond", 0))) for r in rs),
                len(rs), _status_counts(rs),
                sum(int(r.get("rejected_samples", 0)) for r in rs),
                _g(min((float(r["min_enforced_margin"]) for r in rs
                        if r.get("min_enforced_margin") == r.get("min_enforced_margin")),
                       default=None)),
            ])
    return _table(["scenario", "law", "noise", "error declared", "draws beyond it", "runs",
                   "status", "refused samples",
                   "smallest enforced margin"], rows)


def _saturation(data: Data) -> str:
    rows = []
    for scenario, recs in data.items():
        groups: dict[tuple, list[Data]] = defaultdict(list)
        for r in recs:
            groups[r["controller"], r["fraction"], r["safeguard"]].append(r)
        for (ctrl, frac, guarded), rs in groups.items():
            if not guarded and not any(r.get("acted", 0) for r in recs
                                       if r["controller"] == ctrl):
                pass
            rows.append([
                scenario, ctrl, f"{frac:g} × peak", "on" if guarded else "off", len(rs),
                _status_counts(rs), sum(int(r.get("saturated_steps", 0)) for r in rs),
                sum(int(r.get("infeasible", 0)) for r in rs) if guarded else "–",
                ", ".join(sorted({str(r["violated"]) for r in rs if r.get("violated")})) or "–",
            ])
    return _table(["scenario", "law", "torque limit", "safeguard", "runs", "status",
                   "saturated steps", "infeasible safeguard steps", "constraint broken"],
                  rows)


def _bad(data: Data) -> str:
    rows = []
    for r in data["rows"]:
        first = str(r["message"]).replace("\n", " ").replace("|", "\\|")
        first = first if len(first) < 150 else first[:147] + "…"
        rows.append([r["category"], f"`{r['name']}`", f"`{r['field']}`", r["exit_code"],
                     "yes" if r["ok"] else "**no**", first])
    return _table(["kind", "variant", "field named", "exit", "clean", "message (stderr)"],
                  rows)


def _cost(data: Data) -> str:
    rows = [[r["scenario"], r["controller"], r["states"], _ms(r["period"]),
             f"{r['bare_us']:.0f}", f"{r['guarded_us']:.0f}", f"{r['overhead_us']:.0f}",
             f"{100 * r['acted_share']:.0f} %"] for r in data["rows"]]
    return _table(["scenario", "law", "states", "period", "law [µs/call]",
                   "law + safeguard [µs/call]", "safeguard [µs/call]", "calls it acted"],
                  rows)


# -- the document --------------------------------------------------------------------------
def _rerun(data: Data) -> str:
    """The sections run since the report's environment was recorded: when and where."""
    since = cast(dict[str, dict[str, object]], data.get("section_environment", {}))
    if not since:
        return ""
    return "; since re-run: " + ", ".join(
        f"{name} on {env.get('date', '?')} at commit {env.get('commit', '?')}"
        for name, env in since.items())


def render(data: Data, command: str) -> str:
    env = data.get("environment", {})
    cfg = data.get("config", {})
    parts = [
        "# Robustness: the constraints outside the proof",
        "",
        f"*Generated by `{command}` on {env.get('date', '?')}"
        + (f" at commit {env['commit']}" if env.get("commit") else "")
        + f" (Python {env.get('python')}, "
        f"MuJoCo {env.get('mujoco')}, Pinocchio {env.get('pinocchio')})"
        + _rerun(data) + "; the figures are in `docs/robustness_data.json`. Do not edit by "
        "hand.*",
        "",
        "*Its sampled-data and torque-limit sections (1 and 4) were measured before the "
        "safeguard worked inside the actuators' torque box and kept the braking set V "
        "(2026-11-24), without torque limits: [RELIABILITY.md](RELIABILITY.md), made by "
        "`python -m cpbc.verify`, has the campaigns with the URDF torque limits that replace "
        "them. The model-mismatch and noise sections (2 and 3) were re-run on 2026-11-28 with "
        "the guard of that day (the torque box, the braking set, the rate limit where a "
        "scenario has one), the URDF torque limits the scenarios take by default, and the "
        "declared errors of `simulation.model_error` (inertia, armature, damping, friction, "
        "position, velocity); the runs that take the model and the measurement as exact are "
        "kept beside them. The long-run and cost sections were measured with the guard of "
        "2026-11-22 and have not been re-run since.*",
        "",
        "The theorems of Chapters 6–7 hold in continuous time, with a perfect model, exact "
        "measurements and unlimited torque. This report measures what is left of them with a "
        "zero-order-hold controller at 1 kHz, 500 Hz and 100 Hz on MuJoCo physics, with a "
        "plant that differs from the controller's model, with noisy measurements, with "
        "torque limits, with bad input and over long runs.",
        "",
    ]
    summary = data.get("summary_text")
    if summary:
        parts += ["## Findings", "", str(summary), ""]
    if "sampled" in data:
        text, totals = _sampled(data["sampled"])
        parts += [
            "## 1. Sampled-data safety",
            "",
            str(data.get("sampled_method", "")),
            "",
            "Totals over every scenario and constrained law (states × laws):",
            "",
            _table(["control", "runs", "violated without safeguard", "violated with safeguard",
                    "of those, with a physical contact"],
                   [[_hz(p), t[0], t[1], t[2], t[3]] for p, t in sorted(totals.items())]),
            "",
            text,
            "",
        ]
    if "periods" in data:
        parts += ["### Longest safe control period without the safeguard", "",
                  str(data.get("periods_method", "")), "", _periods(data["periods"]), ""]
    if "mismatch" in data:
        table, ke = _mismatch(data["mismatch"])
        tight = _tightness(cast(Data, data["mismatch"]))
        if tight:
            table += ("\n\n**The declared error's bound** (`model_error.InertiaError`) against "
                      "the true error of plants drawn inside it (`robustness.bound_tightness`):"
                      "\n\n" + tight)
        parts += ["## 2. Model mismatch", "", str(data.get("mismatch_method", "")), "", table,
                  "", "### The kinetic-energy laws (Corollaries 6.11, 7.8)", "",
                  str(data.get("ke_verdict", "")), "", *[f"- {k}" for k in ke], ""]
    if "noise" in data:
        parts += ["## 3. Measurement noise", "", str(data.get("noise_method", "")), "",
                  _noise(data["noise"]), ""]
    if "saturation" in data:
        parts += ["## 4. Torque saturation", "", str(data.get("saturation_method", "")), "",
                  _saturation(data["saturation"]), ""]
    if "bad_input" in data:
        bad = data["bad_input"]
        ok = sum(r["ok"] for r in bad["rows"])
        div = bad["diverged"]
        parts += [
            "## 5. Bad input", "",
            f"{len(bad['rows'])} invalid scenarios, generated from one valid scenario by "
            "`tools/reliability/bad_input.py` and run through `python -m cpbc.run`: "
            f"**{ok} of {len(bad['rows'])}** ended with exit code 2, a message on stderr that "
            "names the field, no traceback, and no output or scratch folder left behind "
            "(`tests/test_bad_input.py` runs the same list, plus 40 fuzzed values of numeric "
            "fields on every test run).", "",
            f"A run that goes numerically wrong (PD with K_P = 10⁷ at 500 Hz): exit code "
            f"{div['exit_code']}, status `{div['status']}` at t = {div['end_time']:g} s, "
            f"{'no' if not div['nan_in_summary'] else 'a'} NaN in summary.json.", "",
            _bad(bad), ""]
    if "long_run" in data:
        r = data["long_run"]
        parts += [
            "## 6. Long runs", "",
            f"{r['duration']:g} simulated seconds of `thesis_ch7` / {r['controller']} at 1 kHz "
            f"(RK4): {r['control_steps']:,} control steps in {r['wall_s']:.0f} s, status "
            f"`{r['status']}`. The log is capped at 100 000 samples (`max_log_samples`): when "
            f"full it drops every other sample and halves its rate, so it kept "
            f"{r['samples_kept']:,} samples {r['sample_spacing'] * 1e3:g} ms apart, "
            f"{r['log_bytes'] / 1e6:.1f} MB of arrays (600 001 samples would be "
            f"{600_001 * 10 * 8 / 1e6:.0f} MB). Resident memory: {r['rss_first_kib'] / 1024:.0f}"
            f" MiB after the first 2 % of the run, {r['rss_last_kib'] / 1024:.0f} MiB at the "
            f"end, peak {r['rss_max_kib'] / 1024:.0f} MiB.", ""]
    if "cost" in data:
        parts += ["## 7. What the safeguard costs", "", str(data.get("cost_method", "")), "",
                  _cost(data["cost"]), ""]
    parts += ["## Reproduce", "", "```bash", command, "```", "",
              f"Settings: `{cfg}`" if cfg else "", ""]
    return "\n".join(parts)
