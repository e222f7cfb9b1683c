"""Numbers in scenarios may be written as small expressions of pi: ``2*pi/3``, ``-17*pi/18``."""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable

_BINARY: dict[type[ast.operator], Callable[[float, float], float]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_UNARY: dict[type[ast.unaryop], Callable[[float], float]] = {
    ast.UAdd: operator.pos, ast.USub: operator.neg}
_NAMES = {"pi": math.pi}


def _eval(node: ast.AST) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        return float(node.value)
    if isinstance(node, ast.Name) and node.id in _NAMES:
        return _NAMES[node.id]
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return _BINARY[type(node.op)](_eval(node.left), _eval(node.right))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        return _UNARY[type(node.op)](_eval(node.operand))
    raise ValueError("only numbers, pi, + - * / ** and parentheses are allowed")


def parse_number(value: object) -> object:
    """Turn '2*pi/3' into a float; leave other values for pydantic to check."""
    if isinstance(value, bool):  # YAML's yes/true would otherwise pass as 1.0
        raise ValueError("must be a number, not true/false")
    if isinstance(value, str):
        try:
            return _eval(ast.parse(value.strip(), mode="eval").body)
        except (SyntaxError, ValueError, ZeroDivisionError, OverflowError, TypeError) as exc:
            raise ValueError(f"cannot read {value!r} as a number: {exc}") from None
    return value
