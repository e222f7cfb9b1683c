"""The admissibility checks of an arm scenario: the target and the initial states inside
the joint ranges and the admissible set, and each start inside the braking set."""

from __future__ import annotations

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.constraints import ConstraintSet
from cpbc.constraints.stopping import Braking, stopping_margins
from cpbc.errors import InadmissibleStateError, ScenarioError
from cpbc.model import RobotModel
from cpbc.scenario import schema as s
from cpbc.scenario.arm_setup import CaseEntry
from cpbc.spec.values import vector


def joint_ranges(model: RobotModel, plant: mujoco.MjModel) -> tuple[Array, Array]:
    """The position ranges the plant enforces (MuJoCo's joint stops), in joint coordinates;
    ±inf where a joint has none."""
    n = model.n
    limited = plant.jnt_limited[:n].astype(bool)
    return (np.where(limited, plant.jnt_range[:n, 0], -np.inf),
            np.where(limited, plant.jnt_range[:n, 1], np.inf))


def check_in_range(
    x: Array, model: RobotModel, ranges: tuple[Array, Array], field: str, what: str
) -> None:
    """A state the joint stops would refuse is bad input, limits declared or not (``what``
    prefixes the message)."""
    q = x if model.coordinates.is_identity else np.linalg.solve(model.coordinates.matrix, x)
    lo, hi = ranges
    for i in np.nonzero((q < lo) | (q > hi))[0]:
        raise ScenarioError(
            field,
            f"{what}joint '{model.joint_names[i]}' = {q[i]:.6g} is outside its range "
            f"[{lo[i]:.6g}, {hi[i]:.6g}] (the model's joint limits, where the plant has a hard "
            "stop): move it inside the range",
        )


def check_admissible(monitor: ConstraintSet, x: Array, dx: Array, what: str,
                      field: str) -> None:
    try:
        monitor.check_admissible(x, dx, what)
    except InadmissibleStateError as exc:
        exc.field = field  # the scenario entry, for callers that map errors to the file
        raise


def initial_states(
    scenario: s.Scenario, model: RobotModel, monitor: ConstraintSet,
    ranges: tuple[Array, Array],
) -> tuple[Array, list[CaseEntry]]:
    """The target and the initial states: the right size, inside the joint ranges and S."""
    n = model.n
    given = [k for k in ("target", "goal", "reference") if getattr(scenario, k) is not None]
    if len(given) != 1:
        raise ScenarioError(given[-1] if given else "target",
                            "give one of target: (a joint set point), goal: (a frame's pose) "
                            f"or reference: (a frame's path), not both {' and '.join(given)}"
                            if given else "missing: give target (a joint set point), goal "
                            "(a frame's pose) or reference (a frame's path)")
    target = np.zeros(n)
    if scenario.target is not None:
        target = vector(scenario.target, n, "target")
        check_in_range(target, model, ranges, "target", "")
        check_admissible(monitor, target, np.zeros(n), "target", "target")
    cases = []
    for i, case in enumerate(scenario.cases):
        x0 = vector(case.position, n, f"cases[{i}].position")
        dx0 = vector(case.velocity, n, f"cases[{i}].velocity", default=0.0)
        check_in_range(x0, model, ranges, f"cases[{i}].position", f"case '{case.name}': ")
        check_admissible(monitor, x0, dx0, f"initial state of case '{case.name}' (cases[{i}])",
                          f"cases[{i}]")
        cases.append(CaseEntry(case.name, x0, dx0))
    if len({c.name for c in cases}) != len(cases):
        raise ScenarioError("cases", "case names must be unique")
    return target, cases


def check_stoppable(cases: list[CaseEntry], monitor: ConstraintSet, model: RobotModel,
                     limit: Array) -> None:
    """Refuse an initial state outside the braking set V: the safeguard's brake, within the
    torque limits, would stop the arm past a configuration boundary
    (cpbc.constraints.stopping.Braking); say whether any torque in the box could."""
    braking = Braking.of(model, limit)
    for i, case in enumerate(cases):
        sigma, travel = braking.margins(monitor, model, case.position, case.velocity)
        if not sigma.size or np.all(sigma > 0):
            continue
        k = int(np.argmin(sigma))
        speed = float(np.linalg.norm(case.velocity))
        lost, _, _ = stopping_margins(monitor, model, case.position, case.velocity, limit)
        verdict = ("no torque within the limits can stop it in time either" if lost[k] <= 0
                   else "a brake aimed at that constraint alone might, but the safeguard's "
                   "brake must slow every joint at once")
        raise ScenarioError(
            f"cases[{i}].velocity",
            f"case '{case.name}' is outside the braking set: at {speed:.4g} rad/s the "
            f"actuators' torque limits leave a brake that slows every joint together "
            f"{travel:.4g} rad of travel to stop, which ends past '{monitor.names[k]}' "
            f"(margin {sigma[k]:.4g} there; cpbc.constraints.stopping.Braking); {verdict}. "
            "Start slower or farther from that boundary, or raise simulation.torque_limit",
        )
