"""``python -m cpbc.kernels [--warm] [--check]``: compile every kernel into numba's on-disk
cache (``--warm``, run by scripts/install.sh so a fresh process compiles nothing) and fail
unless every kernel is compiled in nopython mode (``--check``)."""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Iterator, Sequence

from numba.core.registry import CPUDispatcher

MODULES = ("cpbc.kernels.small_solves", "cpbc.kernels.energy", "cpbc.kernels.barriers",
           "cpbc.kernels.laws", "cpbc.kernels.barrier_set", "cpbc.kernels.coordinate_maps",
           "cpbc.kernels.task", "cpbc.kernels.clearance", "cpbc.kernels.sampled_guard",
           "cpbc.kernels.barrier_shaping", "cpbc.kernels.law_terms", "cpbc.kernels.views")


def kernels() -> Iterator[tuple[str, CPUDispatcher]]:
    """Every kernel of the package, by qualified name (importing compiles or loads it)."""
    for name in MODULES:
        module = importlib.import_module(name)
        for attr, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.__module__ == name:
                yield f"{name}.{attr}", value


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
    every = list(kernels())
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
