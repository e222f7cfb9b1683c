"""The registry of the set kernel's kinds (cpbc.kernels.barrier_set): every registered
constraint kind packs its tables (its ``pack_*``), and the set kernel, reading them back
through the kind's row reader, gives what the constraint's general path gives — its own
``barrier_terms`` in Python, and the numpy formulas of the base classes (φ, ∇φ; ψ, Q, ∂ψ/∂x)
where the law's barrier is φ itself."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_registry import BASE, _built

from cpbc.constraints import ConstraintSet
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.kernels import barrier_set, law_terms
from cpbc.scenario.schema.kinds import KINDS


def _general(c: Any) -> Any:
    """``c`` in a subclass whose ``barrier_terms`` only calls its class's: it packs nothing,
    so the set asks its Python method."""
    cls = type(c)

    def barrier_terms(self: Any, *args: Any, **kwargs: Any) -> Any:
        return cls.barrier_terms(self, *args, **kwargs)

    general = type(f"General{cls.__name__}", (cls,), {"barrier_terms": barrier_terms})
    out = cls.__new__(general)
    out.__dict__.update(c.__dict__)
    return out


def _set(n: int, c: Any) -> ConstraintSet:
    if isinstance(c, VelocityConstraint):
        return ConstraintSet(n, (), [c])
    return ConstraintSet(n, [c])


def _numpy_terms(c: Any, state: Any) -> tuple[Any, Any, Any]:
    """The base classes' formulas: φ, Σ ∇φ/φ (configuration); ψ, Σ ∂ψ/∂x/ψ, Π (velocity)."""
    if isinstance(c, VelocityConstraint):
        psi, pi, b = VelocityConstraint.barrier_terms(c, state)
        return psi, b, pi
    phi, b, _ = ConfigurationConstraint.barrier_terms(c, state)
    return phi, b, None


@pytest.mark.parametrize("type_name", KINDS.constraint_types)
def test_every_kind_packs_and_its_kernel_equals_its_general_path(type_name: str,
                                                                 tmp_path: Path) -> None:
    kind = KINDS.constraint(type_name)
    data = copy.deepcopy(BASE)
    data["constraints"] = [{"type": type_name, "name": "c", **kind.examples[type_name]}]
    setup = _built(tmp_path, data)
    (c,) = (*setup.monitor.configuration, *setup.monitor.velocity)
    model, n = setup.model, setup.model.n
    packed = c.packed()
    assert packed is not None and packed.kind in barrier_set.KINDS, type_name
    compiled, python = _set(n, c), _set(n, _general(c))
    assert compiled.python_terms == () and len(python.python_terms) == 1
    localised = getattr(type(c), "barrier_ratio", None) not in (
        None, ConfigurationConstraint.barrier_ratio)
    rng = np.random.default_rng(len(type_name))
    x0, checked = setup.cases[0].position, 0
    for _ in range(60):
        x, dx = x0 + rng.uniform(-0.3, 0.3, n), rng.uniform(-0.5, 0.5, n)
        state = compiled.state(model, x, dx)
        if not np.all(compiled.margins(x, dx, state) > 0):
            continue
        fast = compiled.barrier(state, margins=True)
        slow = python.barrier(state, margins=True)
        assert fast.log_phi == pytest.approx(slow.log_phi, rel=1e-12, abs=1e-12)
        assert fast.log_psi == pytest.approx(slow.log_psi, rel=1e-12, abs=1e-12)
        for a, b in ((fast.gradient, slow.gradient), (fast.weight, slow.weight),
                     (fast.margins, slow.margins)):
            if a is None or b is None:
                assert a is None or not np.any(a)
                assert b is None or not np.any(b)
                continue
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
        if not localised:  # the law's barrier is φ itself: the numpy formulas agree
            values, b, pi = _numpy_terms(c, state)
            total = (fast.log_psi if isinstance(c, VelocityConstraint) else fast.log_phi)
            assert total == pytest.approx(float(np.sum(np.log(values))), rel=1e-10)
            gradient = np.zeros(n) if fast.gradient is None else fast.gradient
            np.testing.assert_allclose(gradient, np.zeros(n) if b is None else b,
                                       rtol=1e-9, atol=1e-9)
            if pi is not None:
                np.testing.assert_allclose(fast.weight, pi, rtol=1e-10, atol=1e-12)
        checked += 1
    assert checked >= 10, type_name


def test_each_registry_gives_each_kind_its_own_code() -> None:
    """A code is a kind's only name inside a kernel: two kinds never share one."""
    assert len(set(barrier_set.KINDS)) == len(barrier_set.KINDS)
    assert set(barrier_set.VELOCITY_KINDS) <= set(barrier_set.KINDS)
    assert len(set(law_terms.KINDS)) == len(law_terms.KINDS)
    assert set(law_terms.FRAME_KINDS) <= set(law_terms.KINDS)
