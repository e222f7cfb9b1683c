"""``type: cbf_qp``: the CBF-QP peer (cpbc.peers.cbf_qp), PD + gravity — or, toward a goal or
reference, an operational-space nominal (cpbc.peers.osc) — filtered by a QP on the same
constraint objects as the laws. cpbc.peers (an optional extra) is imported only when a
scenario builds one."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

from pydantic import Field

from cpbc.controllers.controller import Controller
from cpbc.errors import ScenarioError
from cpbc.scenario.schema.common import Positive
from cpbc.scenario.schema.controller_specs import (
    ConstrainedLawSpec,
    PostureGainsSpec,
    TaskGainsSpec,
)
from cpbc.scenario.schema.kinds.law_inputs import LINEAR, LawInputs
from cpbc.scenario.schema.kinds.registry import LawKind

if TYPE_CHECKING:
    from cpbc.peers.osc import OperationalSpace


class CBFQPSpec(ConstrainedLawSpec):
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


def _nominal(spec: CBFQPSpec, given: LawInputs) -> OperationalSpace | None:
    """The operational-space nominal (``nominal: osc``) toward the goal with the law's task
    and posture gains, or None for PD + gravity."""
    field = f"{given.field}.nominal"
    if spec.nominal == "pd_gravity":
        if given.goal is not None:
            raise ScenarioError(field, "with goal: or reference:, cbf_qp filters an "
                                "operational-space nominal: set nominal: osc")
        return None
    if given.goal is None:
        raise ScenarioError(field, "osc steers a frame: give goal: or reference: in place "
                            "of target:, or nominal: pd_gravity")
    from cpbc.peers.osc import OperationalSpace, OSCGains

    task, posture = spec.task or TaskGainsSpec(), spec.posture or PostureGainsSpec()
    return OperationalSpace(given.model, given.goal, given.target, OSCGains(
        task.omega_n, task.zeta, task.rotation_omega_n or task.omega_n, posture.omega_n,
        posture.zeta))


def build(spec: CBFQPSpec, given: LawInputs) -> Controller:
    osc = _nominal(spec, given)
    from cpbc.peers import CBFQP, PeerUnavailable

    cons = given.constraint_set(spec.constraints)
    loop = given.loop
    try:
        return CBFQP(given.model, given.target, cons, given.gains["kp"], given.gains["kd"],
                     spec.gain, spec.rate_gain, loop.control_period, loop.torque_limit,
                     spec.variant, spec.braking_share, spec.rate_cushion, osc)
    except PeerUnavailable as exc:
        raise ScenarioError(f"{given.field}.type", str(exc)) from None


KIND = LawKind(CBFQPSpec, build, slopes=LINEAR, goal_types=("cbf_qp",))
