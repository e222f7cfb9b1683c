"""The robustness campaigns of docs/ROBUSTNESS.md (tools for this repository, not the library):
the sampled-data sweep with and without the safeguard, the longest safe period of the bare
laws, model mismatch, measurement noise, torque saturation, the safeguard's cost and a long
run. Each is seeded and returns plain records (dicts of numbers and strings) that
``tools.reliability.report`` renders. Runs are the library's checked runs
(:mod:`cpbc.reliability.campaign`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.controllers.safeguard import Safeguard, SafeguardSettings, viable
from cpbc.controllers.safeguard.model_error import DeclaredError, measurement_losses
from cpbc.errors import ConstraintViolation
from cpbc.model.input_bounds import InputBounds
from cpbc.reliability.campaign import (
    RecordingPlant,
    campaign_setup,
    checked_run,
    constrained,
    guarded_run,
    sample_states,
    state_sampler,
)
from cpbc.reliability.sampling import SampledState
from cpbc.results.metrics import judge_status
from cpbc.scenario import ScenarioSetup
from cpbc.scenario.build import ControllerEntry
from cpbc.simulation import LoopSettings, MujocoPlant
from cpbc.simulation.disturbances import MeasurementNoise, PlantMismatch

Record = dict[str, object]
Log = Callable[[str], None]

# the building blocks the suite reaches through this module
__all__ = ["ScenarioSetup", "campaign_setup", "constrained", "sample_states", "state_sampler"]


def _quiet(_: str) -> None:
    pass


def sampled_data_campaign(
    setup: ScenarioSetup,
    scenario: str,
    states: Sequence[SampledState],
    periods: Iterable[float],
    horizon: float,
    safeguard: SafeguardSettings,
    log: Log = _quiet,
) -> list[Record]:
    """Every constrained law of the scenario from every state, at every period, with and
    without the safeguard. One record per (controller, period, safeguard, state)."""
    base = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    out: list[Record] = []
    for entry in constrained(setup):
        for period in periods:
            for guarded in (False, True):
                settings = replace(
                    setup.loop_settings, duration=horizon,
                    bounds=replace(setup.loop_settings.bounds, period=period, torque=None),
                    noise=None,
                )
                start = time.perf_counter()
                bad = 0
                for i, s in enumerate(states):
                    check = checked_run(base, setup, entry, s.position, s.velocity, settings,
                                        safeguard=safeguard if guarded else None)
                    traj = check.trajectory
                    bad += check.violated
                    out.append({
                        "scenario": scenario, "controller": entry.name,
                        "type": entry.controller.type_name, "period": period,
                        "safeguard": guarded, "state": i, "kind": s.kind,
                        "closeness": s.closeness,
                        "viable": viable(entry.controller.constraints, s.position, s.velocity,
                                         period),
                        "outcome": traj.outcome,
                        "violated": check.violated, "at_samples": check.at_samples,
                        "violated_between_samples": check.violated and not check.at_samples,
                        "end_time": traj.end_time, "constraint": check.constraint,
                        "min_margin": check.min_margin, "acted": traj.safeguard_steps,
                        "infeasible": traj.safeguard_infeasible,
                        "out_of_tests": traj.out_of_tests,
                        "control_steps": traj.control_steps,
                        # touched something the law does not know of (a contact or a joint
                        # stop) before any violation
                        "contacts": int(check.touched), "touched": check.touch,
                    })
                log(f"{scenario} {entry.name} h={period * 1e3:g} ms "
                    f"safeguard={'on' if guarded else 'off'}: {bad}/{len(states)} violated "
                    f"({time.perf_counter() - start:.0f} s)")
    return out


def longest_safe_period(
    setup: ScenarioSetup,
    scenario: str,
    states: Sequence[SampledState],
    periods: Sequence[float],
    horizon: float,
    log: Log = _quiet,
) -> list[Record]:
    """For each constrained law without the safeguard: violations at each period, from the
    scenario's own cases (full duration) and from those of ``states`` that are viable at that
    period (``horizon`` seconds each). Runs in which the arm touched a physical obstacle that
    the law does not enforce are counted apart (``contact``): that is not a sampling effect.
    The longest safe period is the longest one such that it and every shorter one saw no
    violation."""
    base = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    out: list[Record] = []
    for entry in constrained(setup):
        cons = entry.controller.constraints
        safe_so_far, longest = True, None
        for period in sorted(periods):
            settings = replace(
                setup.loop_settings, noise=None, log_every=1,
                bounds=replace(setup.loop_settings.bounds, period=period, torque=None),
            )
            case_bad = []
            for case in setup.cases:
                check = checked_run(base, setup, entry, case.position, case.velocity, settings)
                if check.violated and not check.touched:
                    case_bad.append(case.name)
            short = replace(settings, duration=horizon)
            usable = [s for s in states if viable(cons, s.position, s.velocity, period)]
            state_bad = contact = 0
            for s in usable:
                check = checked_run(base, setup, entry, s.position, s.velocity, short)
                if check.violated and check.touched:
                    contact += 1
                elif check.violated:
                    state_bad += 1
            ok = not case_bad and state_bad == 0
            safe_so_far = safe_so_far and ok
            if safe_so_far:
                longest = period
            out.append({
                "scenario": scenario, "controller": entry.name, "period": period,
                "cases_violated": case_bad, "states_violated": state_bad,
                "states": len(usable), "contact": contact, "safe": ok,
            })
            log(f"{scenario} {entry.name} h={period * 1e3:g} ms: cases violated {case_bad}, "
                f"states violated {state_bad}/{len(usable)} (+{contact} with contact)")
        out.append({"scenario": scenario, "controller": entry.name, "longest_safe": longest})
    return out


# -- model mismatch --------------------------------------------------------------------------
def true_kinetic_energy(plant: MujocoPlant, qs: Array, dqs: Array) -> Array:
    """½ q̇ᵀ M(q) q̇ of the MuJoCo plant (its own, mismatched, mass matrix) at each row."""
    data = mujoco.MjData(plant.model)
    m = np.zeros((plant.n, plant.n))
    out = np.empty(len(qs))
    for i, (q, dq) in enumerate(zip(qs, dqs, strict=True)):
        data.qpos[:] = q
        mujoco.mj_forward(plant.model, data)
        mujoco.mj_fullM(plant.model, data, m)
        out[i] = 0.5 * dq @ m @ dq
    return out


@dataclass(frozen=True)
class MismatchLevel:
    """One family of plant perturbations, drawn per run (see PlantMismatch.random)."""

    name: str
    mass: float = 0.0
    inertia: float = 0.0
    damping: float = 0.0
    armature: float = 0.0
    frictionloss: float = 0.0

    def declared(self) -> dict[str, object]:
        """The ``simulation.model_error`` a scenario declares for plants of this family:
        every link's mass and inertia within ±max(mass, inertia), and up to the rotor
        inertia, damping and dry friction the family may add."""
        out: dict[str, object] = {"inertia": max(self.mass, self.inertia)}
        for name, value in (("armature", self.armature), ("damping", self.damping),
                            ("friction", self.frictionloss)):
            if value:
                out[name] = value
        return out


def mismatch_campaign(
    setup: ScenarioSetup,
    scenario: str,
    levels: Sequence[MismatchLevel],
    draws: int,
    seed: int,
    unguarded_types: Sequence[str] = ("cpbc_ke", "bpbc_ke"),
    log_every: int = 10,
    log: Log = _quiet,
    declared: Callable[[MismatchLevel], ScenarioSetup] | None = None,
) -> list[Record]:
    """Every controller on every case of the scenario (full duration, the scenario's control
    period), on ``draws`` seeded perturbed plants per level, with the default safeguard; the
    laws of ``unguarded_types`` also without it; with ``declared``, each constrained law
    also as the scenario that declares the level's error builds it (``declared(level)``,
    its ``simulation.model_error``: :meth:`MismatchLevel.declared`). Violations are judged
    on the true plant: kinetic-energy limits with MuJoCo's (perturbed) mass matrix against
    the scenario's Ω, the rest by kinematics."""
    rng = np.random.default_rng(seed)
    nominal = setup.make_plant()
    nbody, ndof = nominal.model.nbody - 1, nominal.model.nv
    out: list[Record] = []
    for level in levels:
        knows = None if declared is None else declared(level)
        for d in range(draws):
            mismatch = PlantMismatch.random(
                rng, nbody, ndof, level.mass, level.inertia, level.damping, level.armature,
                level.frictionloss,
            )
            plant = setup.make_plant()
            mismatch.apply(plant.model)
            for entry in setup.controllers:
                variants = [(setup, entry, True)]
                if entry.controller.type_name in unguarded_types:
                    variants.append((setup, entry, False))
                if knows is not None and not entry.controller.constraints.empty:
                    variants.append((knows, next(
                        e for e in knows.controllers if e.name == entry.name), True))
                for run_setup, run_entry, guarded in variants:
                    settings = replace(run_setup.loop_settings, log_every=log_every,
                                       noise=None)
                    for case in run_setup.cases:
                        out.append(_mismatch_run(
                            plant, run_setup, run_entry, case.name, case.position,
                            case.velocity, settings, scenario, level.name, d, guarded,
                            setup.monitor,
                        ))
            log(f"{scenario} mismatch {level.name} draw {d + 1}/{draws} done")
    return out


