"""A digest of the closed loops of scenarios and campaign files, to tell whether a change moved
any trajectory by a single bit.

    python -m tools.trajectory_digest scenarios/panda_cpbc_sphere.yaml tools/campaigns/*.yaml
    python -m tools.trajectory_digest --starts 4 --seconds 0.4 FILE ...

For each file: its campaign set-up (cpbc.reliability.campaign.campaign_setup, the scenario's
own plant), ``--starts`` seeded starts (``sample_states``, seed ``--seed``), each run for
``--seconds`` in MuJoCo under each of its first two constrained laws as the scenario builds
them (with their safeguards), and one line: the file, a SHA-1 of every run's positions and
torques (a run that raises adds its error's name), and how many steps the guards acted at.
Run it before and after a change (e.g. from a worktree of the commit before, with
PYTHONPATH pointing at it) and compare the lines: a refactor of the hot path should leave
every digest as it was. Nothing is written.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import warnings
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from cpbc.errors import CpbcError


def digest(path: str, starts: int, seconds: float, seed: int) -> tuple[str, int]:
    """(the SHA-1 of the runs of ``path``, the steps its guards acted at)."""
    from cpbc.reliability.campaign import campaign_setup, sample_states
    from cpbc.simulation import run_mujoco

    setup = campaign_setup(path, integrator=None)
    laws = [e for e in setup.controllers if not e.controller.constraints.empty][:2]
    settings = replace(setup.loop_settings, duration=seconds)
    plant = setup.make_plant()
    found, acted = hashlib.sha1(), 0
    for entry in laws:
        for start in sample_states(setup, starts, seed):
            law = setup.controller(entry)
            try:
                run = run_mujoco(plant, law, setup.model.coordinates, start.position,
                                 start.velocity, settings)
            except CpbcError as exc:  # a run the law refuses is part of what it does
                found.update(type(exc).__name__.encode())
                continue
            found.update(np.asarray(run.position).tobytes())
            found.update(np.asarray(run.torque).tobytes())
            acted += int(getattr(law, "acted", 0))
    return found.hexdigest()[:16], acted


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.trajectory_digest", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", nargs="+", help="scenario or campaign files")
    p.add_argument("--starts", type=int, default=4, help="seeded starts per law (default 4)")
    p.add_argument("--seconds", type=float, default=0.4, help="simulated s per run")
    p.add_argument("--seed", type=int, default=1, help="the starts' seed")
    args = p.parse_args(argv)
    if args.starts < 1 or not args.seconds > 0.0:
        print("error: --starts must be ≥ 1 and --seconds > 0", file=sys.stderr)
        return 2
    warnings.simplefilter("ignore")  # the build's notes, the same before and after
    for path in args.files:
        try:
            value, acted = digest(path, args.starts, args.seconds, args.seed)
        except (CpbcError, OSError) as exc:
            print(f"error: {path}: {exc}", file=sys.stderr)
            return 2
        print(f"{path} {value} acted {acted}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
