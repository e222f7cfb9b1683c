"""The summary paragraphs of docs/ROBUSTNESS.md, computed from the campaign data."""

from __future__ import annotations

import statistics
from collections import Counter, defaultdict
from typing import cast

Data = dict[str, object]


def _hz(p: float) -> str:
    return f"{1 / p:,.0f} Hz"


def _sampled(d: Data) -> list[str]:
    per: dict[float, list[int]] = defaultdict(lambda: [0, 0, 0, 0])
    what: dict[float, Counter[str]] = defaultdict(Counter)
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
                what[r["period"]].update(r.get("touched") or {})
            else:
                t[1] += r["violated"]
        nonviable[0] += int(sc["nonviable_drawn"])
        for r in sc["nonviable_rows"]:
            if r["safeguard"]:
                nonviable[2] += r["violated"]
            else:
                nonviable[1] += r["violated"]
    def touched(p: float, t: list[int]) -> str:
        if not t[3]:
            return ""
        which = "all" if t[3] == t[2] else f"{t[3]} of them"
        kinds = ", ".join(f"{k} {v}" for k, v in what[p].most_common())
        return (f" ({which} after touching something the law does not enforce"
                + (f" — {kinds}" if kinds else "") + f"; {t[2] - t[3]} otherwise)")

    parts = [f"{_hz(p)}: **{t[2]}** with the safeguard" + touched(p, t) + f", {t[1]} without"
             for p, t in sorted(per.items())]
    return [
        f"- **Sampled data.** Over {states} sampled-data-admissible initial states "
        f"({len(d)} scenarios, every constrained law), runs that broke a constraint: "
        + "; ".join(parts) + ". "
        f"{nonviable[0]} further draws were admissible but not viable at 100 Hz (closer to a "
        "configuration boundary than a quarter period of their approach); of those run, "
        f"{nonviable[2]} runs broke a constraint with the safeguard and {nonviable[1]} "
        "without — no held torque that keeps their speed can keep them inside "
        "(`safeguard.viable`); a harder reversal saves some of them."]


def _periods(d: Data) -> list[str]:
    def longest(trail: list[Data], key: str) -> str:
        best = None
        for r in sorted(trail, key=lambda r: r["period"]):
            if r[key]:
                break
            best = r["period"]
        return "< 1 ms" if best is None else f"{best * 1e3:g} ms"

    items = []
    for scenario, recs in d.items():
        for ctrl in [r["controller"] for r in recs if "longest_safe" in r]:
            trail = [r for r in recs if r.get("controller") == ctrl and "period" in r]
            items.append(f"{scenario}/{ctrl} {longest(trail, 'cases_violated')} / "
                         f"{longest(trail, 'states_violated')}")
    return ["- **Longest safe control period of the bare laws** (from the scenario's own "
            "cases / from sampled states near ∂S; tried 1 ms to 100 ms): "
            + "; ".join(items) + "."]


def _mismatch(d: Data) -> list[str]:
    by: dict[str, list[Data]] = defaultdict(list)
    for scenario, recs in d.items():
        if "/" in scenario:
            continue
        for r in recs:
            if (r["safeguard"] or r["type"] not in ("cpbc_ke", "bpbc_ke")) and not r.get(
                    "declared"):
                by[f"{scenario}/{r['controller']}"].append(r)
    items = []
    for key, rs in by.items():
        conv = sum(r["status"] == "converged" for r in rs)
        enf = sum(r["enforced_violation"] for r in rs)
        items.append(f"{key}: {conv}/{len(rs)} converged"
                     + (f", {enf} broke an enforced constraint" if rs[0]["enforces"] else ""))
    kinds: dict[str, int] = defaultdict(int)
    for scenario, recs in d.items():
        if "/" in scenario:
            continue
        for r in recs:
            if r["enforced_violation"] and not r.get("declared"):
                name = str(r["violated"] or r["true_min_constraint"]).split("[")[0]
                kinds[name] += 1
    broken = ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())) or "none"
    velocity_only = all(k in ("rate", "kinetic_energy", "joint_rates", "link_rates")
                        for k in kinds)
    why = (" Every enforced constraint that broke was a velocity constraint; no configuration "
           "constraint (obstacle, joint or relative-angle limit, clearance) broke. The "
           "velocity barriers work through the inertia shaping D(D + ρΠ)⁻¹: along ∂S they make "
           "the *model's* acceleration vanish, so the plant's acceleration there is the model "
           "error itself (a 20 % error in g on the Panda is several N·m), which pushes "
           "through; the configuration barriers ρ∇φ/φ grow without bound and out-push any "
           "bounded error. The safeguard predicts with the same wrong model and does not see "
           "it coming; the KE laws keep the model's energy, not the arm's (below)."
           if velocity_only and kinds else "")
    return ["- **Model mismatch, the error declared** (`simulation.model_error` as the plant's "
            "family: `inertia: 0.2`, and in the second family the added `armature`, `damping`, "
            "`friction` up to their drawn ranges; safeguard on): " + _declared_mismatch(d),
            "- **Model mismatch, the model taken as exact** (±20 % masses and inertias, with or "
            "without unmodelled friction, damping and armature; safeguard on): "
            + "; ".join(items) + ". "
            f"Enforced constraints broken, by kind (all runs, safeguard on and off): {broken}."
            + why]


