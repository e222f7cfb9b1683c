"""The verification campaign of ``python -m cpbc.verify``: seeded initial states of a scenario,
each constrained controller (the laws with their safeguard, and any ``cbf_qp`` peer) at each
control rate, with the scenario's torque limits, judged on the true state at every physics
step (:func:`cpbc.reliability.campaign.checked_run`).

The work is cut into *blocks* (one controller, one rate, a few state seeds) that any process
can run from the scenario's file alone, so that a local process pool and a Dask cluster run
the same blocks and give the same records. State i is drawn by its own sampler seeded with
``seed + i``, so that a failure is reproduced by its seed alone (``--seeds``).

Each state is classed, per rate, before it runs, by what was shown of it:

``stoppable``      some brake within the torque box (cpbc.constraints.brakes: the uniform
                   brake, the least-squares brake, the brake aimed at the nearest constraint;
                   for a model with dry friction each also held against b without it),
                   recomputed from the model at every sample and held over the control period
                   in the true plant (MuJoCo, the run's own physics), brings the arm to rest
                   with every margin the controller keeps positive at every physics step,
                   touching nothing (no contact, no joint range stop: no force outside the
                   box helps it stop): a violation from here is a defect of the controller;
``not_stoppable``  none of them does (it may still be savable by a torque no brake here finds).

Each record also says whether the state lies in the guard's own braking set V
(``in_v``: cpbc.constraints.stopping.Braking, σ > 0, and holdable for one period,
safeguard.viable) and which brake stopped it (``brake``). Without a torque limit the box is
unbounded. Every state runs; the report counts the two classes apart.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, replace

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.brakes import (
    Advance,
    Brake,
    Stop,
    TorqueBox,
    brakes,
    brings_to_rest,
    first_stop,
    ramped,
)
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.stopping import Braking, stopping_margins
from cpbc.controllers.safeguard import viable
from cpbc.model.robot_model import RobotModel
from cpbc.peers.cbf_qp import CBFQP
from cpbc.reliability.campaign import (
    RecordingPlant,
    checked_run,
    constrained,
    kept_constraints,
    state_sampler,
    touching,
)
from cpbc.reliability.sampling import SampledState
from cpbc.scenario import ScenarioSetup, build, load_scenario
from cpbc.scenario.build import ControllerEntry
from cpbc.simulation import MujocoPlant
from cpbc.simulation.disturbances import (
    AccelerationDisturbance,
    Disturber,
    MeasurementNoise,
    PlantMismatch,
)

CLASSES = ("stoppable", "not_stoppable")
TOLERANCE = 1e-6  # a run is "deep" when some margin fell below −TOLERANCE (its own units)
Record = dict[str, object]


@dataclass(frozen=True)
class Mismatch:
    """Plant perturbation drawn per run (PlantMismatch.random), seeded by the state's seed."""

    mass: float = 0.0
    inertia: float = 0.0
    damping: float = 0.0
    armature: float = 0.0
    frictionloss: float = 0.0


@dataclass(frozen=True)
class Plan:
    """What a campaign runs; everything a worker needs besides the scenario's files.

    Attributes:
        scenario: a shipped scenario's name or a path every worker can read.
        seed: state i is drawn with seed + i.
        states: how many states (ignored when ``seeds`` is given).
        rates: control rates [Hz].
        horizon: simulated seconds per run.
        mismatch: plant perturbation per run, or None.
        noise: (σ_x, σ_ẋ) on what the controller sees, or None.
        seeds: run exactly these state seeds.
        disturb: the plant adds an acceleration disturbance at the corners of the
            scenario's declared model error (``simulation.model_error``;
            cpbc.simulation.disturbances), seeded per state.
    """

    scenario: str
    seed: int = 0
    states: int = 100
    rates: tuple[float, ...] = (1000.0, 500.0, 100.0)
    horizon: float = 0.5
    mismatch: Mismatch | None = None
    noise: tuple[float, float] | None = None
    seeds: tuple[int, ...] | None = None
    disturb: bool = False

    def state_seeds(self) -> tuple[int, ...]:
        return self.seeds if self.seeds is not None else tuple(
            self.seed + i for i in range(self.states))


@dataclass(frozen=True)
class Block:
    """One unit of work: a controller at one rate from a few states."""

    plan: Plan
    controller: str
    rate: float
    seeds: tuple[int, ...]


def blocks(plan: Plan, controllers: Sequence[str], size: int) -> list[Block]:
    """The campaign cut into blocks of at most ``size`` states."""
    seeds = plan.state_seeds()
    return [Block(plan, name, rate, seeds[i:i + size])
            for name in controllers for rate in plan.rates
            for i in range(0, len(seeds), size)]


