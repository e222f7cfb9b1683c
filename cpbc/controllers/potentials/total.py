"""A sum of potentials U = Σ U_k, ∂U/∂x = Σ ∂U_k/∂x: a task potential is a sum of frame
springs and a posture spring."""

from __future__ import annotations

from dataclasses import dataclass, field

from cpbc.arrays import Array
from cpbc.constraints.packing import Packed
from cpbc.controllers.potentials.potential import GradientBound, Placed, Potential
from cpbc.errors import CpbcError


@dataclass(frozen=True)
class PotentialSum:
    """U = Σ U_k. It is anchored when one part is (a posture spring), and its gradient is
    bounded by the sum of the parts' bounds when every part has one.

    Attributes:
        parts: the potentials, at least one.
    """

    parts: tuple[Potential, ...]
    frames: tuple[int, ...] = field(init=False)  # every part's, once (read each step)

    def __post_init__(self) -> None:
        if not self.parts:
            raise CpbcError("a sum of potentials needs at least one part")
        object.__setattr__(self, "frames",
                           tuple(dict.fromkeys(f for p in self.parts for f in p.frames)))

    @property
    def anchored(self) -> bool:
        return any(p.anchored for p in self.parts)

    @property
    def gradient_bound(self) -> GradientBound | None:
        bounds = [p.gradient_bound for p in self.parts]
        total = GradientBound(0.0, 0.0)
        for b in bounds:
            if b is None:
                return None
            total = total + b
        return total

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        value, grad = self.parts[0].evaluate(at)
        grad = grad.copy()
        for part in self.parts[1:]:
            u, g = part.evaluate(at)
            value += u
            grad += g
        return value, grad

    def packed(self) -> tuple[Packed, ...] | None:
        """Every part's terms for a law's kernel (added in order, as ``evaluate`` adds
        them), unless a part does not pack or a subclass overrides ``evaluate``."""
        if type(self).evaluate is not PotentialSum.evaluate:
            return None
        terms: list[Packed] = []
        for part in self.parts:
            packed = getattr(part, "packed", None)
            found = None if packed is None else packed()
            if found is None:
                return None
            terms.extend(found)
        return tuple(terms)


def total(*parts: Potential) -> PotentialSum:
    """U = Σ parts."""
    return PotentialSum(tuple(parts))
