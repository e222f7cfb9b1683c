"""``type: cbf_qp``: the CBF-QP peer (cpbc.peers.cbf_qp), PD + gravity filtered by a QP on
the same constraint objects as the laws. cpbc.peers (an optional extra) is imported only when
a scenario builds one."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from cpbc.controllers.base import Controller
from cpbc.errors import ScenarioError
from cpbc.scenario.schema.common import Positive
from cpbc.scenario.schema.controller_specs import ConstrainedLawSpec
from cpbc.scenario.schema.kinds.law_inputs import LINEAR, LawInputs
from cpbc.scenario.schema.kinds.registry import LawKind


class CBFQPSpec(ConstrainedLawSpec):
    """The CBF-QP peer (cpbc.peers.cbf_qp): PD + gravity filtered by a QP."""

    type: Literal["cbf_qp"] = Field(
        description=(
            "the torque-level CBF-QP safety filter around PD + gravity (needs the peers "
            "extra)"))
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


def build(spec: CBFQPSpec, given: LawInputs) -> Controller:
    from cpbc.peers import CBFQP, PeerUnavailable

    cons = given.constraint_set(spec.constraints)
    loop = given.loop
    try:
        return CBFQP(given.model, given.target, cons, given.gains["kp"], given.gains["kd"],
                     spec.gain, spec.rate_gain, loop.control_period, loop.torque_limit,
                     spec.variant, spec.braking_share, spec.rate_cushion)
    except PeerUnavailable as exc:
        raise ScenarioError(f"{given.field}.type", str(exc)) from None


KIND = LawKind(CBFQPSpec, build, slopes=LINEAR)
