"""``python -m cpbc.hardware SCENARIO --robot-ip IP [--dry-run] [--out DIR]
[--controller NAME] [--backend franka|lockstep] [--cpu-latency-us N | --no-cpu-latency]``:
a scenario's controller on a robot.

Exit codes: 0 when the motion ran (whatever the controller did) or the dry run passed, 1 when
the robot ended the motion (its error named, with the last state; the files so far are
written) or the controller failed or overran its deadline, 2 for bad input (one line naming
the field; nothing moves, nothing is written), 130 when interrupted (after braking).
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cpbc.errors import CpbcError
from cpbc.hardware.backend import RobotBackend, RobotFault
from cpbc.hardware.cpu_latency import latency_target
from cpbc.hardware.motion import MotionSettings
from cpbc.hardware.robot_run import (
    HardwareRun,
    choose_controller,
    lockstep_for,
    on_robot,
    run_on_robot,
)
from cpbc.hardware.robot_run import write_run as write_files
from cpbc.scenario import build
from cpbc.scenario.arm_setup import ScenarioSetup
from cpbc.scenario.load import load_any
from cpbc.scenario.schema import SystemScenario

#: Exit code of each way a motion ends.
EXIT = {"completed": 0, "constraint_violated": 0, "interrupted": 130, "robot_error": 1,
        "controller_error": 1, "deadline_missed": 1}


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m cpbc.hardware",
        description="Run a scenario's controller on a torque-controlled robot, from the "
        "state it is in.")
    p.add_argument("scenario", help="scenario YAML file, or the name of a shipped scenario")
    p.add_argument("--robot-ip", help="the robot's address (a Franka's FCI address; "
                   "franky-sim prints its own)")
    p.add_argument("--backend", choices=("franka", "lockstep"), default="franka",
                   help="franka: a Franka through pylibfranka; lockstep: the scenario's "
                   "MuJoCo plant as a robot, one physics step per command (no network)")
    p.add_argument("--controller", help="the scenario's controller to run (when it has "
                   "several)")
    p.add_argument("--dry-run", action="store_true", help="check the state, the model and "
                   "the controller's time, and exit without moving")
    p.add_argument("--out", type=Path, help="output folder (default: runs/<scenario>-robot)")
    p.add_argument("--realtime", action="store_true", help="franka: insist on a real-time "
                   "kernel (libfranka's kEnforce; for a real robot)")
    p.add_argument("--deadline-ms", type=float, default=1.0, help="the longest computation "
                   "of a cycle [ms]; a longer one brakes and ends the motion (default 1)")
    p.add_argument("--cpu-latency-us", type=int, default=0, help="the CPU latency request "
                   "held while the motion runs (/dev/cpu_dma_latency, as cyclictest holds "
                   "it; default 0: every core stays awake between the robot's states)")
    p.add_argument("--no-cpu-latency", action="store_true", help="hold no CPU latency "
                   "request: idle cores may sleep between the robot's states")
    return p


def _backend(args: argparse.Namespace, setup: ScenarioSetup) -> RobotBackend:
    if args.backend == "lockstep":
        return lockstep_for(setup)
    if not args.robot_ip:
        raise CpbcError("--robot-ip: give the robot's address (or --backend lockstep)")
    from cpbc.hardware.franka import FrankaBackend  # pylibfranka only for a Franka

    return FrankaBackend(args.robot_ip, realtime=args.realtime)


def _report(run: HardwareRun, out: Path) -> None:
    s, motion = run.summary, run.motion
    x = s.extra
    if run.start_note:
        print(f"note: {run.start_note}")
    if run.latency is not None and not run.latency.held:
        print(f"note: no CPU latency request held, idle cores may sleep between states: "
              f"{run.latency.reason}")
    print(f"{run.controller}: {motion.ending} after {s.end_time:.3f} s; status {s.status}, "
          f"final error {s.final_error:.4g}")
    print(f"cycle computation: p50 {x['compute_us_p50']:.0f} µs, p99 "
          f"{x['compute_us_p99']:.0f} µs, p99.9 {x['compute_us_p999']:.0f} µs, max "
          f"{x['compute_us_max']:.0f} µs (CPU p50 {x['compute_cpu_us_p50']:.0f}, max "
          f"{x['compute_cpu_us_max']:.0f} µs); lost states {x['lost_states']:.0f}"
          + (f"; CPU latency request {run.latency.target_us} µs held"
             if run.latency is not None and run.latency.held else ""))
    print(f"robot's rules on the log: {run.rules.describe()}")
    print(f"results written to {out}/")


def _fault(run: HardwareRun) -> None:
    fault = run.motion.fault
    assert fault is not None
    where = "no state read"
    if fault.state is not None:
        q, dq = (np.array2string(v, precision=4, max_line_width=300)
                 for v in (fault.state.position, fault.state.velocity))
        where = f"last state q = {q}, q̇ = {dq}"
    print(f"error: the robot stopped the motion: {fault.name} ({fault.detail}); {where}",
          file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    backend: RobotBackend | None = None
    try:
        loaded, file = load_any(args.scenario)
        if isinstance(loaded, SystemScenario):
            raise CpbcError("scenario: a Part I system runs in simulation only; give an arm's "
                            "scenario")
        if not args.deadline_ms > 0:
            raise CpbcError(f"--deadline-ms: give a time > 0 [ms], got {args.deadline_ms}")
        latency_target(args.cpu_latency_us, "--cpu-latency-us")  # names the flag
        setup = on_robot(build(loaded, file), args.deadline_ms * 1e-3)
        entry = choose_controller(setup, args.controller)
        settings = MotionSettings(loaded.simulation.duration, args.deadline_ms * 1e-3,
                                  cpu_latency=None if args.no_cpu_latency
                                  else args.cpu_latency_us)
        backend = _backend(args, setup)
        if args.dry_run:
            from cpbc.hardware.dry_run import dry_run

            report = dry_run(setup, entry, backend, cpu_latency_us=settings.cpu_latency)
            for line in report.describe(backend.joint_names):
                print(line)
            print("dry run passed: nothing moved")
            return 0
        run = run_on_robot(setup, entry, backend, settings)
        out = args.out or Path("runs") / f"{loaded.name}-robot"
        write_files(out, setup, run)
    except RobotFault as fault:  # before a motion: the robot could not be reached
        print(f"error: {fault}", file=sys.stderr)
        return 1
    except CpbcError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted before the motion; nothing moved, nothing written", file=sys.stderr)
        return 130
    finally:
        if backend is not None:
            backend.close()
    if run.motion.fault is not None:
        _fault(run)
    _report(run, out)
    return EXIT[run.motion.ending]


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def cli() -> None:
    signal.signal(signal.SIGTERM, _interrupt)  # as Ctrl-C: brake, finish, write
    code = main()
    with contextlib.suppress(OSError):
        sys.stdout.flush()
    sys.exit(code)


if __name__ == "__main__":
    cli()
