"""Seeded FR3 reaches on franky-sim through cpbc.hardware: out to a target drawn around the
scenario's (joints 1-4, ±0.3 rad) and back to franky-sim's start posture, each motion checked
on its log against the Franka's rules (first command 0, every step within 1 N m, the torque
box, every margin > 0 on the measured states). Prints one line per motion and a total.

    python scripts/franky_reaches.py [--motions 12] [--seed 7] [--scenario FILE]
        [--deadline-ms 50]

franky-sim runs on its own wall clock: run this on an idle machine for timings that mean
anything (the computation's percentiles are this computer's).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import yaml

from cpbc.errors import CpbcError, InadmissibleStateError
from cpbc.hardware.franka import FrankaBackend
from cpbc.hardware.motion import MotionSettings
from cpbc.hardware.robot_run import HardwareRun, choose_controller, run_on_robot
from cpbc.hardware.simulator import FrankySim, loopback_address
from cpbc.scenario import build, load_scenario

ROOT = Path(__file__).resolve().parents[1]
HOME = [0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785]  # franky-sim's start posture


def _line(k: int, target: str, run: HardwareRun) -> str:
    r, x = run.rules, run.summary.extra
    worst = min(r.worst_margin.values())
    return (f"{k:3d} {target:6s} {run.motion.ending:19s} {'yes' if r.kept else 'NO':4s} "
            f"{r.first_command:6.3g} {r.steps_over:5d} {r.largest_step.max():6.3g} "
            f"{worst:8.4f} {run.summary.final_error:7.4f} {x['compute_us_p50']:6.0f} "
            f"{x['compute_us_p999']:8.0f} {x['compute_us_max']:8.0f} {x['lost_states']:5.0f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--motions", type=int, default=12)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--scenario", type=Path, default=ROOT / "tests/scenarios/fr3_reach_ball.yaml")
    p.add_argument("--deadline-ms", type=float, default=50.0)
    args = p.parse_args()
    data = yaml.safe_load(args.scenario.read_text())
    base = np.asarray(data["target"], dtype=float)
    rng = np.random.default_rng(args.seed)
    settings = MotionSettings(data["simulation"]["duration"], args.deadline_ms * 1e-3)
    print("  k target ending              kept  first  over   step   margin   error    p50"
          "    p99.9      max  lost   (N m, m or rad, µs)")
    runs: list[HardwareRun] = []
    with FrankySim(loopback_address()) as sim, tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "reach.yaml"
        while len(runs) < args.motions:
            step = np.zeros(7)
            step[:4] = rng.uniform(-0.3, 0.3, 4)
            for name, target in (("seeded", base + step), ("home", np.array(HOME))):
                data["target"] = [float(v) for v in target]
                path.write_text(yaml.safe_dump(data))
                try:
                    setup = build(*load_scenario(path))
                except (CpbcError, InadmissibleStateError):
                    break  # a target inside the margins: draw another
                backend = FrankaBackend(sim.host)
                try:
                    run = run_on_robot(setup, choose_controller(setup, None), backend,
                                       settings)
                except CpbcError as exc:  # the arm rests where no scenario may start
                    print(f"    stopped: the start is refused: {exc}")
                    return _total(runs)
                finally:
                    backend.close()
                runs.append(run)
                print(_line(len(runs), name, run), flush=True)
    _total(runs)


def _total(runs: list[HardwareRun]) -> None:
    kept = sum(r.rules.kept for r in runs)
    over = sum(r.rules.steps_over for r in runs)
    lost = sum(r.summary.extra["lost_states"] for r in runs)
    print(f"{kept} of {len(runs)} motions kept every rule; {over} cycles over the rate; "
          f"{lost:.0f} lost states; endings: "
          + ", ".join(f"{e} {sum(r.motion.ending == e for r in runs)}"
                      for e in sorted({r.motion.ending for r in runs})))


if __name__ == "__main__":
    main()
