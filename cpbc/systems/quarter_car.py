"""The active quarter car of §3.3 as a plant: MJCF ``models/systems/quarter_car.xml``
and ODE (3.62).

    ẋ1 = x2 − d(t),  ẋ2 = −ω² x1 + ρ u,  ẋ3 = −x2 + x4,  ẋ4 = −u,   |x3| < Ξ  (3.63)

x1 tire deflection z_us − r [m], x2 wheel velocity [m/s], x3 suspension travel z_s − z_us [m],
x4 body velocity [m/s], u actuator force per unit sprung mass [m/s²], r the road height.

MuJoCo: two slide joints (``wheel_z``, ``body_z``), the tire as the wheel joint's stiffness
k_t = m_us ω² plus a ``road`` motor of gear k_t carrying r(t) (so the tire force is
−k_t (z_us − r), exact for prescribed road motion), and a ``suspension`` motor of gear −m_s on
the tendon z_s − z_us carrying u. RK4 holds ctrl over a step, so r is sampled at the step's
midpoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco

from cpbc.backstepping.suspension import QuarterCarConstants
from cpbc.errors import ModelError
from cpbc.margin_kinds import DEFLECTION
from cpbc.resources import models_dir
from cpbc.systems.ode_plant import ConstrainedQuantity, Plant, State, check_close
from cpbc.systems.road import HaversineBump

_WHEEL, _BODY = 0, 1  # qpos/qvel addresses of wheel_z and body_z (checked by verify)
_SUSPENSION, _ROAD = 0, 1  # actuator indices


@dataclass(frozen=True)
class QuarterCar(Plant):
    """The quarter car over a road bump.

    Args:
        road: the bump (default: flat road).
        constants: ω and ρ (default: §3.3.3).
        travel_limit: Ξ [m].
        path: the MJCF (default: the built-in ``quarter_car.xml``).
    """

    road: HaversineBump = field(default_factory=lambda: HaversineBump(0.0))
    constants: QuarterCarConstants = field(default_factory=QuarterCarConstants)
    travel_limit: float = 0.1
    path: Path = field(default_factory=lambda: models_dir() / "systems" / "quarter_car.xml")

    state_names = ("x1", "x2", "x3", "x4")
    input_name = "u [m/s²]"

    @property
    def constrained(self) -> tuple[ConstrainedQuantity, ...]:
        lim = self.travel_limit
        return (ConstrainedQuantity("x3", -lim, lim, "state", 2, DEFLECTION),)

    @property
    def mjcf(self) -> Path:
        return self.path

    def verify(self, model: mujoco.MjModel) -> None:
        names = [model.joint(i).name for i in range(model.njnt)]
        acts = [model.actuator(i).name for i in range(model.nu)]
        if names != ["wheel_z", "body_z"] or acts != ["suspension", "road"]:
            raise ModelError(f"quarter car needs joints (wheel_z, body_z) and actuators "
                             f"(suspension, road); {self.path} has {names} and {acts}")
        m_us = float(model.body("unsprung").mass[0])
        m_s = float(model.body("sprung").mass[0])
        k_t = float(model.jnt_stiffness[_WHEEL])
        check_close("ω² = k_t/m_us", k_t / m_us, self.constants.omega**2)
        check_close("ρ = m_s/m_us", m_s / m_us, self.constants.rho)
        check_close("suspension gear", float(model.actuator_gear[_SUSPENSION, 0]), -m_s)
        check_close("road gear", float(model.actuator_gear[_ROAD, 0]), k_t)
        if any(model.opt.gravity) or model.dof_damping.any() or model.jnt_stiffness[_BODY]:
            raise ModelError("the quarter car (3.62) has no gravity, damping or body spring")

    def read_state(self, model: mujoco.MjModel, data: mujoco.MjData) -> State:
        zu, zs = data.qpos[_WHEEL], data.qpos[_BODY]
        return (
            float(zu) - self.road.height_at(data.time),
            float(data.qvel[_WHEEL]),
            float(zs - zu),
            float(data.qvel[_BODY]),
        )

    def write_state(self, model: mujoco.MjModel, data: mujoco.MjData, x: State) -> None:
        zu = x[0] + self.road.height_at(data.time)
        data.qpos[_WHEEL], data.qpos[_BODY] = zu, zu + x[2]
        data.qvel[_WHEEL], data.qvel[_BODY] = x[1], x[3]

    def write_input(self, model: mujoco.MjModel, data: mujoco.MjData, u: float) -> None:
        data.ctrl[_SUSPENSION] = u

    def before_step(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        data.ctrl[_ROAD] = self.road.height_at(data.time + 0.5 * model.opt.timestep)

    def rhs(self, x: State, u: float, t: float) -> State:
        x1, x2, _, x4 = x
        c = self.constants
        return (x2 - self.road.velocity_at(t), -(c.omega**2) * x1 + c.rho * u, -x2 + x4, -u)

    def breakpoints(self) -> tuple[float, ...]:
        return (self.road.duration,) if self.road.height > 0.0 else ()
