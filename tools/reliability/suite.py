"""The campaigns of docs/ROBUSTNESS.md, section by section, with their settings.

Each section returns a JSON-able dict; ``tools/reliability_report.py`` stores them in
docs/robustness_data.json and ``tools.reliability.report`` renders the Markdown.
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import math
import os
import platform
import subprocess
import tempfile
import time
from collections import Counter, defaultdict
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml

from cpbc.controllers import safeguard as sg
from cpbc.controllers.safeguard import SafeguardSettings, viable
from cpbc.reliability.sampling import SampledState
from cpbc.resources import scenarios_dir
from cpbc.run import main as run_cli
from cpbc.simulation import run_mujoco
from tools.reliability import robustness as cp
from tools.reliability.bad_input import BASE, answer_all

Log = Callable[[str], None]

PLANAR = ["thesis_ch6", "thesis_ch7", "planar_cpbc_ke", "planar_bpbc_ke", "planar_recentred"]


def arm_scenarios() -> list[str]:
    """The URDF-arm scenarios shipped next to the planar ones (Panda, UR5, …)."""
    return sorted(p.stem for p in scenarios_dir().glob("*.yaml")
                  if p.stem.startswith(("panda_", "ur5_", "ur3_", "ur10_", "xarm", "z1_")))


@dataclass(frozen=True)
class Config:
    """What the campaigns run; the defaults are those of the committed report."""

    seed: int = 2007
    periods: tuple[float, ...] = (0.001, 0.002, 0.01)
    states: int = 1000
    arm_states: int = 1000
    horizon: float = 1.0
    arm_horizon: float = 0.5
    nonviable_runs: int = 100
    period_grid: tuple[float, ...] = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1)
    period_states: int = 100
    arm_period_states: int = 20
    mismatch_draws: int = 5
    arm_mismatch_draws: int = 2
    noise_levels: tuple[tuple[str, float, float], ...] = (
        ("low", 1e-4, 1e-3), ("medium", 1e-3, 1e-2), ("high", 1e-2, 5e-2))
    noise_bound_sigmas: float = 4.0  # the measurement error declared: 4 σ
    saturation: tuple[float, ...] = (0.5, 0.1)
    long_duration: float = 600.0
    safeguard: SafeguardSettings = field(default_factory=SafeguardSettings)
    scenarios: tuple[str, ...] = ()  # empty: the planar ones and every arm scenario

    def all_scenarios(self) -> list[str]:
        return list(self.scenarios) or [*PLANAR, *arm_scenarios()]

    def is_arm(self, name: str) -> bool:
        return name not in PLANAR


# -- sampled-data safety ---------------------------------------------------------------------
def _draw(setup: cp.ScenarioSetup, count: int, period: float, seed: int,
          keep_nonviable: int) -> tuple[list[SampledState], list[SampledState], int]:
    """``count`` states of S viable at ``period``; the non-viable ones met on the way."""
    sampler = cp.state_sampler(setup, seed)
    good: list[SampledState] = []
    bad: list[SampledState] = []
    rejected = 0
    while len(good) < count:
        s = sampler.draw()
        if viable(setup.monitor, s.position, s.velocity, period):
            good.append(s)
        else:
            rejected += 1
            if len(bad) < keep_nonviable:
                bad.append(s)
    return good, bad, rejected


def _aggregate(records: list[cp.Record]) -> list[dict[str, object]]:
    groups: dict[tuple, list[cp.Record]] = defaultdict(list)
    for r in records:
        groups[r["controller"], r["period"], r["safeguard"]].append(r)
    rows = []
    for (ctrl, period, guarded), rs in groups.items():
        violated = [r for r in rs if r["violated"]]
        contact = [r for r in violated if r["contacts"]]
        steps = sum(int(r["control_steps"]) for r in rs)
        rows.append({
            "controller": ctrl, "period": period, "safeguard": guarded, "runs": len(rs),
            "violated": len(violated), "with_contact": len(contact),
            "between_samples": sum(bool(r["violated_between_samples"]) for r in violated),
            "runs_acted": sum(int(r["acted"]) > 0 for r in rs),
            "acted_steps": sum(int(r["acted"]) for r in rs), "steps": steps,
            "infeasible_steps": sum(int(r["infeasible"]) for r in rs),
            "min_margin": min(float(r["min_margin"]) for r in rs),
            "kinds": dict(Counter(str(r["kind"]) for r in violated)),
            "constraints": dict(Counter(str(r["constraint"]) for r in violated)),
            "touched": dict(Counter(str(r["touched"]) for r in contact)),
        })
    return rows


def sampled(config: Config, log: Log) -> dict[str, object]:
    out: dict[str, object] = {}
    worst = max(config.periods)
    for name in config.all_scenarios():
        arm = config.is_arm(name)
        setup = cp.campaign_setup(name)
        count = config.arm_states if arm else config.states
        horizon = config.arm_horizon if arm else config.horizon
        keep = config.nonviable_runs // (5 if arm else 1)
        good, bad, rejected = _draw(setup, count, worst, config.seed, keep)
        start = time.perf_counter()
        records = cp.sampled_data_campaign(setup, name, good, config.periods, horizon,
                                           config.safeguard, log)
        nonviable = cp.sampled_data_campaign(setup, name, bad, config.periods, horizon,
                                             config.safeguard, log) if bad else []
        out[name] = {
            "states": len(good), "horizon": horizon,
            "kinds": dict(Counter(s.kind for s in good)),
            "nonviable_drawn": rejected, "nonviable_run": len(bad),
            "rows": _aggregate(records), "nonviable_rows": _aggregate(nonviable),
            "guarded_violations": [r for r in records if r["safeguard"] and r["violated"]][:20],
            "wall_s": time.perf_counter() - start,
        }
    return out


def periods(config: Config, log: Log) -> dict[str, object]:
    out: dict[str, object] = {}
    for name in config.all_scenarios():
        arm = config.is_arm(name)
        setup = cp.campaign_setup(name)
        count = config.arm_period_states if arm else config.period_states
        states = cp.sample_states(setup, count, config.seed + 1)
        out[name] = cp.longest_safe_period(
            setup, name, states, config.period_grid,
            config.arm_horizon if arm else config.horizon, log)
    return out


# -- mismatch, noise, saturation ---------------------------------------------------------------
PLANAR_LEVELS = [
    cp.MismatchLevel("mass/inertia ±20 %", mass=0.2, inertia=0.2),
    cp.MismatchLevel("±20 % + friction, damping, armature", mass=0.2, inertia=0.2,
                     damping=0.05, armature=0.02, frictionloss=0.01),
]
ARM_LEVELS = [
    cp.MismatchLevel("mass/inertia ±20 %", mass=0.2, inertia=0.2),
    cp.MismatchLevel("±20 % + friction, damping, armature", mass=0.2, inertia=0.2,
                     damping=0.5, armature=0.05, frictionloss=0.2),
]


def mismatch(config: Config, log: Log) -> dict[str, object]:
    out: dict[str, object] = {}
    for name in config.all_scenarios():
        arm = config.is_arm(name)
        setup = cp.campaign_setup(name, integrator=None)  # the scenario's own integrator

        def declared(level: cp.MismatchLevel, name: str = name) -> cp.ScenarioSetup:
            return cp.campaign_setup(name, integrator=None, model_error=level.declared())

        out[name] = cp.mismatch_campaign(
            setup, name, ARM_LEVELS if arm else PLANAR_LEVELS,
            config.arm_mismatch_draws if arm else config.mismatch_draws, config.seed, log=log,
            declared=declared)
        out[name + "/tightness"] = [cp.bound_tightness(setup, level, 5, 20, config.seed)
                                    for level in (ARM_LEVELS if arm else PLANAR_LEVELS)]
        out[name + "/levels"] = [asdict(v) for v in (ARM_LEVELS if arm else PLANAR_LEVELS)]
    return out


def noise(config: Config, log: Log) -> dict[str, object]:
    out: dict[str, object] = {}
    for name in config.all_scenarios():
        setup = cp.campaign_setup(name, integrator=None)  # the scenario's own integrator
        out[name] = cp.noise_campaign(setup, name, config.noise_levels, config.seed, log=log,
                                      declared_sigmas=config.noise_bound_sigmas)
    return out


def saturation(config: Config, log: Log) -> dict[str, object]:
    out: dict[str, object] = {}
    for name in config.all_scenarios():
        setup = cp.campaign_setup(name, integrator=None)  # the scenario's own integrator
        out[name] = cp.saturation_campaign(setup, name, config.saturation, log=log)
    return out


# -- cost, long runs, bad input --------------------------------------------------------------
def cost(config: Config, log: Log) -> dict[str, object]:
    rows = []
    for name in config.all_scenarios():
        setup = cp.campaign_setup(name)
        near = cp.sample_states(setup, 200, config.seed + 2)
        for entry in cp.constrained(setup):
            # states along the scenario's own run: what the safeguard meets in operation
            case = setup.cases[0]
            unboxed = replace(setup.loop_settings.bounds, torque=None)
            law = sg.guarded(entry.controller, unboxed, setup.safeguard, setup.also_keep)
            traj = run_mujoco(setup.make_plant(), law, setup.model.coordinates, case.position,
                              case.velocity, replace(setup.loop_settings, duration=min(
                                  5.0, setup.loop_settings.duration), log_every=25,
                                  bounds=unboxed))
            along = [SampledState(x, dx, "trajectory", 1.0)
                     for x, dx in zip(traj.position, traj.velocity, strict=True)][:200]
            for label, states in (("along the scenario's run", along),
                                  ("sampled near ∂S", near)):
                for period in (0.001, 0.01):
                    r = cp.safeguard_cost(setup, entry, states, period)
                    rows.append({"scenario": name, "states": label, "period": period, **r})
                    log(f"cost {name} {entry.name} {label} h={period}: "
                        f"{r['bare_us']:.0f} → {r['guarded_us']:.0f} µs")
    return {"rows": rows}


def long_run(config: Config, log: Log) -> dict[str, object]:
    setup = cp.campaign_setup("thesis_ch7", integrator="RK4")
    entry = next(e for e in setup.controllers if e.name == "BPBC")
    r = cp.long_run(setup, entry, config.long_duration, 100_000)
    log(f"long run: {r}")
    return r


def bad_input(config: Config, log: Log) -> dict[str, object]:
    with tempfile.TemporaryDirectory() as tmp:
        answers = answer_all(Path(tmp))
    rows = [{
        "name": a.variant.name, "category": a.variant.category, "field": a.variant.field,
        "exit_code": a.exit_code, "names_field": a.names_field, "traceback": a.traceback,
        "left_behind": a.left_behind, "ok": a.ok,
        "message": a.message.replace(tmp, "<tmp>"),
    } for a in answers]
    log(f"bad input: {sum(r['ok'] for r in rows)}/{len(rows)} answered cleanly")
    return {"rows": rows, "diverged": _diverged_run()}


def _diverged_run() -> dict[str, object]:
    """A scenario whose gains blow the simulation up: what the CLI reports."""
    data = copy.deepcopy(BASE)
    data["simulation"].update(duration=0.5, torque_limit=None, noise=None)
    data["robot"].pop("plant")
    data["controllers"] = [{"type": "pd", "name": "PD", "kp": 1e7, "kd": 1}]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "wild.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        out, err = io.StringIO(), io.StringIO()
        here = Path.cwd()
        try:  # MuJoCo writes MUJOCO_LOG.TXT into the working folder when it blows up
            os.chdir(tmp)
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = run_cli([str(path), "--out", str(Path(tmp) / "out"), "--quiet",
                                "--no-plots"])
        finally:
            os.chdir(here)
        (run,) = json.loads((Path(tmp) / "out" / "summary.json").read_text())
    return {"exit_code": code, "status": run["status"], "end_time": run["end_time"],
            "final_error": run["final_error"],
            "nan_in_summary": any(isinstance(v, float) and not math.isfinite(v)
                                  for v in run.values())}


# sections whose result is a dict keyed by scenario (merged scenario by scenario)
BY_SCENARIO = frozenset({"periods", "noise", "saturation", "mismatch", "sampled"})

SECTIONS: dict[str, Callable[[Config, Log], dict[str, object]]] = {
    "bad_input": bad_input,
    "cost": cost,
    "long_run": long_run,
    "periods": periods,
    "noise": noise,
    "saturation": saturation,
    "mismatch": mismatch,
    "sampled": sampled,
}


def environment() -> dict[str, object]:
    import mujoco
    import pinocchio

    return {"python": platform.python_version(), "mujoco": mujoco.__version__,
            "pinocchio": pinocchio.__version__, "numpy": np.__version__,
            "machine": platform.machine(), "date": time.strftime("%Y-%m-%d"),
            "commit": _commit()}


def _commit() -> str | None:
    """The git commit of the code that ran (None outside a checkout)."""
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, cwd=Path(__file__).parent, check=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None
