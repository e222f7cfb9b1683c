"""Benchmark set-ups of URDF arms for ``python -m cpbc.bench --robot panda``.

The Panda of ``scenarios/panda_cpbc_sphere.yaml`` with every kind of arm constraint at once:
its 14 URDF joint position limits (one two-sided limit per joint), 7 joint rate limits and
three obstacles (a table plane, a ball and a crate) against every link, each link covered by
spheres from its collision mesh (33 spheres, 99 sphere–obstacle pairs, 30 reported
constraints). Torque calls are timed on states spread along the reach from start to target
(52 of the 64 have a link sphere within the 10 cm influence distance of an obstacle); the
closed loop runs the reach itself in MuJoCo.
"""

from __future__ import annotations

import numpy as np

from cpbc.bench import BenchSetup
from cpbc.constraints import (
    ConstraintSet,
    KineticEnergyLimit,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.constraints.clearance import Clearance
from cpbc.constraints.covering import cover_links
from cpbc.constraints.geometry import BoxObstacle, PlaneObstacle, SphereObstacle
from cpbc.controllers import BPBC, CPBC, PD, Controller, CPBCKineticEnergy, PDGravity, Power
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.loading import finish_mujoco_model, load_arm
from cpbc.scenario.robots import add_scene_geom
from cpbc.simulation import MujocoPlant, PlantSettings

START = np.array([-0.179, 0.172, -0.497, -2.085, 0.103, 2.233, 0.785])
TARGET = np.array([0.179, 0.172, 0.497, -2.085, -0.103, 2.233, 0.785])
OBSTACLES = (
    PlaneObstacle("table", np.zeros(3)),
    SphereObstacle("ball", np.array([0.5, 0.0, 0.3]), 0.08),
    BoxObstacle("crate", np.array([0.3, 0.45, 0.1]), np.array([0.06, 0.06, 0.1])),
)


def panda(states: int = 64, seed: int = 0) -> BenchSetup:
    """The Panda reaching past a ball, with all its limits and three obstacles."""
    arm = load_arm("panda")
    model = RobotModel(arm.model, name="panda")
    names = arm.joint_names
    limits = joint_position_limit(arm.position_lower, arm.position_upper, names)
    rates = joint_rate_limit(0.5 * arm.velocity_limit, names)
    clearance = Clearance(model, cover_links(arm.model, arm.collision_model), OBSTACLES,
                          margin=0.01, influence=0.1)
    energy = KineticEnergyLimit(model, 0.5)
    kp = np.array([60, 60, 60, 60, 20, 20, 20.0])
    kd = np.array([12, 12, 12, 12, 3, 3, 3.0])
    full = ConstraintSet(7, [limits, clearance], [rates])
    controllers: dict[str, Controller] = {
        "pd": PD(model, TARGET, kp, kd),
        "pd_gravity": PDGravity(model, TARGET, kp, kd),
        "cpbc": CPBC(model, TARGET, full, kp, kd, Power(0.2)),
        "cpbc_ke": CPBCKineticEnergy(model, TARGET, ConstraintSet(7, [limits, clearance],
                                                                  [energy]), kp, kd, Power(0.2)),
        "bpbc": BPBC(model, TARGET, ConstraintSet(7, [], [rates]), kp, kd, 1.0, 1.0,
                     Power(0.2)),
    }
    rng = np.random.default_rng(seed)
    check = ConstraintSet(7, [limits, clearance], [rates, energy])
    picked: list[tuple[np.ndarray, np.ndarray]] = []
    while len(picked) < states:
        s = rng.uniform()
        x = (1 - s) * START + s * TARGET + rng.normal(scale=0.05, size=7)
        dx = rng.normal(scale=0.1, size=7)
        if np.all(check.margins(x, dx, model.dynamics(x, dx)) > 0):
            picked.append((x, dx))

    plant = PlantSettings(0.001, "implicitfast")

    def make_plant() -> MujocoPlant:
        spec = arm.mujoco_spec()
        for ob in OBSTACLES:
            add_scene_geom(spec, ob.name, ob.scene_geom(), True, [0.85, 0.25, 0.2, 0.5])
        mj = spec.compile()
        finish_mujoco_model(mj, arm.joint_names)
        return MujocoPlant(mj, plant)

    return BenchSetup(
        "panda", controllers, picked, make_plant, LinearCoordinates.identity(7),
        (START.copy(), np.zeros(7)),
        "14 URDF joint limits, 7 rate limits, table + ball + crate against 10 links "
        "(33 spheres, 99 pairs); implicitfast, 1 kHz control",
        plant, torque_limit=arm.effort_limit,
    )
