"""What the safeguard's rescue search costs, on the Panda campaign states pinned in
tests/test_brakes.py (states outside the guard's braking set V that another brake stops).

Each state runs 0.3 s under its guarded law at its rate, as the test runs it; every call of
the rescue (cpbc.controllers.rescue.Rescue.torque) is timed. A call that searches the brakes
(nothing committed, or the committed brake's one-period prediction failed) is counted apart
from one that holds the committed brake. Prints per state the rescued steps, the searches and
their cost, then the median and range over all searches [ms].

    PYTHONPATH=. python scripts/rescue_cost.py

(``PYTHONPATH=.``: measure this checkout's package, not an installed copy.)
"""

from __future__ import annotations

import platform
import time
from dataclasses import replace

import numpy as np

from cpbc.controllers.rescue import Rescue
from cpbc.reliability.campaign import RecordingPlant, checked_run, kept_constraints
from cpbc.reliability.verification import draw_state
from cpbc.scenario import build, load_scenario

CASES = [("panda_cpbc_sphere", 1000.0, seed) for seed in (1, 5, 22, 51, 61)] + [
    ("panda_cpbc_ke_box", 1000.0, 106), ("panda_cpbc_ke_box", 1000.0, 140),
    ("panda_cpbc_ke_box", 100.0, 127)]


def main() -> None:
    searches: list[float] = []
    holds: list[float] = []
    original = Rescue.torque

    def timed(self: Rescue, *args: object, **kwargs: object) -> object:
        before = self.searches
        start = time.perf_counter()
        out = original(self, *args, **kwargs)  # type: ignore[arg-type]
        took = 1e3 * (time.perf_counter() - start)
        (searches if self.searches > before else holds).append(took)
        return out

    Rescue.torque = timed  # type: ignore[method-assign]
    print("scenario | rate | seed | rescued steps | searches | search ms (median, max)")
    for scenario, rate, seed in CASES:
        setup = build(*load_scenario(scenario))
        entry = next(e for e in setup.controllers if e.controller.type_name != "cbf_qp"
                     and not e.controller.constraints.empty)
        h = 1.0 / rate
        kept = kept_constraints(setup, entry, h, setup.safeguard)
        plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
        s = draw_state(setup, seed)
        settings = replace(setup.loop_settings, duration=0.3, control_period=h, log_every=1,
                           noise=None)
        first = len(searches)
        check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                            safeguard=setup.safeguard)
        mine = searches[first:]
        print(f"{scenario} | {rate:g} Hz | {seed} | {check.trajectory.rescues} | {len(mine)} | "
              + (f"{np.median(mine):.2f}, {max(mine):.2f}" if mine else "-"), flush=True)
    s_ms, h_ms = np.array(searches), np.array(holds)
    print(f"\n{time.strftime('%Y-%m-%d')}, Python {platform.python_version()}, "
          f"{platform.processor() or platform.machine()}")
    if s_ms.size:
        print(f"searches: {s_ms.size}, median {np.median(s_ms):.2f} ms, range "
              f"{s_ms.min():.2f}–{s_ms.max():.2f} ms")
    if h_ms.size:
        print(f"committed holds: {h_ms.size}, median {np.median(h_ms):.3f} ms, range "
              f"{h_ms.min():.3f}–{h_ms.max():.3f} ms")


if __name__ == "__main__":
    main()
