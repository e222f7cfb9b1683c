"""What a constraint or law kind declares, and :class:`Kinds`, the registry of them.

**Where each declaration lives** (so that every import points down the layers model →
constraints → controllers → simulation → results → scenario/CLI):

- The constraint class (``cpbc.constraints``) declares what the results layer needs: its
  margin type and unit and how φ becomes a margin (``margin_type``, ``margins``; see
  cpbc.constraints.margins). It knows nothing of scenarios.
- The law class (``cpbc.controllers``, ``cpbc.peers``) declares nothing for the registry.
- One module per scenario ``type:`` family in ``cpbc.scenario.schema.kinds`` declares the rest: its
  pydantic spec (the YAML entry, with the field descriptions the JSON schema and the
  scenario reference are generated from), its factory (spec → object, with errors that name
  the field), for a constraint the class it builds, for a law what the gain check needs
  (:class:`Slopes`) and which of its types take a goal. Its module-level ``KIND`` is that
  declaration. A kind module imports the layers below, the schema's shared pieces
  (``common``, ``constraint_specs``, ``controller_specs``) and ``cpbc.scenario.values`` —
  never the rest of the scenario layer, which imports it (the Scenario model aggregates the
  kinds' specs).

**The registry is a value, not a global that fills itself.** :class:`Kinds` is frozen and
built from an explicit tuple of those ``KIND`` declarations (``cpbc.scenario.schema.kinds.KINDS``);
the schema's discriminated unions, ``build``, the gain check and the generated docs all read
it. No module registers itself at import, so a test that wants one more kind builds its own
``Kinds`` from ``KINDS`` plus its entry and passes it along; the default stays as it was.
Every entry is checked when a ``Kinds`` is built: a spec whose ``type:`` is not a tuple of
literals, a type name given twice, a constraint class without a margin type the results
know, or a law without the gain check's declaration is refused there, loudly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any, Generic, TypeVar, Union, get_args

from pydantic import BaseModel, Field

from cpbc.arrays import Array
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.constraints.margins import TYPES
from cpbc.controllers.controller import Controller
from cpbc.scenario.schema.kinds.constraint_inputs import ConstraintInputs, SceneSphere
from cpbc.scenario.schema.kinds.law_inputs import LawInputs, Slopes

Constraint = ConfigurationConstraint | VelocityConstraint
S = TypeVar("S", bound=BaseModel)


class KindError(TypeError):
    """A kind declaration the registry cannot use (a programming error, not bad input)."""


def type_names(spec: type[BaseModel]) -> tuple[str, ...]:
    """The ``type:`` values a spec accepts: the arguments of its ``Literal``."""
    info = spec.model_fields.get("type")
    names = get_args(info.annotation) if info is not None else ()
    if not names or not all(isinstance(n, str) for n in names):
        raise KindError(f"{spec.__name__}.type must be a Literal of the scenario type names")
    return tuple(names)


@dataclass(frozen=True)
class ConstraintKind(Generic[S]):
    """A constraint kind of the ``constraints:`` list.

    Attributes:
        spec: its YAML entry (a pydantic model with ``type: Literal[...]`` and ``name``).
        build: the factory, spec → constraint object (ScenarioError naming the field).
        constraint: the class ``build`` returns; it declares the margins' type and unit.
        scene: the sphere the entry places in the MuJoCo scene and the viewer, if any.
    """

    spec: type[S]
    build: Callable[[S, ConstraintInputs], Constraint]
    constraint: type[ConfigurationConstraint] | type[VelocityConstraint]
    scene: Callable[[S, Constraint], SceneSphere] | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return type_names(self.spec)


@dataclass(frozen=True)
class LawKind(Generic[S]):
    """A law kind of the ``controllers:`` list.

    Attributes:
        spec: its YAML entry (a pydantic model with ``type: Literal[...]``, the gains, ``name``).
        build: the factory, spec → controller (ScenarioError naming the field).
        slopes: what the gain check needs: the slopes of its spring and damping near the
            target per unit of K_P and K_D (:class:`Slopes`; law_inputs.LINEAR for a law
            linear in x̃ and ẋ, law_inputs.tanh_slopes for a saturating one). No default: a
            law that does not say is refused.
        goal_types: those of its type names that take a scenario goal (task-space terms).
        start_problem: why the law cannot start from a case's state, if it can say so
            (law, x, ẋ, coordinate names, torque limit, held period) → message or None.
    """

    spec: type[S]
    build: Callable[[S, LawInputs], Controller]
    slopes: Callable[[S, int, str], Slopes]
    goal_types: tuple[str, ...] = ()
    start_problem: Callable[
        [Controller, Array, Array, tuple[str, ...], Array | None, float | None], str | None
    ] | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return type_names(self.spec)


def _check_constraint(kind: ConstraintKind[Any]) -> None:
    declared = getattr(kind.constraint, "margin_type", None)
    if declared not in TYPES:
        raise KindError(
            f"constraint kind {kind.names}: {kind.constraint.__name__} declares no margin type "
            "the results know; set margin_type to one of cpbc.constraints.margins.TYPES (a new "
            "unit is one more entry there)")


def _check_law(kind: LawKind[Any]) -> None:
    if not callable(kind.slopes):
        raise KindError(
            f"law kind {kind.names} declares no slopes for the gain check; give "
            "slopes=law_inputs.LINEAR or law_inputs.tanh_slopes (or its own)")
    unknown = set(kind.goal_types) - set(kind.names)
    if unknown:
        raise KindError(f"law kind {kind.names}: goal_types {sorted(unknown)} are not its types")


def _union(specs: list[type[BaseModel]]) -> Any:
    """The discriminated union of ``specs`` on ``type`` (one spec: itself)."""
    members = specs[0] if len(specs) == 1 else Union[tuple(specs)]  # noqa: UP007
    return Annotated[members, Field(discriminator="type")]


@dataclass(frozen=True)
class Kinds:
    """The constraint and law kinds a scenario may name, by ``type:``."""

    constraints: tuple[ConstraintKind[Any], ...]
    laws: tuple[LawKind[Any], ...]

    def __post_init__(self) -> None:
        for c in self.constraints:
            _check_constraint(c)
        for law in self.laws:
            _check_law(law)
        names = [*self.constraint_types, *self.law_types]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise KindError(f"the scenario types {twice} are declared twice")

    def with_kinds(self, *kinds: ConstraintKind[Any] | LawKind[Any]) -> Kinds:
        """These kinds and ``kinds`` (a new registry; this one is unchanged)."""
        return Kinds(
            (*self.constraints, *(k for k in kinds if isinstance(k, ConstraintKind))),
            (*self.laws, *(k for k in kinds if isinstance(k, LawKind))))

    def constraint(self, type_name: str) -> ConstraintKind[Any]:
        """The constraint kind of a ``type:`` (KeyError naming the known ones)."""
        for kind in self.constraints:
            if type_name in kind.names:
                return kind
        raise KeyError(f"no constraint kind {type_name!r}; known: {self.constraint_types}")

    def law(self, type_name: str) -> LawKind[Any]:
        """The law kind of a ``type:`` (KeyError naming the known ones)."""
        for kind in self.laws:
            if type_name in kind.names:
                return kind
        raise KeyError(f"no law kind {type_name!r}; known: {self.law_types}")

    @property
    def constraint_types(self) -> tuple[str, ...]:
        return tuple(n for k in self.constraints for n in k.names)

    @property
    def law_types(self) -> tuple[str, ...]:
        return tuple(n for k in self.laws for n in k.names)

    @property
    def goal_types(self) -> tuple[str, ...]:
        """Every law type that takes a scenario goal."""
        return tuple(n for k in self.laws for n in k.goal_types)

    def constraint_spec(self) -> Any:
        """The ``constraints:`` item: a union discriminated by ``type``."""
        return _union([k.spec for k in self.constraints])

    def law_spec(self) -> Any:
        """The ``controllers:`` item: a union discriminated by ``type``."""
        return _union([k.spec for k in self.laws])
