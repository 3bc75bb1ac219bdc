"""Parser for Spot's LTL syntax (ltl-planning.md §1; the grammar table is in docs/ltl.md).

Binding, loosest to tightest, exactly as Spot's ``parsetl.yy`` declares it::

    ->  <->        one level, right-associative   a -> b <-> c  =  a -> (b <-> c)
    |              left-associative
    xor            left-associative              a | b xor c   =  a | (b xor c)
    &              left-associative  (also && /\\ ∧)
    *              left-associative  (Wring's and, just tighter than &)
    U R W M        one level, right-associative   a U b R c     =  a U (b R c)
    F G X !        prefix, tighter than every binary operator: F a U b = (F a) U b

plus ``X[n]``, ``F[n:m]``, ``G[n:m]`` (Spot's sugar, expanded into nested ``X``), postfix
``=0``/``=1`` on atoms (Wring), and the tokens of :mod:`tlfleet.agent.ltl.lexer`.

The parser is operator-precedence with explicit stacks (no recursion), so nesting depth is
limited only by :data:`MAX_DEPTH`, which keeps every later recursive pass (printing,
rewriting, translation) far from Python's recursion limit; deeper formulas get a clear
:class:`tlfleet.bus.errors.LtlSyntaxError` rather than a ``RecursionError``. ``&`` and ``|`` build
flattened n-ary nodes, as Spot does (a conjunction of 1 000 atoms is depth 2).
"""

from __future__ import annotations

from types import MappingProxyType

from tlfleet.agent.ltl import lexer as lx
from tlfleet.agent.ltl.formula import (
    FALSE,
    TRUE,
    And,
    Atom,
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
    atoms,
    conj,
    disj,
)
from tlfleet.agent.ltl.lexer import Token, tokenize
from tlfleet.bus.errors import LtlSyntaxError

__all__ = ["BINARY_PRECEDENCE", "MAX_DEPTH", "Token", "atoms", "parse", "tokenize"]

MAX_DEPTH = 200
"""Deepest operator nesting accepted (``X X … X a`` with 200 ``X`` is depth 201)."""

# kind → (precedence, right-associative, constructor); larger binds tighter (docs/ltl.md).
BINARY_PRECEDENCE = MappingProxyType({
    lx.IMPLIES: (1, True, Implies),
    lx.EQUIV: (1, True, Equiv),
    lx.OR: (2, False, disj),
    lx.XOR: (3, False, Xor),
    lx.AND: (4, False, conj),
    lx.STAR: (5, False, conj),
    lx.UNTIL: (6, True, Until),
    lx.RELEASE: (6, True, Release),
    lx.WEAK_UNTIL: (6, True, WeakUntil),
    lx.STRONG_RELEASE: (6, True, StrongRelease),
})
_UNARY = MappingProxyType({lx.NOT: Not, lx.NEXT: Next, lx.FINALLY: Finally,
                           lx.GLOBALLY: Globally, lx.REPEAT: None})


def _describe(token: Token) -> str:
    return "end of input" if token.kind == lx.END else repr(token.text)


def _expand_repeat(letter: str, low: int, high: int | None, f: Formula) -> Formula:
    """Spot's sugar: ``X[n] f`` = X…X f; ``F[n:m] f`` = Xⁿ(f | X(f | … X f)) with m−n more X;
    ``G[n:m]`` likewise with ``&``; an unbounded ``m`` gives Xⁿ F f / Xⁿ G f."""
    if letter == "X":
        result = f
        for _ in range(low):
            result = Next(result)
        return result
    if high is None:
        result = Finally(f) if letter == "F" else Globally(f)
    else:
        result = f
        for _ in range(high - low):
            result = disj(f, Next(result)) if letter == "F" else conj(f, Next(result))
    for _ in range(low):
        result = Next(result)
    return result


def _depth_of_repeat(letter: str, low: int, high: int | None) -> int:
    if letter == "X":
        return low
    return low + (1 if high is None else 2 * (high - low))


class _Chain:
    """An n-ary ``&`` or ``|`` still being gathered by the parser (``items``, flattened)."""

    __slots__ = ("cls", "items")

    def __init__(self, cls: type, items: list):
        self.cls = cls
        self.items = items


def _of_kind(f: object, cls: type) -> bool:
    return isinstance(f, cls) or (isinstance(f, _Chain) and f.cls is cls)


def _flat(f: object, cls: type):
    if isinstance(f, _Chain) and f.cls is cls:
        return f.items
    return f.args if isinstance(f, cls) else (_done(f),)


def _done(f: object) -> Formula:
    """The formula of an operand: a gathered chain becomes its ``And`` / ``Or``."""
    if isinstance(f, _Chain):
        return f.cls(tuple(f.items)) if len(f.items) > 1 else f.items[0]
    return f


