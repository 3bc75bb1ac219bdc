"""Printer for LTL formulas in Spot syntax (ltl-planning.md §1).

Parentheses are added where the grammar of ``agent.ltl.parser`` needs them, and also where Spot's
grammar would read the text differently (Spot binds ``xor`` tighter than ``|`` and puts ``->`` and
``<->`` on one level), so printed formulas can be pasted into Spot/ltlfilt unchanged.
``parse(to_string(f)) == f`` for every tree the parser builds.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from agent.ltl.formula import (
    And,
    Atom,
    Binary,
    Const,
    Equiv,
    Finally,
    Formula,
    Globally,
    Implies,
    Next,
    Not,
    Or,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
    Xor,
)

# Binding strength: larger binds tighter.
_EQUIV, _IMPLIES, _XOR, _OR, _AND, _TEMPORAL, _UNARY, _PRIMARY = range(8)

_BINARY_SYMBOL: Mapping[type, tuple[str, int]] = MappingProxyType({
    Equiv: ("<->", _EQUIV),
    Implies: ("->", _IMPLIES),
    Xor: ("xor", _XOR),
    Until: ("U", _TEMPORAL),
    Release: ("R", _TEMPORAL),
    WeakUntil: ("W", _TEMPORAL),
    StrongRelease: ("M", _TEMPORAL),
})
_UNARY_SYMBOL: Mapping[type, str] = MappingProxyType(
    {Not: "!", Next: "X ", Finally: "F ", Globally: "G "}
)


def _level(f: Formula) -> int:
    match f:
        case Const() | Atom():
            return _PRIMARY
        case Not() | Next() | Finally() | Globally():
            return _UNARY
        case And():
            return _AND
        case Or():
            return _OR
        case Binary():
            return _BINARY_SYMBOL[type(f)][1]
    raise TypeError(f"not an LTL formula: {f!r}")


def _wrap(text: str) -> str:
    return f"({text})"


def _operand(child: Formula, parent_level: int, *, same_level_ok: bool) -> str:
    """Print ``child`` under an operator of ``parent_level``.

    ``same_level_ok`` says whether a child of the same level may stay bare (associativity).
    Children at the ``<->``/``->``/``xor``/``|`` levels are always wrapped under one another
    when the two grammars (ours and Spot's) could disagree.
    """
    text = to_string(child)
    level = _level(child)
    if level > parent_level:
        # Spot reads `a xor b | c` as `(a xor b) | c`; we read it as `a xor (b | c)`.
        if parent_level == _XOR and level == _OR:
            return _wrap(text)
        return text
    if level == parent_level and same_level_ok:
        return text
    return _wrap(text)


def to_string(f: Formula) -> str:
    """Spot-syntax text of ``f`` with the fewest safe parentheses."""
    match f:
        case Const(value):
            return "true" if value else "false"
        case Atom(name):
            return name
        case Not(arg) | Next(arg) | Finally(arg) | Globally(arg):
            symbol = _UNARY_SYMBOL[type(f)]
            inner = to_string(arg)
            if _level(arg) < _UNARY:
                return symbol.strip() + _wrap(inner)
            return symbol + inner
        case And(args) | Or(args):
            level = _level(f)
            symbol = " & " if level == _AND else " | "
            first = _operand(args[0], level, same_level_ok=True)
            rest = [_operand(a, level, same_level_ok=False) for a in args[1:]]
            return symbol.join([first, *rest])
        case Binary(left, right):
            symbol, level = _BINARY_SYMBOL[type(f)]
            if level == _XOR:
                left_text = _operand(left, level, same_level_ok=True)
                right_text = _operand(right, level, same_level_ok=False)
            elif level == _TEMPORAL:
                left_text = _operand(left, level, same_level_ok=False)
                right_text = _operand(right, level, same_level_ok=True)
            else:
                # `->` and `<->`: right-associative, only with themselves.
                left_text = _operand(left, level, same_level_ok=False)
                right_text = _operand(right, level, same_level_ok=type(right) is type(f))
                if _level(right) == _IMPLIES and level == _EQUIV:
                    right_text = _wrap(to_string(right))  # Spot puts -> and <-> on one level
            if level in (_EQUIV, _IMPLIES) and _level(left) in (_EQUIV, _IMPLIES):
                left_text = _wrap(to_string(left))
            return f"{left_text} {symbol} {right_text}"
    raise TypeError(f"not an LTL formula: {f!r}")
