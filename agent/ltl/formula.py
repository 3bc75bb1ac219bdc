"""Immutable LTL formula trees (ltl-planning.md §1; style.md §2).

Every node is a frozen dataclass with tuple children, so formulas are hashable, shareable and
safe to cache on. Semantics (printing, evaluation on lasso words, translation to automata) are
functions over the tree in sibling modules that ``match`` on these node types.

The parser builds n-ary ``And``/``Or`` nodes, flattened as Spot's parser flattens them
(``(a & b) & c`` and ``a & (b & c)`` are both ``And((a, b, c))``), so long conjunctions stay
shallow. ``str(f)`` prints Spot syntax.
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from dataclasses import dataclass


class Formula:
    """Base class of every LTL node."""

    __slots__ = ()

    def __str__(self) -> str:
        from tlfleet.agent.ltl.printer import to_string

        return to_string(self)


@dataclass(frozen=True, slots=True)
class Const(Formula):
    """``true`` or ``false``."""

    value: bool


@dataclass(frozen=True, slots=True)
class Atom(Formula):
    """An atomic proposition: holds at step k iff ``name`` ∈ σk."""

    name: str


@dataclass(frozen=True, slots=True)
class Not(Formula):
    arg: Formula


@dataclass(frozen=True, slots=True)
class Next(Formula):
    """``X arg``."""

    arg: Formula


@dataclass(frozen=True, slots=True)
class Finally(Formula):
    """``F arg`` (eventually, alias ``<>``)."""

    arg: Formula


@dataclass(frozen=True, slots=True)
class Globally(Formula):
    """``G arg`` (always, alias ``[]``)."""

    arg: Formula


@dataclass(frozen=True, slots=True)
class And(Formula):
    """Conjunction of two or more operands."""

    args: tuple[Formula, ...]


@dataclass(frozen=True, slots=True)
class Or(Formula):
    """Disjunction of two or more operands."""

    args: tuple[Formula, ...]


@dataclass(frozen=True, slots=True)
class Binary(Formula):
    """Base of the binary operators other than ``&`` and ``|``."""

    left: Formula
    right: Formula


@dataclass(frozen=True, slots=True)
class Implies(Binary):
    """``left -> right``."""


@dataclass(frozen=True, slots=True)
class Equiv(Binary):
    """``left <-> right``."""


@dataclass(frozen=True, slots=True)
class Xor(Binary):
    """``left xor right``."""


@dataclass(frozen=True, slots=True)
class Until(Binary):
    """``left U right`` (strong until)."""


@dataclass(frozen=True, slots=True)
class Release(Binary):
    """``left R right`` (weak release, alias ``V``): ``right`` holds until and including the
    first ``left``, or forever."""


@dataclass(frozen=True, slots=True)
class WeakUntil(Binary):
    """``left W right`` = ``(left U right) | G left``."""


@dataclass(frozen=True, slots=True)
class StrongRelease(Binary):
    """``left M right`` = ``right U (left & right)``."""


TRUE = Const(True)
FALSE = Const(False)


def conj(*args: Formula) -> Formula:
    """Flattened n-ary conjunction, as the parser builds it (``true`` when empty)."""
    flat = tuple(x for a in args for x in (a.args if isinstance(a, And) else (a,)))
    if not flat:
        return TRUE
    return flat[0] if len(flat) == 1 else And(flat)


def disj(*args: Formula) -> Formula:
    """Flattened n-ary disjunction, as the parser builds it (``false`` when empty)."""
    flat = tuple(x for a in args for x in (a.args if isinstance(a, Or) else (a,)))
    if not flat:
        return FALSE
    return flat[0] if len(flat) == 1 else Or(flat)


def children(f: Formula) -> tuple[Formula, ...]:
    """The direct operands of ``f``."""
    match f:
        case Const() | Atom():
            return ()
        case Not(a) | Next(a) | Finally(a) | Globally(a):
            return (a,)
        case And(args) | Or(args):
            return args
        case Binary(left, right):
            return (left, right)
    raise TypeError(f"not an LTL formula: {f!r}")


def atoms(f: Formula) -> frozenset[str]:
    """The atomic propositions occurring in ``f``."""
    if isinstance(f, Atom):
        return frozenset((f.name,))
    result: frozenset[str] = frozenset()
    for child in children(f):
        result |= atoms(child)
    return result


def size(f: Formula) -> int:
    """Number of nodes of ``f``."""
    return 1 + sum(size(child) for child in children(f))


@contextmanager
def recursion_headroom(frames: int = 20_000):
    """Raise Python's recursion limit to at least ``frames`` for the passes over one formula.

    The parser caps nesting at ``tlfleet.agent.ltl.parser.MAX_DEPTH`` levels; the recursive passes
    (rewriting, the alternating automaton) use a handful of Python frames per level, which on
    Python ≥ 3.11 do not consume C stack, so a few thousand frames are safe.
    """
    old = sys.getrecursionlimit()
    if old < frames:
        sys.setrecursionlimit(frames)
    try:
        yield
    finally:
        if old < frames:
            sys.setrecursionlimit(old)