def bound_tightness(setup: ScenarioSetup, level: MismatchLevel, plants: int, states: int,
                    seed: int) -> Record:
    """How close the declared error's acceleration bound (model_error.InertiaError) comes to
    the true error: plants drawn inside the level (its dry friction left out: MuJoCo's is a
    constraint force, and the bound's friction term is F through |D̂⁻¹| alone), states
    within ±0.5 rad of the target at rates within ±1 rad/s, torques giving the model an
    acceleration within ±20 rad/s² per joint; the plant's acceleration from MuJoCo with the
    same torque. States where MuJoCo adds a constraint force (a contact, a joint stop) are
    skipped. The bound must hold at every one: ``max_ratio`` ≤ 1."""
    rng = np.random.default_rng(seed)
    model = setup.model
    def joint(value: float) -> Array | None:
        return np.full(model.n, value) if value else None

    declared = DeclaredError(max(level.mass, level.inertia), joint(level.armature),
                             joint(level.damping))
    bound = declared.acceleration_bound(model)
    assert bound is not None
    t_mat, t_inv = model.coordinates.matrix, model.coordinates.inverse
    ratios, errors, bounds = [], [], []
    for _ in range(plants):
        plant = setup.make_plant()
        m = plant.model
        PlantMismatch.random(rng, m.nbody - 1, m.nv, level.mass, level.inertia, level.damping,
                             level.armature).apply(m)
        data = mujoco.MjData(m)
        for _ in range(states):
            x = setup.target + rng.uniform(-0.5, 0.5, model.n)
            dx = rng.uniform(-1.0, 1.0, model.n)
            state = model.state(x, dx)
            bias = state.coriolis_force + state.gravity + state.dissipation
            accel = rng.uniform(-20.0, 20.0, model.n)
            data.qpos[:], data.qvel[:] = t_inv @ x, t_inv @ dx
            data.qfrc_applied[:] = t_mat.T @ (bias + state.inertia @ accel)
            mujoco.mj_forward(m, data)
            if data.nefc:
                continue
            error = np.abs(t_mat @ data.qacc - accel)
            b = bound.bound(state, accel)
            ratios.append(error / b)
            errors.append(error)
            bounds.append(b)
    r = np.array(ratios)
    return {"level": level.name, "states": len(r), "max_ratio": float(r.max()),
            "median_ratio": float(np.median(r)), "max_error": np.max(errors, axis=0).tolist(),
            "median_bound": np.median(bounds, axis=0).tolist()}


