"""The logged closed-loop trajectory of one run: an arm's (:class:`Trajectory`) or a Part I
system's (:class:`SystemTrajectory`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array

OUTCOMES = ("completed", "diverged", "constraint_violated")


@dataclass(frozen=True)
class Trajectory:
    """Samples at the control instants, in the controller's coordinates.

    Attributes:
        time: (N,) [s].
        position, velocity: (N, n) [rad, rad/s].
        torque: (N, n) generalised forces the controller asked for.
        joint_torque: (N, n) joint torques applied to the plant (after any saturation).
        lyapunov: (N,) the controller's V at each sample (NaN where undefined).
        outcome: how the run ended: one of OUTCOMES.
        end_time: simulated time at the end [s].
        violated: name of the enforced constraint that crossed zero, if any.
        wall_time: wall-clock time of the loop [s].
        control_steps: number of controller calls.
        saturated_steps: control steps in which a torque limit clipped the command.
        max_contacts: largest number of MuJoCo contacts seen (0 for the reference backend).
        backend: "mujoco" or "reference".
        safeguard_steps: control steps at which the sampled-data safeguard replaced the law's
            torque (0 without a safeguard).
        safeguard_infeasible: of those, steps at which even its braking torque could not
            keep every margin above its floor.
        filter_row_steps: of the safeguard steps, those at which the filter's own safety
            conditions, not the torque box alone, changed the torque (a peer's barrier rows;
            the guard's every step).
        rescues: control steps at which the safeguard held its rescue's brake.
        out_of_tests: control steps that spent the safeguard's budget of tests.
        rejected_samples: noisy measurements outside S (true state inside) that the law
            refused; the law at a rate scaled into S, or a brake, was held instead.
        guarded_steps: per control step, whether the safeguard replaced the law's torque
            (None without a safeguard).
        rate_limited_steps: control steps in which the motors' torque-rate limit clipped the
            command (0 under a safeguard that knows the limit: it never asks for more).
        peak_torque_rate: per joint, the largest |Δτ_q|/h between successive commands, the
            first one from the torque held before the run [N·m/s] (None: not measured, the
            reference backend).
        controller_time_max, controller_time_mean: the wall time of the controller's
            longest call and of its mean call in the loop (the law with its safeguard, the
            state's Pinocchio pass included) [s]; None for the reference backend.
    """

    time: Array
    position: Array
    velocity: Array
    torque: Array
    joint_torque: Array
    lyapunov: Array
    outcome: str
    end_time: float
    violated: str | None
    wall_time: float
    control_steps: int
    saturated_steps: int
    max_contacts: int
    backend: str
    safeguard_steps: int = 0
    safeguard_infeasible: int = 0
    rejected_samples: int = 0
    guarded_steps: Array | None = None
    filter_row_steps: int = 0
    rescues: int = 0
    out_of_tests: int = 0
    rate_limited_steps: int = 0
    peak_torque_rate: Array | None = None
    controller_time_max: float | None = None
    controller_time_mean: float | None = None

    @property
    def steps_per_second(self) -> float:
        return self.control_steps / self.wall_time if self.wall_time > 0 else float("nan")


@dataclass(frozen=True)
class SystemTrajectory:
    """Samples at the control instants.

    Attributes:
        time: (N,) [s].
        state: (N, n) the law's state x.
        input: (N,) the input u applied from each sample on (NaN where the law is undefined).
        outcome: "completed", "diverged" or "constraint_violated" (the state left the law's
            domain: ``violated`` names the error variable).
        end_time: simulated time at the end [s].
        wall_time: wall-clock time of the loop [s].
        backend: "mujoco" or "reference".
        qpos, qvel: (N, nq), (N, nv) MuJoCo's coordinates at the samples (for the 3-D view);
            the reference backend sets them from x (a coordinate x omits stays at zero), or
            leaves them None for a plant that is only its ODE (no MJCF, nothing to show).
    """

    time: Array
    state: Array
    input: Array
    outcome: str
    end_time: float
    violated: str | None
    wall_time: float
    backend: str
    qpos: Array | None = None
    qvel: Array | None = None


class TrajectoryLog:
    """Preallocated log that grows by doubling; decimated by ``every``.

    One row per sample, [t, V, x, ẋ, τ, τ_q], written in a single assignment (cheaper per
    control step than one per quantity). With ``limit``, it never holds more than ``limit``
    samples: when full, it keeps every other sample and doubles ``every``, so a run of any
    length logs on a uniform grid in bounded memory (forced samples, such as the last one,
    are always taken).
    """

    def __init__(self, n: int, capacity: int, every: int = 1, limit: int | None = None) -> None:
        self.n = n
        self.every = max(1, every)
        # An even limit keeps the compacted samples on the grid of the doubled ``every``.
        self.limit = None if limit is None else max(2, limit - limit % 2)
        cap = max(16, capacity // self.every + 2)
        if self.limit is not None:
            cap = min(cap, self.limit)
        self._rows = np.empty((cap, 2 + 4 * n))
        self._k = 0
        self._calls = 0

    def record(self, t: float, v: float, x: Array, dx: Array, tau: Array, tau_q: Array,
               force: bool = False) -> None:
        if not force and self._calls % self.every:
            self._calls += 1
            return
        self._calls += 1
        if self.limit is not None and self._k >= self.limit:
            self._compact()
        if self._k == self._rows.shape[0]:
            grown = np.empty((2 * self._k, self._rows.shape[1]))
            grown[: self._k] = self._rows
            self._rows = grown
        self._rows[self._k] = (t, v, *x.tolist(), *dx.tolist(), *tau.tolist(), *tau_q.tolist())
        self._k += 1

    def _compact(self) -> None:
        """Keep samples 0, 2, 4, … and log at half the rate from now on."""
        keep = (self._k + 1) // 2
        self._rows[:keep] = self._rows[: self._k : 2]
        self._k = keep
        self.every *= 2

    @property
    def nbytes(self) -> int:
        """Memory held by the log's buffer [bytes]."""
        return self._rows.nbytes

    def arrays(self) -> tuple[Array, Array, Array, Array, Array, Array]:
        """time, position, velocity, torque, joint torque, V."""
        rows, n = self._rows[: self._k], self.n
        x, dx, tau, tau_q = (rows[:, 2 + i * n: 2 + (i + 1) * n].copy() for i in range(4))
        return rows[:, 0].copy(), x, dx, tau, tau_q, rows[:, 1].copy()