def checked_controllers(setup: ScenarioSetup) -> list[ControllerEntry]:
    """The controllers a campaign checks: those that enforce constraints (laws and peers)."""
    return constrained(setup)


def draw_state(setup: ScenarioSetup, seed: int) -> SampledState:
    """The state of a seed: one draw of the campaign's sampler seeded with it."""
    return state_sampler(setup, seed).draw()


def in_braking_set(setup: ScenarioSetup, kept: ConstraintSet, x: Array, dx: Array,
                   period: float) -> bool:
    """Whether the state is in the guard's braking set V (σ > 0 of the uniform brake, the
    first-order stopping test) and holdable for one period (safeguard.viable)."""
    limit = setup.loop_settings.bounds.torque
    if limit is not None:
        full = np.broadcast_to(np.asarray(limit, dtype=float), (setup.model.n,))
        lost, _, _ = stopping_margins(setup.monitor, setup.model, x, dx, full)
        if lost.size and not np.all(lost > 0):
            return False
        rate = setup.loop_settings.bounds.rate
        sigma, _ = Braking.of(setup.model, full, rate=rate).margins(
            setup.monitor, setup.model, x, dx, setup.model.gravity(x), period)
        if sigma.size and not np.all(sigma > 0):
            return False
    return viable(kept, x, dx, period)


def stopping_brake(setup: ScenarioSetup, kept: ConstraintSet, x: Array, dx: Array,
                   period: float, plant: MujocoPlant | None = None,
                   disturbance: AccelerationDisturbance | None = None) -> str | None:
    """The first brake (cpbc.constraints.brakes) that, held at ``period`` in the true plant
    within the torque box, brings the arm to rest with every margin of ``kept`` positive at
    every physics step; None if none does. Each brake is held against the model's b (the
    rescue's), and where the model has dry friction and none of them stops the arm,
    against b without it (``brakes.holding_bias``: "…, friction left"). Under a
    torque-rate limit each brake ramps from the gravity torque at the start, at most the
    torque limit (what the run's own first command starts from), at the rate the motors
    allow. ``plant``: the true plant
    to brake in (a fresh one of the scenario's by default); ``disturbance``: the run's,
    which the brakes meet too (the same draws, period by period: a start is stoppable in
    the plant as it is disturbed), and which keeps the rates jittering by h ā: the arm
    rests below 10⁻³ + 2hā."""
    limit = setup.loop_settings.bounds.torque
    rate = setup.loop_settings.bounds.rate
    box = TorqueBox.of(setup.model, math.inf if limit is None else limit)
    # the gravity torque the motors hold at the start, at most their limit (the loop's own)
    held = None if rate is None else np.clip(box.joint(setup.model.gravity(x)), *box.bounds)
    step = None if rate is None else rate * period
    plant = plant or setup.make_plant()
    coords = setup.model.coordinates
    substeps = max(round(period / plant.model.opt.timestep), 1)
    table = brakes(box, kept, setup.model)
    rest = 1e-3 if disturbance is None else 1e-3 + 2.0 * period * float(
        np.max(disturbance.bound))

    def run(brake: Brake) -> Stop:
        plant.reset(coords.to_joint(x), coords.to_joint(dx))
        return brings_to_rest(brake, setup.model, kept.margins_along,
                              _true_advance(plant, box, coords.matrix, substeps, step, held,
                                            None if disturbance is None
                                            else disturbance.drawn(), setup.model),
                              x, dx, period, rest=rest)

    return first_stop(tuple(table), table, run)[0]


def _true_advance(plant: MujocoPlant, box: TorqueBox, t_mat: Array, substeps: int,
                  rate_step: Array | None = None, held: Array | None = None,
                  disturber: Disturber | None = None,
                  model: RobotModel | None = None) -> Advance:
    """The true plant as a plant for brings_to_rest: τ clipped to the box (and, under a
    torque-rate limit ``rate_step`` = ρh, to what one period reaches from the joint torque
    last held, ``held`` before the first), held for one control period, every physics step
    reported (controller coordinates). A step that acted
    through a contact or a joint's range stop ends the braking unstopped (None): a force
    outside the torque box stopped the arm then, not the brake (a UR5 started 3 ms above a
    floor its law did not keep was classed stoppable by a brake that rested on the floor).
    ``disturber``: the run's disturbance, added to each period's command as the loop adds
    it; ``model``: the controller's, whose inertia at the measured state reaches the brake
    under the rate limit as the safeguard reaches its torques (brakes.ramped)."""
    data = plant.data
    last = [held]

    def advance(tau: Array) -> tuple[Array, Array] | None:
        inertia = None if model is None or rate_step is None else model.inertia(
            t_mat @ data.qpos)
        tau_q = box.joint(ramped(box, tau, rate_step, last[0], inertia))
        last[0] = tau_q
        plant.apply(tau_q if disturber is None
                    else tau_q + disturber.force(plant.model, plant.data))
        qs, dqs = [], []
        for _ in range(substeps):
            plant.step(1)
            if touching(data):
                return None
            qs.append(data.qpos.copy())
            dqs.append(data.qvel.copy())
        if plant.unstable():
            return None
        return np.array(qs) @ t_mat.T, np.array(dqs) @ t_mat.T

    return advance


