"""The controllers of an arm scenario: the ``controllers:`` items and their gains."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

from cpbc.scenario.schema.common import Gain, Positive, RunName, Strict


class IdentityShapingSpec(Strict):
    type: Literal["identity"] = Field(description="s(x) = x: V = L/(ΦΨ)")


class PowerShapingSpec(Strict):
    type: Literal["power"] = Field(description="s(x) = x^α")
    alpha: Positive = Field(description="α, the barrier's exponent (smaller: a weaker barrier)")


class TanhShapingSpec(Strict):
    type: Literal["tanh"] = Field(description="s(x) = tanh(σx)")
    sigma: Positive = Field(description="σ [1/unit of ΦΨ]")


ShapingSpec = Annotated[
    IdentityShapingSpec | PowerShapingSpec | TanhShapingSpec, Field(discriminator="type")
]


class TaskGainsSpec(Strict):
    """A goal's task gains in physical units, scaled by the arm's task-space inertia Λ at the
    posture (cpbc.taskspace.gains): the task closes at ω_n, ζ, the posture terms' share taken
    off, K_p = (ω_n² − ω_p²) Λ, D_x = 2 (ζ ω_n − ζ_p ω_p) Λ; the orientation spring
    at ``rotation_omega_n`` (ω_n when omitted). The bounded laws (bpbc, bpbc_ke) saturate the
    position spring beyond 1/``xi`` [m] and the task damping beyond 1/``gamma`` [m/s]."""

    omega_n: Positive = Field(
        default=8.0, description=(
            "natural frequency of the task [rad/s]: K_p = (ω_n² − ω_p²) Λ, ω_p the "
            "posture's"))
    zeta: Positive = Field(
        default=1.0, description=(
            "damping ratio of the task: D_x = 2 (ζ ω_n − ζ_p ω_p) Λ, ζ_p ω_p the posture's"))
    rotation_omega_n: Positive | None = Field(
        default=None, description=(
            "natural frequency of the orientation spring [rad/s]; omega_n when omitted"))
    xi: Positive = Field(
        default=10.0, description=(
            "bpbc, bpbc_ke: the position spring saturates beyond 1/xi [1/m]"))
    gamma: Positive = Field(
        default=10.0, description=(
            "bpbc, bpbc_ke: the task damping saturates beyond 1/gamma [s/m]"))


class PostureGainsSpec(Strict):
    """A goal's posture spring and joint damping: K_n = ω_n² D_ii, K_D = 2 ζ ω_n D_ii at the
    posture. Never off (it keeps the law's V a barrier on the boundary of S)."""

    omega_n: Positive = Field(
        default=2.0, description=(
            "natural frequency of the posture spring [rad/s]: K_n = ω_n² D_ii"))
    zeta: Positive = Field(
        default=1.0, description=(
            "damping ratio of the joint damping: K_D = 2 ζ ω_n D_ii"))


class GainsSpec(Strict):
    """K_P, K_D directly (``kp``, ``kd``), or in physical terms: a natural frequency
    ``omega_n`` [rad/s] and damping ratio ``zeta`` per coordinate (or one for all), scaled by
    the arm's inertia at the target: K_P,i = D_ii(x_d) ω_n,i², K_D,i = 2 ζ_i ω_n,i D_ii(x_d)
    (see cpbc.scenario.gains)."""

    # omega_n and zeta come first so that kp's and kd's checks see them (info.data)
    omega_n: Gain | None = Field(
        default=None, description=(
            "natural frequency per coordinate, or one for all [rad/s]: K_P,i = D_ii(x_d) "
            "ω_n,i²"))
    zeta: Gain | None = Field(
        default=None, description=(
            "damping ratio per coordinate, or one for all: K_D,i = 2 ζ_i ω_n,i D_ii(x_d)"))
    kp: Gain | None = Field(
        default=None, description=(
            "K_P: one number or one per coordinate (instead of omega_n, zeta)"))
    kd: Gain | None = Field(
        default=None, description=(
            "K_D: one number or one per coordinate (instead of omega_n, zeta)"))
    # with a scenario goal: the task and posture gains in place of kp, kd
    task: TaskGainsSpec | None = Field(
        default=None, description=(
            "with a scenario goal: the task gains in place of kp, kd"))
    posture: PostureGainsSpec | None = Field(
        default=None, description=(
            "with a scenario goal: the posture gains in place of kp, kd"))
    on_infeasible: Literal["stop", "rejoin"] | None = Field(
        default=None, description=(
            "with a scenario reference: this law's governor policy in place of "
            "reference.governor.on_infeasible (to compare stop and rejoin in one scenario)"))
    reference_speed: Positive | None = Field(
        default=None, description=(
            "with a scenario reference: this law's path runs this many times its nominal "
            "speed (to compare speeds in one scenario); 1 when omitted"))

    @field_validator("kp", "kd", mode="before")
    @classmethod
    def _not_null(cls, v: object, info: ValidationInfo) -> object:
        # kp: null is a slip, unless the gains are given as omega_n, zeta (as a dumped
        # scenario has them)
        if v is None and info.data.get("omega_n") is None and info.data.get("task") is None:
            raise ValueError("must be a number or a list of numbers, not null")
        return v

    @model_validator(mode="after")
    def _one_form(self) -> GainsSpec:
        given = {k for k in ("kp", "kd", "omega_n", "zeta") if getattr(self, k) is not None}
        if self.task is not None or self.posture is not None:
            if given:
                raise ValueError(f"give task and posture gains, or {', '.join(sorted(given))}"
                                 ", not both (a goal's law takes task: and posture:)")
            return self
        if given & {"kp", "kd"} and given & {"omega_n", "zeta"}:
            raise ValueError("give either kp and kd, or omega_n and zeta, not both")
        if given not in ({"kp", "kd"}, {"omega_n", "zeta"}):
            missing = ({"kp", "kd"} - given) if given & {"kp", "kd"} else (
                {"omega_n", "zeta"} - given if given else {"kp", "kd"})
            raise ValueError(f"{' and '.join(sorted(missing))} missing: give kp and kd, or "
                             "omega_n [rad/s] and zeta")
        return self


class PDSpec(GainsSpec):
    type: Literal["pd", "pd_gravity"] = Field(
        description=(
            "pd: −K_P x̃ − K_D ẋ (the thesis's baseline); pd_gravity: g − K_P x̃ − K_D ẋ "
            "(6.10). Constraints are only monitored"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))


class CPBCSpec(GainsSpec):
    type: Literal["cpbc", "cpbc_ke"] = Field(
        description=(
            "cpbc: Theorem 6.9, any configuration and velocity constraints; cpbc_ke: "
            "Corollary 6.11, configuration constraints and one kinetic_energy_limit"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))
    shaping: ShapingSpec | None = Field(
        default=None, description=(
            "the barrier's shaping s: identity, power (α) or tanh (σ)"))
    # names of scenario constraints; all when omitted
    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))


