"""A scenario's constrained law as a Gymnasium environment: the policy's action is a target
streamed to the law's tracker (cpbc.reference.tracker), and the law, in the scenario's
safeguard, drives the scenario's MuJoCo plant at its control rate underneath. One ``step``
is one policy period: the action is streamed once, then the sampled-data loop's own pieces
(cpbc.simulation.loop: the torque limit, the rate limit, the measurement noise, the
safeguard's counts) run its control periods.

Whatever the policy sends, the law keeps the scenario's constraints: the env does not end
an episode for a risky action (there is none); it reports each step's smallest margins and
what the safeguard did in ``info``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import gymnasium
import mujoco
import numpy as np
from gymnasium import spaces

from cpbc.arrays import Array
from cpbc.constraints.geometry import matrix_to_quat
from cpbc.errors import ConstraintViolation, CpbcError, ParameterError
from cpbc.gym.actions import (
    ActionKind,
    JointDelta,
    JointTarget,
    Measured,
    PoseDelta,
    PositionDelta,
)
from cpbc.model.measured_state import finite_vector
from cpbc.model.robot_model import RobotModel
from cpbc.reference.governor import GovernorSettings
from cpbc.reference.tracker import ReferenceTracker, tracking
from cpbc.scenario import ScenarioSetup, build, load_scenario
from cpbc.scenario.arm_setup import ControllerEntry
from cpbc.scenario.state_checks import joint_ranges
from cpbc.simulation.loop import ArmLoop, substeps_per_control

ACTIONS = ("pose_delta", "position_delta", "joint_target", "joint_delta")
STARTS = 100  # seeded draws of a start inside S before the env starts at x_n itself

Observation = dict[str, Array]
Action = np.ndarray  # float32 in the env's box; anything array-like is checked
Reward = Callable[[Observation, dict[str, Any]], float]


@dataclass(frozen=True)
class EnvSettings:
    """The environment's options (``make_env``'s keywords), checked at construction
    (``ValueError`` naming the option).

    Attributes:
        controller: the scenario's law by name (None: its last law with constraints).
        policy_rate: actions per second [Hz], > 0; the control period must divide its
            period (e.g. 20 Hz: 50 control steps of 1 ms per ``step``).
        max_episode_steps: ``step`` calls before ``truncated``, ≥ 1.
        max_step: the largest point delta per action [m] (``pose_delta``,
            ``position_delta``), > 0.
        max_turn: the largest rotation per action [rad] (``pose_delta``), > 0.
        max_joint_step: the largest joint delta per action [rad or m] (``joint_delta``),
            > 0.
        start_spread: a reset draws each joint's start uniformly within ± this [rad or m]
            of the law's posture x_n (seeded by ``reset(seed=...)``), ≥ 0; draws outside
            the constraints' set are drawn again.
        governor: the reference governor's settings (``GovernorSettings()`` when None).
        reward: ``reward(observation, info)`` → float; None: minus the frame's distance to
            the scenario's goal point [m].
    """

    controller: str | None = None
    policy_rate: float = 20.0
    max_episode_steps: int = 500
    max_step: float = 0.02
    max_turn: float = 0.1
    max_joint_step: float = 0.05
    start_spread: float = 0.02
    governor: GovernorSettings | None = None
    reward: Reward | None = None

    def __post_init__(self) -> None:
        for name in ("policy_rate", "max_step", "max_turn", "max_joint_step"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ParameterError(name, f"{name} must be a finite number > 0, got "
                                           f"{value!r}")
        spread = self.start_spread
        if not (isinstance(spread, int | float) and math.isfinite(spread) and spread >= 0):
            raise ParameterError("start_spread", "start_spread must be a finite number ≥ 0 "
                                                 f"[rad or m], got {spread!r}")
        steps = self.max_episode_steps
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise ParameterError("max_episode_steps", "max_episode_steps must be a whole "
                                                      f"number ≥ 1, got {steps!r}")


class ScenarioEnv(gymnasium.Env[dict[str, Any], Action]):
    """A scenario's constrained law driven by a policy: each ``step`` streams the action's
    target to the law's tracker, then runs one policy period of the law, in its safeguard,
    on the scenario's MuJoCo plant. Build it with ``make_env``.

    The action is a float32 vector in [-1, 1]^k; a finite action outside the box is clipped
    to it. An action that is not k finite numbers raises ``ValueError`` (naming ``action``)
    and nothing happens: no time passes and the previous target stays in force.

    The observation is a dict of float64 arrays: ``joint_position`` x and
    ``joint_velocity`` ẋ (the law's coordinates: rad or m, per s), ``frame_position`` p [m]
    and ``frame_orientation`` (a unit quaternion (w, x, y, z), w ≥ 0) of the tracked frame
    in the world.

    ``info`` after each ``step``: ``margin``, the smallest margin of every constraint of the
    scenario over the step's control periods (from MuJoCo's state at each), ``closest`` its
    constraint, ``margins`` each constraint row's smallest (in the order of
    ``constraint_names``); ``safeguard_steps``, ``safeguard_infeasible``, ``rescues``: the
    control periods at which the safeguard changed the law's torque, could not meet all its
    conditions, held a rescue brake; ``saturated_steps``: periods whose torque was clipped to
    the torque limit; ``obstacle_contacts``: the most contacts between the arm and an
    obstacle in MuJoCo at any period; ``blocked_by``: the tracker's ``blocked_by`` (what
    holds the frame off its target); ``outcome``: None, or ``constraint_violated`` /
    ``diverged`` when the episode is ``terminated``. ``truncated`` after
    ``max_episode_steps`` steps. Reset after either before stepping again.

    Attributes:
        setup: the built scenario; ``entry`` the law's entry.
        tracker: the current episode's tracker (its ``requested`` target, ``blocked_by``).
        plant: the MuJoCo plant (``plant.data``: MuJoCo's own state).
        steps_per_action: control periods per ``step``.
        constraint_names: the scenario's constraint rows, as in ``info['margins']``.
        joint_lower, joint_upper: the joints' box (the plant's stops, ±π where a joint has
            none), ``joint_target``'s -1 and 1.
    """

    metadata = {"render_modes": []}  # noqa: RUF012 (gymnasium's class attribute)

    def __init__(self, setup: ScenarioSetup, action: str, settings: EnvSettings) -> None:
        if action not in ACTIONS:
            raise ParameterError("action", f"action must be one of {', '.join(ACTIONS)}, got "
                                           f"{action!r}")
        if setup.goal is None or setup.reference is not None:
            raise ParameterError("scenario", "scenario: a policy streams targets to a law "
                                 "built for a goal: give a goal scenario (goal:), not a joint "
                                 "target or a reference")
        self.setup, self.settings, self.action = setup, settings, action
        self.entry = _entry(setup, settings.controller)
        loop = setup.loop_settings
        h = loop.bounds.period
        try:
            self.steps_per_action = substeps_per_control(1.0 / settings.policy_rate, h)
        except CpbcError:
            raise ParameterError("policy_rate", f"policy_rate: its period must be a whole "
                                 f"number of control periods of {h} s, got "
                                 f"{settings.policy_rate} Hz") from None
        self.plant = setup.make_plant()
        self.substeps = substeps_per_control(h, self.plant.model.opt.timestep)
        # the loop's pieces for one episode; its log holds 2 samples (the env logs nothing)
        self._loop_settings = replace(loop, max_log_samples=2,
                                      log_every=self.steps_per_action)
        model = setup.model
        self._kinematics = RobotModel(model.model, model.coordinates, name=model.name)
        self._frame, self._offset = setup.goal.goal.frame, setup.goal.goal.offset
        self.constraint_names = setup.monitor.names
        self._obstacles = {mujoco.mj_name2id(self.plant.model, mujoco.mjtObj.mjOBJ_GEOM,
                                             ob.name) for ob in setup.obstacles}
        lower, upper = _joint_box(setup, self.plant.model)
        self.joint_lower, self.joint_upper = lower, upper
        self._kind = _kind(action, settings, lower, upper)
        self.action_space = spaces.Box(-1.0, 1.0, (self._kind.size,), np.float32)
        n = model.n
        self.observation_space = spaces.Dict({
            "joint_position": spaces.Box(lower, upper, (n,), np.float64),
            "joint_velocity": spaces.Box(-np.inf, np.inf, (n,), np.float64),
            "frame_position": spaces.Box(-np.inf, np.inf, (3,), np.float64),
            "frame_orientation": spaces.Box(-1.0, 1.0, (4,), np.float64),
        })
        self.tracker: ReferenceTracker | None = None
        self._arm: ArmLoop | None = None
        self._steps = 0
        self._over = True

    @property
    def action_units(self) -> str:
        """What the action's numbers mean, in words."""
        return self._kind.units

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        """A new episode: the arm at rest at a start drawn near the law's posture x_n
        (``start_spread``; seeded by ``seed``), a fresh tracker and safeguard, the applied
        target at the law's goal."""
        super().reset(seed=seed)
        setup, entry = self.setup, self.entry
        x0 = self._start()
        h = setup.loop_settings.bounds.period
        self.tracker = tracking(entry.controller, h, settings=self.settings.governor,
                                run=setup.controller(entry))
        coords = setup.model.coordinates
        self.plant.reset(coords.inverse @ x0, np.zeros(setup.model.n))
        steps = self.settings.max_episode_steps * self.steps_per_action
        self._arm = ArmLoop(self.plant, self.tracker, coords, self._loop_settings, steps)
        self._arm.start(x0)
        self._steps, self._over = 0, False
        x, dx = self._state()
        return self._observe(x, dx), {}

    def step(self, action: Action) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """Stream the action's target, then run one policy period of control periods."""
        arm, tracker = self._arm, self.tracker
        if arm is None or tracker is None or self._over:
            raise CpbcError("the episode has ended (or not begun): call reset() first")
        kind = self._kind
        a = finite_vector(action, kind.size, "action", kind.units).clip(-1.0, 1.0)
        x, dx = self._state()
        kind.send(tracker, a, self._measured(x))
        guard = self._counts(arm)
        low = np.full(len(self.constraint_names), np.inf)
        outcome, contacts = self._run(arm, low)
        x, dx = self._state()
        obs = self._observe(x, dx)
        k = int(np.argmin(low))
        done = self._counts(arm)
        info: dict[str, Any] = {
            "margin": float(low[k]), "closest": self.constraint_names[k], "margins": low,
            "safeguard_steps": done[0] - guard[0],
            "safeguard_infeasible": done[1] - guard[1],
            "rescues": done[2] - guard[2], "saturated_steps": done[3] - guard[3],
            "obstacle_contacts": contacts, "blocked_by": tracker.blocked_by,
            "outcome": outcome,
        }
        self._steps += 1
        terminated = outcome is not None
        truncated = not terminated and self._steps >= self.settings.max_episode_steps
        self._over = terminated or truncated
        return obs, self._reward(obs, info), terminated, truncated, info

    @staticmethod
    def _counts(arm: ArmLoop) -> tuple[int, int, int, int]:
        """The safeguard's counts (acted, infeasible, rescues) and the clipped torques."""
        g = arm.guard
        if g is None:
            return 0, 0, 0, arm.saturated
        return g.acted, g.infeasible, g.rescues, arm.saturated

    def _run(self, arm: ArmLoop, low: Array) -> tuple[str | None, int]:
        """One policy period of control periods (the loop's observe, control, hold), the
        smallest margins from MuJoCo's state after each written into ``low``; the outcome
        (None while the run goes on) and the most arm-obstacle contacts."""
        monitor, data, contacts = self.setup.monitor, self.plant.data, 0
        period = self.setup.loop_settings.bounds.period
        for _ in range(self.steps_per_action):
            state = arm.observe()
            if state is None:
                return "diverged", contacts
            try:
                u = arm.control(arm.k * period, state)
            except ConstraintViolation:
                return "constraint_violated", contacts
            if u is None or not arm.hold(u, self.substeps):
                return "diverged", contacts
            x, dx = self._state()
            np.minimum(low, monitor.margins(x, dx), out=low)
            if data.ncon:
                contacts = max(contacts, _contacts(data, self._obstacles))
        return None, contacts

    def _state(self) -> tuple[Array, Array]:
        """MuJoCo's state in the law's coordinates."""
        data, coords = self.plant.data, self.setup.model.coordinates
        if coords.is_identity:
            return data.qpos.copy(), data.qvel.copy()
        return coords.matrix @ data.qpos, coords.matrix @ data.qvel

    def _measured(self, x: Array) -> Measured:
        kin = self._kinematics.state(x, np.zeros(len(x)), frames=(self._frame,))
        frame = kin.frames[self._frame]
        p, _ = frame.point(self._offset)
        return Measured(x, np.array(p), np.array(frame.rotation))

    def _observe(self, x: Array, dx: Array) -> Observation:
        now = self._measured(x)
        return {"joint_position": x, "joint_velocity": dx, "frame_position": now.position,
                "frame_orientation": matrix_to_quat(now.rotation)}

    def _reward(self, obs: Observation, info: dict[str, Any]) -> float:
        if self.settings.reward is not None:
            return float(self.settings.reward(obs, info))
        assert self.setup.goal is not None
        return -float(np.linalg.norm(obs["frame_position"] - self.setup.goal.goal.position))

    def _start(self) -> Array:
        """x_n, moved by a seeded uniform draw within ± ``start_spread`` per joint, drawn
        again while it is outside the scenario's constraints (at rest) or the joint box."""
        setup = self.setup
        assert setup.goal is not None
        home = setup.goal.posture
        spread = self.settings.start_spread
        rest = np.zeros(setup.model.n)
        for _ in range(STARTS if spread > 0 else 0):
            x = home + self.np_random.uniform(-spread, spread, size=home.shape)
            inside = np.all((x >= self.joint_lower) & (x <= self.joint_upper))
            if inside and np.all(setup.monitor.margins(x, rest) > 0):
                return x
        return home.copy()


