"""What the half-space of half_space.py costs CPBC's ``torque`` (the planar arm with the
thesis's constraints, a ceiling on its end point; the Panda of the bench, a ceiling on its
hand): without it, with it beside the compiled terms (its terms in Python),
and with the whole law on its general path (what any constraint without a kernel cost before
cpbc.constraints.python_terms). ``python docs/examples/half_space_cost.py``: medians of
single calls over the bench's states, in one process."""

from __future__ import annotations

import statistics
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from half_space import HalfSpace

from cpbc.bench import planar_2link
from cpbc.bench_arms import panda
from cpbc.constraints import ConstraintSet
from cpbc.controllers import CPBC


class General(CPBC):
    """CPBC taking its general path, method by method (its ``_law`` overridden)."""

    def _law(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        return super()._law(*args, **kwargs)


def median_us(law: CPBC, states: list, rounds: int = 30) -> float:  # type: ignore[type-arg]
    times = []
    for _ in range(rounds):
        for x, dx in states:
            start = time.perf_counter()
            law.torque(x, dx)
            times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e6


def costs(robot: str) -> dict[str, float]:
    """The three medians [µs] on ``robot`` (planar_2link or panda)."""
    setup = planar_2link() if robot == "planar_2link" else panda()
    frame, normal, depth = (("end_point", [0, 1, 0], 1.9) if robot == "planar_2link" else
                            ("panda_hand", [0, 0, 1], 1.5))
    base = setup.controllers["cpbc"]
    assert isinstance(base, CPBC)
    cs = base.constraints
    ceiling = HalfSpace(base.model, frame, normal, depth, "ceiling")
    with_it = ConstraintSet(cs.n, [*cs.configuration, ceiling], cs.velocity)
    args = (base.model, base.target)
    gains = (base.kp, base.kd, base.shaping)
    laws = {"compiled, without the half-space": CPBC(*args, cs, *gains),
            "with it, its terms in Python": CPBC(*args, with_it, *gains),
            "with it, the whole law general": General(*args, with_it, *gains)}
    states = setup.states
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for law in laws.values():
            for x, dx in states[:4]:
                law.torque(x, dx)
    return {name: median_us(law, states) for name, law in laws.items()}


def main() -> None:
    for robot in ("planar_2link", "panda"):
        found = costs(robot)
        first = next(iter(found.values()))
        for name, us in found.items():
            print(f"{robot}: {name}: {us:.2f} µs ({us / first:.2f}×)")


if __name__ == "__main__":
    main()
