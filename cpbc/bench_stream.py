"""What a streamed target costs (``python -m cpbc.bench --robot panda``'s ``stream``): the
task-space CPBC of ``panda_goal_pose`` in its safeguard, following targets a policy streams at
50 Hz (cpbc.reference.tracker: a random walk within 3 cm of the goal, a new target every 20
calls), against the same law, built apart, with its fixed goal.

- The step's cost: ``torque`` calls on the same admissible states (cpbc.bench's task-space
  states), each call timed, the two laws taking turns on each state so that a change of the
  machine's load hits both alike; the median over every call of each, their ratio (target ≤
  1.1), and the range of the ratio of the per-round medians. Medians of single calls, not
  means of blocks: on a loaded machine a block's mean takes in whatever preemption fell
  inside it.
- The call's tail: every ``torque`` call timed in a closed 1 kHz MuJoCo loop from the goal's
  posture (the user's own loop, the collector off), the two laws in lock step on a plant
  each; p50, p99, p99.9 and the maximum [µs], and p99.9/p50 (target ≤ 3 for the streamed
  call), in wall time and in the thread's CPU time (``cpu_``: without the time the process
  was preempted, which a loaded machine adds to the wall time's tail).

Nothing is asserted: figures for the docs.
"""

from __future__ import annotations

import gc
import statistics
import time

import numpy as np

from cpbc.arrays import Array
from cpbc.bench_tail import quantiles
from cpbc.controllers.controller import Controller
from cpbc.reference.tracker import ReferenceTracker, tracking

POLICY = 20  # control steps per streamed target (50 Hz at 1 kHz)
WALK = 0.03  # [m]: the policy's targets stay this close to the goal, per axis


class _Policy:
    """A seeded random walk of targets near the goal, one every ``POLICY`` calls."""

    def __init__(self, law: ReferenceTracker, goal: Array, seed: int) -> None:
        self.law, self.goal = law, goal
        self.rng = np.random.default_rng(seed)
        self.walk = goal.copy()
        self.k = 0

    def tick(self) -> None:
        if self.k % POLICY == 0:
            step = self.rng.normal(scale=0.005, size=3)
            self.walk = self.goal + np.clip(self.walk - self.goal + step, -WALK, WALK)
            self.law.set_target(self.walk)
        self.k += 1


def stream_pair(seed: int = 0) -> tuple[Controller, ReferenceTracker, _Policy, Array]:
    """The fixed-goal law in its safeguard, the streamed one (each from its own build of
    ``panda_goal_pose``: a tracker steers its law in place), its policy, and the goal's
    posture."""
    from cpbc.scenario import build, load_scenario

    def guarded() -> tuple[Controller, Controller, Array, Array]:
        setup = build(*load_scenario("panda_goal_pose"))
        assert setup.goal is not None
        entry = next(e for e in setup.controllers if e.controller.type_name == "cpbc")
        return (setup.controller(entry), entry.controller, setup.goal.goal.position,
                setup.goal.posture)

    fixed, _, _, posture = guarded()
    run, law, goal, _ = guarded()
    streamed = tracking(law, 1e-3, run=run)
    return fixed, streamed, _Policy(streamed, goal, seed), posture


def step_cost(fixed: Controller, streamed: ReferenceTracker, policy: _Policy,
              states: list[tuple[Array, Array]], repeats: int) -> dict[str, float]:
    """The two laws' torque calls on ``states``, interleaved (module docstring) [µs]."""
    for x, dx in states[:8]:
        fixed.torque(x, dx)
        policy.tick()
        streamed.torque(x, dx)
    clock = time.perf_counter_ns
    rounds: list[tuple[list[int], list[int]]] = []
    for _ in range(repeats):
        a, b = [], []
        gc.disable()
        try:
            for x, dx in states:
                start = clock()
                fixed.torque(x, dx)
                a.append(clock() - start)
                policy.tick()  # the policy's call is its own, not the control step's
                start = clock()
                streamed.torque(x, dx)
                b.append(clock() - start)
        finally:
            gc.enable()
        rounds.append((a, b))
    fixed_us = statistics.median(t for a, _ in rounds for t in a) / 1e3
    streamed_us = statistics.median(t for _, b in rounds for t in b) / 1e3
    ratios = [statistics.median(b) / statistics.median(a) for a, b in rounds]
    return {"fixed_us": fixed_us, "streamed_us": streamed_us,
            "ratio": streamed_us / fixed_us, "ratio_min": min(ratios),
            "ratio_max": max(ratios)}


def call_tail(fixed: Controller, streamed: ReferenceTracker, policy: _Policy,
              posture: Array, steps: int) -> dict[str, float]:
    """Each law's ``torque`` timed at every step of its own closed loop (module
    docstring): p50 … max [µs] of each, and p99.9/p50."""
    from cpbc.scenario import build, load_scenario

    setup = build(*load_scenario("panda_goal_pose"))
    plants = {"fixed": setup.make_plant(), "streamed": setup.make_plant()}
    laws: dict[str, Controller] = {"fixed": fixed, "streamed": streamed}
    times: dict[str, list[int]] = {k: [] for k in laws}
    cpu: dict[str, list[int]] = {k: [] for k in laws}
    wall, thread = time.perf_counter_ns, time.thread_time_ns
    for plant in plants.values():
        plant.reset(posture, np.zeros(len(posture)))
    gc.disable()
    try:
        for _ in range(steps):
            policy.tick()
            for key, law in laws.items():
                plant = plants[key]
                data = plant.data
                start, start_cpu = wall(), thread()
                tau = law.torque(data.qpos, data.qvel)
                end, end_cpu = wall(), thread()
                times[key].append(end - start)
                cpu[key].append(end_cpu - start_cpu)
                plant.apply(tau)
                plant.step(1)
    finally:
        gc.enable()
    out: dict[str, float] = {}
    for key in laws:
        for clock, found in (("", times[key]), ("cpu_", cpu[key])):
            q = quantiles(found[100:])  # the first steps warm the caches
            out.update({f"{key}_{clock}{name}_us": value for name, value in q.items()})
            out[f"{key}_{clock}p999_over_p50"] = q["p999"] / q["p50"]
    return out


def stream_times(states: list[tuple[Array, Array]], repeats: int,
                 steps: int = 20_000) -> dict[str, float]:
    """The step's cost and the call's tail (module docstring)."""
    fixed, streamed, policy, posture = stream_pair()
    return {**step_cost(fixed, streamed, policy, states, repeats),
            **call_tail(fixed, streamed, policy, posture, steps)}
