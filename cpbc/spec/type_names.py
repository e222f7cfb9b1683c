"""How a kind's ``type:`` names are read off its spec, and the error of a kind declaration the
registry cannot use."""

from __future__ import annotations

from typing import get_args

from pydantic import BaseModel


class KindError(TypeError):
    """A kind declaration the registry cannot use (a programming error, not bad input)."""


def type_names(spec: type[BaseModel]) -> tuple[str, ...]:
    """The ``type:`` values a spec accepts: the arguments of its ``Literal``."""
    info = spec.model_fields.get("type")
    names = get_args(info.annotation) if info is not None else ()
    if not names or not all(isinstance(n, str) for n in names):
        raise KindError(f"{spec.__name__}.type must be a Literal of the scenario type names")
    return tuple(names)
