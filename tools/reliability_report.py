"""Run the reliability campaigns and write docs/ROBUSTNESS.md.

    python -m tools.reliability_report                  # every section (about 2 h, 1 core)
    python -m tools.reliability_report --sections cost,bad_input
    python -m tools.reliability_report --render-only    # re-render from the stored data
    python -m tools.reliability_report --quick --data /tmp/r.json --out /tmp/R.md

Each finished section is merged into the data file (docs/robustness_data.json) at once, so
an interrupted run keeps what it finished and sections can be re-run one at a time.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

from tools.reliability import suite
from tools.reliability.report import render

ROOT = Path(__file__).resolve().parent.parent


def _log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def _methods(config: suite.Config) -> dict[str, str]:
    """The prose around the tables: how each campaign was run."""
    c = config
    rates = ", ".join(f"{1 / p:,.0f} Hz" for p in c.periods)
    return {
        "sampled_method": (
            f"**How.** For every scenario, {c.states} initial states ({c.arm_states} for the "
            f"URDF arms) drawn by a seeded sampler (`cpbc.reliability.sampling`, seed {c.seed}) "
            "inside the admissible set S of the scenario's constrained laws, at positions the "
            "arm can take (inside the plant's joint ranges, touching nothing, every monitored "
            "clearance positive: `campaign.physically_possible`): 40 % anywhere in a box "
            "around the target (± π, within joint limits) with velocities anywhere inside "
            "the rate or energy bounds, 60 % pushed to a boundary the law enforces — the "
            "nearest velocity margin, or the nearest configuration margin (moving down its "
            "gradient, with a velocity towards ∂S), or both — to a fraction log-uniform in "
            "[10⁻⁴, 10⁻¹] of its value. Every constrained law of the scenario runs from every "
            f"state for {c.horizon:g} s ({c.arm_horizon:g} s for the arms) at {rates}, "
            "zero-order hold, on MuJoCo's default integrator (semi-implicit Euler) at a 1 ms "
            "timestep, with and without the safeguard, no torque limit (that is section 4). "
            "A run *violates* when a margin of a constraint the law enforces is ≤ 0 at any "
            "physics step — between control instants too — or the law refused a state, or "
            "the run diverged. A run in which the arm touched something the law does not "
            "enforce (a MuJoCo contact or a joint's range stop) before its first violation is "
            "counted, and shown apart with what it touched first (an obstacle by name, "
            "`self`, or a joint stop): the UR5's BPBC bounds rates only, and its arm can hit "
            "the floor or run its elbow into the stop at ±π. Such a run breaks its rate bound "
            "at any control rate — the contact impulse does it, not the sampling.\n\n"
            "**Viability.** Some states of S cannot be kept in S by any held torque that does "
            "not speed the arm up: a state "
            "at distance d from a configuration boundary, approaching it at speed v, moves at "
            "least v·h/4 towards it within one period if its speed may not grow (a constant "
            "deceleration that reverses the motion; anything gentler goes further). The "
            "sampler therefore counts states with d < v·h/4 at 100 Hz (`safeguard.viable`) "
            "apart: they are drawn, counted, and a share of them is run separately (second "
            "table); the headline counts are over the viable ones.\n\n"
            "**The safeguard** (`cpbc/controllers/safeguard/`, on by default, "
            "`simulation.safeguard: false` turns it off) predicts the state half a period and "
            "one period ahead under the held torque with the controller's model; when a "
            "margin m would not keep e^{−κh} of its value above a cushion δ = η·(h/10 ms)·"
            "m(x_d, 0) (κ = "
            f"{c.safeguard.decay_rate:g}/s, η = {c.safeguard.cushion:g}), it blends the "
            "law's torque toward a braking torque τ_b = C ẋ + g − λ D ẋ / h (λ = 1 stops the "
            "model's motion in one period, λ = 2 reverses it; when neither meets the "
            f"condition, {c.safeguard.brake_search} golden-section steps search λ in between) "
            f"by the smallest factor it finds in {c.safeguard.backoffs} Illinois steps. "
            "*Infeasible* steps are those at which no candidate met the condition; the "
            "safeguard then takes the smallest λ that keeps every margin above its cushion; "
            "failing that, an *escape* brake that ends the period at a velocity pushing off "
            "the nearby configuration boundaries (and only stops the joints leaving theirs), "
            "if its configuration margins recover as the condition asks by the end of the "
            "period; failing that, the λ that comes closest. Besides the law's own "
            "constraints it keeps those the scenario only monitors "
            "(`simulation.safeguard_monitored`): for the UR5, the floor clearance and the "
            "URDF joint ranges, which BPBC does not enforce. The runs and steps at which it "
            "acted are counted."),
        "periods_method": (
            "The bare law (no safeguard), same integrator, at control periods of "
            + ", ".join(f"{p * 1e3:g}" for p in c.period_grid)
            + " ms: the scenario's own cases for their full duration, and "
            f"{c.period_states} sampled states ({c.arm_period_states} for the arms; those "
            "viable at the period) for the same horizon as above. The longest safe period is "
            "the longest one at which, and at every shorter one, nothing was violated. Runs "
            "in which the arm touched a physical obstacle that the law does not enforce (UR5 "
            "BPBC enforces only rate limits) are counted apart, not as failures of sampling."),
        "mismatch_method": (
            "The controller keeps the nominal Pinocchio model; the MuJoCo plant is perturbed "
            "(`robot.plant` overrides, `PlantMismatch.random`, seed "
            f"{c.seed}): every body's mass and rotational inertia scaled by independent "
            "factors uniform in [0.8, 1.2]; in the second family also unmodelled joint "
            "damping, armature and dry friction, uniform in [0, 0.05 N·m·s/rad], "
            "[0, 0.02 kg·m²], [0, 0.01 N·m] on the planar arm and [0, 0.5], [0, 0.05], "
            f"[0, 0.2] on the URDF arms. {c.mismatch_draws} plants per family "
            f"({c.arm_mismatch_draws} for the arms); every controller on every case of the "
            "scenario for its full duration, with the scenario's integrator, control period "
            "and torque limits, safeguard on (the default); the kinetic-energy laws also "
            "without it; and every constrained law once more as the scenario that declares "
            "the family's error builds it (*error declared*: `simulation.model_error` with "
            "`inertia: 0.2`, and in the second family `armature`, `damping` and `friction` at "
            "the tops of their ranges): its guard holds, at each step, the acceleration error "
            "such a plant can have at the law's acceleration (`model_error.InertiaError`), "
            "and its kinetic-energy laws keep Ω/(1 + e) of the model's energy. The rows "
            "without it take the model as exact. Violations are judged on the plant: a "
            "kinetic-energy limit with MuJoCo's perturbed mass matrix (the energy the arm "
            "really has) against the scenario's Ω, the other constraints by kinematics. "
            "Status as `judge_status` gives it (1 cm/0.005 rad/s bands; *held*: at rest short "
            "of the target while the safeguard acted on most of the last steps)."),
        "noise_method": (
            "Gaussian noise on the position and rate the controller sees "
            "(`simulation.noise`, seeded), every controller, every case, full duration, "
            "safeguard on. When a noisy sample is outside S but the arm is not, the law "
            "refuses it (ConstraintViolation); the loop counts it as a refused sample and "
            "answers with the law at the measured rate scaled back just inside S (or the held "
            "torque when a position was measured outside); if the arm itself has left S the "
            "run ends `constraint_violated` with its time. The status column is what the CLI "
            "prints; the table of the CLI adds the number of refused samples to the status. "
            f"Each constrained law also runs with the measurement error declared at "
            f"{c.noise_bound_sigmas:g} σ (`simulation.model_error.position/velocity`): its guard "
            "keeps every measured margin above what such an error can hide "
            "(`model_error.measurement_losses`), so the true margins stay positive while the "
            "noise stays inside the bound; Gaussian noise does not always, and the draws "
            "beyond it are counted (the loop's generator replayed). *No room*: the declared "
            "rate error is as large as a rate bound of the law, which leaves no state the "
            "guard can keep. Margins are read on the logged samples (every 10th control "
            "instant)."),
        "saturation_method": (
            "Symmetric joint torque limits at a fraction of the largest joint torque each "
            "controller asked for in its unlimited run (`simulation.torque_limit`), every "
            "case, full duration, with and without the safeguard (which then predicts with "
            "the clipped torque). The CLI reports the saturated steps in the status column."),
        "cost_method": (
            "Median wall time of one call of the law, and of the law wrapped in the "
            "safeguard, over 200 states along the scenario's own run (what the safeguard "
            "meets in operation, where it rarely acts) and over 200 states sampled near ∂S "
            "(where it acts often), on this project's shared 2-core machine."),
    }


def _store(path: Path, section: str, result: dict[str, object], wall: int,
           config: suite.Config) -> dict[str, object]:
    """Merge one finished section into the data file; returns the whole data.

    Sections keyed by scenario are merged scenario by scenario, so that runs of different
    ``--scenarios`` (in parallel processes too: the file is locked while it is rewritten)
    add up to one report.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        data: dict[str, object] = json.loads(path.read_text()) if path.is_file() else {}
        old = data.get(section)
        if config.scenarios and isinstance(old, dict) and section in suite.BY_SCENARIO:
            result = old | result
        data[section] = result
        wall_s = data.setdefault("wall_s", {})
        key = section if not config.scenarios else f"{section}:{','.join(config.scenarios)}"
        wall_s[key] = wall  # type: ignore[index]
        # the report's environment is its first run's; each section run since is noted
        environment = suite.environment()
        data.setdefault("environment", environment)
        data.setdefault("section_environment", {})[section] = environment  # type: ignore[index]
        data["config"] = {k: v for k, v in asdict(config).items()
                          if k not in ("safeguard", "scenarios")} | {
            "safeguard": asdict(config.safeguard)}
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(data, indent=1, default=str))
        tmp.replace(path)
    return data


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sections", default=",".join(suite.SECTIONS),
                   help=f"comma-separated, of: {', '.join(suite.SECTIONS)}")
    p.add_argument("--data", type=Path, default=ROOT / "docs" / "robustness_data.json")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "ROBUSTNESS.md")
    p.add_argument("--render-only", action="store_true")
    p.add_argument("--quick", action="store_true", help="tiny sizes, to try the script")
    p.add_argument("--scenarios", default="", help="comma-separated (default: all)")
    args = p.parse_args(argv)
    config = suite.Config()
    if args.quick:
        config = replace(config, states=6, arm_states=2, horizon=0.2, arm_horizon=0.1,
                         nonviable_runs=5, period_grid=(0.001, 0.01), period_states=3,
                         arm_period_states=1, mismatch_draws=1, arm_mismatch_draws=1,
                         saturation=(0.5,), long_duration=5.0,
                         noise_levels=(("medium", 1e-3, 1e-2),))
    if args.scenarios:
        config = replace(config, scenarios=tuple(args.scenarios.split(",")))
    data: dict[str, object] = json.loads(args.data.read_text()) if args.data.is_file() else {}
    if not args.render_only:
        unknown = set(args.sections.split(",")) - set(suite.SECTIONS)
        if unknown:
            p.error(f"unknown sections {sorted(unknown)}; choose from {list(suite.SECTIONS)}")
        for name in args.sections.split(","):
            start = time.perf_counter()
            _log(f"section {name} …")
            result = suite.SECTIONS[name](config, _log)
            wall = round(time.perf_counter() - start)
            data = _store(args.data, name, result, wall, config)
            _log(f"section {name} done in {wall} s")
    data.update(_methods(config))
    from tools.reliability.findings import findings, ke_verdict

    data["summary_text"] = findings(data)
    data["ke_verdict"] = ke_verdict(data)
    command = "python -m tools.reliability_report" + (" --quick" if args.quick else "")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(render(data, command))
    _log(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