def _mismatch_run(
    plant: MujocoPlant, setup: ScenarioSetup, entry: ControllerEntry, case: str,
    x0: Array, dx0: Array, settings: LoopSettings, scenario: str, level: str, draw: int,
    guarded: bool, monitor: ConstraintSet,
) -> Record:
    """One run on the perturbed plant, judged against ``monitor`` (the scenario's own
    constraints, its Ω, whatever the law keeps)."""
    coords = setup.model.coordinates
    safeguard = (setup.safeguard or SafeguardSettings()) if guarded else None
    traj = guarded_run(plant, setup, entry, x0, dx0, settings, safeguard)
    status, settle = judge_status(traj, entry.controller.target, setup.criteria)
    xs, dxs = traj.position, traj.velocity
    parts: list[tuple[tuple[str, ...], Array]] = [
        (c.names, c.values_along(xs)) for c in monitor.configuration
    ]
    ke_excess = math.nan
    for v in monitor.velocity:
        if isinstance(v, KineticEnergyLimit):  # the plant's energy, not the model's
            ke = true_kinetic_energy(plant, xs @ coords.inverse.T, dxs @ coords.inverse.T)
            parts.append((v.names, (v.limit - ke)[:, None]))
            ke_excess = float(np.max(ke) / v.limit)
        else:  # rate limits do not depend on the dynamics
            parts.append((v.names, v.values_along(xs, dxs)))
    worst, worst_name = math.inf, None
    for names, m in parts:
        m = np.where(np.isnan(m), -np.inf, np.asarray(m).reshape(len(xs), -1))
        if m.size and float(m.min()) < worst:
            worst = float(m.min())
            worst_name = names[int(np.argmin(m.min(axis=0)))]
    enforced = set(entry.controller.constraints.names)
    return {
        "scenario": scenario, "controller": entry.name, "type": entry.controller.type_name,
        "case": case, "level": level, "draw": draw, "safeguard": guarded,
        "declared": settings.declared_error is not None, "status": status,
        "end_time": traj.end_time, "violated": traj.violated,
        "final_error": float(np.max(np.abs(traj.position[-1] - entry.controller.target))),
        "settle_time": settle, "true_min_margin": worst, "true_min_constraint": worst_name,
        "true_violation": bool(worst <= 0 or status == "constraint_violated"),
        "enforced_violation": bool(
            status == "constraint_violated"
            or (worst <= 0 and worst_name in enforced)
        ),
        "ke_peak_over_limit": ke_excess, "acted": traj.safeguard_steps,
        "enforces": sorted(enforced),
    }


