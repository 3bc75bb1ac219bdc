"""Parser of STL sub-task strings (stl-funnel.md §2; scenarios.md task column).

Grammar (whitespace ignored)::

    task      := ("G" | "F") "[" number "," number "]" conj
    conj      := literal ("&" literal)*
    literal   := "!" literal | "(" conj ")" | "true" | predicate
    predicate := expr ("<=" | "<" | ">=" | ">") expr
    expr      := term (("+" | "-") term)*
    term      := unary (("*" | "/") unary)*
    unary     := "-" unary | primary
    primary   := number | "pi" | p<id> | x<id> | y<id> | th<id> | "[" expr "," expr "]"
               | f "(" expr ("," expr)* ")" | "(" expr ")"

``p3`` is robot 3's position (2-vector), ``x3``/``y3``/``th3`` its state components. Negation
applies to a single predicate (eq. (3a)); disjunction and nested temporal operators are outside
the fragment and are rejected with a message saying so. Every error is a
:class:`FormulaSyntaxError` with the 1-based column of the offending token and what was expected
there.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

from tlfleet.agent.model.scenario import Robot
from tlfleet.agent.stl.syntax import (
    COMPARISONS,
    FUNCTIONS,
    And,
    BinOp,
    Call,
    Const,
    Expr,
    Neg,
    Not,
    Position,
    Predicate,
    Psi,
    Shape,
    StateVar,
    Temporal,
    Top,
    VecLit,
)
from tlfleet.bus.errors import FormulaSyntaxError

_TOKEN_RE = re.compile(
    r"\s*(?:(?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)"
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)"
    r"|(?P<op><=|>=|&&|\|\||[<>&!|()\[\],+\-*/~=])"
    r"|(?P<bad>\S))"
)
_VAR_RE = re.compile(r"^(p|x|y|th)(\d+)$")


@dataclass(frozen=True, slots=True)
class _Token:
    kind: str  # number | name | op | end
    text: str
    column: int  # 1-based


def _tokenize(text: str) -> list[_Token]:
    tokens = []
    pos = 0
    while pos < len(text):
        match = _TOKEN_RE.match(text, pos)
        if match is None:  # only trailing whitespace is left
            break
        kind = match.lastgroup
        if kind is None:
            break
        value = match.group(kind)
        column = match.start(kind) + 1
        if kind == "bad":
            raise FormulaSyntaxError(text, column, f"unexpected character {value!r}")
        tokens.append(_Token(kind, value, column))
        pos = match.end()
    tokens.append(_Token("end", "", len(text) + 1))
    return tokens


class _Parser:
    def __init__(self, text: str, robot_ids: frozenset[int] | None):
        self.text = text
        self.tokens = _tokenize(text)
        self.pos = 0
        self.robot_ids = robot_ids

    # ----------------------------------------------------------------- helpers

    @property
    def tok(self) -> _Token:
        return self.tokens[self.pos]

    def fail(self, message: str, token: _Token | None = None) -> FormulaSyntaxError:
        token = token or self.tok
        return FormulaSyntaxError(self.text, token.column, message)

    def found(self, token: _Token | None = None) -> str:
        token = token or self.tok
        return "end of formula" if token.kind == "end" else repr(token.text)

    def expect(self, text: str, what: str) -> _Token:
        token = self.tok
        if token.text != text or token.kind == "end":
            self.reject_outside_fragment()
            raise self.fail(f"expected {what}, found {self.found()}")
        self.pos += 1
        return token

    def reject_outside_fragment(self) -> None:
        token = self.tok
        if token.text in ("|", "||"):
            raise self.fail("'|' (disjunction) is not in the STL fragment of eq. (3a)")
        if token.text in ("&&",):
            raise self.fail("use '&' for conjunction")
        if token.text == "=":
            raise self.fail("expected a comparison (<=, <, >=, >); '=' is not one")

    # ----------------------------------------------------------------- temporal level

    def task(self) -> Temporal:
        token = self.tok
        if token.kind != "name" or token.text not in ("G", "F"):
            raise self.fail(f"expected 'G[a,b]' or 'F[a,b]' at the start of the task, "
                            f"found {self.found()}")
        self.pos += 1
        self.expect("[", f"'[' after {token.text!r}")
        a_token = self.tok
        a = self.number("the window start a")
        self.expect(",", "',' between the window bounds")
        b = self.number("the window end b")
        self.expect("]", "']' closing the time window")
        if not 0 <= a <= b:
            raise self.fail(f"time window [{a:g}, {b:g}] needs 0 <= a <= b", a_token)
        body = self.conj()
        self.reject_outside_fragment()
        if self.tok.kind != "end":
            raise self.fail(f"expected '&' or end of formula, found {self.found()}")
        return Temporal(token.text, a, b, body)

    def number(self, what: str) -> float:
        sign = 1.0
        if self.tok.text == "-":
            sign = -1.0
            self.pos += 1
        token = self.tok
        if token.kind != "number":
            raise self.fail(f"expected a number for {what}, found {self.found()}")
        self.pos += 1
        return sign * float(token.text)

    # ----------------------------------------------------------------- boolean level

    def conj(self) -> Psi:
        items = [self.literal()]
        while self.tok.text == "&":
            self.pos += 1
            items.append(self.literal())
        flat: list[Predicate | Not] = []
        for item in items:
            match item:
                case And(children):
                    flat.extend(children)
                case Top():
                    pass
                case _:
                    flat.append(item)
        if not flat:
            return Top()
        if len(flat) == 1:
            return flat[0]
        return And(tuple(flat))

    def literal(self) -> Psi:
        token = self.tok
        if token.text in ("!", "~"):
            self.pos += 1
            inner = self.literal()
            if not isinstance(inner, Predicate):
                raise self.fail("negation applies to a single predicate (eq. (3a))", token)
            return Not(inner)
        if token.kind == "name" and token.text == "true":
            self.pos += 1
            return Top()
        if token.kind == "name" and token.text in ("G", "F"):
            raise self.fail("nested temporal operators are not in the STL fragment of eq. (3b)")
        if token.text == "(":
            # Either a parenthesised conjunction or a predicate whose lhs starts with '('.
            start = self.pos
            try:
                self.pos += 1
                inner = self.conj()
                self.expect(")", "')' closing the parenthesis")
                if self.tok.text in (*COMPARISONS, "+", "-", "*", "/"):
                    raise self.fail("a comparison of a parenthesised expression")
                return inner
            except FormulaSyntaxError as first:
                self.pos = start
                try:
                    return self.predicate()
                except FormulaSyntaxError as second:
                    raise (first if first.column > second.column else second) from None
        return self.predicate()

    def predicate(self) -> Predicate:
        lhs_token = self.tok
        lhs, lhs_shape = self.expr()
        cmp = self.tok
        if cmp.text not in COMPARISONS:
            self.reject_outside_fragment()
            raise self.fail(f"expected a comparison (<=, <, >=, >) after the expression, "
                            f"found {self.found()}")
        self.pos += 1
        rhs_token = self.tok
        rhs, rhs_shape = self.expr()
        if lhs_shape != "scalar":
            raise self.fail("a comparison needs scalar sides; the left side is a 2-vector "
                            "(use norm or dist)", lhs_token)
        if rhs_shape != "scalar":
            raise self.fail("a comparison needs scalar sides; the right side is a 2-vector "
                            "(use norm or dist)", rhs_token)
        return Predicate(lhs, cmp.text, rhs)

    # ----------------------------------------------------------------- expressions

    def expr(self) -> tuple[Expr, Shape]:
        left, shape = self.term()
        while self.tok.text in ("+", "-"):
            op = self.tok
            self.pos += 1
            right, rshape = self.term()
            if shape != rshape:
                raise self.fail(f"cannot {'add' if op.text == '+' else 'subtract'} a "
                                f"{_shape_name(shape)} and a {_shape_name(rshape)}", op)
            left = BinOp(op.text, left, right)
        return left, shape

    def term(self) -> tuple[Expr, Shape]:
        left, shape = self.unary()
        while self.tok.text in ("*", "/"):
            op = self.tok
            self.pos += 1
            right, rshape = self.unary()
            if op.text == "*" and shape == "vector" and rshape == "vector":
                raise self.fail("cannot multiply two 2-vectors", op)
            if op.text == "/" and rshape == "vector":
                raise self.fail("cannot divide by a 2-vector", op)
            left = BinOp(op.text, left, right)
            shape = "vector" if "vector" in (shape, rshape) else "scalar"
        return left, shape

    def unary(self) -> tuple[Expr, Shape]:
        if self.tok.text == "-":
            self.pos += 1
            arg, shape = self.unary()
            if isinstance(arg, Const):
                return Const(-arg.value), shape
            return Neg(arg), shape
        return self.primary()

    def primary(self) -> tuple[Expr, Shape]:
        token = self.tok
        if token.kind == "number":
            self.pos += 1
            return Const(float(token.text)), "scalar"
        if token.text == "(":
            self.pos += 1
            inner = self.expr()
            self.expect(")", "')' closing the parenthesis")
            return inner
        if token.text == "[":
            self.pos += 1
            x, xs = self.expr()
            self.expect(",", "',' between the vector components")
            y_token = self.tok
            y, ys = self.expr()
            self.expect("]", "']' closing the vector")
            if xs != "scalar":
                raise self.fail("vector components must be scalars", token)
            if ys != "scalar":
                raise self.fail("vector components must be scalars", y_token)
            return VecLit(x, y), "vector"
        if token.kind == "name":
            return self.name()
        raise self.fail(f"expected a number, a robot state (p3, x3, y3, th3), a function or '(', "
                        f"found {self.found()}")

    def name(self) -> tuple[Expr, Shape]:
        token = self.tok
        self.pos += 1
        if token.text == "pi":
            return Const(math.pi), "scalar"
        var = _VAR_RE.match(token.text)
        if var:
            robot = int(var.group(2))
            if self.robot_ids is not None and robot not in self.robot_ids:
                known = ", ".join(str(r) for r in sorted(self.robot_ids))
                raise self.fail(f"robot {robot} is not in the scenario (robots: {known})", token)
            if var.group(1) == "p":
                return Position(robot), "vector"
            return StateVar(robot, var.group(1)), "scalar"
        if token.text in FUNCTIONS:
            return self.call(token)
        if token.text in ("G", "F"):
            raise self.fail("nested temporal operators are not in the STL fragment of eq. (3b)",
                            token)
        if self.tok.text == "(":
            known = ", ".join(FUNCTIONS)
            raise self.fail(f"unknown function {token.text!r} (known: {known})", token)
        raise self.fail(f"unknown name {token.text!r}: expected p<id>, x<id>, y<id>, th<id>, "
                        f"pi or a function", token)

    def call(self, token: _Token) -> tuple[Expr, Shape]:
        func = token.text
        arity, signature = FUNCTIONS[func]
        self.expect("(", f"'(' after {func!r}")
        args: list[Expr] = []
        shapes: list[Shape] = []
        while True:
            arg, shape = self.expr()
            args.append(arg)
            shapes.append(shape)
            if self.tok.text != ",":
                break
            self.pos += 1
        self.expect(")", f"')' closing the arguments of {func!r}")
        if len(args) != arity:
            raise self.fail(f"{func} takes {arity} argument{'s' if arity > 1 else ''} "
                            f"({signature}), got {len(args)}", token)
        if func in ("sin", "cos", "abs", "angdist") and "vector" in shapes:
            raise self.fail(f"{func} expects scalar arguments ({signature})", token)
        if func == "dist" and shapes[0] != shapes[1]:
            raise self.fail(f"dist expects two arguments of the same shape ({signature})", token)
        return Call(func, tuple(args)), "scalar"


def _shape_name(shape: Shape) -> str:
    return "scalar" if shape == "scalar" else "2-vector"


def parse_task(text: str, robot_ids: Iterable[int] | None = None) -> Temporal:
    """Parse one sub-task ``G[a,b] ψ`` / ``F[a,b] ψ``.

    ``robot_ids``: the scenario's robots; a state of any other robot is an error naming it.
    Raises :class:`FormulaSyntaxError` (1-based column, what was expected).
    """
    ids = None if robot_ids is None else frozenset(robot_ids)
    return _Parser(text, ids).task()


@functools.lru_cache(maxsize=512)
def parsed_task(text: str) -> Temporal:
    """:func:`parse_task` without the robot check, once per process and text (trees are
    immutable, so every user shares one): for tasks the scenario loader has already checked."""
    return parse_task(text)


def robot_subtasks(robot: Robot) -> tuple[Temporal, ...]:
    """The STL sub-tasks of ``robot`` as formula trees, in order (:func:`parsed_task`)."""
    return tuple(parsed_task(text) for text in robot.stl)


def parse_psi(text: str, robot_ids: Iterable[int] | None = None) -> Psi:
    """Parse a non-temporal formula ψ (eq. (3a)) on its own."""
    parser = _Parser(text, None if robot_ids is None else frozenset(robot_ids))
    psi = parser.conj()
    parser.reject_outside_fragment()
    if parser.tok.kind != "end":
        raise parser.fail(f"expected '&' or end of formula, found {parser.found()}")
    return psi
