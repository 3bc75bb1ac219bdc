"""Printer for LTL formulas in Spot syntax (ltl-planning.md §1; docs/ltl.md).

The printer uses Spot's precedence table (``tlfleet.agent.ltl.parser.BINARY_PRECEDENCE``) and adds
parentheses only where Spot's parser would otherwise read a different tree, so printed formulas
paste into Spot/ltlfilt unchanged and ``parse(to_string(f)) == f`` for every tree the parser
builds. Atoms that Spot would not read back as that one atom (``"door open"``, ``Fa``, ``true``)
are printed between double quotes.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
from types import MappingProxyType

from tlfleet.agent.ltl.formula import (
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
from tlfleet.agent.ltl.lexer import is_bare_atom

# Binding strength, as in Spot's parser: larger binds tighter.
_ARROW, _OR, _XOR, _AND, _TEMPORAL, _UNARY, _PRIMARY = 1, 2, 3, 4, 6, 7, 8

_BINARY_SYMBOL: Mapping[type, tuple[str, int]] = MappingProxyType({
    Equiv: ("<->", _ARROW),
    Implies: ("->", _ARROW),
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


@lru_cache(maxsize=4096)
def atom_text(name: str) -> str:
    """``name`` bare when Spot reads it back as that atom, else double-quoted (memoised: the
    translator prints its automaton states' formulas to order them, atoms over and over)."""
    if is_bare_atom(name):
        return name
    return '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _operand(child: Formula, parent_level: int, *, bare_if_same: bool) -> str:
    """``child`` printed under an operator of ``parent_level``: bare when it binds tighter, or
    equally tight on the side the operator associates to (``bare_if_same``)."""
    text = to_string(child)
    level = _level(child)
    if level > parent_level or (level == parent_level and bare_if_same):
        return text
    return f"({text})"


def to_string(f: Formula) -> str:
    """Spot-syntax text of ``f`` with the fewest parentheses Spot needs to read the same tree."""
    match f:
        case Const(value):
            return "true" if value else "false"
        case Atom(name):
            return atom_text(name)
        case Not(arg) | Next(arg) | Finally(arg) | Globally(arg):
            symbol = _UNARY_SYMBOL[type(f)]
            inner = to_string(arg)
            if _level(arg) < _UNARY:
                return f"{symbol.strip()}({inner})"
            return symbol + inner
        case And(args) | Or(args):
            level = _level(f)
            symbol = " & " if level == _AND else " | "
            return symbol.join(_operand(a, level, bare_if_same=False) for a in args)
        case Binary(left, right):
            symbol, level = _BINARY_SYMBOL[type(f)]
            right_assoc = level != _XOR
            left_text = _operand(left, level, bare_if_same=not right_assoc)
            right_text = _operand(right, level, bare_if_same=right_assoc)
            return f"{left_text} {symbol} {right_text}"
    raise TypeError(f"not an LTL formula: {f!r}")