def classify(setup: ScenarioSetup, kept: ConstraintSet, x: Array, dx: Array,
             period: float) -> str:
    """The class of an initial state at a control period (the module docstring), for a
    controller that keeps ``kept``."""
    return "stoppable" if stopping_brake(setup, kept, x, dx, period) else "not_stoppable"


def _law_at(entry: ControllerEntry, period: float) -> ControllerEntry:
    """The entry as it runs at ``period``: a CBF-QP's default first-order gain is 1/(2h)."""
    law = entry.controller
    if isinstance(law, CBFQP):
        return ControllerEntry(entry.name, law.at_period(period))
    return entry


def _plant(setup: ScenarioSetup, plan: Plan, seed: int, base: RecordingPlant) -> RecordingPlant:
    if plan.mismatch is None:
        return base
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    m = plan.mismatch
    PlantMismatch.random(np.random.default_rng(seed), plant.model.nbody - 1, plant.model.nv,
                         m.mass, m.inertia, m.damping, m.armature, m.frictionloss,
                         ).apply(plant.model)
    return plant


def _disturbance(setup: ScenarioSetup, plan: Plan, seed: int) -> AccelerationDisturbance | None:
    """The plant's disturbance inside the declared model error (joint coordinates: the
    campaign refuses ``disturb`` on other coordinates), or None."""
    bound = setup.loop_settings.model_error
    if not plan.disturb or bound is None:
        return None
    return AccelerationDisturbance(bound, seed)


def _steps_at_limit(joint_torque: Array, limit: Array | None) -> int:
    """Control steps at which some applied joint torque sat on its limit."""
    if limit is None:
        return 0
    applied = np.abs(joint_torque[np.all(np.isfinite(joint_torque), axis=1)])
    return int(np.sum(np.any(applied >= np.asarray(limit) * (1 - 1e-6), axis=1)))


def _rate_share(peak: Array | None, limit: Array | None) -> float | None:
    """The largest peak joint torque rate of a run as a share of its limit (None without
    one): ≤ 1 when every command stayed within what the motors can do."""
    if peak is None or limit is None:
        return None
    return float(np.max(np.asarray(peak) / np.asarray(limit)))


def run_block(block: Block) -> list[Record]:
    """Every run of a block, one record each. Builds the scenario in this process."""
    plan = block.plan
    setup = build(*load_scenario(plan.scenario))  # the scenario's own physics
    entry = next(e for e in setup.controllers if e.name == block.controller)
    period = 1.0 / block.rate
    entry = _law_at(entry, period)
    base = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    kept = kept_constraints(setup, entry, period, setup.safeguard)
    out: list[Record] = []
    for seed in block.seeds:
        s = draw_state(setup, seed)
        settings = replace(
            setup.loop_settings, duration=plan.horizon,
            bounds=replace(setup.loop_settings.bounds, period=period), log_every=1,
            noise=None if plan.noise is None else MeasurementNoise(*plan.noise, seed=seed),
            disturbance=_disturbance(setup, plan, seed),
        )
        brake = stopping_brake(setup, kept, s.position, s.velocity, period, base,
                               settings.disturbance)
        kind = "stoppable" if brake else "not_stoppable"
        in_v = in_braking_set(setup, kept, s.position, s.velocity, period)
        phase = 0.0 if setup.reference is None else setup.reference.phase(entry.name, seed)
        check = checked_run(_plant(setup, plan, seed, base), setup, entry, s.position,
                            s.velocity, settings, kept, safeguard=setup.safeguard, phase=phase)
        traj = check.trajectory
        out.append({
            "controller": entry.name, "type": entry.controller.type_name, "rate": block.rate,
            "seed": seed, "class": kind, "in_v": in_v, "brake": brake,
            "violated": bool(check.violated),
            "min_margin": float(check.min_margin), "constraint": check.constraint,
            "end_time": float(traj.end_time), "outcome": traj.outcome,
            "final_error": float(np.max(np.abs(traj.position[-1] - entry.controller.target))),
            "control_steps": int(traj.control_steps), "acted": int(traj.safeguard_steps),
            "infeasible": int(traj.safeguard_infeasible),
            "rows_acted": int(traj.filter_row_steps), "rescues": int(traj.rescues),
            "at_limit": _steps_at_limit(traj.joint_torque, settings.bounds.torque),
            "rate_clipped": int(traj.rate_limited_steps),
            "peak_rate_share": _rate_share(traj.peak_torque_rate, settings.bounds.rate),
            "position": s.position.tolist(), "velocity": s.velocity.tolist(),
            **({} if setup.reference is None else {"phase": phase}),
        })
    return out


