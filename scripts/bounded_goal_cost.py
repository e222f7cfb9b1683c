"""What packing the bounded task terms saves: the bare torque call of task-space BPBC and
BPBC-KE (tests/scenarios/panda_goal_bpbc.yaml, panda_goal_pose's goal) as one kernel call,
against the same laws with the ln cosh position spring and the tanh task damping computed as
before they had kernels (numpy on FrameKinematics.point, in subclasses, so the law takes its
general path method by method).

The four laws take turns on each chunk of 8 states in every round, the collector paused in
each round (cpbc.bench.time_interleaved); prints per law the median and range over the
rounds of the mean cost of one call [µs], and the median and range of the per-round ratios
before/after.

    PYTHONPATH=. python scripts/bounded_goal_cost.py [rounds]

(``PYTHONPATH=.``: measure this checkout's package, not an installed copy.)
"""

from __future__ import annotations

import copy
import os
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from bounded_goal import bounded_goal_laws

from cpbc.arrays import Array
from cpbc.bench import time_interleaved
from cpbc.controllers.controller import Controller
from cpbc.controllers.potentials import FramePositionLogCosh, PotentialSum
from cpbc.controllers.potentials.log_cosh import LogCoshSum
from cpbc.controllers.potentials.potential import Placed, frame_at
from cpbc.controllers.task_damping import TaskTanhDamping


class NumpyLogCosh(FramePositionLogCosh):
    """The spring as it was computed before its kernel."""

    def evaluate_toward(self, at: Placed, goal: Array) -> tuple[float, Array]:
        p, jv = frame_at(at, self.frame).point(self.offset)
        value, force = LogCoshSum(self.stiffness, self.xi).evaluate(p - goal)
        return value, jv.T @ force


class NumpyTanh(TaskTanhDamping):
    """The damping as it was computed before its kernel."""

    def force_with(self, at: Placed, dx: Array, feedforward: Array) -> Array:
        _, jv = frame_at(at, self.frame).point(self.offset)
        return jv.T @ (self.gain * np.tanh(self.gamma * (jv @ dx - feedforward)))


def before(law: Controller) -> Controller:
    """A copy of ``law`` with its two bounded task terms computed in numpy."""
    old = copy.copy(law)
    position, *rest = old.potential.parts  # type: ignore[attr-defined]
    damping = old.task_damping  # type: ignore[attr-defined]
    old.potential = PotentialSum((NumpyLogCosh(  # type: ignore[attr-defined]
        position.frame, position.goal, position.stiffness, position.xi, position.reach,
        position.offset), *rest))
    old.task_damping = NumpyTanh(damping.frame, damping.gain, damping.gamma,  # type: ignore[attr-defined]
                                 damping.reach, damping.offset, damping.feedforward)
    return old


def main() -> None:
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 30
    laws, states = bounded_goal_laws(states=64)
    timed: dict[str, Controller] = {}
    for name, law in laws.items():
        timed[f"{name} packed"] = law
        timed[f"{name} before"] = before(law)
        assert law.packed_law().terms is not None  # type: ignore[attr-defined]
        assert timed[f"{name} before"].packed_law().terms is None  # type: ignore[attr-defined]
        for x, dx in states:
            np.testing.assert_allclose(law.torque(x, dx), timed[f"{name} before"].torque(x, dx),
                                       rtol=1e-12, atol=1e-12)
    blocks = time_interleaved(timed, states, rounds)
    print(f"{len(states)} states, {rounds} rounds, load {os.getloadavg()[0]:.2f}")
    for name, spent in blocks.items():
        print(f"{name:16s} median {statistics.median(spent):7.2f} µs  "
              f"range {min(spent):7.2f}–{max(spent):7.2f}")
    for name in laws:
        ratios = [b / a for a, b in zip(blocks[f"{name} packed"], blocks[f"{name} before"],
                                        strict=True)]
        print(f"{name:16s} before/packed median {statistics.median(ratios):.2f}  "
              f"range {min(ratios):.2f}–{max(ratios):.2f}")


if __name__ == "__main__":
    main()
