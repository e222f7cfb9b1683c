"""The summary paragraphs of docs/RELIABILITY.md, computed from the campaign data."""

from __future__ import annotations

import statistics
from collections import defaultdict

Data = dict[str, object]


def _hz(p: float) -> str:
    return f"{1 / p:,.0f} Hz"


def _sampled(d: Data) -> list[str]:
    per: dict[float, list[int]] = defaultdict(lambda: [0, 0, 0, 0])
    nonviable = [0, 0, 0]
    states = 0
    for sc in d.values():
        states += int(sc["states"])
        for r in sc["rows"]:
            t = per[r["period"]]
            if r["safeguard"]:
                t[0] += r["runs"]
                t[2] += r["violated"]
                t[3] += r["with_contact"]
            else:
                t[1] += r["violated"]
        nonviable[0] += int(sc["nonviable_drawn"])
        for r in sc["nonviable_rows"]:
            if r["safeguard"]:
                nonviable[2] += r["violated"]
            else:
                nonviable[1] += r["violated"]
    parts = [f"{_hz(p)}: **{t[2]}** with the safeguard"
             + (f" (all {t[3]} with a physical contact the law does not enforce)"
                if t[2] and t[2] == t[3] else "")
             + f", {t[1]} without" for p, t in sorted(per.items())]
    return [
        f"- **Sampled data.** Over {states} sampled-data-admissible initial states "
        f"({len(d)} scenarios, every constrained law), runs that broke a constraint: "
        + "; ".join(parts) + ". "
        f"{nonviable[0]} further draws were admissible but not viable at 100 Hz (closer to a "
        "configuration boundary than a quarter period of their approach); of those run, "
        f"{nonviable[2]} runs broke a constraint with the safeguard and {nonviable[1]} "
        "without — no held torque can save them."]


def _periods(d: Data) -> list[str]:
    items = []
    for scenario, recs in d.items():
        for r in recs:
            if "longest_safe" in r:
                v = r["longest_safe"]
                items.append(f"{scenario}/{r['controller']}: "
                             + ("none (fails at 1 ms)" if v is None else f"{v * 1e3:g} ms"))
    return ["- **Longest safe control period of the bare laws** (scenario cases and sampled "
            "states): " + "; ".join(items) + "."]


def _mismatch(d: Data) -> list[str]:
    by: dict[str, list[Data]] = defaultdict(list)
    for scenario, recs in d.items():
        if scenario.endswith("/levels"):
            continue
        for r in recs:
            if r["safeguard"] or r["type"] not in ("cpbc_ke", "bpbc_ke"):
                by[f"{scenario}/{r['controller']}"].append(r)
    items = []
    for key, rs in by.items():
        conv = sum(r["status"] == "converged" for r in rs)
        enf = sum(r["enforced_violation"] for r in rs)
        items.append(f"{key}: {conv}/{len(rs)} converged"
                     + (f", {enf} broke an enforced constraint" if rs[0]["enforces"] else ""))
    return ["- **Model mismatch** (±20 % masses and inertias, with or without unmodelled "
            "friction, damping and armature; safeguard on): " + "; ".join(items) + "."]


def ke_verdict(data: Data) -> str:
    d = data.get("mismatch")
    if not d:
        return ""
    ke = [r for k, recs in d.items() if not k.endswith("/levels") for r in recs
          if r["type"] in ("cpbc_ke", "bpbc_ke")]
    if not ke:
        return ""
    others = [r for k, recs in d.items() if not k.endswith("/levels") for r in recs
              if r["type"] not in ("cpbc_ke", "bpbc_ke", "pd", "pd_gravity")]
    bare = [r for r in ke if not r["safeguard"]]
    over = [r for r in bare if r["enforced_violation"]]
    peak = max(float(r["ke_peak_over_limit"]) for r in bare) if bare else float("nan")
    conv = sum(r["status"] == "converged" for r in ke)
    conv_other = sum(r["status"] == "converged" for r in others)
    enf_other = sum(r["enforced_violation"] for r in others)
    return (
        "The thesis says (after Corollaries 6.11 and 7.8) that the two laws are robust to "
        "modelling errors in D, C and F because those terms do not appear in (6.67) and "
        "(7.34). That is half true. C and F indeed do not appear, and neither does D⁻¹; but "
        "D does, twice: in the energy bound ψ = Ω − ½ẋᵀDẋ that the law keeps positive, and in "
        "L. With a wrong D the law keeps the *model's* energy below Ω, not the arm's: the "
        "true energy may exceed Ω by up to the largest eigenvalue of D̂⁻¹D (≈ 1.2 for ±20 % "
        f"masses). Measured without the safeguard: {len(over)} of {len(bare)} runs of the "
        f"KE laws took the plant's true kinetic energy over Ω (peak {peak:.3g} × Ω). "
        f"Convergence: {conv} of {len(ke)} KE-law runs converged, against {conv_other} of "
        f"{len(others)} for the other constrained laws (which use D, C and D⁻¹, and broke an "
        f"enforced constraint in {enf_other} runs). Verdict: the structure claim holds (no C, "
        "no F, no D⁻¹, and no convergence loss from errors in them); the constraint claim "
        "holds only for the model's energy — to bound the arm's energy under a ±e error in "
        "D, set Ω to (1 − e) times the real bound.")