def _group(records: Iterable[Record]) -> dict[tuple[str, float], list[Record]]:
    groups: dict[tuple[str, float], list[Record]] = {}
    for r in records:
        groups.setdefault((str(r["controller"]), float(r["rate"])), []).append(r)  # type: ignore[arg-type]
    return groups


def _worst(rows: Sequence[Record]) -> tuple[float, str | None]:
    if not rows:
        return math.inf, None
    low = min(rows, key=lambda r: float(r["min_margin"]))  # type: ignore[arg-type]
    return float(low["min_margin"]), low["constraint"]  # type: ignore[arg-type,return-value]


def summarise(plan: Plan, records: Iterable[Record]) -> Record:
    """The campaign's document: per controller and rate the viable runs, their violations
    (runs with a margin ≤ 0) and of those the runs deeper than TOLERANCE, the worst margin and
    depth, the seeds of each failure, the viable runs that start in V and their violations,
    the share of steps the filter changed (and of those its own rows or conditions, not the
    torque box alone), its infeasible steps and the steps the guard's rescue held a brake;
    not-stoppable runs, apart."""
    rows = []
    order = sorted(_group(records).items(), key=lambda kv: (kv[0][0], -kv[0][1]))
    for (name, rate), group in order:
        group.sort(key=lambda r: int(r["seed"]))  # type: ignore[call-overload]
        ok = [r for r in group if r["class"] == CLASSES[0]]
        failures = [{k: r[k] for k in ("seed", "constraint", "end_time", "min_margin",
                                       "outcome", "position", "velocity", "in_v")}
                    for r in ok if r["violated"]]
        in_v = [r for r in ok if r["in_v"]]
        low, where = _worst(ok)
        steps = sum(int(r["control_steps"]) for r in group)  # type: ignore[call-overload]
        rows.append({
            "controller": name, "type": group[0]["type"], "rate": rate, "runs": len(ok),
            "violations": len(failures), "worst_margin": low, "worst_constraint": where,
            "deep_violations": sum(float(f["min_margin"]) < -TOLERANCE  # type: ignore[arg-type]
                                   for f in failures),
            "worst_depth": max(0.0, -low), "tolerance": TOLERANCE,
            "failures": failures,
            # the stoppable starts in the uniform brake's braking set V, which every step
            # bounded in time keeps (the guard's (S2)); the others need a rescue's search
            "in_v": {"runs": len(in_v), "violations": sum(bool(r["violated"]) for r in in_v)},
            "non_viable": {k: {"runs": sum(r["class"] == k for r in group),
                               "violations": sum(r["class"] == k and bool(r["violated"])
                                                 for r in group)}
                           for k in CLASSES[1:]},
            "filter_share": sum(int(r["acted"]) for r in group) / max(steps, 1),  # type: ignore[call-overload]
            "infeasible_steps": sum(int(r["infeasible"]) for r in group),  # type: ignore[call-overload]
            "row_share": sum(int(r.get("rows_acted", r["acted"])) for r in group)  # type: ignore[call-overload]
            / max(steps, 1),
            "rescues": sum(int(r.get("rescues", 0)) for r in group),  # type: ignore[call-overload]
            "torque_limit_share": sum(int(r["at_limit"]) for r in group) / max(steps, 1),  # type: ignore[call-overload]
            # under a torque-rate limit: the steps at which the plant had to clip a command
            # (the controller asked for more than the motors can do) and the largest peak
            # rate as a share of the limit, over every run
            "rate_clipped_steps": sum(int(r.get("rate_clipped", 0)) for r in group),  # type: ignore[call-overload]
            "peak_rate_share": max((float(r["peak_rate_share"]) for r in group  # type: ignore[arg-type]
                                    if r.get("peak_rate_share") is not None), default=None),
        })
    doc = asdict(plan)
    doc["rates"] = list(plan.rates)
    doc["seeds"] = list(plan.state_seeds())
    return {"plan": doc, "results": rows}
