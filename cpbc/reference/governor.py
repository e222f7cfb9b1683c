"""The explicit reference governor on the path parameter (TASKSPACE §3, Claim C).

The applied path time s_v advances, once per control period h, by

    ṡ_v = min(ρ, κ · max(0, Γ − V̄)/Γ, v_max/|dp/ds(s_v)|),   ρ = ρ_max while s_v < t, else 1
    V̄ = V(x, ẋ; v) · s(ΦΨ(x_n(s_v), 0))                       (the law's V normalised, J)

and never onto an inadmissible stretch of the posture path (cpbc.reference.posture_path):
when the next step would enter one, s_v stops at its start and the governor is *blocked*
by the stretch's constraint. ``stop`` stays there. ``rejoin`` waits until the path's own
clock t has passed the stretch, then carries the applied reference from where it stopped to
the stretch's end, at the same rate, along the straight blend (point and posture), and
continues the path from there, catching up at ρ_max. The plan checks that blend's postures
(every configuration margin ≥ δ/2 at 21 points, cpbc.reference.plan.blend_admissible); a
stretch whose blend fails is planned as lasting to the path's end, so rejoin stops there.

{V̄ ≤ Γ} is forward invariant: at V̄ = Γ the reference stops (ṡ_v = 0, ṗ_ff = 0) and V̄ is
non-increasing for a frozen reference. v_max keeps the applied reference Lipschitz even
where the path jumps (a CSV glitch).

Per step the governor does scalar arithmetic only (``PathGovernor.advance``); the
tables it reads (normalisation and stretches) are built offline.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

POLICIES = ("stop", "rejoin")


@dataclass(frozen=True)
class GovernorSettings:
    """The reference governor's settings (module docstring), all checked at construction
    (``ValueError`` naming the field).

    Attributes:
        budget: Γ [J], > 0: the applied reference moves only while V̄ < Γ.
        gain: κ [1/s], > 0: how fast the pace falls as V̄ nears Γ.
        catch_up: ρ_max, ≥ 1: the path's rate while the applied path time lags its clock.
        max_speed: v_max [m/s], > 0: the fastest the applied point moves (a path's jump, a
            streamed target's jump of any size).
        margin: δ, ≥ 0: the configuration margin of S_δ a planned path's posture keeps.
        on_infeasible: ``stop`` or ``rejoin`` at an inadmissible stretch of a path.
        max_joint_speed: [rad/s or m/s], > 0: the fastest the applied posture moves toward
            a streamed joint target.
        max_angular_speed: [rad/s], > 0: the fastest the applied orientation turns toward a
            streamed one.
    """

    budget: float = 1.0
    gain: float = 20.0
    catch_up: float = 1.5
    max_speed: float = 1.0
    margin: float = 0.03
    on_infeasible: str = "stop"
    max_joint_speed: float = 1.0
    max_angular_speed: float = 1.0

    def __post_init__(self) -> None:
        for name in ("budget", "gain", "max_speed", "max_joint_speed", "max_angular_speed"):
            if not getattr(self, name) > 0:
                raise ValueError(f"governor.{name} must be > 0")
        if not self.catch_up >= 1 or not self.margin >= 0:
            raise ValueError("governor.catch_up must be ≥ 1 and governor.margin ≥ 0")
        if self.on_infeasible not in POLICIES:
            raise ValueError(f"governor.on_infeasible must be one of {POLICIES}")


@dataclass(frozen=True)
class Block:
    """A blocked stretch: the constraint, when (run time) and where (path time) it stopped."""

    constraint: str
    time: float
    path_time: float


class PathGovernor:
    """s_v and its state; ``advance`` once per control period.

    Attributes:
        s: the applied path time s_v; ``rate``: the last ṡ_v; ``blend``: during a rejoin, the
            share (0..1) of the way from the stop to the stretch's end, else None.
        blocks: every block so far; ``steps_slowed`` / ``steps_blocked``: counts of steps
            with ṡ_v < 0.95 (not blocked) and blocked.
    """

    def __init__(self, settings: GovernorSettings, duration: float, period: float,
                 stretches: tuple[tuple[float, float, str], ...],
                 blend_times: tuple[float, ...] = ()) -> None:
        """``blend_times``: per stretch, the path time a rejoin's blend takes at ṡ_v = 1."""
        self.settings, self.duration, self.h = settings, duration, period
        self.stretches = stretches
        self.blend_times = blend_times or tuple(period for _ in stretches)
        self.s, self.rate, self.t = 0.0, 0.0, 0.0
        self.blend: float | None = None
        self.blocked: tuple[float, float, str] | None = None
        self.blocks: list[Block] = []
        self.steps_slowed = self.steps_blocked = 0
        self._next = 0  # the index of the next stretch ahead of s_v

    def start_at(self, s: float) -> None:
        """Start at path time ``s`` (a campaign's drawn phase, outside every stretch): s_v and
        the run clock at s, the stretches that begin before it passed."""
        self.s = self.t = s
        self._next = sum(1 for stretch in self.stretches if stretch[0] < s)

    def _rate(self, vbar: float, speed: float) -> float:
        st = self.settings
        cap = st.catch_up if self.s < self.t else 1.0
        gate = st.gain * max(0.0, st.budget - vbar) / st.budget
        return min(cap, gate, st.max_speed / speed if speed > 0.0 else cap)

    def advance(self, t: float, vbar: float, speed: float) -> float:
        """s_v after the step at run time t, from V̄ and |dp/ds(s_v)| (module docstring)."""
        self.t = t
        if self.blocked is not None:
            return self._held(t, vbar, speed)
        rate = self._rate(vbar, speed)
        s = min(self.s + rate * self.h, self.duration, t + self.h)
        if self._next < len(self.stretches) and s >= self.stretches[self._next][0]:
            start = self.stretches[self._next]
            self.blocked = start
            self.blocks.append(Block(start[2], t, self.s))
            self.steps_blocked += 1
            self.rate = 0.0
            return self.s
        if rate < 0.95 and self.s < self.duration:
            self.steps_slowed += 1
        self.s = s
        self.rate = rate if s < self.duration else 0.0  # at the end the reference rests
        return s

    def _held(self, t: float, vbar: float, speed: float) -> float:
        """Blocked: stay (stop), or carry the reference over the stretch once t is past its
        end (rejoin)."""
        assert self.blocked is not None
        end = self.blocked[1]
        if self.settings.on_infeasible == "stop" or t < end or math.isinf(end):
            self.steps_blocked += 1
            self.rate = 0.0
            return self.s
        rate = self._rate(vbar, speed)
        span = max(self.blend_times[self._next], self.h)
        self.blend = min(1.0, (self.blend or 0.0) + rate * self.h / span)
        self.rate = 0.0
        if self.blend >= 1.0:
            self.s, self.blend, self.blocked = end, None, None
            self._next += 1
        return self.s

    @property
    def blocked_now(self) -> bool:
        return self.blocked is not None