def _declared_mismatch(d: Data) -> str:
    """The declared runs: what broke on the plant, what converged, what the guard held still,
    and how close the bound came to the drawn plants' true error."""
    every = [r for k, recs in d.items() if "/" not in k for r in cast(list[Data], recs)
             if r["enforces"] and r["safeguard"] and r["type"] not in PEERS]
    runs = [r for r in every if r.get("declared")]
    if not runs:
        return "not run."
    by_level: dict[str, list[Data]] = defaultdict(list)
    for r in runs:
        by_level[str(r["level"])].append(r)
    parts = []
    for level, rs in by_level.items():
        broke = [r for r in rs if r["enforced_violation"]]
        what = Counter(str(r["violated"] or r["true_min_constraint"]).split("[")[0]
                       for r in broke)
        where = Counter(f"{r['scenario']}/{r['controller']}" for r in broke)
        parts.append(
            f"{level}: **{len(broke)}** of {len(rs)} runs broke an enforced constraint on the "
            "plant" + (f" ({', '.join(f'{k} {v}' for k, v in sorted(what.items()))}: "
                       f"{', '.join(f'{k} {v}' for k, v in sorted(where.items()))})"
                       if broke else "")
            + f"; {_counts(rs)}" + _final_errors(rs, [
                r for r in every if r["level"] == level and not r.get("declared")]))
    tight = [t for k, recs in d.items() if k.endswith("/tightness")
             for t in cast(list[Data], recs)]
    tail = ""
    if tight:
        worst = max(_number(t["max_ratio"]) for t in tight)
        low = min(_number(t["median_ratio"]) for t in tight)
        high = max(_number(t["median_ratio"]) for t in tight)
        tail = (f" The bound held on every drawn plant (largest true error / bound "
                f"{worst:.2f}; the median ratio per scenario and family {low:.2f}–{high:.2f}: "
                "a worst case over independent links' errors, which random draws rarely "
                "line up).")
    return "; ".join(parts) + "." + tail + _peers_declared(d)


# laws that are safety filters of their own: the safeguard does not wrap them
# (cpbc.controllers.safeguard.guarded), so a declared error is not held for them
PEERS = ("cbf_qp",)


def _peers_declared(d: Data) -> str:
    """The peers' runs under a declared error, apart: no safeguard holds it for them."""
    runs = [r for k, recs in d.items() if "/" not in k for r in cast(list[Data], recs)
            if r.get("declared") and r["type"] in PEERS]
    if not runs:
        return ""
    broke = [r for r in runs if r["enforced_violation"]]
    names = ", ".join(sorted({f"{r['scenario']}/{r['controller']}" for r in runs}))
    return (f" The peers ({names}) are safety filters of their own, which the safeguard does "
            "not wrap, and nothing in them holds a declared error: "
            f"{len(broke)} of {len(runs)} of their runs broke an enforced constraint "
            f"({_counts(runs)}).")


def _final_errors(declared: list[Data], exact: list[Data]) -> str:
    """The median final joint error of the declared runs against the same laws taking the
    model as exact, on the planar arm and on the URDF arms apart."""
    def median(rs: list[Data]) -> str:
        return f"{statistics.median(_number(r['final_error']) for r in rs):.3g}" if rs else "–"

    def planar(r: Data) -> bool:
        return str(r["scenario"]).startswith(("thesis_", "planar_"))

    parts = []
    for name, keep in (("planar", planar), ("arms", lambda r: not planar(r))):
        mine = [r for r in declared if keep(r)]
        if mine:
            parts.append(f"{name} {median(mine)} rad "
                         f"(taken as exact: {median([r for r in exact if keep(r)])})")
    return "; median final error " + ", ".join(parts) if parts else ""


