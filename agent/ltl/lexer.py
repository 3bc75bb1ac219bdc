"""Tokenizer for Spot's LTL syntax (ltl-planning.md §1; docs/ltl.md "Grammar").

It follows Spot's scanner (``spot/parsetl/scantl.ll``) rule for rule, re-implemented by hand:

* the longest match wins, and on equal length the earlier rule (constants, then operators, then
  atoms), so ``true`` is the constant but ``trueish`` an atom, and ``aUb`` is one atom while
  ``a U b`` is an until;
* atoms are ``[a-zA-EH-WYZ_.][a-zA-Z0-9_.]*`` or ``[FGX][0-9][a-zA-Z0-9_.]*`` where a formula is
  expected, so ``GFa`` is ``G F a`` and ``F1`` an atom; right after an operand (where an
  operator is expected) they may not start with ``F G M R U V W X`` nor continue with
  ``F G X``, so ``aUb`` … ``p=0Uq`` splits the way Spot splits it; any text between double
  quotes is an atom (``"door open"``, with ``\\`` escapes);
* ``1``/``0`` and ``true``/``false`` in any case are the constants; ``X[n]``, ``F[n:m]``,
  ``G[n:m]`` (separators ``:`` ``..`` ``,`` ``to``; ``$``, ``inf`` or nothing for an unbounded
  upper end; a trailing ``!`` for the strong variants) are single tokens; ``/* … */`` comments
  nest.

PSL/SERE syntax (braces, ``;``, ``[*]``, ``|->`` …) is recognised and refused with a clear error.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from types import MappingProxyType

from tlfleet.bus.errors import LtlSyntaxError

__all__ = ["Token", "is_bare_atom", "tokenize"]

# Token kinds of the binary operators, unary operators and other punctuation.
IMPLIES, EQUIV, OR, XOR, AND, STAR = "->", "<->", "|", "xor", "&", "*"
UNTIL, RELEASE, WEAK_UNTIL, STRONG_RELEASE = "U", "R", "W", "M"
NOT, NEXT, FINALLY, GLOBALLY = "!", "X", "F", "G"
REPEAT = "repeat"  # X[n], F[n:m], G[n:m]: ``value`` = (operator letter, low, high or None)
ATOM, TRUE, FALSE, LPAR, RPAR, END = "atom", "true", "false", "(", ")", "end"
POST_NEG, POST_POS = "=0", "=1"

_ANY = "a-zA-Z0-9_."
_INITIAL_ATOM = re.compile(rf"[a-zA-EH-WYZ_.][{_ANY}]*|[FGX][0-9][{_ANY}]*")
_AFTER_OPERAND_ATOM = re.compile(rf"[a-zA-EH-LN-QSTYZ_.](?:[a-zA-EH-WYZ0-9_.][{_ANY}]*)?")
_CONSTANT = re.compile(r"(?i:true|false)")

# Symbolic operators (text → kind), longest first when tried in order.
_SYMBOLS: tuple[tuple[str, str], ...] = tuple(sorted({
    "<-->": EQUIV, "<->": EQUIV, "<=>": EQUIV, "↔": EQUIV, "⇔": EQUIV,
    "-->": IMPLIES, "->": IMPLIES, "=>": IMPLIES, "→": IMPLIES, "⟶": IMPLIES, "⇒": IMPLIES,
    "⟹": IMPLIES,
    "||": OR, "|": OR, "+": OR, "\\/": OR, "∨": OR, "∪": OR,
    "&&": AND, "&": AND, "/\\": AND, "∧": AND, "∩": AND, "*": STAR,
    "^": XOR, "⊕": XOR,
    "!": NOT, "~": NOT, "¬": NOT,
    "[]": GLOBALLY, "□": GLOBALLY, "⬜": GLOBALLY, "◻": GLOBALLY,
    "<>": FINALLY, "◇": FINALLY, "⋄": FINALLY, "♢": FINALLY,
    "()": NEXT, "○": NEXT, "◯": NEXT,
    "(": LPAR, ")": RPAR,
    "=0": POST_NEG, "=1": POST_POS,
}.items(), key=lambda item: -len(item[0])))

# Spot's PSL/SERE tokens: recognised so that the error says what they are.
_PSL = ("[]->", "[]=>", "<>->", "<>=>", "|->", "|=>", "↦", "⤇", "##", "[*", "[+]", "[:*",
        "[:+]", "[=", "[->", "{", "}", ";", ":")

_WORD_OPERATORS = MappingProxyType({
    "xor": XOR, "U": UNTIL, "R": RELEASE, "V": RELEASE, "W": WEAK_UNTIL, "M": STRONG_RELEASE,
    "F": FINALLY, "G": GLOBALLY, "X": NEXT,
})
_REPEAT_SEPARATORS = ("..", ":", ",", "to")


@dataclass(frozen=True, slots=True)
class Token:
    """``kind`` is one of the kinds above; ``text`` the source text; ``column`` is 1-based;
    ``value`` the atom's name or a repetition's ``(letter, low, high)``."""

    kind: str
    text: str
    column: int
    value: object = None


def _word_at(text: str, i: int, after_operand: bool) -> tuple[str, str | None] | None:
    """The token Spot's scanner reads at ``text[i]`` among constants, word operators and atoms:
    ``(kind, matched text)``; longest match, ties to the earlier rule (constants, operators,
    atoms)."""
    candidates: list[tuple[int, int, str, str]] = []  # (-length, rule order, kind, text)
    m = _CONSTANT.match(text, i)
    if m:
        candidates.append((-len(m.group()), 0, m.group().lower(), m.group()))
    for word, kind in _WORD_OPERATORS.items():
        if text.startswith(word, i):
            candidates.append((-len(word), 1, kind, word))
    if text.startswith("first_match", i):
        candidates.append((-11, 1, "psl", "first_match"))
    m = (_AFTER_OPERAND_ATOM if after_operand else _INITIAL_ATOM).match(text, i)
    if m:
        candidates.append((-len(m.group()), 2, ATOM, m.group()))
    if not candidates:
        return None
    _neg, _order, kind, word = min(candidates)
    return kind, word


def is_bare_atom(name: str) -> bool:
    """Whether ``name`` prints without quotes: Spot reads it back as this one atom."""
    if not name:
        return False
    found = _word_at(name, 0, after_operand=False)
    return found is not None and found == (ATOM, name)


def _repeat(text: str, i: int, letter: str, column: int) -> tuple[Token, int]:
    """Parse ``[n]``, ``[n:m]``, ``[n:]``, ``[n:$]``, ``[!]`` … starting at the ``[`` at ``i``."""
    start = i
    i += 1

    def skip_space(j: int) -> int:
        while j < len(text) and text[j] in " \t\r\n":
            j += 1
        return j

    def number(j: int) -> tuple[int | None, int]:
        m = re.compile(r"[0-9]+").match(text, j)
        return (int(m.group()), m.end()) if m else (None, j)

    def fail(j: int, what: str) -> LtlSyntaxError:
        return LtlSyntaxError(text, j + 1, f"in {letter}[…]: {what}")

    i = skip_space(i)
    low, i = number(i)
    high: int | None
    i = skip_space(i)
    separator = next((s for s in _REPEAT_SEPARATORS if text.startswith(s, i)), None)
    if separator is None:
        if low is None and not text.startswith("!]", i):
            raise fail(i, "expected a number")
        high = low
        if letter != "X":
            raise fail(i, f"{letter}[n:m] expects two parameters")
    else:
        if letter == "X":
            raise fail(i, "X[n] expects one parameter")
        i = skip_space(i + len(separator))
        high, i = number(i)
        if high is None:
            i = skip_space(i)
            for unbounded in ("$", "inf"):
                if text.startswith(unbounded, i):
                    i += len(unbounded)
                    break
        if low is None:
            low = 0
    i = skip_space(i)
    if text.startswith("!]", i):  # strong variant: the same as the weak one on infinite words
        i += 2
    elif text.startswith("]", i):
        i += 1
    else:
        got = repr(text[i]) if i < len(text) else "end of input"
        raise fail(i, f"expected ']', got {got}")
    if low is None:
        low = high = 1  # X[!] is X
    if high is not None and high < low:
        raise fail(start, f"empty range [{low}:{high}]")
    return Token(REPEAT, text[column - 1 : i], column, (letter, low, high)), i


def _comment_end(text: str, i: int) -> int:
    """The index after the comment that opens at ``text[i]`` (``/* … */``, nested ones too)."""
    depth, j, n = 0, i, len(text)
    while j < n:
        if text.startswith("/*", j):
            depth += 1
            j += 2
        elif text.startswith("*/", j):
            depth -= 1
            j += 2
            if depth == 0:
                break
        else:
            j += 1
    if depth:
        raise LtlSyntaxError(text, i + 1, "unclosed comment")
    return j


def _quoted_atom(text: str, i: int) -> tuple[Token, int]:
    """The atom quoted from ``text[i]`` (a ``"``; a backslash takes the next character as it
    is) and the index after its closing quote."""
    j, n = i + 1, len(text)
    name = []
    while j < n and text[j] != '"':
        if text[j] == "\\" and j + 1 < n:
            j += 1
        name.append(text[j])
        j += 1
    if j >= n:
        raise LtlSyntaxError(text, i + 1, "unclosed string (missing '\"')")
    return Token(ATOM, text[i : j + 1], i + 1, "".join(name)), j + 1


def tokenize(text: str) -> list[Token]:
    """Split ``text`` into tokens (Spot's scanner, see module docstring), ending with ``END``."""
    tokens: list[Token] = []
    i = 0
    n = len(text)
    after_operand = False
    while i < n:
        ch = text[i]
        if ch.isspace():
            i += 1
            continue
        if text.startswith("/*", i):
            i = _comment_end(text, i)
            continue
        column = i + 1
        if ch == '"':
            token, i = _quoted_atom(text, i)
            tokens.append(token)
            after_operand = True
            continue
        if ch == "1" or ch == "0":
            tokens.append(Token(TRUE if ch == "1" else FALSE, ch, column))
            after_operand = True
            i += 1
            continue
        if ch in "FGX":
            j = i + 1
            while j < n and text[j] in " \t\r\n":
                j += 1
            if j < n and text[j] == "[" and not text.startswith("[]", j):
                token, i = _repeat(text, j, ch, column)
                tokens.append(token)
                after_operand = False
                continue
        found = _word_at(text, i, after_operand) if (ch.isalpha() or ch in "_.") else None
        if found is not None:
            kind, word = found
            if kind == "psl":
                raise LtlSyntaxError(text, column, f"PSL operator {word!r} is not supported")
            tokens.append(Token(kind, word, column, word if kind == ATOM else None))
            after_operand = kind in (ATOM, TRUE, FALSE)
            i += len(word)
            continue
        psl = next((p for p in _PSL if text.startswith(p, i)), None)
        symbol = next(((s, k) for s, k in _SYMBOLS if text.startswith(s, i)), None)
        if psl is not None and (symbol is None or len(psl) > len(symbol[0])):
            raise LtlSyntaxError(text, column, f"PSL/SERE operator {psl!r} is not supported")
        if symbol is not None:
            word, kind = symbol
            if kind in (POST_NEG, POST_POS) and not (tokens and tokens[-1].kind == ATOM):
                raise LtlSyntaxError(text, column, f"{word!r} may only follow an atom")
            tokens.append(Token(kind, word, column))
            after_operand = kind in (RPAR, POST_NEG, POST_POS)
            i += len(word)
            continue
        raise LtlSyntaxError(text, column, f"unexpected character {ch!r}")
    tokens.append(Token(END, "", n + 1))
    return tokens
