"""The building blocks of a campaign: a scenario's seeded initial states (only positions the
arm can take) and a *checked run* from one of them — the closed loop on a plant that records
every physics step, judged on the true state: a *violation* is a margin of a constraint the
law enforces at or below zero at any physics step (not only at the control instants), a run
the law ended itself (ConstraintViolation), or one that diverged. ``python -m cpbc.verify``
runs them (docs/RELIABILITY.md); the repository's robustness campaigns
(``tools/reliability/robustness.py``, docs/ROBUSTNESS.md) too.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.controllers import safeguard as sg
from cpbc.controllers.safeguard import SafeguardSettings
from cpbc.reliability.sampling import SampledState, StateSampler
from cpbc.scenario import ScenarioSetup, build, load_scenario
from cpbc.scenario.build import ControllerEntry
from cpbc.scenario.schema.arm_specs import ModelErrorSpec
from cpbc.simulation import LoopSettings, MujocoPlant, PlantSettings, run_mujoco
from cpbc.simulation.trajectory import Trajectory

Record = dict[str, object]
Log = Callable[[str], None]


# -- set-up --------------------------------------------------------------------------------
def campaign_setup(
    scenario: str | Path, integrator: str | None = "Euler", timestep: float = 0.001,
    model_error: dict[str, object] | None = None,
) -> ScenarioSetup:
    """A shipped or given scenario, with MuJoCo's default integrator (semi-implicit Euler)
    at ``timestep`` unless told otherwise; ``integrator=None`` keeps the scenario's own.
    ``model_error``: the scenario's ``simulation.model_error`` replaced by this one (its
    fields), as a scenario that declares it would be built."""
    spec, file = load_scenario(scenario)
    if model_error is not None:
        sim = spec.simulation.model_copy(
            update={"model_error": ModelErrorSpec.model_validate(model_error)})
        spec = spec.model_copy(update={"simulation": sim})
    setup = build(spec, file)
    setup.plant_settings = PlantSettings(timestep, integrator or spec.simulation.integrator)
    return setup


def constrained(setup: ScenarioSetup) -> list[ControllerEntry]:
    """The controllers of a scenario that enforce constraints (the baselines enforce none)."""
    return [e for e in setup.controllers if not e.controller.constraints.empty]


_LIMIT_JOINT = int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT)


def touching(data: mujoco.MjData) -> bool:
    """Whether the last physics step acted through a contact or a joint's range stop: forces
    no controller of the package commands (mj_step finds them at the state it starts from)."""
    return bool(data.ncon) or bool(data.nefc and np.any(
        data.efc_type[: data.nefc] == _LIMIT_JOINT))


class RecordingPlant(MujocoPlant):
    """A MuJoCo plant that keeps its state after every physics step, so that constraints
    can be checked between control instants. ``rows`` holds (qpos, qvel) per step;
    ``first_touch`` the row of the first contact or joint stop and ``touched`` what it was:
    the obstacle's name, ``self`` (two links), or ``joint stop <joint>``."""

    def __init__(self, model: mujoco.MjModel, settings: PlantSettings) -> None:
        super().__init__(model, settings)
        self.rows: list[Array] = []
        self.first_touch: int | None = None
        self.touched: str | None = None

    def reset(self, q: Array, dq: Array) -> None:
        super().reset(q, dq)
        self.rows = [np.concatenate([self.data.qpos, self.data.qvel])]
        self.first_touch = self.touched = None

    def step(self, substeps: int) -> None:
        model, data = self.model, self.data
        for _ in range(substeps):
            mujoco.mj_step(model, data)
            # mj_step finds contacts and active limits at the state it starts from (the last
            # row), then integrates: a touch there acts during this step
            if self.first_touch is None and touching(data):
                self.first_touch = len(self.rows) - 1
                self.touched = self._what_touched()
            self.rows.append(np.concatenate([data.qpos, data.qvel]))

    def _what_touched(self) -> str:
        model, data = self.model, self.data
        if data.ncon:
            for g in data.contact[0].geom:
                if model.geom_bodyid[g] == 0:  # the scene's obstacles hang on the world body
                    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "world"
            return "self"
        row = int(np.flatnonzero(data.efc_type[: data.nefc] == _LIMIT_JOINT)[0])
        joint = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, int(data.efc_id[row]))
        return f"joint stop {joint}"

    def fine_states(self, t_mat: Array) -> tuple[Array, Array]:
        """(x, ẋ) at every physics step, in controller coordinates x = T q."""
        a = np.array(self.rows)
        n = self.n
        return a[:, :n] @ t_mat.T, a[:, n:] @ t_mat.T


def _min_margin(
    constraints: ConstraintSet, xs: Array, dxs: Array
) -> tuple[float, str | None, int | None]:
    """The smallest margin, its constraint and the first row at which a margin is ≤ 0."""
    if constraints.empty or not len(xs):
        return math.inf, None, None
    m = constraints.margins_along(xs, dxs)
    m = np.where(np.isnan(m), -np.inf, m)
    flat = int(np.argmin(m))
    i, j = divmod(flat, m.shape[1])
    crossed = np.flatnonzero(m.min(axis=1) <= 0)
    return float(m[i, j]), constraints.names[j], int(crossed[0]) if crossed.size else None


