"""Part I systems: a ``system:`` block in place of ``robot:``, and the ``SystemScenario``."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field

from cpbc.scenario.schema.common import (
    MAX_CASES,
    CaseName,
    NonNegative,
    Number,
    Positive,
    RunName,
    SafeName,
    Strict,
    Vector,
)

StrictBool = Annotated[bool, Field(strict=True)]


class SuspensionGainsSpec(Strict):
    """The design constants of §3.3.3 (Theorem 3.6), under the thesis's names."""

    k1: Positive = Field(default=3.5, description="k1 of §3.3.3 (Theorem 3.6)")
    k2: Positive = Field(default=0.051, description="k2 of §3.3.3 (Theorem 3.6)")
    k3: Positive = Field(default=0.07, description="k3 of §3.3.3 (Theorem 3.6)")
    k4: Positive = Field(default=50.0, description="k4 of §3.3.3 (Theorem 3.6)")
    c1: Positive = Field(default=0.049, description="c1 of §3.3.3 (Theorem 3.6)")
    c2: Positive = Field(default=300.0, description="c2 of §3.3.3 (Theorem 3.6)")
    c3: Positive = Field(default=500.0, description="c3 of §3.3.3 (Theorem 3.6)")


class SuspensionLawSpec(Strict):
    """The law (3.88); ``barrier: false`` is the same law with ½k3 z1² in place of the log
    barrier (no travel guarantee), the unconstrained comparison."""

    name: RunName = Field(description="the law's name in the output")
    barrier: StrictBool = Field(
        default=True, description=(
            "the log barrier on the travel; false: ½k3 z1² in its place (no travel guarantee)"))
    gains: SuspensionGainsSpec = Field(
        default=SuspensionGainsSpec(), description="the design constants")


