"""The worked example of docs/new-constraint.md (docs/examples/half_space.py), run as a user
outside the package would: its kind reaches a scenario, its kernel's terms equal the numpy
formulas of the base class, and a law that enforces it keeps its one kernel call for every
other term (only the half-space's terms run in Python, and the law says so once)."""

from __future__ import annotations

import copy
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from test_registry import BASE, _built

from cpbc.constraints.constraint_types import ConfigurationConstraint
from cpbc.controllers.packed_law import python_path_notes
from cpbc.kernels.barrier_set import LINEAR, RATE
from cpbc.kernels.python_terms import PYTHON_CONFIGURATION
from cpbc.scenario.schema.kinds import KINDS

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "half_space.py"


@pytest.fixture(scope="module")
def example() -> ModuleType:
    spec = importlib.util.spec_from_file_location("half_space_example", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # where pydantic resolves the spec's annotations
    spec.loader.exec_module(module)
    return module


def _general(law):  # type: ignore[no-untyped-def]
    """The law taking its general path (a subclass whose ``_law`` only calls the base's)."""

    class General(type(law)):  # type: ignore[misc]
        def _law(self, *args, **kwargs):  # type: ignore[no-untyped-def]
            return super()._law(*args, **kwargs)

    copy_ = type(law).__new__(type(law))
    copy_.__dict__.update(law.__dict__)
    copy_.__class__ = General
    return copy_


def test_the_half_space_example_runs_beside_the_compiled_terms(example: ModuleType,
                                                               tmp_path: Path) -> None:
    kinds = KINDS.with_modules(example)
    data = copy.deepcopy(BASE)
    data["constraints"] = [*data["constraints"][:2],
                           {"type": "half_space", "name": "ceiling", "frame": "end_point",
                            "normal": [0, 1, 0], "depth": 1.9}]
    data["controllers"] = [{"type": "cpbc", "kp": 4, "kd": 2, "name": "law"}]
    setup = _built(tmp_path, data, kinds)
    entry = setup.controllers[0].controller
    law = getattr(entry, "law", entry)
    (note,) = python_path_notes(entry)
    assert "'ceiling' (HalfSpace) has no kernel" in note
    tables = law.constraints.packed_tables
    assert law.packed_law().terms is not None and tables is not None
    assert tables.plan[:, 0].tolist() == [LINEAR, PYTHON_CONFIGURATION, RATE]
    ceiling = next(c for c in law.constraints.configuration if c.names == ("ceiling",))
    general = _general(law)
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(30):
        x, dx = rng.uniform(-1.0, 1.5, 2), rng.uniform(-0.5, 0.5, 2)
        state = law.state(x, dx)
        if not np.all(law.constraints.margins(x, dx, state) > 0):
            continue
        phi, b, _ = ceiling.barrier_terms(state)  # the kernel
        ref_phi, ref_b, _ = ConfigurationConstraint.barrier_terms(ceiling, state)  # numpy
        np.testing.assert_allclose(phi, ref_phi, rtol=1e-12)
        np.testing.assert_allclose(b, ref_b, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(law.torque(x, dx), general.torque(x, dx), rtol=1e-12,
                                   atol=1e-12)
        checked += 1
    assert checked >= 10
