"""Exact evaluation of LTL on ultimately periodic (lasso) words u·v^ω (ltl-planning.md §2, item 1).

A lasso word has finitely many distinct suffixes: position ``i`` of ``u·v`` (length ``n``) has the
successor ``i + 1``, except the last position whose successor is ``len(u)`` (the loop start). Every
subformula is evaluated on those ``n`` positions as a tuple of booleans; ``U`` and ``M`` are least
fixpoints and ``R`` and ``W`` greatest fixpoints of their one-step expansion (Baier & Katoen,
Def. 5.6 / Lemma 5.18), computed by backward sweeps until nothing changes (at most two sweeps
over the loop suffice, the loop is short).
"""

from __future__ import annotations

from collections.abc import Sequence

from tlfleet.agent.ltl.formula import (
    And,
    Atom,
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
from tlfleet.agent.ltl.parser import parse


class _Word:
    """The ``n`` positions of ``u·v`` and their successor map."""

    def __init__(self, prefix: Sequence[frozenset[str]], loop: Sequence[frozenset[str]]):
        if not loop:
            raise ValueError("the loop of a lasso word must not be empty")
        self.letters = [frozenset(x) for x in (*prefix, *loop)]
        self.n = len(self.letters)
        self.loop_start = len(prefix)
        self.succ = [*range(1, self.n), self.loop_start]


def _fixpoint(word: _Word, now, later, least: bool) -> tuple[bool, ...]:
    """Solve ``x[i] = now[i] or (later[i] and x[succ(i)])`` as a least or greatest fixpoint.

    ``U``: now = right, later = left, least. ``R``: written as its dual by the caller.
    """
    x = [not least] * word.n
    changed = True
    while changed:
        changed = False
        for i in range(word.n - 1, -1, -1):
            value = now[i] or (later[i] and x[word.succ[i]])
            if value != x[i]:
                x[i] = value
                changed = True
    return tuple(x)


def _eval(f: Formula, word: _Word, memo: dict[Formula, tuple[bool, ...]]) -> tuple[bool, ...]:
    if f in memo:
        return memo[f]
    n = word.n
    match f:
        case Const(value):
            result = (value,) * n
        case Atom(name):
            result = tuple(name in letter for letter in word.letters)
        case Not(a):
            result = tuple(not v for v in _eval(a, word, memo))
        case Next(a):
            va = _eval(a, word, memo)
            result = tuple(va[word.succ[i]] for i in range(n))
        case Finally(a):
            result = _fixpoint(word, _eval(a, word, memo), (True,) * n, least=True)
        case Globally(a):
            # G a = !F !a
            na = tuple(not v for v in _eval(a, word, memo))
            result = tuple(not v for v in _fixpoint(word, na, (True,) * n, least=True))
        case And(args):
            values = [_eval(a, word, memo) for a in args]
            result = tuple(all(v[i] for v in values) for i in range(n))
        case Or(args):
            values = [_eval(a, word, memo) for a in args]
            result = tuple(any(v[i] for v in values) for i in range(n))
        case Implies(a, b):
            va, vb = _eval(a, word, memo), _eval(b, word, memo)
            result = tuple((not x) or y for x, y in zip(va, vb, strict=True))
        case Equiv(a, b):
            va, vb = _eval(a, word, memo), _eval(b, word, memo)
            result = tuple(x == y for x, y in zip(va, vb, strict=True))
        case Xor(a, b):
            va, vb = _eval(a, word, memo), _eval(b, word, memo)
            result = tuple(x != y for x, y in zip(va, vb, strict=True))
        case Until(a, b):
            result = _fixpoint(word, _eval(b, word, memo), _eval(a, word, memo), least=True)
        case WeakUntil(a, b):
            # a W b: greatest fixpoint of x = b | (a & X x)
            result = _fixpoint(word, _eval(b, word, memo), _eval(a, word, memo), least=False)
        case Release(a, b):
            # a R b = !(!a U !b)
            na = tuple(not v for v in _eval(a, word, memo))
            nb = tuple(not v for v in _eval(b, word, memo))
            result = tuple(not v for v in _fixpoint(word, nb, na, least=True))
        case StrongRelease(a, b):
            # a M b = b U (a & b)
            va, vb = _eval(a, word, memo), _eval(b, word, memo)
            both = tuple(x and y for x, y in zip(va, vb, strict=True))
            result = _fixpoint(word, both, vb, least=True)
        case _:
            raise TypeError(f"not an LTL formula: {f!r}")
    memo[f] = result
    return result


def holds(
    formula: Formula | str,
    prefix: Sequence[frozenset[str]],
    loop: Sequence[frozenset[str]],
) -> bool:
    """Whether the lasso word ``prefix · loop^ω`` satisfies ``formula`` at step 0.

    Each letter is the set of atomic propositions true at that step; ``loop`` must be non-empty.
    """
    f = parse(formula) if isinstance(formula, str) else formula
    return _eval(f, _Word(prefix, loop), {})[0]


def evaluate(
    formula: Formula, prefix: Sequence[frozenset[str]], loop: Sequence[frozenset[str]]
) -> tuple[bool, ...]:
    """Truth value of ``formula`` at every position of ``prefix + loop`` (for diagnostics)."""
    return _eval(formula, _Word(prefix, loop), {})
