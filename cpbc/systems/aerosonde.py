"""The Aerosonde UAV of Chapter 5 as a longitudinal ODE plant (AeroSim's model), with its
airspeed loop on thrust. The MJCF ``models/systems/aerosonde.xml`` only replays the path.

Why an ODE and not a MuJoCo body: the aircraft is one rigid body in the vertical plane, with no
contact and no linkage, so MuJoCo would integrate nothing but the forces applied to it; and
AeroSim's lift and moment depend on α̇ (C_Lα̇, C_Mα̇), an implicit equation in the state
derivative that the ODE solves exactly at every evaluation, whereas forces applied to a MuJoCo
body are held over a physics step and could only use last step's α̇. Simulink's AeroSim, on
which the thesis ran, is itself this ODE. So the plant is simulated by the reference backend
(DOP853) only; the MuJoCo backend refuses it.

State x = (h, v_z, α, q, x, v_x, ∫e) [m, m/s, rad, rad/s, m, m/s, m]: the design model's four
states first (the laws read them directly: "controller inputs h, v_z = ḣ, α, q"), then the
horizontal position and speed, and the airspeed loop's integral of e = V_ref − V. Input u = δ_E
[rad], clipped to ±``elevator_limit`` by the actuator. With V = √(v_x² + v_z²),
γ = atan2(v_z, v_x), θ = γ + α and (L, D, M) from :func:`~cpbc.systems.aerosim.aero_forces`
at ρ = ρ_ISA(h):

    m v̇_x = T cos θ − D cos γ − L sin γ
    m v̇_z = T sin θ − D sin γ + L cos γ − m g
    q̇ = M / I_yy,   α̇ = q − γ̇,   γ̇ = (v_x v̇_z − v_z v̇_x)/V²
    T = clip(T_d, 0, T_max(V)),  T_d = T_trim + m[k_p e + k_i ∫e],
    d/dt ∫e = e − (T_d − T)/(m k_i τ)     (back-calculation anti-windup)

α̇ appears on both sides (through C_Lα̇, C_Mα̇); it is solved by fixed-point iteration, which
contracts by ≈ q̄S c̄ C_Lα̇/(2 m V²) ≈ 0.005 per pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from cpbc.backstepping.altitude_model import AltitudeModel
from cpbc.errors import CpbcError, ModelError
from cpbc.margin_kinds import ANGLE, CLIMB
from cpbc.resources import models_dir
from cpbc.systems.aerosim import (
    GRAVITY,
    AerosondeParameters,
    aero_forces,
    full_throttle_thrust,
    isa_density,
)
from cpbc.systems.ode_plant import ConstrainedQuantity, Plant, State

#: airspeeds at which T_max(V) is tabulated [m/s]
_THRUST_GRID = np.linspace(15.0, 50.0, 71)


@dataclass(frozen=True)
class AirspeedLoop:
    """The separate airspeed loop on thrust (not in the thesis; PART1 Ch. 5 §3.5):
    PI on e = V_ref − V around the trim thrust, scaled by the mass, with anti-windup."""

    kp: float = 1.0  # [1/s]
    ki: float = 0.1  # [1/s²]
    tracking: float = 1.0  # τ of the back-calculation anti-windup [s]


@dataclass(frozen=True)
class AerosondePlant(Plant):
    """The longitudinal Aerosonde, trimmed in level flight at ``airspeed`` and ``altitude``.

    Args:
        parameters: AeroSim's data (default: the sample Aerosonde, gross mass).
        airspeed: V_ref of the airspeed loop and of the trim [m/s].
        altitude: trim altitude [m]: the trim thrust and T_max(V) use ρ there.
        climb_rate_limit: B of (5.33) [m/s].
        elevator_limit: the actuator's range ±δ_E,max [rad] (57.3° = 1 rad).
        loop: the airspeed loop's gains.
        command_times: times where the altitude command steps (the reference integrates
            piecewise there).
    """

    parameters: AerosondeParameters = field(default_factory=AerosondeParameters)
    airspeed: float = 23.0
    altitude: float = 100.0
    climb_rate_limit: float = 3.5
    elevator_limit: float = 1.0
    loop: AirspeedLoop = field(default_factory=AirspeedLoop)
    command_times: tuple[float, ...] = ()
    path: Path = field(default_factory=lambda: models_dir() / "systems" / "aerosonde.xml")
    _thrust_max: np.ndarray = field(init=False, repr=False, compare=False)
    _trim: tuple[float, float, float] = field(init=False, repr=False, compare=False)

    state_names = ("h", "vz", "alpha", "q", "x", "vx", "int_e")
    input_name = "elevator [rad]"
    #: the MJCF only displays logged states: the ODE is the plant
    physics = False

    def __post_init__(self) -> None:
        for name in ("airspeed", "climb_rate_limit", "elevator_limit"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise CpbcError(f"{name} = {value!r} must be > 0")
        rho = isa_density(self.altitude)
        tmax = [full_throttle_thrust(self.parameters, rho, v) for v in _THRUST_GRID]
        object.__setattr__(self, "_thrust_max", np.array(tmax))
        object.__setattr__(self, "_trim", self._solve_trim(rho))

    # -- description ----------------------------------------------------------------------
    @property
    def constrained(self) -> tuple[ConstrainedQuantity, ...]:
        b, e = self.climb_rate_limit, self.elevator_limit
        lo, hi = self.parameters.alpha_bounds
        return (
            ConstrainedQuantity("vz", -b, b, "state", 1, CLIMB),
            # the stall and the elevator's travel are the aircraft's limits (AeroSim clips
            # both), not constraints of the problem: reported, not judged
            ConstrainedQuantity("alpha", lo, hi, "state", 2, ANGLE, limit=True),
            ConstrainedQuantity("elevator", -e, e, "input", 0, ANGLE, limit=True),
        )

    def breakpoints(self) -> tuple[float, ...]:
        return self.command_times

    def design_model(self, rho: float | None = None, mass: float | None = None) -> AltitudeModel:
        """The constants of (5.3) at the trim condition; ρ and m may be overridden (the
        thesis does not say which it used)."""
        p = self.parameters
        return AltitudeModel.from_coefficients(
            airspeed=self.airspeed, rho=isa_density(self.altitude) if rho is None else rho,
            mass=p.mass if mass is None else mass, iyy=p.iyy, wing_area=p.wing_area,
            chord=p.chord, cl0=p.cl0, cl_alpha=p.cl_alpha, cm0=p.cm0, cm_alpha=p.cm_alpha,
            cm_q=p.cm_q, cm_elevator=p.cm_elevator, g=GRAVITY)

    # -- trim -----------------------------------------------------------------------------
    @property
    def trim(self) -> tuple[float, float, float]:
        """(α, δ_E, T) of level flight at (airspeed, altitude) [rad, rad, N]."""
        return self._trim

    def _solve_trim(self, rho: float) -> tuple[float, float, float]:
        p, v = self.parameters, self.airspeed

        def residual(z: np.ndarray) -> list[float]:
            alpha, elevator, thrust = (float(c) for c in z)
            f = aero_forces(p, rho, v, alpha, 0.0, 0.0, elevator)
            return [thrust * math.cos(alpha) - f.drag,
                    thrust * math.sin(alpha) + f.lift - p.mass * GRAVITY, f.moment]

        from scipy.optimize import fsolve  # loaded when used (CLI start-up)

        sol, _, ok, msg = fsolve(residual, [0.09, -0.12, 10.0], full_output=True, xtol=1e-13)
        if ok != 1 or not p.alpha_bounds[0] < sol[0] < p.alpha_bounds[1]:
            raise CpbcError(f"no level trim at V = {v:g} m/s: {msg}")
        return float(sol[0]), float(sol[1]), float(sol[2])

    def initial_state(self, altitude: float, climb_rate: float = 0.0) -> State:
        """Trimmed for level flight (α, q = 0, ∫e = 0) at ``altitude``, the velocity turned
        to the given climb rate at the same airspeed."""
        if not abs(climb_rate) < self.airspeed:
            raise CpbcError(f"climb rate {climb_rate:g} m/s is not below the airspeed")
        vx = math.sqrt(self.airspeed**2 - climb_rate**2)
        return (altitude, climb_rate, self.trim[0], 0.0, 0.0, vx, 0.0)

    # -- dynamics -------------------------------------------------------------------------
    def thrust(self, airspeed: float, integral: float) -> tuple[float, float]:
        """T [N] of the airspeed loop, and the demand above its range (0 ≤ T ≤ T_max(V))."""
        m, loop = self.parameters.mass, self.loop
        demand = self.trim[2] + m * (loop.kp * (self.airspeed - airspeed) + loop.ki * integral)
        top = float(np.interp(airspeed, _THRUST_GRID, self._thrust_max))
        thrust = min(max(demand, 0.0), top)
        return thrust, demand - thrust

    def rhs(self, x: State, u: float, t: float) -> State:
        p = self.parameters
        h, vz, alpha, q, _, vx, integral = x
        v2 = vx * vx + vz * vz
        v = math.sqrt(v2)
        gamma = math.atan2(vz, vx)
        theta = gamma + alpha
        elevator = min(max(u, -self.elevator_limit), self.elevator_limit)
        rho = isa_density(h)
        e = self.airspeed - v
        thrust, excess = self.thrust(v, integral)
        alpha_dot, ax, az, qd = 0.0, 0.0, 0.0, 0.0
        for _ in range(30):
            f = aero_forces(p, rho, v, alpha, alpha_dot, q, elevator)
            ax = (thrust * math.cos(theta) - f.drag * math.cos(gamma)
                  - f.lift * math.sin(gamma)) / p.mass
            az = (thrust * math.sin(theta) - f.drag * math.sin(gamma)
                  + f.lift * math.cos(gamma)) / p.mass - GRAVITY
            qd = f.moment / p.iyy
            new = q - (vx * az - vz * ax) / v2
            if abs(new - alpha_dot) <= 1e-13 * (1.0 + abs(new)):
                alpha_dot = new
                break
            alpha_dot = new
        # back-calculation anti-windup: a saturated demand bleeds the integral back (continuous
        # in the state, unlike conditional integration, whose sliding mode stalls the solver)
        unwind = excess / (self.parameters.mass * self.loop.ki * self.loop.tracking)
        return (vz, az, alpha_dot, qd, vx, ax, e - unwind)

    # -- display (the MJCF replays the path; MuJoCo simulates nothing) ----------------------
    @property
    def mjcf(self) -> Path:
        return self.path

    def verify(self, model: mujoco.MjModel) -> None:
        names = [model.joint(i).name for i in range(model.njnt)]
        if names != ["x", "h", "pitch"]:
            raise ModelError(f"the Aerosonde's display needs joints (x, h, pitch); "
                             f"{self.path} has {names}")

    def write_state(self, model: mujoco.MjModel, data: mujoco.MjData, x: State) -> None:
        h, vz, alpha, q, xpos, vx, _ = x
        data.qpos[:] = (xpos, h, math.atan2(vz, vx) + alpha)  # pitch θ = γ + α
        data.qvel[:] = (vx, vz, q)

    def read_state(self, model: mujoco.MjModel, data: mujoco.MjData) -> State:
        raise ModelError(_ODE_ONLY)

    def write_input(self, model: mujoco.MjModel, data: mujoco.MjData, u: float) -> None:
        raise ModelError(_ODE_ONLY)


_ODE_ONLY = ("the Aerosonde is an ODE plant (AeroSim's longitudinal model); its MJCF only "
             "replays the path: run it with the reference backend")