@dataclass(frozen=True)
class RunCheck:
    """One run judged on the true state.

    Attributes:
        violated: any enforced margin ≤ 0 at a physics step, or the law refused the state,
            or the run diverged.
        at_samples: the violation was seen at a control instant (the law's own check).
        min_margin: the smallest enforced margin over every physics step.
        constraint: the constraint of ``min_margin``.
        touched: the arm touched something the law does not know of — a MuJoCo contact or a
            joint's range stop — strictly before the first violation (or at all, without
            one): what broke then was not the law's sampling.
        touch: what it touched first (RecordingPlant.touched), when ``touched``.
    """

    trajectory: Trajectory
    violated: bool
    at_samples: bool
    min_margin: float
    constraint: str | None
    touched: bool = False
    touch: str | None = None


def guarded_run(
    plant: MujocoPlant, setup: ScenarioSetup, entry: ControllerEntry, x0: Array, dx0: Array,
    settings: LoopSettings, safeguard: SafeguardSettings | None,
    progress: Callable[[float], None] | None = None, phase: float = 0.0,
) -> Trajectory:
    """The entry's law in the loop, wrapped in ``safeguard`` (with the scenario's extra
    constraints) at the settings' period and torque limit when it is given; with a
    reference, inside its tracker, starting at path time ``phase``."""
    law = sg.guarded(entry.controller, settings.bounds, safeguard, setup.also_keep,
                     settings.model_error, settings.declared_error)
    if setup.reference is not None:
        law = setup.reference.tracker(entry.name, entry.controller, law,
                                      settings.bounds.period, phase)
    return run_mujoco(plant, law, setup.model.coordinates, x0, dx0, settings, progress)


def kept_constraints(setup: ScenarioSetup, entry: ControllerEntry, period: float,
                     safeguard: SafeguardSettings | None) -> ConstraintSet:
    """What the entry, as it runs at ``period``, promises to keep: the law's constraints and,
    wrapped in its safeguard, the scenario's monitored ones the safeguard keeps besides
    (``simulation.safeguard_monitored``): a run that crosses one of those is a violation
    too."""
    law = sg.guarded(entry.controller, replace(setup.loop_settings.bounds, period=period),
                     safeguard, setup.also_keep)
    return law.guarded if isinstance(law, sg.Safeguard) else law.constraints


def checked_run(
    plant: RecordingPlant,
    setup: ScenarioSetup,
    entry: ControllerEntry,
    x0: Array,
    dx0: Array,
    settings: LoopSettings,
    constraints: ConstraintSet | None = None,
    safeguard: SafeguardSettings | None = None,
    phase: float = 0.0,
) -> RunCheck:
    """run_mujoco (the law wrapped in ``safeguard`` if given), then the enforced margins at
    every physics step of the true plant."""
    traj = guarded_run(plant, setup, entry, x0, dx0, settings, safeguard, phase=phase)
    cons = constraints if constraints is not None else entry.controller.constraints
    xs, dxs = plant.fine_states(setup.model.coordinates.matrix)
    low, name, first = _min_margin(cons, xs, dxs)
    at_samples = traj.outcome in ("constraint_violated", "diverged")
    if not at_samples and not cons.empty:
        sample_low, _, _ = _min_margin(cons, traj.position, traj.velocity)
        at_samples = sample_low <= 0
    violated = at_samples or low <= 0
    if traj.outcome == "constraint_violated" and traj.violated is not None:
        name = traj.violated
    touch = plant.first_touch
    touched = touch is not None and (first is None or touch < first)
    return RunCheck(traj, violated, at_samples, low, name, touched,
                    plant.touched if touched else None)


# -- sampled-data safety -------------------------------------------------------------------
def physically_possible(setup: ScenarioSetup) -> Callable[[Array], bool]:
    """Whether the arm can be at a position (controller coordinates): inside the plant's
    joint ranges — MuJoCo enforces a URDF's limits with constraint forces the laws do not
    know of — and touching nothing (no MuJoCo contact: not inside an obstacle, the floor or
    itself)."""
    plant = setup.make_plant()
    model, data = plant.model, plant.data
    limited = model.jnt_limited.astype(bool)
    dofs = model.jnt_qposadr[limited]
    lo, hi = model.jnt_range[limited].T
    t_inv = setup.model.coordinates.inverse

    def possible(x: Array) -> bool:
        q = t_inv @ x
        if not (np.all(q[dofs] > lo) and np.all(q[dofs] < hi)):
            return False
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        return data.ncon == 0

    return possible


def state_sampler(setup: ScenarioSetup, seed: int) -> StateSampler:
    """The seeded sampler of the admissible set S of the scenario's constrained laws (when
    they share one; else of every constraint of the scenario), at positions the arm can
    take (:func:`physically_possible`) and that keep every configuration constraint of the
    scenario. States are pushed towards the boundaries the laws enforce, not towards those
    only monitored (a clearance the UR5's BPBC does not know of, say)."""
    sets = [e.controller.constraints for e in constrained(setup)]
    shared = bool(sets) and all(c.names == sets[0].names for c in sets)
    target_set = sets[0] if shared else setup.monitor
    possible = physically_possible(setup)
    monitored = setup.monitor.configuration

    def reachable(x: Array) -> bool:
        return possible(x) and all(bool(np.all(c.value(x) > 0)) for c in monitored)

    return StateSampler(target_set, setup.target, seed=seed, reachable=reachable)


def sample_states(setup: ScenarioSetup, count: int, seed: int) -> list[SampledState]:
    """``count`` admissible initial states of the scenario (all its constraints), seeded."""
    return state_sampler(setup, seed).draw_many(count)