def _number(value: object) -> float:
    """A number of the stored data (JSON: int or float)."""
    return float(cast(float, value))


def _counts(rs: list[Data]) -> str:
    c = Counter(str(r["status"]) for r in rs)
    return ", ".join(f"{v} {k}" for k, v in sorted(c.items()))


def ke_verdict(data: Data) -> str:
    d = data.get("mismatch")
    if not d:
        return ""
    every = [r for k, recs in d.items() if "/" not in k for r in recs
             if r["type"] in ("cpbc_ke", "bpbc_ke")]
    ke = [r for r in every if not r.get("declared")]
    declared = [r for r in every if r.get("declared")]
    if not ke:
        return ""
    bare = [r for r in ke if not r["safeguard"]]
    over = [r for r in bare if float(r["ke_peak_over_limit"]) > 1.0]
    peak = max(float(r["ke_peak_over_limit"]) for r in bare) if bare else float("nan")
    by_scenario: dict[str, list[Data]] = defaultdict(list)
    for r in ke:
        if r["safeguard"]:
            by_scenario[f"{r['scenario']}/{r['controller']}"].append(r)
    conv = "; ".join(
        f"{k}: {sum(r['status'] == 'converged' for r in rs)} of {len(rs)} converged"
        + (f", {sum(r['status'] == 'constraint_violated' for r in rs)} ended when the "
           "model's energy reached Ω" if any(r["status"] == "constraint_violated" for r in rs)
           else "")
        for k, rs in by_scenario.items())
    return (
        "The thesis says (after Corollaries 6.11 and 7.8) that the two laws are robust to "
        "modelling errors in D, C and F because those terms do not appear in (6.67) and "
        "(7.34). That is half true. C, F and D⁻¹ indeed do not appear; but D does, in the "
        "energy bound ψ = Ω − ½ẋᵀDẋ that the law keeps positive and in L. With a wrong D the "
        "law bounds the *model's* energy, not the arm's: the arm's energy may exceed Ω by up "
        "to the largest eigenvalue of D̂⁻¹D (≈ 1.2 for ±20 % masses). Measured without the "
        f"safeguard: {len(over)} of {len(bare)} perturbed runs took the plant's true kinetic "
        f"energy over Ω (peak {peak:.3g} × Ω). With the safeguard (the default): {conv}. "
        f"Without it, {sum(r['status'] == 'constraint_violated' for r in bare)} of "
        f"{len(bare)} runs ended when the model's energy reached Ω (the law's own barrier "
        "crossed: under mismatch its invariance argument no longer holds). "
        + _ke_verdict_tail(ke) + _ke_declared(declared))


def _ke_declared(declared: list[Data]) -> str:
    """What the laws did when the scenario declared the inertia error."""
    text = (" The arm's energy is at most (1 + e) times the model's when every link's mass and "
            "inertia is within ±e (ΔD is the links' pieces of D̂ scaled by at most e), so a "
            "scenario that declares `simulation.model_error: {inertia: e}` has its laws keep "
            "Ω/(1 + e) of the model's energy")
    if not declared:
        return text + "."
    energy = [float(cast(float, r["ke_peak_over_limit"])) for r in declared]
    over, peak = sum(e > 1.0 for e in energy), max(energy)
    return (text + f": declared so, {over} of {len(declared)} perturbed runs took the plant's "
            f"true energy over Ω (peak {peak:.3g} × Ω), {_counts(declared)}.")


