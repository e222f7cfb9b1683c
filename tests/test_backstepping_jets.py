"""Taylor jets: each elementary function against its closed-form derivatives, a composite
against a polynomial fit of samples, and the bookkeeping of orders."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cpbc.backstepping import jets as J

X0, B = 0.37, 1.3  # x(t) = X0 + B t: the k-th derivative of g(x(t)) is g^{(k)}(X0)·B^k

CLOSED_FORMS = {
    "tanh": (J.tanh, lambda x: (math.tanh(x), 1 - math.tanh(x) ** 2,
                                -2 * math.tanh(x) * (1 - math.tanh(x) ** 2),
                                -2 * (1 - math.tanh(x) ** 2) * (1 - 3 * math.tanh(x) ** 2))),
    "arctan": (J.arctan, lambda x: (math.atan(x), 1 / (1 + x * x), -2 * x / (1 + x * x) ** 2,
                                    (6 * x * x - 2) / (1 + x * x) ** 3)),
    "exp": (J.exp, lambda x: (math.exp(x),) * 4),
    "log": (J.log, lambda x: (math.log(x), 1 / x, -1 / x**2, 2 / x**3)),
    "sin": (J.sin, lambda x: (math.sin(x), math.cos(x), -math.sin(x), -math.cos(x))),
    "cos": (J.cos, lambda x: (math.cos(x), -math.sin(x), -math.cos(x), math.sin(x))),
    "sqrt": (J.sqrt, lambda x: (x**0.5, 0.5 * x**-0.5, -0.25 * x**-1.5, 0.375 * x**-2.5)),
    "reciprocal": (lambda v: 1.0 / v, lambda x: (1 / x, -1 / x**2, 2 / x**3, -6 / x**4)),
    "cube": (lambda v: v**3, lambda x: (x**3, 3 * x * x, 6 * x, 6.0)),
}


@pytest.mark.parametrize("name", sorted(CLOSED_FORMS))
def test_elementary_functions_against_closed_forms(name: str) -> None:
    fun, derivs = CLOSED_FORMS[name]
    jet = fun(J.Jet([X0, B, 0.0, 0.0]))
    for k, d in enumerate(derivs(X0)):
        assert jet.derivative(k) == pytest.approx(d * B**k, rel=1e-13, abs=1e-14)


def test_composite_against_a_polynomial_fit() -> None:
    """g(x(t)) for a quartic x(t) and g mixing every operation, against samples of g(x(t))."""
    c = [0.3, 0.7, -0.2, 0.1, 0.05]

    def g(v):
        return v * J.tanh(v) / (1.0 + v * v) - 3.0 / v + J.exp(J.sin(v)) * J.arctan(2.0 * v)

    jet = g(J.Jet(c))
    ts = np.linspace(-0.02, 0.02, 9)
    samples = [g(sum(ci * t**i for i, ci in enumerate(c))) for t in ts]
    fit = np.polyfit(ts, samples, 8)[::-1]
    for k in range(5):
        assert jet.c[k] == pytest.approx(fit[k], rel=1e-5, abs=1e-6)


def test_orders_and_constants() -> None:
    a = J.Jet([1.0, 2.0, 3.0])
    b = J.Jet([1.0, 1.0])
    assert (a * b).order == 1  # the unknown higher coefficients of b are not invented
    assert (a + 2.0).c == (3.0, 2.0, 3.0)
    assert (2.0 - a).c == (1.0, -2.0, -3.0)
    assert a.dot().c == (2.0, 6.0)
    assert J.as_jet(5.0, 2).c == (5.0, 0.0, 0.0)
    assert J.coefficient(5.0, 0) == 5.0 and J.coefficient(5.0, 1) == 0.0
    with pytest.raises(ValueError):
        J.Jet([1.0]).dot()
    arr = J.tanh(J.Jet([np.array([0.1, 0.2]), np.array([1.0, 1.0])]))
    assert arr.c[1] == pytest.approx(1 - np.tanh([0.1, 0.2]) ** 2)
