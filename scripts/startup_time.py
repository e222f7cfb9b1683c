"""Start-up of a fresh process: import cpbc, build a guarded Panda law, call ``torque`` once.

The target is "a fresh run's import plus first torque call ≤ 1 s" after
``scripts/install.sh`` (numba's cache warm, so nothing compiles). Two paths, each timed in
``--runs`` fresh interpreters taking turns, printed as median and range of wall-clock and
CPU seconds:

- ``api``: the Python API — the Panda with its URDF limits, the sphere cover of its links
  (``cached_cover``), a ball, joint ranges and rates, CPBC, one ``torque``;
- ``scenario``: ``load_scenario`` and ``build`` of ``scenarios/panda_cpbc_sphere.yaml``, then
  its guarded CPBC's first ``torque``.

    PYTHONPATH=. python scripts/startup_time.py [--runs 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

API = """
import json, time
t0, c0 = time.perf_counter(), time.process_time()
import numpy as np
from cpbc.constraints import (Clearance, ConstraintSet, SphereObstacle, cached_cover,
                              joint_position_limit, joint_rate_limit)
from cpbc.controllers import CPBC, Power
from cpbc.model import RobotModel
from cpbc.model.loading import load_arm
t_import = time.perf_counter()
arm = load_arm("panda")
model = RobotModel(arm.model, name="panda")
names = list(arm.joint_names)
ball = SphereObstacle("ball", np.array([0.5, 0.0, 0.3]), 0.08)
cons = ConstraintSet(model.n, [
    joint_position_limit(arm.position_lower, arm.position_upper, names),
    Clearance(model, cached_cover(arm.model, arm.collision_model), [ball], 0.01, 0.1)],
    [joint_rate_limit(0.5 * arm.velocity_limit, names)])
law = CPBC(model, np.array([0.179, 0.172, 0.497, -2.085, -0.103, 2.233, 0.785]), cons,
           kp=60.0, kd=12.0, shaping=Power(0.2))
law.torque(np.array([-0.179, 0.172, -0.497, -2.085, 0.103, 2.233, 0.785]), np.zeros(7))
print(json.dumps({"import": t_import - t0, "wall": time.perf_counter() - t0,
                  "cpu": time.process_time() - c0}))
"""

SCENARIO = """
import json, time
t0, c0 = time.perf_counter(), time.process_time()
from pathlib import Path
from cpbc.scenario import build, load_scenario
t_import = time.perf_counter()
setup = build(*load_scenario(Path("scenarios/panda_cpbc_sphere.yaml")))
entry = next(e for e in setup.controllers if e.name == "CPBC")
case = setup.cases[0]
setup.controller(entry).torque(case.position, case.velocity)
print(json.dumps({"import": t_import - t0, "wall": time.perf_counter() - t0,
                  "cpu": time.process_time() - c0}))
"""


def one(code: str) -> dict[str, float]:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=5, help="fresh processes per path")
    args = p.parse_args()
    runs: dict[str, list[dict[str, float]]] = {"api": [], "scenario": []}
    for _ in range(args.runs):  # the two paths take turns, so load hits both alike
        runs["api"].append(one(API))
        runs["scenario"].append(one(SCENARIO))
    for path, rs in runs.items():
        parts = []
        for key in ("import", "wall", "cpu"):
            v = [r[key] for r in rs]
            parts.append(f"{key} {statistics.median(v):.3f} s ({min(v):.3f}–{max(v):.3f})")
        print(f"{path:<9} " + ", ".join(parts))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