class QuarterCarSpec(Strict):
    """The active quarter car of §3.3 over a haversine bump (its height is per case).
    ω and ρ are the built-in MJCF's (§3.3.3)."""

    type: Literal["quarter_car"] = Field(
        description=(
            "the active quarter car of §3.3 over a haversine bump"))
    # Ξ [m]
    travel_limit: Positive = Field(default=0.1, description="Ξ, the suspension travel limit [m]")
    # l [m]
    bump_length: Positive = Field(default=2.0, description="l, the bump's length [m]")
    # v [m/s]
    speed: Positive = Field(default=25.0, description="v, the car's speed [m/s]")
    laws: Annotated[list[SuspensionLawSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared"))


class WheelPendulumGainsSpec(Strict):
    """The design constants of §3.5.3 (Proposition 3.11), under the thesis's names."""

    k1: Positive = Field(default=57.5e-3, description="k1 of §3.5.3 (Proposition 3.11)")
    k2: Positive = Field(default=2.225, description="k2 of §3.5.3 (Proposition 3.11)")
    k3: Positive = Field(default=0.25, description="k3 of §3.5.3 (Proposition 3.11)")
    k4: Positive = Field(default=0.501, description="k4 of §3.5.3 (Proposition 3.11)")
    c1: Positive = Field(default=0.5, description="c1 of §3.5.3 (Proposition 3.11)")
    c2: Positive = Field(default=1.0, description="c2 of §3.5.3 (Proposition 3.11)")


class WheelPendulumLawSpec(Strict):
    name: RunName = Field(description="the law's name in the output")
    gains: WheelPendulumGainsSpec = Field(
        default=WheelPendulumGainsSpec(), description=(
            "the design constants"))


class ReactionWheelSpec(Strict):
    """The reaction wheel pendulum of §3.5 (the built-in MJCF's d's, §3.5.3)."""

    type: Literal["reaction_wheel_pendulum"] = Field(
        description=(
            "the reaction wheel pendulum of §3.5"))
    # on |q̇1| [rad/s]
    rate_limit: Positive = Field(
        default=1.0, description="bound on the pendulum's rate |q̇1| [rad/s]")
    # on |τ| [N m]
    torque_limit: Positive = Field(default=0.4, description="bound on the wheel torque |τ| [N·m]")
    laws: Annotated[list[WheelPendulumLawSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared"))


class ChainGainsSpec(Strict):
    """The design constants of §4.4 (Theorem 4.12, manual tuning), under the thesis's names,
    read as PART1 Ch. 4 §2.6 reading H1 (see cpbc.backstepping.integrator_chain_law)."""

    c1: Positive = Field(
        default=0.5 / math.pi, description="c1 of §4.4 (Theorem 4.12, manual tuning)")
    c2: Positive = Field(default=1.0, description="c2 of §4.4 (Theorem 4.12, manual tuning)")
    c3: Positive = Field(default=50.0, description="c3 of §4.4 (Theorem 4.12, manual tuning)")
    c4: Positive = Field(default=1.0, description="c4 of §4.4 (Theorem 4.12, manual tuning)")
    k1: Positive = Field(default=1.0, description="k1 of §4.4 (Theorem 4.12, manual tuning)")
    k2: Positive = Field(default=2.0, description="k2 of §4.4 (Theorem 4.12, manual tuning)")
    k3: Positive = Field(default=3.0, description="k3 of §4.4 (Theorem 4.12, manual tuning)")
    k4: Positive = Field(default=5.61, description="k4 of §4.4 (Theorem 4.12, manual tuning)")
    k5: Positive = Field(default=1.0, description="k5 of §4.4 (Theorem 4.12, manual tuning)")
    k6: Positive = Field(default=354.5, description="k6 of §4.4 (Theorem 4.12, manual tuning)")
    k7: Positive = Field(default=10.0, description="k7 of §4.4 (Theorem 4.12, manual tuning)")


class ChainLawSpec(Strict):
    name: RunName = Field(description="the law's name in the output")
    gains: ChainGainsSpec = Field(default=ChainGainsSpec(), description="the design constants")


class IntegratorChainSpec(Strict):
    """The 4th-order integrator chain of §4.4 (4.92): an ODE, no MuJoCo model; ``limits``
    are Ξ on |ξ2|, |ξ3|, |ξ4| (4.93), ξ1 is unconstrained."""

    type: Literal["integrator_chain"] = Field(
        description=(
            "the 4th-order integrator chain of §4.4 (4.92), an ODE"))
    limits: Annotated[list[Positive], Field(min_length=3, max_length=3)] = Field(
        default=[2.5, 12.0, 700.0], description=(
            "Ξ2, Ξ3, Ξ4 on |ξ2|, |ξ3|, |ξ4| (4.93)"))
    laws: Annotated[list[ChainLawSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared"))


class TraditionalAltitudeGainsSpec(Strict):
    """c1 … c4 of §5.3.1 (the law (5.30))."""

    c1: Positive = Field(default=1.5, description="c1 of §5.3.1 (the law 5.30)")
    c2: Positive = Field(default=10.0, description="c2 of §5.3.1 (the law 5.30)")
    c3: Positive = Field(default=5.0, description="c3 of §5.3.1 (the law 5.30)")
    c4: Positive = Field(default=0.1, description="c4 of §5.3.1 (the law 5.30)")


class ConstrainedAltitudeGainsSpec(Strict):
    """c1 … c4, k1 … k3 of §5.4.3 (the law (5.61)); k2 + c1 must not exceed the climb-rate
    limit B, and k2 > c1 (Theorem 5.5)."""

    c1: Positive = Field(default=1.5, description="c1 of §5.4.3 (the law 5.61)")
    c2: Positive = Field(default=1.0, description="c2 of §5.4.3 (the law 5.61)")
    c3: Positive = Field(default=5.0, description="c3 of §5.4.3 (the law 5.61)")
    c4: Positive = Field(default=10.0, description="c4 of §5.4.3 (the law 5.61)")
    k1: Positive = Field(default=1.5, description="k1 of §5.4.3 (the law 5.61)")
    k2: Positive = Field(default=2.0, description="k2 of §5.4.3 (the law 5.61)")
    k3: Positive = Field(default=0.5, description="k3 of §5.4.3 (the law 5.61)")


class TraditionalAltitudeLawSpec(Strict):
    """§5.3's traditional backstepping law: nothing bounds the climb rate."""

    type: Literal["traditional"] = Field(description="§5.3's traditional backstepping law")
    name: RunName = Field(description="the law's name in the output")
    gains: TraditionalAltitudeGainsSpec = Field(
        default=TraditionalAltitudeGainsSpec(), description=(
            "the design constants"))


class ConstrainedAltitudeLawSpec(Strict):
    """§5.4's law with the log barrier on the climb-rate error: |v_z| < k2 + c1."""

    type: Literal["constrained"] = Field(
        description=(
            "§5.4's law with the log barrier on the climb rate"))
    name: RunName = Field(description="the law's name in the output")
    gains: ConstrainedAltitudeGainsSpec = Field(
        default=ConstrainedAltitudeGainsSpec(), description=(
            "the design constants"))


AltitudeLawSpec = Annotated[TraditionalAltitudeLawSpec | ConstrainedAltitudeLawSpec,
                            Field(discriminator="type")]


class AerosondeSpec(Strict):
    """The Aerosonde UAV of Chapter 5 (AeroSim's longitudinal model, an ODE plant: the
    reference backend only). ``air_density`` and ``mass`` are what the laws' design model
    assumes and the aircraft's mass (the thesis gives neither); ``air_density`` defaults to
    ISA at each case's start altitude. Each case's ``state`` is [altitude [m], climb rate
    [m/s]]: level trim at ``airspeed`` with the velocity turned to that climb rate."""

    type: Literal["aerosonde"] = Field(
        description=(
            "the Aerosonde UAV of Chapter 5 (AeroSim's longitudinal model; reference backend "
            "only)"))
    # v_T [m/s], held by the airspeed loop on thrust
    airspeed: Positive = Field(
        default=23.0, description="v_T, held by the airspeed loop on thrust [m/s]")
    # B [m/s]
    climb_rate_limit: Positive = Field(default=3.5, description="B, the bound on |v_z| [m/s]")
    # [rad] (57.3°)
    elevator_limit: Positive = Field(default=1.0, description="the elevator's travel [rad]")
    # ρ of the design model [kg/m³]
    air_density: Positive | None = Field(
        default=None, description=(
            "ρ of the laws' design model [kg/m³]; ISA at each case's start altitude when "
            "omitted"))
    # [kg] (AeroSim gross; 8.5 empty)
    mass: Positive = Field(
        default=13.5, description="the aircraft's mass [kg] (AeroSim gross; 8.5 empty)")
    laws: Annotated[list[AltitudeLawSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared"))


SystemSpec = Annotated[QuarterCarSpec | ReactionWheelSpec | IntegratorChainSpec | AerosondeSpec,
                       Field(discriminator="type")]


class SystemSimulationSpec(Strict):
    """``control_period`` defaults to the timestep; ``tolerance`` judges convergence on the
    components the system names (the pendulum, not its wheel)."""

    duration: Positive = Field(description="simulated time of each run [s]")
    timestep: Positive = Field(default=0.001, description="physics or output timestep [s]")
    control_period: Positive | None = Field(
        default=None, description=(
            "control period [s]; the timestep when omitted"))
    integrator: Literal["Euler", "RK4", "implicit", "implicitfast"] = Field(
        default="RK4", description=(
            "MuJoCo's integrator"))
    backend: Literal["mujoco", "reference"] = Field(
        default="mujoco", description=(
            "mujoco or reference (solve_ivp on the system's ODE)"))
    tolerance: Positive = Field(
        default=0.01, description=(
            "convergence band on the components the system names"))
    max_steps: Annotated[int, Field(ge=1, strict=True)] = Field(
        default=10_000_000, description=(
            "steps per run above which the scenario is refused"))

    @property
    def period(self) -> float:
        """The control period h [s]: ``control_period``, or one timestep when omitted."""
        return self.control_period or self.timestep


class AltitudeCommandSpec(Strict):
    """A step of the altitude command: h_d = ``altitude`` [m] from ``time`` [s] on."""

    time: NonNegative = Field(description="when the command starts [s]")
    altitude: Number = Field(description="h_d from then on [m]")


class SystemCaseSpec(Strict):
    """An initial state x(0) in the system's own state (see cpbc.systems); the quarter car's
    cases give the bump height A [m], the Aerosonde's the altitude commands (h_d is the
    start altitude until the first)."""

    name: CaseName = Field(description="the case's name (a folder name of the output)")
    state: Vector = Field(
        description=(
            "the initial state x(0) in the system's own coordinates (see cpbc.systems)"))
    bump_height: NonNegative | None = Field(
        default=None, description="quarter car: the bump height A [m]")
    commands: list[AltitudeCommandSpec] | None = Field(
        default=None, description=(
            "Aerosonde: the altitude command steps (h_d is the start altitude until the "
            "first)"))


class SystemScenario(Strict):
    """A Part I scenario: a system with its laws, simulation and cases."""

    name: SafeName = Field(description="the scenario's name: letters, digits, _ . + -")
    description: str = Field(default="", description="free text")
    system: SystemSpec = Field(description="the Part I system and its laws")
    simulation: SystemSimulationSpec = Field(description="the simulation")
    cases: Annotated[list[SystemCaseSpec], Field(min_length=1, max_length=MAX_CASES)] = Field(
        description=(
            "initial states; every law runs on every case"))
