"""``python -m cpbc.tune {check,optimise,starts} SCENARIO``: the tuning of §4.3.3–§4.3.6 for a
Chapter 4 scenario (the integrator chain of §4.4), from the law's gains in the scenario file.

    check     every condition of §4.3 for the law's gains, with the worst-case bounds X_i (4.88)
    optimise  the constants meeting the theorem's rules (§4.3.3, with domination) or the manual
              ones (§4.3.6, without), optimising S (4.91) or the size of D; ``--relax`` adds
              the §4.3.4 search for the least factor on the limits when it is infeasible
    starts    manual tuning step 3: the scenario's cases and random starts simulated, each
              judged (converged, limit crossed, left D, …) with the rise of U (4.70)
    schedule  gain scheduling (§4.3.5), EXPERIMENTAL, NO STABILITY GUARANTEE: per region of a
              partition (bands of |ξ1| × nested boxes of the constrained states) the
              optimisation under both rules with the sups over the region only; then the
              scenario's cases under the switched law and under the single-gain manual tuning

Exit codes: 0 when it ran (and, for ``optimise``, found feasible constants; for ``schedule``,
some region meets the theorem's rules), 1 when the optimisation is infeasible (``schedule``: in
every region), 2 for bad input (the message names the field; nothing is written), 130
interrupted.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from cpbc.backstepping import ChainGains, IntegratorChainController
from cpbc.backstepping.admissible_starts import AdmissibleStarts, sample_starts, simulate_starts
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.gain_scheduling import (
    NO_GUARANTEE,
    Partition,
    RegionTuning,
    Schedule,
    SwitchedRun,
    schedule,
    simulate_switched,
    single_gain,
    switched_law,
)
from cpbc.backstepping.integrator_chain_law import local_problems, thesis_symbols, tuning_problem
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw
from cpbc.backstepping.parameter_constraints import check_parameters
from cpbc.backstepping.tuning import OBJECTIVES, RULES, TuningResult, optimise, relax
from cpbc.errors import CpbcError, ScenarioError
from cpbc.scenario.load import load_any
from cpbc.scenario.schema import ChainLawSpec, IntegratorChainSpec, SystemScenario


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m cpbc.tune", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    for name, text in (("check", "the §4.3 conditions for the law's gains"),
                       ("optimise", "constrained optimisation of the constants (§4.3.3)"),
                       ("starts", "admissible starts by simulation (§4.3.6 step 3)"),
                       ("schedule", "gain scheduling (§4.3.5), no stability guarantee")):
        s = sub.add_parser(name, help=text)
        s.add_argument("scenario", help="a Chapter 4 scenario file or shipped name")
        s.add_argument("--law", help="the law's name (default: the first)")
        s.add_argument("--json", type=Path, help="also write the result to this file")
        if name == "optimise":
            s.add_argument("--rules", choices=sorted(RULES), default="theorem")
            s.add_argument("--objective", choices=OBJECTIVES, default="thesis")
            s.add_argument("--free", nargs="+", help="the constants to vary (default: all "
                           "under the theorem's rules, those in X_i under the manual ones)")
            s.add_argument("--starts", type=int, default=4, help="starting points (default 4)")
            s.add_argument("--maxiter", type=int, default=60)
            s.add_argument("--seed", type=int, default=0)
            s.add_argument("--relax", action="store_true",
                           help="if infeasible, search the least factor on the limits (§4.3.4)")
        if name == "starts":
            s.add_argument("--count", type=int, default=50, help="random starts (default 50)")
            s.add_argument("--spread", type=float, default=50.0,
                           help="ξ1(0) uniform in ±spread (default 50)")
            s.add_argument("--duration", type=float, default=120.0)
            s.add_argument("--seed", type=int, default=0)
        if name == "schedule":
            _schedule_arguments(s)
    return p


def _schedule_arguments(s: argparse.ArgumentParser) -> None:
    s.add_argument("--bands", type=float, nargs="+", default=[0.0, 1.0, math.inf],
                   help="edges of the |ξ1| bands, from 0 (default 0 1 inf)")
    s.add_argument("--shares", type=float, nargs="+", default=[0.03, 0.3, 1.0],
                   help="nested boxes |ξ_i| ≤ q Ξ_i, inner first (default 0.03 0.3 1)")
    s.add_argument("--fixed", nargs="+", default=[], metavar="NAME",
                   help="constants kept at the scenario's values in every region (e.g. c1 k1)")
    s.add_argument("--starts", type=int, default=1, help="starting points per problem")
    s.add_argument("--maxiter", type=int, default=40)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--duration", type=float, default=None,
                   help="simulated seconds (default: the scenario's; 0: no simulation)")


def _load(args: argparse.Namespace
          ) -> tuple[SystemScenario, IntegratorChainSpec, ChainLawSpec]:
    scenario, _ = load_any(args.scenario)
    if not isinstance(scenario, SystemScenario) or not isinstance(
            scenario.system, IntegratorChainSpec):
        raise ScenarioError("system.type", "tuning (§4.3) applies to the Chapter 4 system: "
                            "type: integrator_chain")
    spec = scenario.system
    names = [law.name for law in spec.laws]
    law = next((la for la in spec.laws if la.name == (args.law or names[0])), None)
    if law is None:
        raise ScenarioError("--law", f"no law {args.law!r}; the scenario has {names}")
    return scenario, spec, law


def _gains(law: ChainLawSpec) -> ChainGains:
    return ChainGains(**law.gains.model_dump())


def _check(args: argparse.Namespace, console: Console) -> tuple[int, dict[str, object]]:
    _, spec, law = _load(args)
    chk = check_parameters(IntegratorChainController(_gains(law)).law, spec.limits)
    console.print(chk.table(thesis_symbols), markup=False)
    verdict = ("Theorem 4.12's conditions hold" if chk.theorem_holds else
               "manual-tuning conditions (§4.3.6) hold; domination fails: stability not "
               "guaranteed" if chk.holds("well-posed", "state bound") else
               "the manual-tuning conditions fail")
    console.print(verdict)
    return 0, {"verdict": verdict, "state_bounds": list(chk.worst.state_bounds),
               "failed": [c.label for c in chk.failed()]}


def _result_table(r: TuningResult, start: dict[str, float]) -> Table:
    t = Table(title=f"§4.3 tuning, {r.rules} rules, objective {r.objective}")
    for col in ("constant", "given", "found"):
        t.add_column(col)
    for k, v in r.values.items():
        t.add_row(k, f"{start[k]:.6g}", f"{v:.6g}")
    for i, a in enumerate(r.a or ()):
        t.add_row(f"a{i + 1}", "-", f"{a:.4g}")
    return t


def _optimise(args: argparse.Namespace, console: Console) -> tuple[int, dict[str, object]]:
    _, spec, law = _load(args)
    problem = tuning_problem(_gains(law), spec.limits, args.rules, args.free)
    kwargs = {"objective": args.objective, "starts": args.starts, "maxiter": args.maxiter,
              "seed": args.seed}
    r = optimise(problem, args.rules, **kwargs)
    console.print(_result_table(r, problem.values()))
    console.print(r.check.table(thesis_symbols), markup=False)
    console.print(escape(thesis_symbols(r.message())))
    doc: dict[str, object] = {
        "rules": r.rules, "objective": r.objective, "feasible": r.feasible, "values": r.values,
        "a": r.a, "utility": r.utility, "given_utility": r.start_utility,
        "state_bounds": list(r.check.worst.state_bounds), "limits": list(spec.limits),
        "failed": [c.label for c in r.failed], "message": thesis_symbols(r.message()),
        "conflicts": {c.pair: c.ratio for c in r.conflicts}, "evaluations": r.evaluations,
    }
    if r.feasible:
        gains = ", ".join(f"{k}: {v:.6g}" for k, v in r.values.items())
        console.print(f"gains for the scenario file: {{{gains}}}")
        return 0, doc
    if args.relax:
        rel = relax(problem, args.rules, **kwargs)
        console.print(rel.message())
        doc["relaxation"] = {"factor": rel.factor, "cap": rel.cap, "tried": rel.tried}
    return 1, doc


def _starts(args: argparse.Namespace, console: Console) -> tuple[int, dict[str, object]]:
    scenario, spec, law = _load(args)
    ctrl = IntegratorChainController(_gains(law))
    cases = np.array([c.state for c in scenario.cases], dtype=float)
    rand = sample_starts(tuple(spec.limits), 1, args.count, args.spread, args.seed)
    res = simulate_starts(ctrl.law, tuple(spec.limits), np.vstack([cases, rand]),
                          args.duration)
    console.print(_starts_table(res, [c.name for c in scenario.cases]))
    counts = res.counts()
    console.print(f"random starts (ξ1 in ±{args.spread:g}, ξ2..ξ4 in ±0.95 Ξ): "
                  + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return 0, {"cases": {c.name: o.verdict for c, o in zip(scenario.cases, res.outcomes,
                                                            strict=False)},
               "counts": counts, "duration": args.duration,
               "outcomes": [o.__dict__ for o in res.outcomes]}


def _starts_table(res: AdmissibleStarts, names: Sequence[str]) -> Table:
    t = Table(title=f"admissible starts over {res.duration:g} s (manual tuning, §4.3.6)")
    for col in ("start", "ξ(0)", "verdict", "peaks |ξ2|, |ξ3|, |ξ4|", "U rise"):
        t.add_column(col)
    for name, o in zip(names, res.outcomes, strict=False):
        peaks = ", ".join(f"{p:.4g}" for p in o.peaks)
        t.add_row(escape(name), ", ".join(f"{v:.4g}" for v in o.start), o.verdict, peaks,
                  f"{o.u_rise:.3g}")
    return t


def _schedule(args: argparse.Namespace, console: Console) -> tuple[int, dict[str, object]]:
    scenario, spec, law = _load(args)
    limits = tuple(float(v) for v in spec.limits)
    try:
        partition = Partition(limits, tuple(args.bands), tuple(args.shares))
    except DesignError as exc:
        raise ScenarioError(f"--{exc.parameter}", exc.reason) from exc
    for name in ("starts", "maxiter"):
        if getattr(args, name) < 1:
            raise ScenarioError(f"--{name}", "must be ≥ 1")
    unknown = [n for n in args.fixed if n not in ChainGains.names()]
    if unknown:
        raise ScenarioError("--fixed", f"unknown constants {unknown}; the constants are "
                            f"{', '.join(ChainGains.names())}")
    duration = scenario.simulation.duration if args.duration is None else args.duration
    if not duration >= 0:
        raise ScenarioError("--duration", "must be ≥ 0")
    console.print(f"[bold]{NO_GUARANTEE}[/bold]")
    gains = _gains(law)
    kw = {"starts": args.starts, "maxiter": args.maxiter, "seed": args.seed}
    single = optimise(tuning_problem(gains, limits, "manual"), "manual", **kw)
    fallback = single.values if single.feasible else gains.__dict__
    sched = schedule(local_problems(gains, limits, args.fixed), partition, dict(fallback), **kw)
    console.print(_schedule_table(sched))
    doc: dict[str, object] = {"warning": NO_GUARANTEE, "limits": list(limits),
                              "bands": list(args.bands), "shares": list(args.shares),
                              "fixed": list(args.fixed),
                              "single_gain": {"feasible": single.feasible,
                                              "values": single.values},
                              "regions": [_region_doc(r) for r in sched.regions]}
    if duration > 0:
        build = _chain_law
        runs = {"scheduled": switched_law(sched, build),
                "single-gain manual": single_gain(limits, build(dict(fallback)))}
        sims = {(c.name, label): simulate_switched(sw, c.state, duration)
                for c in scenario.cases for label, sw in runs.items()}
        console.print(_switched_table(sims, limits, duration))
        doc["simulations"] = [{"case": c, "law": lab, **r.__dict__} for (c, lab), r in
                              sims.items()]
    feasible = sum(r.theorem.feasible for r in sched.regions)
    console.print(f"{feasible} of {len(sched.regions)} regions meet the theorem's rules "
                  f"locally; {NO_GUARANTEE}")
    return (0 if sched.any_theorem_feasible else 1), doc


def _chain_law(values: dict[str, float]) -> MultipleConstraintLaw:
    return IntegratorChainController(ChainGains(**values)).law


def _region_doc(r: RegionTuning) -> dict[str, object]:
    def one(t: TuningResult) -> dict[str, object]:
        return {"feasible": t.feasible, "values": t.values, "a": t.a, "utility": t.utility,
                "state_bounds": list(t.check.worst.state_bounds),
                "failed": [c.label for c in t.failed],
                "conflicts": {c.pair: c.ratio for c in t.conflicts},
                "message": thesis_symbols(t.message())}

    reg = r.region
    return {"label": reg.label(), "xi1_band": [reg.x_low, reg.x_high],
            "box": list(reg.xi_bounds or ()), "theorem": one(r.theorem),
            "manual": one(r.manual), "used": r.used, "values": r.values,
            "coverage": list(r.coverage or ())}


def _schedule_table(sched: Schedule) -> Table:
    t = Table(title="§4.3.5 gain scheduling: local problems (sups over the region ∩ D)")
    for col in ("region", "theorem rules", "S", "failing", "manual rules", "S ", "used",
                "max |z_i|/K_i on R"):
        t.add_column(col)
    for r in sched.regions:
        th, ma = r.theorem, r.manual
        t.add_row(escape(r.region.label()), "feasible" if th.feasible else "INFEASIBLE",
                  f"{th.utility:.4g}", ", ".join(sorted({c.label for c in th.failed})),
                  "feasible" if ma.feasible else "INFEASIBLE", f"{ma.utility:.4g}", r.used,
                  ", ".join(f"{c:.3g}" for c in r.coverage or ()))
    return t


def _switched_table(sims: dict[tuple[str, str], SwitchedRun], limits: Sequence[float],
                    duration: float) -> Table:
    t = Table(title=f"switched law vs single gain, RK4 h = 0.005 s, {duration:g} s "
              "(NO STABILITY GUARANTEE)")
    for col in ("case", "law", "peaks |ξ2|, |ξ3|, |ξ4|", "limits", "settled (s)", "switches",
                "U rises at switches (max)", "left D", "crossed"):
        t.add_column(col)
    lim = ", ".join(f"{v:g}" for v in limits)
    for (case, label), r in sims.items():
        rise = max(r.u_jumps, default=0.0)
        t.add_row(escape(case), label, ", ".join(f"{p:.4g}" for p in r.peaks), lim,
                  "-" if r.settle_time is None else f"{r.settle_time:.2f}", str(r.switches),
                  f"{r.u_rises_at_switches} ({rise:.3g})", str(r.left_domain), str(r.crossed))
    return t


COMMANDS = {"check": _check, "optimise": _optimise, "starts": _starts, "schedule": _schedule}


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    console = Console(width=None if sys.stdout.isatty() else 200)
    err = Console(stderr=True, width=None if sys.stderr.isatty() else 200)
    try:
        code, doc = COMMANDS[args.command](args, console)
    except CpbcError as exc:
        err.print(f"[bold red]error:[/bold red] {escape(str(exc))}", highlight=False)
        return 2
    except KeyboardInterrupt:
        err.print("interrupted")
        return 130
    if args.json:
        args.json.write_text(json.dumps(doc, indent=2, default=float))
    return code


if __name__ == "__main__":
    sys.exit(main())