# -- noise and saturation ----------------------------------------------------------------------
def noise_campaign(
    setup: ScenarioSetup,
    scenario: str,
    levels: Sequence[tuple[str, float, float]],
    seed: int,
    log_every: int = 10,
    log: Log = _quiet,
    declared_sigmas: float | None = None,
) -> list[Record]:
    """Every controller on every case with Gaussian noise (name, σ_x, σ_ẋ) on what it sees;
    with ``declared_sigmas`` k, each constrained law also with the measurement error
    declared as k σ (``simulation.model_error.position/velocity``), and the noise samples
    beyond it counted (``beyond``)."""
    plant = setup.make_plant()
    n = setup.model.n
    out: list[Record] = []
    for name, sx, sv in levels:
        for entry in setup.controllers:
            variants: list[float | None] = [None]
            if declared_sigmas is not None and not entry.controller.constraints.empty:
                variants.append(declared_sigmas)
            for k in variants:
                for case in setup.cases:
                    settings = replace(
                        setup.loop_settings, log_every=log_every,
                        noise=MeasurementNoise(sx, sv, seed),
                        declared_error=None if k is None else DeclaredError(
                            position=np.full(n, k * sx), velocity=np.full(n, k * sv)),
                    )
                    record = _status_record(
                        plant, setup, entry, case.name, case.position, case.velocity,
                        settings, {"scenario": scenario, "level": name, "sigma_position": sx,
                                   "sigma_velocity": sv, "declared": k is not None,
                                   "bound_sigmas": k}, setup.safeguard or SafeguardSettings())
                    if k is not None:
                        record["declarable"] = declarable(setup, entry, settings)
                    if k is not None and "control_steps" in record:
                        record["beyond"] = noise_beyond(
                            seed, n, int(str(record["control_steps"])), k, (sx, sv))
                    out.append(record)
        log(f"{scenario} noise {name} done")
    return out


def declarable(setup: ScenarioSetup, entry: ControllerEntry, settings: LoopSettings) -> bool:
    """Whether the declared measurement error leaves room at the target at rest: every
    margin of the law there above what the error can hide (model_error.measurement_losses).
    A rate error as large as a rate bound leaves none: no guard can keep it."""
    declared = settings.declared_error
    cons = entry.controller.constraints
    if declared is None or cons.empty:
        return True
    target = entry.controller.target
    state = cons.state(setup.model, target, np.zeros(setup.model.n))
    end, _ = measurement_losses(cons, state, declared, settings.bounds.period)
    return bool(np.all(cons.margins(target, np.zeros(setup.model.n)) > end))


def noise_beyond(seed: int, n: int, samples: int, k: float,
                 sigmas: tuple[float, float]) -> int:
    """How many of a run's noise draws fell beyond k σ: the loop's generator replayed (each
    control instant draws n position then n rate deviates, cpbc.simulation.loop)."""
    rng = np.random.default_rng(seed)
    count = 0
    for _ in range(samples):
        for sigma in sigmas:
            draw = rng.standard_normal(n)
            if sigma > 0:
                count += int(np.count_nonzero(np.abs(draw) > k))
    return count


def saturation_campaign(
    setup: ScenarioSetup,
    scenario: str,
    fractions: Sequence[float],
    log_every: int = 10,
    log: Log = _quiet,
) -> list[Record]:
    """Every controller on every case with joint torque limits at ``fraction`` × the peak
    joint torque it asked for in the unlimited run, with and without the safeguard."""
    plant = setup.make_plant()
    out: list[Record] = []
    for entry in setup.controllers:
        for case in setup.cases:
            free = guarded_run(
                plant, setup, entry, case.position, case.velocity,
                replace(setup.loop_settings, log_every=log_every, noise=None), setup.safeguard,
            )
            peak = np.max(np.abs(np.nan_to_num(free.joint_torque)), axis=0)
            for frac in fractions:
                limit = np.maximum(frac * peak, 1e-6)
                for guarded in (False, True):
                    settings = replace(
                        setup.loop_settings, log_every=log_every, noise=None,
                        bounds=replace(setup.loop_settings.bounds, torque=limit),
                    )
                    out.append(_status_record(
                        plant, setup, entry, case.name, case.position, case.velocity,
                        settings, {"scenario": scenario, "fraction": frac,
                                   "safeguard": guarded, "peak": peak.tolist()},
                        SafeguardSettings() if guarded else None,
                    ))
        log(f"{scenario} saturation {entry.name} done")
    return out