class _Parser:
    """Operator precedence (shunting-yard) over the tokens: ``operands`` holds ``(tree,
    depth)``, ``operators`` the unary, binary and ``(`` tokens not yet reduced."""

    def __init__(self, text: str):
        self.text = text
        self.tokens = tokenize(text)
        self.operands: list[tuple[Formula, int]] = []
        self.operators: list[Token] = []

    def fail(self, token: Token, message: str) -> LtlSyntaxError:
        return LtlSyntaxError(self.text, token.column, message)

    def parse(self) -> Formula:
        expect_operand = True
        previous: Token | None = None
        for token in self.tokens:
            kind = token.kind
            if expect_operand:
                expect_operand = not self.operand(token, previous)
            elif kind in (lx.POST_NEG, lx.POST_POS):
                self.postfix(token, previous)
            elif kind in BINARY_PRECEDENCE:
                self.binary(token)
                expect_operand = True
            elif kind == lx.RPAR:
                self.close(token)
            elif kind == lx.END:
                self.end(token)
            else:
                raise self.fail(token, f"expected an operator or end of input, "
                                       f"got {_describe(token)}")
            previous = token
        (tree, _depth), = self.operands
        return _done(tree)

    def operand(self, token: Token, previous: Token | None) -> bool:
        """Read a token where a formula starts: a prefix operator or ``(`` (False: a formula
        is still expected) or an atom or constant (True); anything else is an error."""
        kind = token.kind
        if kind in _UNARY or kind == lx.LPAR:
            self.operators.append(token)
            return False
        if kind == lx.ATOM:
            self.push(Atom(token.value), 1, token)
            return True
        if kind == lx.TRUE or kind == lx.FALSE:
            self.push(TRUE if kind == lx.TRUE else FALSE, 1, token)
            return True
        if previous is None:
            raise self.fail(token, f"expected a formula, got {_describe(token)}")
        if previous.kind == lx.LPAR and kind == lx.RPAR:
            raise self.fail(token, "expected a formula inside '(', got ')'")
        if previous.kind == lx.LPAR:
            raise self.fail(token, f"expected a formula, got {_describe(token)}")
        raise self.fail(token, f"expected a formula after {previous.text!r}, "
                               f"got {_describe(token)}")

    def postfix(self, token: Token, previous: Token | None) -> None:
        """A postfix ``=0`` (the atom is false: its negation) or ``=1`` (the atom itself), allowed
        after an atom only."""
        if previous is None or previous.kind != lx.ATOM:
            raise self.fail(token, f"{token.text!r} may only follow an atom")
        if token.kind == lx.POST_NEG:
            tree, depth = self.operands.pop()
            self.push(Not(tree), depth + 1, token)

    def binary(self, token: Token) -> None:
        """A binary operator: first reduce the pending operators that bind at least as tightly
        (all unary ones; equal precedence only when left-associative)."""
        operators = self.operators
        level, _right, _make = BINARY_PRECEDENCE[token.kind]
        while operators and operators[-1].kind != lx.LPAR:
            top = operators[-1].kind
            if top in _UNARY:
                self.reduce_top()
                continue
            top_level, top_right, _ = BINARY_PRECEDENCE[top]
            if top_level > level or (top_level == level and not top_right):
                self.reduce_top()
            else:
                break
        operators.append(token)

    def close(self, token: Token) -> None:
        """``)``: reduce back to the matching ``(``."""
        operators = self.operators
        while operators and operators[-1].kind != lx.LPAR:
            self.reduce_top()
        if not operators:
            raise self.fail(token, "expected an operator or end of input, got ')'")
        operators.pop()

    def end(self, token: Token) -> None:
        """End of input: reduce everything; a ``(`` left open is an error."""
        operators = self.operators
        while operators:
            if operators[-1].kind == lx.LPAR:
                opening = operators[-1]
                raise self.fail(token, f"expected ')' to close '(' at column "
                                       f"{opening.column}, got end of input")
            self.reduce_top()

    def push(self, tree: Formula, depth: int, where: Token) -> None:
        if depth > MAX_DEPTH:
            raise self.fail(where, f"formula nested more than {MAX_DEPTH} levels deep "
                                   f"(split it or use fewer nested operators)")
        self.operands.append((tree, depth))

    def reduce_top(self) -> None:
        """Apply the top operator to its operands."""
        op = self.operators.pop()
        operands = self.operands
        if op.kind in _UNARY:
            arg, depth = operands.pop()
            arg = _done(arg)
            if op.kind == lx.REPEAT:
                letter, low, high = op.value
                tree = _expand_repeat(letter, low, high, arg)
                self.push(tree, depth + _depth_of_repeat(letter, low, high), op)
            else:
                self.push(_UNARY[op.kind](arg), depth + 1, op)
            return
        right, rd = operands.pop()
        left, ld = operands.pop()
        make = BINARY_PRECEDENCE[op.kind][2]
        if make is conj or make is disj:
            # flattened: a same-kind operand adds no level; the operands are gathered in
            # one list, so a chain of n operators costs O(n), not O(n²) tuple copies
            cls = And if make is conj else Or
            ld += not _of_kind(left, cls)
            rd += not _of_kind(right, cls)
            items = left.items if isinstance(left, _Chain) and left.cls is cls \
                else list(_flat(left, cls))
            items.extend(_flat(right, cls))
            self.push(_Chain(cls, items), max(ld, rd), op)
        else:
            self.push(make(_done(left), _done(right)), 1 + max(ld, rd), op)


def parse(text: str) -> Formula:
    """Parse ``text`` (Spot syntax, docs/ltl.md) into an immutable formula tree.

    Raises :class:`tlfleet.bus.errors.LtlSyntaxError` (a ``FormulaSyntaxError``) whose one-line
    message names the formula, the 1-based column and what was expected there.
    """
    if not isinstance(text, str):
        raise TypeError(f"expected a formula string, got {type(text).__name__}")
    return _Parser(text).parse()