def make_env(scenario: str | Path | ScenarioSetup, action: str = "pose_delta",
             **options: Any) -> ScenarioEnv:
    """A Gymnasium environment in which a policy streams targets to a scenario's
    constrained law (``ScenarioEnv``).

    Args:
        scenario: a goal scenario: a shipped scenario's name (``panda_goal_pose``), a
            scenario file, or a built ``ScenarioSetup``.
        action: what the policy's action in [-1, 1]^k is: ``pose_delta`` (k = 6: the frame's
            point by ``max_step`` · a[:3] m and a rotation vector ``max_turn`` · a[3:] rad
            from its measured pose), ``position_delta`` (k = 3, the point alone),
            ``joint_target`` (k = n: the joints' target, -1 at each joint's lower limit,
            1 at its upper) or ``joint_delta`` (k = n: ``max_joint_step`` · a from the
            measured joints).
        **options: the fields of ``EnvSettings`` (``policy_rate``, ``max_episode_steps``,
            ``max_step``, ``start_spread``, ``reward``, …).

    Raises:
        ValueError: an unknown option or action, an option out of its range, or a scenario
            that is not a goal scenario (a ``ScenarioError`` when the file is bad).
    """
    try:
        settings = EnvSettings(**options)
    except TypeError:
        known = ", ".join(EnvSettings.__dataclass_fields__)
        unknown = sorted(set(options) - set(EnvSettings.__dataclass_fields__))
        raise ParameterError("options", f"unknown option(s) {', '.join(unknown)}: make_env "
                                        f"takes {known}") from None
    setup = scenario if isinstance(scenario, ScenarioSetup) else build(*load_scenario(scenario))
    return ScenarioEnv(setup, action, settings)


