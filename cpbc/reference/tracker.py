"""A law that follows a moving reference: ``ReferenceTracker`` wraps a law built for a
goal, steers its springs and damping to a ``MovingTarget``, and
each control step (one ``evaluate`` call) moves the target, either along a planned path
under the ``PathGovernor``, or toward a streamed target set
with ``ReferenceTracker.set_target`` (teleoperation, a learned policy), by the classical
ERG attraction

    v ← v + h · min(κ Δ, 1) · v_max · (r − v)/max(|r − v|, v_max h),   Δ = max(0, Γ − V̄)/Γ

with V̄ normalised at the law's posture x_n, which a streamed target leaves where it is
(no path to continue it along: far targets leave a posture-spring compromise).

It is a Controller like any law, so cpbc.simulation.loop.run_mujoco runs it unchanged; it
knows nothing of the simulator (its clock is its own count of control steps).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from cpbc.arrays import Array
from cpbc.controllers.controller import Controller, Evaluation, SafetyFilter
from cpbc.controllers.potentials import FrameAxisSpring, FrameOrientationSpring
from cpbc.errors import ParameterError
from cpbc.model.measured_state import finite_vector
from cpbc.model.robot_model import ArmState, RobotModel
from cpbc.reference.governor import GovernorSettings, PathGovernor
from cpbc.reference.holding import holding_constraint
from cpbc.reference.plan import ReferencePlan, log_norm
from cpbc.reference.rotations import angle_between, rotation_matrix, turned_toward
from cpbc.reference.stream_checks import positive_period, state_vector
from cpbc.reference.target import Follower, MovingTarget, Steered, steer

REACHED = 0.01  # [m]: a frame this close to its streamed point has reached it
REACHED_JOINTS = 0.01  # [rad or m]: every joint this close to its streamed target
STALLED = 0.01  # [m/s]: a frame slower than this is at rest
STALLED_JOINTS = 0.01  # [rad/s or m/s]: joints all slower than this are at rest


class ReferenceTracker(Controller):
    """A law that follows a moving target: a planned path under the reference governor, or
    targets streamed by a policy or a teleoperator (``set_target``, ``set_pose``,
    ``set_joint_target``) at any rate, each moved toward at the governor's pace
    (the ERG attraction of this module). It is a controller like any law: ask it for a
    torque at the control rate (``torque(x, dx)``, or the loop of
    cpbc.simulation.loop.run_mujoco).

    Args:
        law: a law built for a goal (a task potential with a posture spring).
        period: the control period h [s].
        plan: a planned path (cpbc.reference.plan.plan_reference), or None for a streamed
            target starting at the law's goal.
        settings: the governor's settings.
        feedforward: pass ṗ_ff = ṡ_v dp/ds to the task damping (else ṗ_ff = 0).
        run: the controller that computes the torque, when not ``law`` itself: the law
            wrapped in its sampled-data safeguard (cpbc.controllers.safeguard.guarded), which
            holds the same, steered, law object. Use ``tracking`` to get a tracker that
            reports such a safeguard's counts to the loop.

    Raises:
        ParameterError: (a ``ValueError``) ``period`` is not a finite number > 0, or ``law``
            has no frame position spring to steer.

    Attributes:
        requested: the streamed point p_r [m] (for a joint target, its forward kinematics).
        requested_posture: the streamed joint target, or None.
        requested_rotation: the streamed orientation R_r, or None.
        frame_name: the frame whose point a streamed point target moves (``frame`` its id,
            ``offset`` the point in its axes, None for its origin).
        moving: the applied target (point, posture and their feed-forward) the law reads.
        pace: the last step's share min(κΔ, 1) of the governor's top speeds.
        log_s: along a plan, s_v per step (``log_blocked``, ``log_applied`` likewise).

    A law follows one tracker at a time: a second tracker on the same law steers it to its
    own target, and the first one's targets no longer reach it.
    """

    def __init__(self, law: Controller, period: float, plan: ReferencePlan | None = None,
                 settings: GovernorSettings | None = None, feedforward: bool = True,
                 run: Controller | None = None) -> None:
        h = positive_period(period)
        start, frame, offset = _spring_point(law)
        super().__init__(law.model, law.target, law.constraints)
        self.run = law if run is None else run
        self.type_name = law.type_name  # type: ignore[misc]
        self.law, self.h, self.plan, self.feedforward = law, h, plan, feedforward
        self.frame, self.offset = frame, offset
        self.frame_name = str(self.model.model.frames[frame].name)
        # the frame's kinematics between steps (a joint target, blocked_by) on data of its
        # own: the law's model data holds its step's pass, which nothing else may touch
        self._kinematics = RobotModel(law.model.model, law.model.coordinates,
                                      name=law.model.name)
        self.settings = settings or GovernorSettings()
        if plan is not None:
            start = plan.points[0]
        posture = plan.postures[0] if plan is not None else law.target
        self.moving = MovingTarget(start, posture)
        steer(law, self.moving)
        self.potential, self.task_damping = law.potential, law.task_damping
        self.torque_bound = law.torque_bound
        self.governor = None if plan is None else PathGovernor(
            self.settings, plan.path.duration, h, plan.postures_path.stretches,
            plan.blend_times)
        self.stream_norm = math.exp(log_norm(law, self.moving.posture))
        self.requested = self.moving.position.copy()
        self.requested_velocity = np.zeros(3)
        self.requested_posture: Array | None = None  # a streamed joint target, else None
        self.home = self.moving.posture.copy()  # the law's x_n, where a point stream keeps it
        self._posture_away = False  # whether the applied posture is off x_n or streamed
        self._arrived = False  # the applied point is at a still requested point, x_n at rest
        self._fed = self._spinning = False  # a nonzero ṗ_r, ω_r is streamed
        self._gap = np.zeros(3)  # work space of the point's step
        self.requested_rotation: Array | None = None  # a streamed orientation, else None
        self.requested_angular_velocity = np.zeros(3)  # its ω_r, the angular feed-forward
        self._rotation_away = False  # whether the applied rotation is turning toward it
        self.requested_posture_velocity = np.zeros(self.model.n)
        self._last: tuple[Array, Array] | None = None  # the state of the last step
        self.pace = 1.0  # the last step's share min(κΔ, 1) of the governor's top speed
        self.k = 0
        self.log_s: list[float] = []
        self.log_blocked: list[bool] = []
        self.log_applied: list[Array] = []

    @property
    def frames(self) -> tuple[int, ...]:
        """The frames the wrapped law reads (its potential's, or a peer nominal's)."""
        return self.law.frames

    @property
    def reads_motion(self) -> bool:
        """Whether the wrapped law reads the constraints' second-order terms (a peer's)."""
        return self.law.reads_motion

    def start_at(self, phase: float) -> None:
        """Begin the path at path time ``phase`` (outside its stretches) instead of 0: the
        governor's s_v and clock, and the target at the path's point and posture there."""
        assert self.plan is not None and self.governor is not None
        self.governor.start_at(phase)
        self.k = round(phase / self.h)
        row = _between(self.plan.rows, phase, self.plan.period)
        self.moving.set(row[:3], None, row[3:])

    def set_target(self, position: ArrayLike, velocity: ArrayLike | None = None) -> None:
        """Stream a target point for the law's frame: ``position`` p_r [m] in the world
        frame, 3 finite numbers, and its ``velocity`` ṗ_r [m/s] for the feed-forward (None:
        zero), from the next step on; it replaces a streamed joint target (the posture
        then returns to the law's x_n). The applied point moves toward it at the
        governor's pace, however far it is.

        Raises:
            ParameterError: (a ``ValueError``) ``position`` or ``velocity`` is not 3 finite
                numbers; the previous target stays in force.
        """
        p, v = self._point(position, velocity)
        self.requested[:] = p
        self.requested_velocity[:] = 0.0 if v is None else v
        self.requested_posture = None
        self.requested_posture_velocity[:] = 0.0
        self.requested_angular_velocity[:] = 0.0
        self._fed, self._spinning = bool(v is not None and v.any()), False
        self._arrived = False

    def set_pose(self, position: ArrayLike, rotation: ArrayLike,
                 velocity: ArrayLike | None = None,
                 angular_velocity: ArrayLike | None = None) -> None:
        """Stream a pose for the law's frame: its point's ``position`` as
        ``set_target``, and its ``rotation`` R_r in the world, a 3 × 3 rotation matrix
        or a unit quaternion (w, x, y, z), toward which the law's orientation spring is
        turned (an axis spring: its world axis to R_r a_b, the rotation about it left
        free) along the shortest rotation, at most ``max_angular_speed`` at the governor's
        pace; ``velocity`` ṗ_r [m/s] is the point's feed-forward and ``angular_velocity``
        ω_r [rad/s] (world axes; None: zero) the frame's: once the applied orientation is
        R_r, the task damping damps J_ω ẋ − ω_r (no faster than ``max_angular_speed`` at
        the governor's pace; an axis goal's damping leaves the spin about its axis free, and
        the bounded laws' tanh damping has no angular term to read it). A later point
        target keeps the orientation (with no angular feed-forward).

        The first pose steers the law's orientation spring to the applied orientation; the
        law keeps its compiled step, which reads it (and ω_r) before each step.

        Raises:
            ParameterError: (a ``ValueError``) ``position``, ``rotation``, ``velocity`` or
                ``angular_velocity`` is not as above, or the law has no orientation spring
                on the frame; the previous target stays in force.
        """
        p, v = self._point(position, velocity)
        r = rotation_matrix(rotation, "rotation")
        w = None if angular_velocity is None else finite_vector(
            angular_velocity, 3, "angular_velocity",
            f"the angular velocity of frame '{self.frame_name}' in the world [rad/s]")
        if self.moving.rotation is None:
            self._steer_orientation()
        self.requested[:] = p
        self.requested_velocity[:] = 0.0 if v is None else v
        self.requested_posture = None
        self.requested_posture_velocity[:] = 0.0
        self.requested_angular_velocity[:] = 0.0 if w is None else w
        self._fed = bool(v is not None and v.any())
        self._spinning = bool(w is not None and w.any())
        self.requested_rotation = r
        self._rotation_away = True
        self._arrived = False

    def _point(self, position: ArrayLike, velocity: ArrayLike | None
               ) -> tuple[Array, Array | None]:
        """A streamed point and its velocity, checked."""
        p = finite_vector(position, 3, "position", f"the target point of frame "
                                                   f"'{self.frame_name}' in the world [m]")
        v = None if velocity is None else finite_vector(
            velocity, 3, "velocity", "the velocity of the target point of frame "
                                     f"'{self.frame_name}' [m/s]")
        return p, v

    def _steer_orientation(self) -> None:
        """Steer the law's orientation (or axis) spring on the frame to the applied
        rotation, which starts at the spring's goal (an axis spring's: the frame's rotation
        at the law's posture x_n)."""
        parts = getattr(self.law.potential, "parts", (self.law.potential,))
        springs = [getattr(q, "spring", q) for q in parts]
        found = [q for q in springs if isinstance(q, FrameOrientationSpring | FrameAxisSpring)
                 and q.frame == self.frame]
        if not found or isinstance(self.law, Follower):
            raise ParameterError("rotation", "rotation: the law has no orientation or axis "
                                             f"spring on frame '{self.frame_name}' to stream "
                                             "an orientation to: stream points (set_target), "
                                             "or build the law for a goal with an orientation")
        spring = found[0]
        if isinstance(spring, FrameOrientationSpring):
            self.moving.orient(spring.rotation)
        else:
            kin = self._kinematics.state(self.home, np.zeros(self.model.n),
                                         frames=(self.frame,)).frames[self.frame]
            self.moving.orient(kin.rotation, spring.tool)
        steer(self.law, self.moving)
        self.potential = self.law.potential

    def set_joint_target(self, joints: ArrayLike, velocity: ArrayLike | None = None
                         ) -> None:
        """Stream a joint target: ``joints`` x_r, n finite numbers in the law's coordinates
        [rad or m], and their ``velocity`` ẋ_r (None: zero), from the next step on. The
        posture x_n and the frame's point (at x_r's forward kinematics) move toward it
        together at the governor's pace (``max_speed`` for the point, ``max_joint_speed``
        for the joints); it replaces a streamed point target.

        Raises:
            ParameterError: (a ``ValueError``) ``joints`` or ``velocity`` is not n finite
                numbers; the previous target stays in force.
        """
        n = self.model.n
        x = finite_vector(joints, n, "joints", "a target for joints "
                                               f"{', '.join(self.model.joint_names)}")
        v = np.zeros(n) if velocity is None else finite_vector(
            velocity, n, "velocity", "the joint target's velocity")
        kin = self._kinematics.state(x, v, frames=(self.frame,)).frames[self.frame]
        p, jv = kin.point(self.offset)
        self.requested[:] = p
        self.requested_velocity[:] = jv @ v
        self.requested_posture = x
        self.requested_posture_velocity[:] = v
        self.requested_angular_velocity[:] = 0.0
        self._fed, self._spinning = bool(self.requested_velocity.any()), False
        self._posture_away = True
        self._arrived = False

    def state(self, x: Array, dx: Array) -> ArmState:
        """The per-step state the torque's controller reads at (x, ẋ), each n finite
        numbers (else ParameterError naming ``x`` or ``dx``)."""
        n = self.model.n
        shape = (n,)
        # the hot path: both arrays of n finite numbers, checked by one finite sum of squares
        if getattr(x, "shape", None) == shape == getattr(dx, "shape", None) and (
                math.isfinite(float(x.dot(x) + dx.dot(dx)))):
            return self.run.state(x, dx)
        return self.run.state(state_vector(x, n, "x"), state_vector(dx, n, "dx"))

    @property
    def blocked_by(self) -> str | None:
        """What holds the frame off its target: with a plan, the constraint that blocks the
        governor (None when it is not blocked); with a streamed target, at the last step's
        state, the constraint whose barrier holds the arm at rest short of the target
        (cpbc.reference.holding), or ``unreachable`` when none does, and None while the
        applied target is still on its way, the arm is moving (frame faster than
        ``STALLED``; for a joint target a joint faster than ``STALLED_JOINTS``) or the
        target is reached (within ``REACHED``, ``REACHED_JOINTS``). The applied target
        stalls on its way when the law's normalised V̄ nears the governor's budget Γ
        (``pace`` × ``max_speed`` below ``STALLED``): a target held off so is reported
        too."""
        if self.governor is not None:
            blocked = self.governor.blocked
            return None if blocked is None else blocked[2]
        on_way = not np.array_equal(self.moving.position, self.requested)
        if self._last is None or (on_way and self.pace * self.settings.max_speed > STALLED):
            return None
        x, dx = self._last
        if self.requested_posture is not None:
            pull = self.requested_posture - x
            reached = float(np.max(np.abs(pull))) <= REACHED_JOINTS
            moving = float(np.max(np.abs(dx))) > STALLED_JOINTS
        else:
            kin = self._kinematics.state(x, dx, frames=(self.frame,)).frames[self.frame]
            p, jv = kin.point(self.offset)
            error = p - self.requested
            pull = -(jv.T @ error)
            reached = float(np.linalg.norm(error)) <= REACHED
            moving = float(np.linalg.norm(jv @ dx)) > STALLED
        if reached or moving:
            return None
        return holding_constraint(self.constraints, x, pull)

    def prime(self, x: Array, dx: Array) -> None:
        self.run.prime(x, dx)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        out = self.run.evaluate_state(state, margins)
        if self.plan is not None:
            self._follow_path(self.plan, out.lyapunov)
        else:
            self._last = (state.x.copy(), state.dx.copy())
            self._follow_stream(out.lyapunov)
        self.k += 1
        return out

    def _follow_path(self, plan: ReferencePlan, v: float) -> None:
        gov = self.governor
        assert gov is not None
        i = plan.index(gov.s)
        vbar = v * math.exp(plan.log_norm[i])
        # the fastest table segment a step (≤ ρ_max h) can reach: v_max holds across jumps
        k = min(int(gov.s / plan.period), len(plan.speeds) - 1)
        s = gov.advance(self.k * self.h, vbar, max(plan.speeds[k:k + 3]))
        j = plan.index(s)
        row = _between(plan.rows, s, plan.period)  # the point and the posture at once
        point, posture = row[:3], row[3:]
        if gov.blend is not None:  # a rejoin carries the reference over a stretch
            end = plan.index(gov.blocked[1]) if gov.blocked else j
            w = gov.blend
            self.moving.set((1 - w) * point + w * plan.points[end], None,
                            (1 - w) * posture + w * plan.postures[end])
        else:
            rate = gov.rate if self.feedforward else 0.0
            ahead = rate * plan.row_tangents[j]
            self.moving.set(point, ahead[:3], posture, ahead[3:])
        self.log_s.append(s)
        self.log_blocked.append(gov.blocked_now)
        self.log_applied.append(self.moving.position.copy())

    def _follow_stream(self, v: float) -> None:
        """One ERG step of the applied point toward the requested one, and of the applied
        posture toward a streamed joint target (after one, back to the law's x_n once a
        point is streamed again), at one share of the way for both; the feed-forward is
        passed once there, no faster than the pace."""
        st, target = self.settings, self.moving
        vbar = v * self.stream_norm  # normalised at the law's posture x_n
        pace = min(st.gain * max(0.0, st.budget - vbar) / st.budget, 1.0)
        self.pace = pace
        if self._arrived:  # at a still target: nothing moves
            return
        if not (self._posture_away or self._rotation_away):  # the point alone moves
            self._move_point(pace)
            return
        gap = self.requested - target.position
        share = _share(math.hypot(*gap), self.h * pace * st.max_speed)
        goal = self.home if self.requested_posture is None else self.requested_posture
        turn = goal - target.posture
        share = min(share, _share(math.hypot(*turn),
                                  self.h * pace * st.max_joint_speed))
        rotation, aim = target.rotation, self.requested_rotation
        if self._rotation_away and rotation is not None and aim is not None:
            share = min(share, _share(angle_between(rotation, aim),
                                      self.h * pace * st.max_angular_speed))
            target.turn(turned_toward(rotation, aim, share))
            self._rotation_away = share < 1.0
        target.set(target.position + share * gap,
                   _capped(self.requested_velocity, pace * st.max_speed, share),
                   target.posture + share * turn,
                   _capped(self.requested_posture_velocity, pace * st.max_joint_speed,
                           share), self._spin(pace))
        self._posture_away = self.requested_posture is not None or share < 1.0

    def _move_point(self, pace: float) -> None:
        """The applied point's step toward the requested one alone (the hot path: in place,
        with nothing to write when the pace is zero and no feed-forward is streamed)."""
        target, speed = self.moving, self.settings.max_speed
        step = self.h * pace * speed
        if step == 0.0 and not (self._fed or self._spinning or target.fed):
            return  # held where it is (V̄ at or over the budget)
        gap = np.subtract(self.requested, target.position, out=self._gap)
        distance = math.hypot(*gap)  # no overflow for a huge finite target
        if distance <= step:
            target.set(self.requested, _capped(self.requested_velocity, pace * speed, 1.0)
                       if self._fed else None, angular_velocity=self._spin(pace))
            self._arrived = not (self._fed or self._spinning)
            return
        gap *= step / distance
        gap += target.position
        target.set(gap)

    def _spin(self, pace: float) -> Array | None:
        """The angular feed-forward ω_r once the applied orientation has reached the
        streamed one, no faster than the pace allows; None (zero) before."""
        if self._rotation_away or not self._spinning:
            return None
        return _capped(self.requested_angular_velocity, pace * self.settings.max_angular_speed,
                       1.0)


class GuardedReferenceTracker(ReferenceTracker, SafetyFilter):
    """A tracker whose ``run`` is a safety filter: the loop reads the filter's counts."""

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        out = super().evaluate_state(state, margins)
        run = self.run
        assert isinstance(run, SafetyFilter)
        self.acted, self.infeasible = run.acted, run.infeasible
        self.rescues, self.out_of_tests = run.rescues, run.out_of_tests
        return out

    @property
    def row_active_steps(self) -> int:
        run = self.run
        assert isinstance(run, SafetyFilter)
        return run.row_active_steps

    def holding(self, tau: Array, added: Array | None = None) -> None:
        run = self.run
        assert isinstance(run, SafetyFilter)
        run.holding(tau, added)


def tracking(law: Controller, period: float, plan: ReferencePlan | None = None,
             settings: GovernorSettings | None = None, feedforward: bool = True,
             run: Controller | None = None) -> ReferenceTracker:
    """A law that follows a moving target: a ``ReferenceTracker``, or a
    ``GuardedReferenceTracker`` (which reports the safeguard's counts to the loop) when
    ``run`` is a safety filter.

    Args:
        law: a law built for a goal (a task potential: a frame position spring and a
            posture spring).
        period: the control period h [s], > 0: the tracker's clock is its count of steps.
        plan: a planned path, or None to stream targets (``set_target``, ``set_pose``,
            ``set_joint_target``), starting at the law's goal.
        settings: the reference governor's settings (``GovernorSettings()`` when omitted).
        feedforward: pass the reference's velocity to the task damping.
        run: the controller that computes the torque (the law in its safeguard), when not
            ``law`` itself.

    Raises:
        ParameterError: (a ``ValueError``) ``period`` is not a finite number > 0, or ``law``
            has no frame position spring to steer.
    """
    cls = GuardedReferenceTracker if isinstance(run, SafetyFilter) else ReferenceTracker
    return cls(law, period, plan, settings, feedforward, run)


def _between(table: Array, s: float, h: float) -> Array:
    """The table's row at path time s, linear between the control grid's rows (so that the
    applied point moves no faster than s does along a jump of the path)."""
    x = s / h
    i = min(int(x), len(table) - 2)
    w = min(max(x - i, 0.0), 1.0)
    return (1.0 - w) * table[i] + w * table[i + 1]


def _share(distance: float, step: float) -> float:
    """The share of the way a step of length ``step`` covers (1 when it gets there)."""
    return 1.0 if distance <= step else step / distance


def _capped(velocity: Array, speed: float, share: float) -> Array | None:
    """The feed-forward once the target is reached (``share`` 1), no faster than ``speed``;
    None (zero) on the way."""
    if share < 1.0 or not speed > 0:
        return None
    size = math.hypot(*velocity)
    return velocity if size <= speed else velocity * (speed / size)


def _spring_point(law: Controller) -> tuple[Array, int, Array | None]:
    """The goal, frame and offset of the law's frame position spring (as built, or as a
    tracker steered it before), or of a follower's operational-space nominal (the CBF-QP
    peer's ``osc``, cpbc.peers.osc): the streamed target's start and the point it moves."""
    from cpbc.controllers.potentials import PotentialSum

    nominal = getattr(law, "osc", None) if isinstance(law, Follower) else None
    if nominal is not None:
        goal = nominal.goal
        return np.array(nominal.target.position, dtype=float), goal.frame, goal.offset
    pot = law.potential
    for part in pot.parts if isinstance(pot, PotentialSum) else (pot,):
        spring = part.spring if isinstance(part, Steered) else part
        goal = getattr(spring, "goal", None)
        if goal is not None and np.shape(goal) == (3,):
            return np.array(goal, dtype=float), spring.frame, spring.offset  # type: ignore[union-attr]
    raise ParameterError("law", f"law: a {law.type_name} law without a frame position "
                                "spring cannot follow a streamed target; build it for a "
                                "frame goal (a task potential)")
