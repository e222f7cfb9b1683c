"""``python -m cpbc.bench [--robot NAME] [--json] [--markdown PATH] [--check]``: what one
control step costs.

Prints, for each controller, the median wall time of one ``torque`` call (µs) and the
closed-loop rate (control steps per second, MuJoCo physics included). Medians over repeated
blocks; nothing here is asserted inside the unit tests. ``--json`` prints the document (with
each figure's range over the blocks and how the run was made), ``--markdown`` writes the same
document as a Markdown fragment (``cpbc.bench_report``; the docs' tables are these).
``--check`` exits 1 when CPBC costs more than 3× PD + gravity measured in the same run (a
ratio, so it holds across machines), or when a compiled kernel is not compiled in nopython
mode (it fell back to object mode, or ``NUMBA_DISABLE_JIT`` left it uncompiled;
``python -m cpbc.kernels --check``).
"""

from __future__ import annotations

import argparse
import gc
import json
import shlex
import statistics
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cpbc.arrays import Array
from cpbc.bench_report import markdown as bench_markdown
from cpbc.bench_tail import TAILS, bench_tails
from cpbc.constraints import (
    ConstraintSet,
    KineticEnergyLimit,
    LinearLimit,
    PointOutsideSphere,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.controllers import (
    BPBC,
    CPBC,
    PD,
    BPBCKineticEnergy,
    Controller,
    CPBCKineticEnergy,
    PDGravity,
    Power,
    RecentredBarrier,
)
from cpbc.controllers.hold import plant_step
from cpbc.controllers.safeguard import SafeguardSettings, guarded
from cpbc.errors import CpbcError
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.input_bounds import InputBounds
from cpbc.provenance import provenance
from cpbc.resources import models_dir
from cpbc.simulation import LoopSettings, MujocoPlant, PlantSettings, run_mujoco


@dataclass(frozen=True)
class BenchSetup:
    """Controllers of one robot, the states to time them on, and a plant for the loop."""

    robot: str
    controllers: dict[str, Controller]
    states: list[tuple[Array, Array]]
    make_plant: Callable[[], MujocoPlant]
    coordinates: LinearCoordinates
    start: tuple[Array, Array]
    notes: str
    plant: PlantSettings  # what make_plant steps with (the safeguard reads its step)
    torque_limit: Array | None = None  # the actuators' box for the peer comparison (--peers)

    def safeguard(self) -> SafeguardSettings:
        """The safeguard's settings as the scenario builder sets them for this plant (its
        step where the integrator is one-stage: cpbc.controllers.hold.plant_step)."""
        return SafeguardSettings(plant_step=plant_step(self.plant.integrator,
                                                       self.plant.timestep))


def planar_2link() -> BenchSetup:
    """The thesis's arm in absolute link angles, with the thesis's constraints (Section 6.4)."""
    path = models_dir() / "planar_2link.xml"
    coords = LinearCoordinates.absolute_link_angles(2)
    rk4 = PlantSettings(0.001, "RK4")
    model = RobotModel.from_mjcf(path, coordinates=coords)
    names = ["theta1", "theta2"]
    rates = joint_rate_limit([0.3, 0.2], names)
    obstacle = PointOutsideSphere(model, "end_point", [0, 2, 0], 0.5)
    relative = LinearLimit([[-1, 1]], [-17 * np.pi / 18], [17 * np.pi / 18], ["relative"])
    energy = KineticEnergyLimit(model, 0.5)
    limits = joint_position_limit([-0.5, -0.5], [3.5, 3.5], names)
    target = np.array([np.pi, 2 * np.pi / 3])
    kp, kd = 4.0, 20.0
    controllers: dict[str, Controller] = {
        "pd": PD(model, target, kp, kd),
        "pd_gravity": PDGravity(model, target, kp, kd),
        "cpbc": CPBC(model, target, ConstraintSet(2, [obstacle, relative], [rates]), kp, kd,
                     Power(0.2)),
        "cpbc_ke": CPBCKineticEnergy(
            model, target, ConstraintSet(2, [obstacle, relative], [energy]), kp, kd, Power(0.2)
        ),
        "recentred": RecentredBarrier(model, target, ConstraintSet(2, [limits], [rates]), kp, kd),
        "bpbc": BPBC(model, target, ConstraintSet(2, [], [rates]), [2, 10], [4, 20], 1, 1,
                     Power(0.2)),
        "bpbc_ke": BPBCKineticEnergy(model, target, ConstraintSet(2, [], [energy]), [2, 10],
                                     [4, 20], 1, 1, Power(0.2)),
    }
    rng = np.random.default_rng(0)
    states = [(rng.uniform(-0.4, 0.4, 2), rng.uniform(-0.1, 0.1, 2)) for _ in range(64)]
    return BenchSetup(
        "planar_2link", controllers, states,
        lambda: MujocoPlant.from_file(path, rk4),
        coords, (np.zeros(2), np.zeros(2)),
        "thesis constraints (obstacle, relative angle, 2 rate limits); RK4, 1 kHz control",
        rk4,
    )


def panda() -> BenchSetup:
    """The Panda with URDF limits and three obstacles (cpbc.bench_arms; imported lazily)."""
    from cpbc.bench_arms import panda as setup

    return setup()


ROBOTS: dict[str, Callable[[], BenchSetup]] = {"planar_2link": planar_2link, "panda": panda}
# the bare CPBC torque call's cost over PD + g that the project aims at, per arm; --check
# fails above CHECK_RATIO (a regression gate, not the target)
COST_TARGETS = {"planar_2link": 1.5, "panda": 2.5}
CHECK_RATIO = 3.0


@contextmanager
def collector_paused() -> Iterator[None]:
    """Python's garbage collector off inside a timed block, as ``timeit`` does: a collection
    that happens to fall in one block (≈ 8 ms, seen on the guarded Panda) is the
    interpreter's cost, not the law's, and made the guarded figure swing 3× between runs."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if collecting:
            gc.enable()


def time_blocks(
    ctrl: Controller, states: Sequence[tuple[Array, Array]], repeats: int
) -> list[float]:
    """The mean cost of one torque call in each of ``repeats`` blocks over ``states`` [µs],
    the collector paused in each (:func:`collector_paused`); a rare path the law takes on
    some state (a rescue search) stays in the block's mean."""
    blocks = []
    for _ in range(repeats):
        with collector_paused():
            start = time.perf_counter()
            for x, dx in states:
                ctrl.torque(x, dx)
            blocks.append((time.perf_counter() - start) / len(states) * 1e6)
    return blocks


def time_torque(ctrl: Controller, states: Sequence[tuple[Array, Array]], repeats: int) -> float:
    """Median over ``repeats`` blocks of the mean cost of one torque call [µs]."""
    return statistics.median(time_blocks(ctrl, states, repeats))


def time_loop(
    setup: BenchSetup, ctrl: Controller, seconds: float, repeats: int, safeguard: bool = True
) -> float:
    """Median closed-loop control steps per second (controller + MuJoCo + logging), with the
    default sampled-data safeguard around a constrained law or (``safeguard=False``) the bare
    law."""
    plant = setup.make_plant()
    settings = LoopSettings(seconds, InputBounds(0.001))
    law = guarded(ctrl, settings.bounds, setup.safeguard() if safeguard else None)
    rates = []
    for _ in range(repeats):
        traj = run_mujoco(plant, law, setup.coordinates, *setup.start, settings)
        rates.append(traj.steps_per_second)
    return statistics.median(rates)


# the bare law timed in the peers' blocks, beside its guarded self (peer_times)
BESIDE = "cpbc_bare"


def peer_times(setup: BenchSetup, repeats: int) -> dict[str, list[float]]:
    """--peers: the CPBC law as the loop runs it (with its safeguard) and the CBF-QP filter
    (cpbc.peers, DAQP) on the same constraint objects, gains, torque box and states, and the
    bare law beside them (``BESIDE``: the guarded step's ratio to it is taken in the same
    blocks, where the QP's calls have left the caches as cold for both): the µs of each
    timed block."""
    from cpbc.peers import CBFQP

    law = setup.controllers["cpbc"]
    period = 0.001
    contenders: dict[str, Controller] = {
        "cpbc_guarded": guarded(law, InputBounds(period, setup.torque_limit),
                                setup.safeguard()),
        "cbf_qp": CBFQP(law.model, law.target, law.constraints, law.kp, law.kd,  # type: ignore[attr-defined]
                        gain=20.0, bounds=InputBounds(period, setup.torque_limit)),
        BESIDE: law,
    }
    for ctrl in contenders.values():
        time_torque(ctrl, setup.states[:8], 1)
    return time_interleaved(contenders, setup.states, repeats)


def time_governor(repeats: int, steps: int = 5000) -> float:
    """The reference governor's step (cpbc.reference.governor, target ≤ 2 µs) [µs]: a path
    with one blocked stretch far ahead, V̄ below the budget, median over ``repeats`` blocks."""
    from cpbc.reference.governor import GovernorSettings, PathGovernor

    gov = PathGovernor(GovernorSettings(), 1e9, 0.001, ((5e8, 6e8, "x"),))
    times = []
    for r in range(repeats):
        with collector_paused():
            start = time.perf_counter()
            for k in range(steps):
                gov.advance((r * steps + k) * 0.001, 0.1, 0.25)
            times.append((time.perf_counter() - start) / steps)
    return statistics.median(times) * 1e6


def taskspace_pair(states: int = 64, seed: int = 0
                   ) -> tuple[dict[str, Controller], list[tuple[Array, Array]]]:
    """``panda_goal_pose``'s task-space CPBC as the scenario builds it, and a joint CPBC with
    its constraint set, joint gains and shaping toward its posture (the IK posture), with
    states admissible for that set spread from the case's start to the posture."""
    from cpbc.scenario import build, load_scenario

    setup = build(*load_scenario("panda_goal_pose"))
    task = next(e.controller for e in setup.controllers if e.controller.type_name == "cpbc")
    assert isinstance(task, CPBC)
    joint = CPBC(task.model, setup.target, task.constraints, task.kp, task.kd, task.shaping)
    rng = np.random.default_rng(seed)
    start, posture = setup.cases[0].position, setup.target
    picked: list[tuple[Array, Array]] = []
    while len(picked) < states:
        s = rng.uniform()
        x = (1 - s) * start + s * posture + rng.normal(scale=0.05, size=start.shape[0])
        dx = np.asarray(rng.normal(scale=0.1, size=start.shape[0]))
        if np.all(task.constraints.margins(x, dx) > 0):
            picked.append((x, dx))
    return {"taskspace_cpbc": task, "joint_cpbc": joint}, picked


def time_interleaved(controllers: dict[str, Controller], states: Sequence[tuple[Array, Array]],
                     repeats: int, chunk: int = 8) -> dict[str, list[float]]:
    """Every controller's mean cost of one torque call [µs] in each of ``repeats`` rounds;
    within a round the controllers take turns on each ``chunk`` of states, so that a change
    of the machine's load hits them alike; the collector paused in each round."""
    for ctrl in controllers.values():
        time_torque(ctrl, states[:chunk], 1)
    blocks: dict[str, list[float]] = {k: [] for k in controllers}
    for _ in range(repeats):
        spent = dict.fromkeys(controllers, 0.0)
        with collector_paused():
            for at in range(0, len(states), chunk):
                part = states[at:at + chunk]
                for k, ctrl in controllers.items():
                    start = time.perf_counter()
                    for x, dx in part:
                        ctrl.torque(x, dx)
                    spent[k] += time.perf_counter() - start
        for k in controllers:
            blocks[k].append(spent[k] / len(states) * 1e6)
    return blocks


def taskspace_times(repeats: int) -> dict[str, float]:
    """Bare task-space CPBC against bare joint CPBC on ``panda_goal_pose``'s arm and
    constraints (``taskspace_pair``; target ≤ 1.2): medians [µs], the median of the
    per-round ratios and their range."""
    controllers, states = taskspace_pair()
    blocks = time_interleaved(controllers, states, repeats)
    ratios = [t / j for t, j in zip(blocks["taskspace_cpbc"], blocks["joint_cpbc"],
                                    strict=True)]
    return {"taskspace_cpbc_us": statistics.median(blocks["taskspace_cpbc"]),
            "joint_cpbc_us": statistics.median(blocks["joint_cpbc"]),
            "ratio": statistics.median(ratios), "ratio_min": min(ratios),
            "ratio_max": max(ratios)}


def _print_taskspace(ts: dict[str, float]) -> None:
    print(f"panda_goal_pose, bare laws, same states: task-space CPBC {ts['taskspace_cpbc_us']:.1f}"
          f" µs, joint CPBC {ts['joint_cpbc_us']:.1f} µs, ratio {ts['ratio']:.2f} (range "
          f"{ts['ratio_min']:.2f}–{ts['ratio_max']:.2f}; target ≤ 1.2)")


def _print_stream(st: dict[str, float]) -> None:
    print(f"streamed target (cpbc.bench_stream): {st['streamed_us']:.1f} µs against "
          f"{st['fixed_us']:.1f} µs with the fixed goal, ratio {st['ratio']:.3f} (range "
          f"{st['ratio_min']:.3f}–{st['ratio_max']:.3f}; target ≤ 1.1)")
    for key in ("streamed", "fixed"):
        for clock, what in (("", "wall"), ("cpu_", "CPU")):
            cells = ", ".join(f"{q} {st[f'{key}_{clock}{q}_us']:.0f}"
                              for q in ("p50", "p99", "p999", "max"))
            print(f"  {key} call in closed loop, {what} time [µs]: {cells}; p99.9/p50 "
                  f"{st[f'{key}_{clock}p999_over_p50']:.2f}"
                  + (" (target ≤ 3)" if key == "streamed" and not clock else ""))


def _print_tail(tail: dict[str, object], how: str, target: bool) -> None:
    cells = ", ".join(f"{k} {tail[k]:.0f}" for k in ("p50", "p99", "p999", "p9999", "max"))
    cpu = tail["cpu"]
    assert isinstance(cpu, dict)
    cpu_cells = ", ".join(f"{k} {cpu[k]:.0f}" for k in ("p50", "p999", "p9999", "max"))
    rate = "" if tail["rate_limit"] is None else f", {tail['rate_limit']:g} N·m/s"
    label = f" ({how})" if tail["time_budget_us"] is None else \
        f" ({how}: {tail['test_budget']} tests, {tail['rescue_budget']} model periods, " \
        f"{tail['time_budget_us']:.0f} µs{rate})"
    print(f"guarded step in closed loop{label} [µs]: {cells}; CPU {cpu_cells}; over "
          f"{tail['steps']:,} steps ({tail['acting_steps']:,} acting, {tail['rescues']} "
          f"rescues, {tail['out_of_tests']} out of tests); max / p50 "
          f"{tail['max_over_p50']:.1f}" + (" (target ≤ 5; p99.99 ≤ 250)" if target else ""))
    own = tail.get("own")
    if isinstance(own, dict):
        print(f"  each step's least of {tail['repeats']} repeats [µs]: "
              + ", ".join(f"{k} {own[k]:.0f}" for k in ("p50", "p99", "p999", "p9999", "max"))
              + f" over {tail['own_steps']:,} steps made alike; max / p50 "
              f"{tail['own_max_over_p50']:.1f}")
    law = tail["bare_law"]
    assert isinstance(law, dict)
    print("  its law alone at the same states [µs]: "
          + ", ".join(f"{k} {law[k]:.1f}" for k in ("p50", "p99", "p999", "p9999", "max"))
          + f"; max / p50 {tail['bare_law_max_over_p50']:.1f}")


def guarded_over_bare(peers: dict[str, list[float]]) -> dict[str, float]:
    """The guarded step against its bare law in the same blocks (``peer_times``): medians
    [µs], the median of the per-block ratios and their range (target ≤ 5)."""
    ratios = [g / b for g, b in zip(peers["cpbc_guarded"], peers[BESIDE], strict=True)]
    return {"guarded_us": statistics.median(peers["cpbc_guarded"]),
            "bare_us": statistics.median(peers[BESIDE]), "ratio": statistics.median(ratios),
            "ratio_min": min(ratios), "ratio_max": max(ratios)}


def _print_peers(torque_us: dict[str, float], beside: dict[str, float]) -> None:
    qp = torque_us["cbf_qp"]
    print(f"peers, same states: cbf_qp {qp:.1f} µs, cpbc guarded {torque_us['cpbc_guarded']:.1f}"
          f" µs, cpbc bare {beside['bare_us']:.1f} µs (in the same blocks)")
    print(f"cbf_qp / cpbc guarded: {qp / torque_us['cpbc_guarded']:.2f}x; "
          f"cbf_qp / cpbc bare: {qp / beside['bare_us']:.2f}x")
    print(f"cpbc guarded / cpbc bare, same blocks: {beside['ratio']:.2f}x (range "
          f"{beside['ratio_min']:.2f}–{beside['ratio_max']:.2f}; target ≤ 5)")


def made(argv: Sequence[str] | None, repeats: int, states: int) -> dict[str, object]:
    """How this run was made (cpbc.provenance), with what one figure is a median of."""
    args = sys.argv[1:] if argv is None else list(argv)
    return {**provenance(shlex.join(["python", "-m", "cpbc.bench", *args])),
            "blocks": repeats, "calls_per_block": states}


def _print_text(setup: BenchSetup, document: dict[str, object], torque_us: dict[str, float],
                loop: dict[str, float], bare: dict[str, float]) -> None:
    """The figures as text (without --json)."""
    ratio = float(document["cpbc_over_pd_gravity"])  # type: ignore[arg-type]
    governor = float(document["governor_us"])  # type: ignore[arg-type]
    taskspace = document.get("taskspace")
    print(f"robot: {setup.robot} ({setup.notes})")
    print(f"{'controller':<12} {'torque [µs]':>12} {'loop [steps/s]':>15} "
          f"{'bare law loop':>14}")
    for k in setup.controllers:
        extra = f"{bare[k]:>14,.0f}" if k in bare else f"{'':>14}"
        print(f"{k:<12} {torque_us[k]:>12.1f} {loop[k]:>15,.0f} {extra}")
    print("loop: with the default sampled-data safeguard around the constrained laws; "
          "bare law loop: without it")
    target = COST_TARGETS[setup.robot]
    print(f"cpbc / pd_gravity cost ratio: {ratio:.2f} (target ≤ {target}: "
          + ("met)" if ratio <= target else "not met)"))
    print(f"reference governor: {governor:.2f} µs a step (target ≤ 2)")
    if taskspace is not None:
        _print_taskspace(taskspace)  # type: ignore[arg-type]
    stream = document.get("stream")
    if stream is not None:
        _print_stream(stream)  # type: ignore[arg-type]
    beside = document.get("guarded_over_bare")
    if beside is not None:
        _print_peers(torque_us, beside)  # type: ignore[arg-type]
    for key, how in TAILS:
        tail = document.get(key)
        if tail is not None:
            _print_tail(tail, how, key == TAILS[0][0])  # type: ignore[arg-type]


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m cpbc.bench", description=__doc__)
    p.add_argument("--robot", choices=sorted(ROBOTS), default="planar_2link")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--repeats", type=int, default=15, help="timed blocks per figure")
    p.add_argument("--loop-seconds", type=float, default=2.0, help="simulated s per loop run")
    p.add_argument("--check", action="store_true",
                   help=f"exit 1 if CPBC costs more than {CHECK_RATIO:g}x PD + gravity, or a "
                   "kernel is not compiled in nopython mode")
    p.add_argument("--peers", action="store_true",
                   help="also time the guarded law and the cbf_qp peer (needs cpbc[peers])")
    p.add_argument("--tail-steps", type=int, default=100_000,
                   help="with --peers on the panda: guarded closed-loop steps to time for "
                   "the tail (guarded_tail_us; cpbc.bench_tail)")
    p.add_argument("--tail-repeats", type=int, default=1,
                   help="with --peers on the panda: make the tail's runs this many times and "
                   "report each step's least time over them too (own: the host's "
                   "interruptions taken out)")
    p.add_argument("--markdown", metavar="PATH",
                   help="also write the figures as a Markdown fragment (cpbc.bench_report)")
    args = p.parse_args(argv)
    if args.tail_repeats < 1:
        print(f"error: --tail-repeats {args.tail_repeats}: give 1 or more", file=sys.stderr)
        return 2
    if args.markdown and not Path(args.markdown).resolve().parent.is_dir():
        print(f"error: --markdown {args.markdown}: its folder does not exist", file=sys.stderr)
        return 2
    setup = ROBOTS[args.robot]()
    try:
        peers = peer_times(setup, args.repeats) if args.peers else {}
    except CpbcError as exc:  # the optional solver is missing
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for ctrl in setup.controllers.values():  # warm up caches and lazy imports
        time_torque(ctrl, setup.states[:8], 1)
    blocks_us = time_interleaved(setup.controllers, setup.states, args.repeats)
    torque_us = {k: statistics.median(v) for k, v in blocks_us.items()}
    blocks = max(3, args.repeats // 3)
    loop = {k: time_loop(setup, c, args.loop_seconds, blocks)
            for k, c in setup.controllers.items()}
    bare = {k: time_loop(setup, c, args.loop_seconds, blocks, safeguard=False)
            for k, c in setup.controllers.items() if not c.constraints.empty}
    ratio = torque_us["cpbc"] / torque_us["pd_gravity"]
    beside = guarded_over_bare(peers) if peers else None
    peers = {k: v for k, v in peers.items() if k != BESIDE}  # the table's cpbc is its own
    blocks_us.update(peers)
    torque_us.update({k: statistics.median(v) for k, v in peers.items()})
    governor = time_governor(args.repeats)
    document: dict[str, object] = {"robot": setup.robot, "torque_us": torque_us,
                "torque_us_range": {k: [min(v), max(v)] for k, v in blocks_us.items()},
                "closed_loop_steps_per_second": loop,
                "closed_loop_bare_law_steps_per_second": bare,
                "cpbc_over_pd_gravity": ratio, "governor_us": governor,
                "notes": setup.notes, "made": made(argv, args.repeats, len(setup.states))}
    if beside is not None:
        document["guarded_over_bare"] = beside
    if setup.robot == "panda":  # the task-space pair is panda_goal_pose's arm
        document["taskspace"] = taskspace_times(args.repeats)
        from cpbc.bench_stream import stream_times

        document["stream"] = stream_times(taskspace_pair()[1], args.repeats)
    tails = bench_tails(args.tail_steps, args.tail_repeats) if peers and setup.robot == "panda" \
        else {}  # the closed loop's worst steps, for a deadline
    document.update(tails)
    if args.markdown:
        Path(args.markdown).write_text(bench_markdown([document]), encoding="utf-8")
    if args.json:
        print(json.dumps(document))
    else:
        _print_text(setup, document, torque_us, loop, bare)
    if args.check:
        from cpbc.kernels.__main__ import problems

        found = problems()
        for line in found:
            print(f"kernel: {line}", file=sys.stderr)
        return 1 if ratio > CHECK_RATIO or found else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
