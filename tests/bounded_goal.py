"""panda_goal_pose's goal under the bounded-torque laws (tests/scenarios/panda_goal_bpbc.yaml):
task-space BPBC and BPBC-KE as the scenario builds them (ln cosh position spring, axis
spring, joint ln cosh posture spring, tanh task damping, on a point 10 cm past the hand),
and states admissible for both; the helpers the packed-law and kernel tests share."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cpbc.controllers.controller import Controller
from cpbc.scenario import build, load_scenario

SCENARIO = Path(__file__).resolve().parent / "scenarios" / "panda_goal_bpbc.yaml"


def bounded_goal_laws(states: int, seed: int = 0
                      ) -> tuple[dict[str, Controller], list[tuple[np.ndarray, np.ndarray]]]:
    """The scenario's laws by type name ("bpbc", "bpbc_ke") and ``states`` states spread from
    its start to the goal's posture, with rates that drive the tanh damping into saturation
    on some axes, inside both laws' constraints."""
    setup = build(*load_scenario(SCENARIO))
    laws = {e.controller.type_name: e.controller for e in setup.controllers}
    rng = np.random.default_rng(seed)
    start, posture = setup.cases[0].position, setup.target
    picked: list[tuple[np.ndarray, np.ndarray]] = []
    while len(picked) < states:
        s = rng.uniform()
        x = (1 - s) * start + s * posture + rng.normal(scale=0.2, size=start.shape[0])
        dx = rng.normal(scale=0.4, size=start.shape[0])
        if all(np.all(law.constraints.margins(x, dx) > 0) for law in laws.values()):
            picked.append((x, dx))
    return laws, picked
