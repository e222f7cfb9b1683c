"""The admissibility checks of an arm scenario: the target and the initial states inside
the joint ranges and the admissible set, and each start inside the braking set."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.constraints import ConstraintSet
from cpbc.constraints.brakes import (
    Brake,
    Stop,
    TorqueBox,
    brakes,
    brings_to_rest,
    first_stop,
    model_advance,
)
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
                    limit: Array, period: float, rate: Array | None = None) -> dict[str, str]:
    """Refuse an initial state that no brake within the torque (and torque-rate) limits
    stops before a configuration boundary, in the controller's model: the uniform brake of
    the braking set V (cpbc.constraints.stopping.Braking) and, outside V, the rescue's
    brakes held until rest (cpbc.constraints.brakes, ramped from the gravity torque at the
    start under a rate limit). A start outside V that one of those stops runs (the
    safeguard's rescue holds that brake); it is returned, per case, as a note to print."""
    braking = Braking.of(model, limit, rate=rate)
    outside: dict[str, str] = {}
    for i, case in enumerate(cases):
        sigma, travel = braking.margins(monitor, model, case.position, case.velocity,
                                        period=period)
        in_v = not sigma.size or bool(np.all(sigma > 0))
        # under a rate limit a moving start may lose a velocity margin while the torque
        # ramps, which V (configuration margins) does not see: a brake must show it stops
        if in_v and (rate is None or not np.any(case.velocity)):
            continue
        brake = _stopping_brake(monitor, model, limit, rate, period, case)
        k = int(np.argmin(sigma)) if sigma.size else 0
        speed = float(np.linalg.norm(case.velocity))
        where = (f"at {speed:.4g} rad/s the brake that slows every joint together within the "
                 f"motors' limits travels {travel:.4g} rad to stop, which ends past "
                 f"'{monitor.names[k]}' (margin {sigma[k]:.4g} there)") if not in_v else (
                 f"at {speed:.4g} rad/s, with the torque ramping at the motors' rate limit")
        if brake is not None:
            if not in_v:
                outside[case.name] = (
                    f"case '{case.name}' starts outside the safeguard's braking set V: "
                    f"{where}; the {brake.replace('_', ' ')} brake stops it in the model, "
                    "and the safeguard's rescue holds it there")
            continue
        _refuse(i, case, monitor, model, limit, rate, where, k, in_v)
    return outside


def _refuse(i: int, case: CaseEntry, monitor: ConstraintSet, model: RobotModel,
            limit: Array, rate: Array | None, where: str, k: int, in_v: bool) -> None:
    """The refusal of a start no brake stops (check_stoppable)."""
    if in_v:
        verdict = ("no brake within the torque and torque-rate limits (uniform, "
                   "least-squares, aimed), ramped from the gravity torque, keeps every "
                   "constraint")
    else:
        lost, _, _ = stopping_margins(monitor, model, case.position, case.velocity, limit)
        verdict = ("no torque within the limits can stop it in time either" if lost[k] <= 0
                   else "nor does any of the rescue's brakes (least-squares, aimed)")
    raise ScenarioError(
        f"cases[{i}].velocity",
        f"case '{case.name}' cannot be stopped inside the constraints: {where}; "
        f"{verdict}. Start slower or farther from that boundary, or raise "
        "simulation.torque_limit" + ("" if rate is None else
                                     " or simulation.torque_rate_limit"),
    )


def _stopping_brake(monitor: ConstraintSet, model: RobotModel, limit: Array,
                    rate: Array | None, period: float, case: CaseEntry) -> str | None:
    """The first of the rescue's brakes that, held in the model at ``period`` (ramped at
    ``rate`` from the gravity torque), brings the case's start to rest with every
    configuration margin positive; None if none does."""
    box = TorqueBox.of(model, limit)
    table = brakes(box, monitor, model)
    x, dx = case.position, case.velocity
    steps = max(math.ceil(period / 0.001 - 1e-9), 1)

    def run(brake: Brake) -> Stop:
        advance = model_advance(model, box, x, dx, period, steps,
                                None if rate is None else rate * period, model.gravity(x))
        return brings_to_rest(brake, model, monitor.margins_along, advance, x, dx, period)

    # the cheapest first: any brake that stops it will do (a least-squares brake solves a
    # bounded least-squares problem every period, ~1 ms; held for a ramped stop, ~25 s)
    return first_stop(("uniform", "least_squares", "aimed"), table, run)[0]