def _status_record(
    plant: MujocoPlant, setup: ScenarioSetup, entry: ControllerEntry, case: str, x0: Array,
    dx0: Array, settings: LoopSettings, extra: Record, safeguard: SafeguardSettings | None,
) -> Record:
    try:
        traj = guarded_run(plant, setup, entry, x0, dx0, settings, safeguard)
    except Exception as exc:  # the point of the campaign: any crash is a finding
        return {**extra, "controller": entry.name, "case": case, "status": "crashed",
                "error": f"{type(exc).__name__}: {exc}"}
    status, _ = judge_status(traj, entry.controller.target, setup.criteria)
    margins = setup.monitor.margins_along(traj.position, traj.velocity)
    enforced = [setup.monitor.names.index(n) for n in entry.controller.constraints.names]
    low = float(np.nanmin(margins[:, enforced])) if enforced else math.nan
    return {
        **extra, "controller": entry.name, "type": entry.controller.type_name, "case": case,
        "status": status, "end_time": traj.end_time, "violated": traj.violated,
        "final_error": float(np.max(np.abs(traj.position[-1] - entry.controller.target))),
        "min_enforced_margin": low, "saturated_steps": traj.saturated_steps,
        "rejected_samples": traj.rejected_samples, "acted": traj.safeguard_steps,
        "infeasible": traj.safeguard_infeasible, "control_steps": traj.control_steps,
        "finite": bool(np.all(np.isfinite(traj.position))),
    }


# -- cost and long runs -------------------------------------------------------------------
def safeguard_cost(
    setup: ScenarioSetup, entry: ControllerEntry, states: Sequence[SampledState],
    period: float, repeats: int = 5,
) -> Record:
    """Median µs per call of the bare law and of the guarded law over the same states."""
    guard = Safeguard(entry.controller, InputBounds(period), also_keep=setup.also_keep)
    law = entry.controller

    def timed(f: Callable[[Array, Array], object]) -> float:
        blocks = []
        for _ in range(repeats):
            start = time.perf_counter()
            calls = 0
            for s in states:
                try:
                    f(s.position, s.velocity)
                    calls += 1
                except ConstraintViolation:
                    pass
            blocks.append((time.perf_counter() - start) / max(calls, 1))
        return float(np.median(blocks)) * 1e6

    bare = timed(law.evaluate)
    guarded = timed(guard.evaluate)
    return {"controller": entry.name, "type": law.type_name, "bare_us": bare,
            "guarded_us": guarded, "overhead_us": guarded - bare,
            "acted_share": guard.acted / max(guard.calls, 1)}


def _rss_kib() -> int:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return -1


def long_run(setup: ScenarioSetup, entry: ControllerEntry, duration: float,
             max_log_samples: int) -> Record:
    """One run of ``duration`` simulated seconds; resident memory sampled as it goes."""
    case = setup.cases[0]
    rss: list[int] = []
    settings = replace(setup.loop_settings, duration=duration, log_every=1,
                       max_log_samples=max_log_samples)
    plant = setup.make_plant()
    before = _rss_kib()
    start = time.perf_counter()
    traj = guarded_run(plant, setup, entry, case.position, case.velocity, settings, setup.safeguard,
                progress=lambda _f: rss.append(_rss_kib()))
    wall = time.perf_counter() - start
    status, _ = judge_status(traj, entry.controller.target, setup.criteria)
    log_bytes = sum(a.nbytes for a in (traj.time, traj.position, traj.velocity, traj.torque,
                                       traj.joint_torque, traj.lyapunov))
    return {
        "controller": entry.name, "duration": duration, "control_steps": traj.control_steps,
        "status": status, "samples_kept": len(traj.time),
        "sample_spacing": float(np.median(np.diff(traj.time))) if len(traj.time) > 1 else 0.0,
        "log_bytes": log_bytes, "rss_before_kib": before,
        "rss_first_kib": rss[0] if rss else -1, "rss_last_kib": rss[-1] if rss else -1,
        "rss_max_kib": max(rss) if rss else -1, "wall_s": wall,
        "acted": traj.safeguard_steps,
    }
