"""The shaping functions s of V = L / s(ΦΨ) (Theorem 6.9 and the Remarks after Corollary
6.11), as the laws read them: r(x) = x s'(x)/s(x) and log s(x), both from log x (the
products Φ, Ψ are never formed). cpbc.controllers.shaping's classes call this."""

from __future__ import annotations

import math

from cpbc.kernels import kernel

IDENTITY, POWER, TANH = 0, 1, 2


@kernel("UniTuple(float64, 2)(int64, float64, float64)", inline=True)
def shaping_terms(kind: int, parameter: float, log_x: float) -> tuple[float, float]:
    """r(x) and log s(x) at x = exp(log_x) for

    - ``IDENTITY`` s(x) = x (Theorem 6.9): r = 1;
    - ``POWER`` s(x) = x^α (eq. 6.70), α = ``parameter``: r = α;
    - ``TANH`` s(x) = tanh(σx), σ = ``parameter``: r = 2σx / sinh(2σx), which tends to 1 at
      the boundary and to 0 far from it."""
    if kind == IDENTITY:
        return 1.0, log_x
    if kind == POWER:
        return parameter, parameter * log_x
    x = math.exp(min(log_x, 700.0))
    y = 2.0 * parameter * x
    if y < 1e-8:
        ratio = 1.0
    elif y > 700.0:
        ratio = 0.0
    else:
        ratio = y / math.sinh(y)
    y = parameter * x
    if y < 1e-8:
        log_s = math.log(parameter) + log_x
    else:
        log_s = math.log(math.tanh(y)) if y < 20.0 else 0.0
    return ratio, log_s