class RecentredSpec(GainsSpec):
    type: Literal["recentred"] = Field(
        description=(
            "the re-centred barrier (Cases 2–3, eqs. 6.53–6.65): joint_position_limit and "
            "velocity constraints"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))
    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))


class BPBCSpec(GainsSpec):
    type: Literal["bpbc", "bpbc_ke"] = Field(
        description=(
            "bpbc: Theorem 7.7, bounded torque, a joint_rate_limit on every joint; bpbc_ke: "
            "Corollary 7.8, one kinetic_energy_limit"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))
    xi: Gain = Field(
        default=1.0, description=(
            "Ξ of the ln cosh potential: one number or one per coordinate"))
    gamma: Gain = Field(
        default=1.0, description=(
            "Γ of the K_D tanh(Γẋ) damping: one number or one per coordinate"))
    shaping: ShapingSpec | None = Field(
        default=None, description=(
            "the barrier's shaping s: identity, power (α) or tanh (σ)"))
    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))


class CBFQPSpec(GainsSpec):
    """The CBF-QP peer (cpbc.peers.cbf_qp): PD + gravity, or an operational-space nominal
    toward a goal or reference, filtered by a QP."""

    type: Literal["cbf_qp"] = Field(
        description=(
            "the torque-level CBF-QP safety filter around PD + gravity (needs the peers "
            "extra)"))
    nominal: Literal["pd_gravity", "osc"] = Field(
        default="pd_gravity", description=(
            "the torque it filters: pd_gravity (g − K_P x̃ − K_D ẋ toward target:) or osc "
            "(operational-space control toward goal: or reference:, with task: and posture: "
            "gains; cpbc.peers.osc)"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))
    # cpbc.peers.cbf_rows
    variant: Literal["braking", "exponential"] = Field(
        default="braking", description=(
            "braking (default) or exponential: the earlier filter"))
    # k [1/s]: α'(0) of the braking rows, or the exponential poles
    gain: Positive = Field(
        default=20.0, description=(
            "k [1/s]: α'(0) of the braking rows, or the exponential variant's double pole"))
    # γ of the first-order rows [1/s]; 1/(2h) when omitted
    rate_gain: Positive | None = Field(
        default=None, description=(
            "γ of the first-order rows [1/s]; 1/(2h) when omitted"))
    # β: share of the box's deceleration
    braking_share: float = Field(
        default=0.5, gt=0, le=1, description=(
            "β ∈ (0, 1]: the share of the torque box's deceleration a braking row counts on"))
    # c on rate rows; 2e-3 (h/1 ms)^1.7
    rate_cushion: float | None = Field(
        default=None, ge=0, description=(
            "c on rate rows [rad/s]; 2e-3 (h / 1 ms)^1.7 when omitted"))
    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))


ControllerSpec = Annotated[
    PDSpec | CPBCSpec | RecentredSpec | BPBCSpec | CBFQPSpec, Field(discriminator="type")
]