def _entry(setup: ScenarioSetup, name: str | None) -> ControllerEntry:
    """The scenario's law called ``name``, or (None) its last law with constraints."""
    entries = setup.controllers
    if name is None:
        constrained = [e for e in entries if e.controller.constraints.names]
        return (constrained or entries)[-1]
    for e in entries:
        if e.name == name:
            return e
    raise ParameterError("controller", f"controller must be one of the scenario's laws "
                                       f"({', '.join(e.name for e in entries)}), got {name!r}")


def _joint_box(setup: ScenarioSetup, plant: mujoco.MjModel) -> tuple[Array, Array]:
    """The joints' ranges in the law's coordinates (the plant's stops), ±π where a joint
    has none or the coordinates are not the joints'."""
    lo, hi = joint_ranges(setup.model, plant)
    if not setup.model.coordinates.is_identity:
        lo, hi = np.full_like(lo, -np.pi), np.full_like(hi, np.pi)
    return np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)


def _kind(action: str, settings: EnvSettings, lower: Array, upper: Array) -> ActionKind:
    if action == "pose_delta":
        return PoseDelta(settings.max_step, settings.max_turn)
    if action == "position_delta":
        return PositionDelta(settings.max_step)
    if action == "joint_target":
        return JointTarget(lower, upper)
    return JointDelta(settings.max_joint_step, len(lower))


def _contacts(data: mujoco.MjData, obstacles: set[int]) -> int:
    """Contacts between an obstacle and a geom that is not one (the arm)."""
    return sum(1 for c in data.contact[:data.ncon]
               if (c.geom1 in obstacles) != (c.geom2 in obstacles))
