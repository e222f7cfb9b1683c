"""cpbc.bench_stream: the streamed target's cost figures are made and well formed (what they
say is printed by ``python -m cpbc.bench --robot panda``, never asserted against a clock)."""

from __future__ import annotations

import math

from cpbc.bench import taskspace_pair
from cpbc.bench_stream import stream_pair, stream_times
from cpbc.reference.target import Steered


def test_the_stream_figures_are_made() -> None:
    found = stream_times(taskspace_pair(states=8)[1], repeats=2, steps=300)
    for law in ("fixed", "streamed"):
        for clock in ("", "cpu_"):
            q = [found[f"{law}_{clock}{k}_us"] for k in ("p50", "p99", "p999", "max")]
            assert all(math.isfinite(v) and v > 0 for v in q) and q == sorted(q)
    assert found["ratio_min"] <= found["ratio_max"] and found["ratio"] > 0


def test_the_streamed_law_follows_its_policy_and_the_fixed_one_keeps_its_goal() -> None:
    fixed, streamed, policy, _ = stream_pair()
    law = getattr(fixed, "law", None)  # the fixed goal's law inside its safeguard
    assert law is not None and law is not streamed.law  # built apart: steered alone
    assert not any(isinstance(p, Steered) for p in law.potential.parts)
    start = streamed.requested.copy()
    for _ in range(41):
        policy.tick()
    assert policy.k == 41 and not (streamed.requested == start).all()
    assert max(abs(streamed.requested - policy.goal)) <= 0.03
