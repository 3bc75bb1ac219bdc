"""Parser for Spot-compatible LTL syntax (ltl-planning.md §1).

Grammar, loosest to tightest binding::

    equiv    := implies ( '<->' equiv )?                   right-associative
    implies  := xor ( '->' implies )?                      right-associative
    xor      := or ( ('xor' | '^') or )*                   left-associative
    or       := and ( ('|' | '||') and )*                  left-associative
    and      := temporal ( ('&' | '&&') temporal )*        left-associative
    temporal := unary ( ('U' | 'R' | 'V' | 'W' | 'M') temporal )?   right-associative
    unary    := ('!' | 'X' | 'F' | 'G' | '[]' | '<>') unary | primary
    primary  := ATOM | 'true' | 'false' | '1' | '0' | '(' equiv ')'

``ATOM`` is ``[a-z_][a-z0-9_]*`` (not a keyword). Upper-case operator letters need no space
around them (``GFa`` is ``G F a``), as in Spot. Errors raise
:class:`agent.errors.FormulaSyntaxError` with the 1-based column and what was expected.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from types import MappingProxyType

from agent.errors import FormulaSyntaxError
from agent.ltl.formula import (
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
)

__all__ = ["Token", "atoms", "parse", "tokenize"]

_IDENT = re.compile(r"[a-z_][a-z0-9_]*")
_SYMBOLS = ("<->", "->", "&&", "||", "[]", "<>", "&", "|", "!", "(", ")", "^")
_OPERATOR_LETTERS = frozenset("XFGURVWM")
_KEYWORDS = MappingProxyType({"true": "true", "false": "false", "xor": "xor"})

_UNARY = MappingProxyType(
    {"!": Not, "X": Next, "F": Finally, "G": Globally, "[]": Globally, "<>": Finally}
)
_TEMPORAL = MappingProxyType(
    {"U": Until, "R": Release, "V": Release, "W": WeakUntil, "M": StrongRelease}
)
_AND = frozenset({"&", "&&"})
_OR = frozenset({"|", "||"})
_XOR = frozenset({"xor", "^"})


@dataclass(frozen=True, slots=True)
class Token:
    """``kind`` is ``'atom'``, ``'end'`` or the operator/keyword text; ``column`` is 1-based."""

    kind: str
    text: str
    column: int


def tokenize(text: str) -> list[Token]:
    """Split ``text`` into tokens, ending with an ``'end'`` token."""
    tokens: list[Token] = []
    i = 0
    n = len(text)
    while i < n:
        ch = text[i]
        if ch.isspace():
            i += 1
            continue
        match = _IDENT.match(text, i)
        if match:
            word = match.group()
            tokens.append(Token(_KEYWORDS.get(word, "atom"), word, i + 1))
            i = match.end()
            continue
        if ch in "01" and not (i + 1 < n and text[i + 1].isalnum()):
            tokens.append(Token("true" if ch == "1" else "false", ch, i + 1))
            i += 1
            continue
        if ch in _OPERATOR_LETTERS:
            tokens.append(Token(ch, ch, i + 1))
            i += 1
            continue
        for symbol in _SYMBOLS:
            if text.startswith(symbol, i):
                tokens.append(Token(symbol, symbol, i + 1))
                i += len(symbol)
                break
        else:
            if ch.isalpha() and ch.isupper():
                hint = "atoms are lower-case; operators are X F G U R V W M"
                raise FormulaSyntaxError(text, i + 1, f"unknown operator {ch!r} ({hint})")
            raise FormulaSyntaxError(text, i + 1, f"unexpected character {ch!r}")
    tokens.append(Token("end", "", n + 1))
    return tokens


def _describe(token: Token) -> str:
    return "end of input" if token.kind == "end" else repr(token.text)


class _Parser:
    """Recursive descent over the token list; one method per grammar level."""

    def __init__(self, text: str):
        self.text = text
        self.tokens = tokenize(text)
        self.pos = 0

    @property
    def current(self) -> Token:
        return self.tokens[self.pos]

    def advance(self) -> Token:
        token = self.tokens[self.pos]
        self.pos += 1
        return token

    def fail(self, token: Token, message: str) -> FormulaSyntaxError:
        return FormulaSyntaxError(self.text, token.column, message)

    def parse(self) -> Formula:
        if self.current.kind == "end":
            raise self.fail(self.current, "expected a formula, got end of input")
        result = self.equiv()
        if self.current.kind != "end":
            raise self.fail(
                self.current,
                f"expected an operator or end of input, got {_describe(self.current)}",
            )
        return result

    def operand(self, after: Token, level) -> Formula:
        """Parse the right operand of ``after``, with a clear message when it is missing."""
        if self.current.kind in ("end", ")") or self.current.kind in _BINARY_KINDS:
            raise self.fail(
                self.current,
                f"expected a formula after {after.text!r}, got {_describe(self.current)}",
            )
        return level()

    def equiv(self) -> Formula:
        left = self.implies()
        if self.current.kind == "<->":
            op = self.advance()
            return Equiv(left, self.operand(op, self.equiv))
        return left

    def implies(self) -> Formula:
        left = self.xor()
        if self.current.kind == "->":
            op = self.advance()
            return Implies(left, self.operand(op, self.implies))
        return left

    def xor(self) -> Formula:
        left = self.disjunction()
        while self.current.kind in _XOR:
            op = self.advance()
            left = Xor(left, self.operand(op, self.disjunction))
        return left

    def disjunction(self) -> Formula:
        left = self.conjunction()
        while self.current.kind in _OR:
            op = self.advance()
            left = Or((left, self.operand(op, self.conjunction)))
        return left

    def conjunction(self) -> Formula:
        left = self.temporal()
        while self.current.kind in _AND:
            op = self.advance()
            left = And((left, self.operand(op, self.temporal)))
        return left

    def temporal(self) -> Formula:
        left = self.unary()
        if self.current.kind in _TEMPORAL:
            op = self.advance()
            return _TEMPORAL[op.kind](left, self.operand(op, self.temporal))
        return left

    def unary(self) -> Formula:
        if self.current.kind in _UNARY:
            op = self.advance()
            return _UNARY[op.kind](self.operand(op, self.unary))
        return self.primary()

    def primary(self) -> Formula:
        token = self.current
        if token.kind == "atom":
            self.advance()
            return Atom(token.text)
        if token.kind == "true":
            self.advance()
            return TRUE
        if token.kind == "false":
            self.advance()
            return FALSE
        if token.kind == "(":
            self.advance()
            if self.current.kind == ")":
                raise self.fail(self.current, "expected a formula inside '(', got ')'")
            inner = self.operand(token, self.equiv)
            if self.current.kind != ")":
                raise self.fail(
                    self.current,
                    f"expected ')' to close '(' at column {token.column}, "
                    f"got {_describe(self.current)}",
                )
            self.advance()
            return inner
        raise self.fail(token, f"expected a formula, got {_describe(token)}")


_BINARY_KINDS = frozenset({"<->", "->", *_XOR, *_OR, *_AND, *_TEMPORAL})


def parse(text: str) -> Formula:
    """Parse ``text`` (Spot syntax, ltl-planning.md §1) into an immutable formula tree.

    Raises :class:`agent.errors.FormulaSyntaxError` naming the 1-based column and what was
    expected there.
    """
    if not isinstance(text, str):
        raise TypeError(f"expected a formula string, got {type(text).__name__}")
    return _Parser(text).parse()
