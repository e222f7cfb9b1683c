""":class:`Kinds`, the registry of every constraint and law kind, found by walking the packages
that declare them.

**Where each declaration lives** (so that every import points down the layers model →
constraints → controllers → simulation → results → scenario/CLI): in the kind's own module,
after the class. A constraint module of ``cpbc.constraints`` ends with ``KINDS``, a tuple of
:class:`~cpbc.constraints.constraint_kind.ConstraintKind` (its spec, its factory, the class
whose ``margin_type`` says how the results report it, an example entry per type); a law
module of ``cpbc.controllers`` or ``cpbc.peers`` with ``KINDS``, a tuple of
:class:`~cpbc.controllers.law_kind.LawKind` (its spec, its factory, what the gain check needs,
an example entry per type, which of its types take a goal). The specs' vocabulary is in
``cpbc.spec`` and ``cpbc.controllers.law_specs``.

**The registry is a value found by reading, not a global that fills itself.**
:func:`declared_kinds` imports every module of a package, in sorted order, and collects the
``KINDS`` of those that have one; ``cpbc.scenario.schema.kinds.KINDS`` is the frozen
:class:`Kinds` of those packages. No module registers itself, so a new kind is one module and
its test, and a test that wants one more kind builds its own ``Kinds`` (from its own package,
or ``KINDS.with_modules(module)``) and passes it along; the default stays as it was. The
schema's discriminated unions, ``build``, the gain check and the generated docs all read it.
Every entry is checked when a ``Kinds`` is built: a spec whose ``type:`` is not a tuple of
literals, a type name given twice, a type without an example, a constraint class without a
margin type the results know, or a law without the gain check's declaration is refused
there, loudly.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Iterable
from dataclasses import dataclass
from types import ModuleType
from typing import Annotated, Any, Union

from pydantic import BaseModel, Field

from cpbc.constraints.constraint_kind import ConstraintKind
from cpbc.constraints.margins import TYPES
from cpbc.controllers.law_kind import LawKind
from cpbc.spec.type_names import KindError


def _check_examples(kind: ConstraintKind[Any] | LawKind[Any]) -> None:
    missing = [n for n in kind.names if n not in kind.examples]
    if missing:
        raise KindError(f"kind {kind.names} gives no example entry for {missing}; the "
                        "contract test builds one per type")


def _check_constraint(kind: ConstraintKind[Any]) -> None:
    _check_examples(kind)
    declared = getattr(kind.constraint, "margin_type", None)
    if declared not in TYPES:
        raise KindError(
            f"constraint kind {kind.names}: {kind.constraint.__name__} declares no margin type "
            "the results know; set margin_type to one of cpbc.margin_kinds.TYPES (a new unit "
            "is one more entry there)")


def _check_law(kind: LawKind[Any]) -> None:
    _check_examples(kind)
    if not callable(kind.slopes):
        raise KindError(
            f"law kind {kind.names} declares no slopes for the gain check; give "
            "slopes=law_kind.LINEAR or law_kind.tanh_slopes (or its own)")
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

    @classmethod
    def of(cls, kinds: Iterable[ConstraintKind[Any] | LawKind[Any]]) -> Kinds:
        """The registry of ``kinds``, constraints and laws each in the order given."""
        kinds = tuple(kinds)
        return cls(tuple(k for k in kinds if isinstance(k, ConstraintKind)),
                   tuple(k for k in kinds if isinstance(k, LawKind)))

    def with_kinds(self, *kinds: ConstraintKind[Any] | LawKind[Any]) -> Kinds:
        """These kinds and ``kinds`` (a new registry; this one is unchanged)."""
        return Kinds.of((*self.constraints, *self.laws, *kinds))

    def with_modules(self, *modules: ModuleType) -> Kinds:
        """These kinds and those the ``modules`` declare (their ``KINDS``)."""
        return self.with_kinds(*(k for m in modules for k in declared_in(m)))

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


def declared_in(module: ModuleType) -> tuple[ConstraintKind[Any] | LawKind[Any], ...]:
    """The kinds a module declares: its ``KINDS`` (none when it has no such tuple)."""
    kinds = getattr(module, "KINDS", ())
    bad = [k for k in kinds if not isinstance(k, ConstraintKind | LawKind)]
    if not isinstance(kinds, tuple) or bad:
        raise KindError(f"{module.__name__}.KINDS must be a tuple of ConstraintKind or "
                        "LawKind")
    return kinds


def declared_kinds(*packages: ModuleType) -> tuple[ConstraintKind[Any] | LawKind[Any], ...]:
    """Every kind the modules of ``packages`` declare: each package's modules (one level,
    a subpackage counting as one module) imported in the order of their names, and the
    ``KINDS`` of those that have one. Deterministic: the same files give the same registry."""
    found: list[ConstraintKind[Any] | LawKind[Any]] = []
    for package in packages:
        for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
            module = importlib.import_module(f"{package.__name__}.{info.name}")
            found += declared_in(module)
    return tuple(found)