def _ke_verdict_tail(ke: list[Data]) -> str:
    """The verdict's sentences on what the safeguarded runs did, from the runs themselves."""
    guarded = [r for r in ke if r["safeguard"]]
    planar = [r for r in guarded if r["scenario"].startswith(("thesis_", "planar_"))]
    arms = [r for r in guarded if r not in planar]
    parts = ["Verdict: the claim holds for the structure — no C, F or D⁻¹ to get wrong"]
    if planar:
        conv = sum(r["status"] == "converged" for r in planar)
        parts.append(f"; on the planar arm {conv} of {len(planar)} perturbed runs of the two "
                     "laws converged with the safeguard")
    if arms:
        hit = sum(r["status"] == "constraint_violated" for r in arms)
        names = ", ".join(sorted({str(r["scenario"]) for r in arms}))
        parts.append(f"; on the URDF arms ({names}) {hit} of {len(arms)} ended when the "
                     "model's energy reached its bound")
    return ("".join(parts) + " — but not for the constraint: the bound holds on the model's "
            "energy only, and a wrong g (it is in both laws) pushes the arm against it.")


def _noise(d: Data) -> list[str]:
    broke: dict[str, list[str]] = defaultdict(list)
    kinds: dict[str, int] = defaultdict(int)
    refused = 0
    for scenario, recs in d.items():
        for r in recs:
            if r.get("declared"):
                continue
            refused += int(r.get("rejected_samples", 0))
            if r["status"] in ("constraint_violated", "diverged", "crashed") and r["type"] not in (
                    "pd", "pd_gravity"):
                broke[r["level"]].append(f"{scenario}/{r['controller']}/{r['case']}")
                kinds[str(r.get("violated") or r["status"]).split("[")[0]] += 1
    crashed = sum(r["status"] == "crashed" for recs in d.values() for r in recs)
    items = [f"{level}: {len(v)} runs ({', '.join(sorted(set(v)))})"
             for level, v in broke.items()]
    return [_declared_noise(d), "- **Noise, taken as exact.** Runs of constrained laws that "
            "ended `constraint_violated` or "
            "`diverged`: " + ("; ".join(items) if items else "none") + f". {refused} noisy "
            f"samples outside S were refused and answered without ending a run; {crashed} "
            "runs crashed. What broke, by constraint: "
            + (", ".join(f"{k} {v}" for k, v in sorted(kinds.items())) or "nothing") + "."
            + (" A law that rides a velocity bound keeps the *measured* rate inside it, a "
               "σ-sized error away from the true one, and the barrier cannot see the "
               "difference: with a noisy rate estimate, tighten the bound by a few σ (or "
               "filter the rate)." if kinds.keys() & {"rate", "kinetic_energy"} else "")]


def _declared_noise(d: Data) -> str:
    """The constrained laws' runs with the measurement error declared at k σ (the peers',
    which no safeguard wraps, apart)."""
    every = [r for recs in d.values() for r in cast(list[Data], recs) if r.get("declared")]
    runs = [r for r in every if r["type"] not in PEERS]
    peers = [r for r in every if r["type"] in PEERS]
    if not runs:
        return "- **Noise, the error declared**: not run."
    k = runs[0].get("bound_sigmas")
    parts = []
    for level in dict.fromkeys(str(r["level"]) for r in runs):
        rs = [r for r in runs if r["level"] == level]
        bad = [r for r in rs if r["status"] in ("constraint_violated", "diverged", "crashed")]
        room = [r for r in bad if r.get("declarable", True)]
        beyond = sum(int(_number(r.get("beyond", 0))) for r in rs)
        beyond_bad = sum(int(_number(r.get("beyond", 0))) for r in bad)
        names = ", ".join(sorted({f"{r['scenario']}/{r['controller']}/{r['case']}"
                                  for r in bad}))
        parts.append(
            f"{level}: **{len(bad)}** of {len(rs)} runs ended `constraint_violated` or "
            f"`diverged`" + (f" ({names}; {len(bad) - len(room)} of them where the declared "
                             "rate error is as large as a rate bound, which leaves no state to "
                             f"keep; {beyond_bad} noise draws beyond {k:g} σ in them)"
                             if bad else "")
            + f"; {_counts(rs)}; {beyond} draws beyond {k:g} σ in all")
    bad_peers = [r for r in peers
                 if r["status"] in ("constraint_violated", "diverged", "crashed")]
    tail = (f" The peers, which the safeguard does not wrap: {len(bad_peers)} of {len(peers)} "
            "of their runs ended `constraint_violated` or `diverged`." if peers else "")
    return (f"- **Noise, the error declared** ({k:g} σ of each level as "
            "`simulation.model_error.position/velocity`, which the guard keeps every margin "
            "above: `model_error.measurement_losses`; safeguard on): " + "; ".join(parts) + "."
            + tail)


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
