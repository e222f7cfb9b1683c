"""The safeguard's acceptance test (step 3 of the package docstring): F(τ) of (S1) and (S2)
over a prediction, the law's torque as the guard holds it (corrected for the hold), and the
Illinois blend toward a replacement torque for the smallest share that passes."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.hold import hold_corrected
from cpbc.controllers.safeguard.members import GuardMembers
from cpbc.controllers.safeguard.prediction import Predictor
from cpbc.model.robot_model import ArmState


class Acceptance(GuardMembers):
    """(S1), (S2) and the blend: mixed into :class:`cpbc.controllers.safeguard.Safeguard`."""

    @staticmethod
    def _no_nan(m: Array) -> Array:
        raise NotImplementedError

    def _check(self, predict: Predictor, end_floor: Array, mid_floor: Array | None,
               stop: tuple[float, Array] | None = None,
               past: np.ndarray | None = None) -> Callable[[Array], float]:
        """F(τ) = min_i m_i/floor_i − 1 over the predicted end (and mid-period
        configuration) margins of every prediction, and with ``stop`` = (1/(2θA), floors)
        the braking margins σ_i at the predicted ends: ≥ 0 when τ keeps every margin above
        its floor. ``past`` marks the margins already ≤ 0 (only the extra constraints can
        be): their floor is their present value, compared by difference, and their braking
        margin is not held (:meth:`_guard`)."""
        guarded, no_nan, nc = self.guarded, self._no_nan, self._n_config
        past_mid = None if past is None else past[:nc]
        past_v = None if past is None else past[nc:]
        has_velocity = bool(guarded.velocity)

        def f(t: Array) -> float:
            mids, ends, speeds, inner_x, inner_v = predict(t)
            velocity = no_nan(guarded.velocity_margins_along(ends, speeds))
            # the velocity margins inside the period too, held to their end floor: under a
            # held torque whose acceleration turns within the period a rate can cross its
            # bound and be back by the end (seen at 100 Hz once the torque was corrected
            # for the hold)
            inner = float(_shares(no_nan(guarded.velocity_margins_along(inner_x, inner_v)),
                                  end_floor[nc:], past_v).min()) if has_velocity else math.inf
            if mid_floor is None:
                return min(inner, float(_shares(velocity, end_floor, past).min())) - 1.0
            rows = [mids, ends]
            if stop is not None:  # x_s = x₁ + (|ẋ₁|/(2θA)) ẋ₁, A frozen at the sample
                speed = np.sqrt(np.einsum("ij,ij->i", speeds, speeds))
                rows.append(ends + (stop[0] * speed)[:, None] * speeds)
            config = no_nan(guarded.configuration_margins_along(np.concatenate(rows)))
            r = len(ends)
            end = np.concatenate((config[r:2 * r], velocity), axis=1)
            low = min(inner, float(_shares(end, end_floor, past).min()),
                      float(_shares(config[:r], mid_floor, past_mid).min()))
            if stop is not None:
                braking = config[2 * r:] / stop[1]
                if past_mid is not None:
                    braking = np.where(past_mid, np.inf, braking)
                low = min(low, float(braking.min()))
            return low - 1.0

        return f

    def _braking_floor(self, state: ArmState, bias: Array) -> tuple[float, Array] | None:
        """(1/(2θA), the floors of the braking margins σ_i: their cushions δ_i), or None
        without a torque box, at rest, or where the box leaves no deceleration (then no
        torque can help and σ is not held). σ is held above its cushion, not by the decay
        rule (S1): that would cost a second evaluation of every constraint per step, at the
        stopping point of the sample, and φ itself is held by (S1) already."""
        if self.braking is None:
            return None
        per_speed = self.braking.per_speed(state.inertia, bias, state.dx)
        if per_speed == 0.0 or per_speed == math.inf:
            return None
        return per_speed, self._sigma_floor

    def _held(self, state: ArmState, bias: Array, law: Array,
              slack: Callable[[Array], float]) -> tuple[Array, float]:
        """The law's torque as the guard would hold it, and F of (S1) there: corrected for
        the hold (:func:`hold_corrected`, by the plant's share ``hold_share``) and scaled
        into the torque box. If that fails (S1) while the law's own torque keeps it, the
        blend of the two with as much of the correction as (S1) lets through (F ≥ 0): the
        correction, not the law, is what fails then. It is right for a plant whose
        acceleration drifts within the period (the corrected prediction), while the frozen
        prediction sees the correction and none of the drift, and finds the margin moved
        by s h Δa against the law's own torque; near a velocity bound that is more than
        (S1) allows, and braking there fought the law on every other step."""
        share = self.hold_share
        tau = hold_corrected(self.model, state, bias, law, self.period, share) if share else law
        boxed = self._box(bias, tau)
        if boxed is not tau:
            self.scaled += 1
            tau = boxed
        f0 = slack(tau)
        if f0 >= 0.0 or not share:
            return tau, f0
        plain = self._box(bias, law)
        f_plain = slack(plain)
        if f_plain < 0.0:
            return tau, f0
        self.uncorrected += 1
        return self._blend(tau, plain, f0, f_plain, slack), 0.0

    def _blend(self, tau: Array, brake: Array, f0: float, f1: float,
               slack: Callable[[Array], float]) -> Array:
        """Illinois steps for the smallest β with F(β) ≥ 0, bracketed by F(0) < 0 ≤ F(1)."""
        lo, f_lo, hi, f_hi = 0.0, f0, 1.0, f1
        side = 0
        for _ in range(self.settings.backoffs):
            beta = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            if not lo < beta < hi:
                beta = 0.5 * (lo + hi)
            f = slack((1.0 - beta) * tau + beta * brake)
            if f >= 0.0:
                hi, f_hi = beta, f
                if side == 1:
                    f_lo *= 0.5
                side = 1
            else:
                lo, f_lo = beta, f
                if side == -1:
                    f_hi *= 0.5
                side = -1
        return (1.0 - hi) * tau + hi * brake


def _shares(m: Array, floor: Array, past: np.ndarray | None) -> Array:
    """m / floor per margin (≥ 1: the margin keeps its floor); where ``past`` (floor ≤ 0, the
    margin broken already) 1 + (m − floor)/|floor| instead, which is ≥ 1 when m ≥ floor."""
    if past is None:
        return m / floor
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(past, 1.0 + (m - floor) / np.maximum(np.abs(floor), 1e-12), m / floor)
