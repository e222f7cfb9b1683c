"""What the scenario's ``controllers:`` items share: their gains, shaping, task and posture
gains, and the bases of the law kinds' specs (each kind's own spec is declared at the end of
its law's module, cpbc.controllers.law_kind)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

from cpbc.spec.fields import Gain, Positive, Strict
from cpbc.spec.names import RunName


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
    (see cpbc.scenario.gain_check)."""

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


class LawSpec(GainsSpec):
    """What every ``controllers:`` entry has: its gains, its ``type`` and its ``name``. Each
    law kind (cpbc.controllers.law_kind) narrows ``type`` to its names and adds its own keys."""

    type: str = Field(description="the law")
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))


class ConstrainedLawSpec(LawSpec):
    """A law that enforces scenario constraints: ``constraints`` names them."""

    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))



class ShapedLawSpec(ConstrainedLawSpec):
    """A barrier law whose barrier takes a shaping s (CPBC and BPBC, Chapters 6–7)."""

    shaping: ShapingSpec | None = Field(
        default=None, description=(
            "the barrier's shaping s: identity, power (α) or tanh (σ)"))
