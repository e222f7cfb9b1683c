"""``python -m cpbc.kernels [--warm] [--check]``: compile every kernel into numba's on-disk
cache (``--warm``, run by scripts/install.sh so a fresh process compiles nothing) and fail
unless every kernel is compiled in nopython mode (``--check``)."""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Callable, Iterator, Sequence

from numba.core.registry import CPUDispatcher

# each after the kernel modules it imports, so that each step of --warm's progress compiles
# its own kernels (importing a module compiles those it imports first)
MODULES = tuple(f"cpbc.kernels.{m}" for m in (
    "views", "small_solves", "friction_error", "margin_losses", "bounded_lsq", "energy",
    "plan_tables", "task",
    "torque_box", "clearance", "clearance_motion", "coordinate_maps", "state_terms",
    "barrier_shaping", "barriers", "python_rows", "barrier_set", "law_terms", "laws",
    "braking_path", "stopping_test", "shares", "sampled_guard", "joint_placements",
    "frozen_slack", "slide"))


def module_kernels(name: str) -> list[tuple[str, CPUDispatcher]]:
    """The kernels of one module, by qualified name (importing it compiles or loads them)."""
    module = importlib.import_module(name)
    return [(f"{name}.{attr}", value) for attr, value in vars(module).items()
            if isinstance(value, CPUDispatcher) and value.__module__ == name]


def kernels() -> Iterator[tuple[str, CPUDispatcher]]:
    """Every kernel of the package, by qualified name (importing compiles or loads it)."""
    for name in MODULES:
        yield from module_kernels(name)


def warm(say: Callable[[str], None]) -> list[tuple[str, CPUDispatcher]]:
    """Every kernel, compiled (or loaded from numba's cache) module by module, saying after
    each module which it was, how many of how many, and how long it took: a cold compile
    takes minutes, and a silent one looks hung."""
    every = []
    for i, name in enumerate(MODULES, 1):
        start = time.perf_counter()
        found = module_kernels(name)
        every += found
        say(f"[{i}/{len(MODULES)}] {name}: {len(found)} kernels, "
            f"{time.perf_counter() - start:.1f} s")
    return every


def problems() -> list[str]:
    """Kernels not compiled, or compiled other than in nopython mode (empty when all are);
    none found at all is one (NUMBA_DISABLE_JIT runs them as Python)."""
    every = list(kernels())
    if not every:
        return ["no compiled kernels (NUMBA_DISABLE_JIT is set?)"]
    found = []
    for name, dispatcher in every:
        if hasattr(dispatcher, "inner_signature"):
            continue  # compiled only into its callers (cpbc.kernels.inner)
        if not dispatcher.targetoptions.get("nopython", False):
            found.append(f"{name}: not nopython")
        if not dispatcher.signatures:
            found.append(f"{name}: not compiled")
        for sig in dispatcher.signatures:
            if getattr(dispatcher.overloads[sig], "objectmode", True):  # pragma: no cover
                found.append(f"{name}{sig}: object mode")
    return found


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cpbc.kernels", description=__doc__)
    parser.add_argument("--warm", action="store_true", help="compile into the on-disk cache")
    parser.add_argument("--check", action="store_true", help="exit 1 unless all are nopython")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    every = warm(lambda line: print(line, flush=True)) if args.warm else list(kernels())
    if not every:
        print("no compiled kernels (NUMBA_DISABLE_JIT is set?)", file=sys.stderr)
        return 1 if args.check else 0
    inner = sum(hasattr(d, "inner_signature") for _, d in every)
    alone = len(every) - inner
    if args.warm:
        print(f"{alone} kernels compiled or loaded from numba's cache in "
              f"{time.perf_counter() - start:.2f} s ({inner} more compiled into their "
              "callers only)")
    if args.check:
        found = problems()
        for line in found:
            print(line, file=sys.stderr)
        if found:
            return 1
        print(f"{alone} kernels, all nopython ({inner} more inside them)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