def _noise(d: Data) -> list[str]:
    broke: dict[str, list[str]] = defaultdict(list)
    refused = 0
    for scenario, recs in d.items():
        for r in recs:
            refused += int(r.get("rejected_samples", 0))
            if r["status"] in ("constraint_violated", "diverged", "crashed") and r["type"] not in (
                    "pd", "pd_gravity"):
                broke[r["level"]].append(f"{scenario}/{r['controller']}/{r['case']}")
    crashed = sum(r["status"] == "crashed" for recs in d.values() for r in recs)
    items = [f"{level}: {len(v)} runs ({', '.join(sorted(set(v)))})"
             for level, v in broke.items()]
    return ["- **Noise.** Runs of constrained laws that ended `constraint_violated` or "
            "`diverged`: " + ("; ".join(items) if items else "none") + f". {refused} noisy "
            f"samples outside S were refused and answered without ending a run; {crashed} "
            "runs crashed."]


def _saturation(d: Data) -> list[str]:
    on = defaultdict(int)
    off = defaultdict(int)
    runs = defaultdict(int)
    for recs in d.values():
        for r in recs:
            if r["type"] in ("pd", "pd_gravity"):
                continue
            key = r["fraction"]
            bad = r["status"] in ("constraint_violated", "diverged", "crashed")
            if r["safeguard"]:
                on[key] += bad
                runs[key] += 1
            else:
                off[key] += bad
    items = [f"limit {f:g} × peak: {off[f]} of {runs[f]} runs broke a constraint without the "
             f"safeguard, {on[f]} with it" for f in sorted(runs, reverse=True)]
    return ["- **Torque limits.** Constrained laws: " + "; ".join(items)
            + ". Every run ends with a status; the CLI names the saturated steps."]


def _cost(d: Data) -> list[str]:
    along = [r["overhead_us"] for r in d["rows"] if r["states"].startswith("along")]
    near = [r["overhead_us"] for r in d["rows"] if not r["states"].startswith("along")]
    if not along:
        return []
    return [f"- **Safeguard cost**: median {statistics.median(along):.0f} µs per call along "
            f"the scenarios' runs (range {min(along):.0f}–{max(along):.0f}), median "
            f"{statistics.median(near):.0f} µs near ∂S, where it acts and back-steps."]


def findings(data: Data) -> str:
    lines: list[str] = []
    if "sampled" in data:
        lines += _sampled(data["sampled"])
    if "periods" in data:
        lines += _periods(data["periods"])
    if "mismatch" in data:
        lines += _mismatch(data["mismatch"])
    if "noise" in data:
        lines += _noise(data["noise"])
    if "saturation" in data:
        lines += _saturation(data["saturation"])
    if "bad_input" in data:
        rows = data["bad_input"]["rows"]
        lines.append(f"- **Bad input**: {sum(r['ok'] for r in rows)} of {len(rows)} invalid "
                     "scenarios exit with code 2, name their field, print no traceback and "
                     "write nothing.")
    if "long_run" in data:
        r = data["long_run"]
        lines.append(f"- **Long run**: {r['duration']:g} s at 1 kHz kept {r['samples_kept']:,} "
                     f"log samples ({r['log_bytes'] / 1e6:.1f} MB); resident memory "
                     f"{r['rss_first_kib'] / 1024:.0f} → {r['rss_last_kib'] / 1024:.0f} MiB.")
    if "cost" in data:
        lines += _cost(data["cost"])
    return "\n".join(lines)
