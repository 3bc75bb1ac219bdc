"""Reading Büchi automata in the Hanoi Omega-Automata format, HOA v1 (docs/ltl.md "Tools").

So that a user can plan with an automaton produced by another tool (Spot's ``ltl2tgba``,
``autfilt``, Owl …): ``read_hoa(text)`` returns an :class:`tlfleet.agent.ltl.buchi.Buchi`.

Supported: ``Acceptance: 1 Inf(0)`` (Büchi) or ``0 t`` (all runs accept), state-based or
transition-based marks (transition marks are moved onto a copy of the target state: a run sees
infinitely many marked edges iff it visits infinitely many marked copies), explicit labels
(``[0 & !1 | t]``) or implicit labels (one edge per letter, in valuation order), several
``Start:`` lines, aliases (``Alias: @a 0&1``). Anything else — generalised or parity
acceptance, alternation (``Start: 0&1``) — is refused with a :class:`tlfleet.bus.errors.LtlError`
naming the line. Format: https://adl.github.io/hoaf/
"""

from __future__ import annotations

import re
from pathlib import Path

from tlfleet.agent.ltl import bdd
from tlfleet.agent.ltl.bdd import FALSE, TRUE, Bdd
from tlfleet.agent.ltl.buchi import Buchi
from tlfleet.bus.errors import LtlError


def _fail(source: str, line: int, what: str) -> LtlError:
    return LtlError(f"{source}: line {line}: {what}")


class _Label:
    """Recursive-descent parser of a HOA label expression: ``or := and ('|' and)*`` …"""

    MAX_DEPTH = 256  # nested parentheses a label may have (Spot writes flat sums of cubes)

    def __init__(self, text: str, aliases: dict[str, Bdd], num_ap: int, fail):
        self.tokens = re.findall(r"\d+|@[\w\-.]+|[tf]|[&|!()]|\S", text)
        self.pos = 0
        self.depth = 0
        self.aliases = aliases
        self.num_ap = num_ap
        self.fail = fail

    def parse(self) -> Bdd:
        result = self.disjunction()
        if self.pos != len(self.tokens):
            raise self.fail(f"unexpected {self.tokens[self.pos]!r} in label")
        return result

    def peek(self) -> str | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def disjunction(self) -> Bdd:
        result = self.conjunction()
        while self.peek() == "|":
            self.pos += 1
            result = result | self.conjunction()
        return result

    def conjunction(self) -> Bdd:
        result = self.atom()
        while self.peek() == "&":
            self.pos += 1
            result = result & self.atom()
        return result

    def atom(self) -> Bdd:
        token = self.peek()
        if token is None:
            raise self.fail("label ends early")
        self.pos += 1
        if token == "!":  # a run of negations read in a loop: no recursion per '!'
            negations = 1
            while self.peek() == "!":
                self.pos += 1
                negations += 1
            inner = self.atom()
            return ~inner if negations % 2 else inner
        if token == "(":
            self.depth += 1
            if self.depth > self.MAX_DEPTH:
                raise self.fail(f"label nested more than {self.MAX_DEPTH} parentheses deep")
            inner = self.disjunction()
            if self.peek() != ")":
                raise self.fail("expected ')' in label")
            self.pos += 1
            self.depth -= 1
            return inner
        if token == "t":
            return TRUE
        if token == "f":
            return FALSE
        if token.isdigit():
            i = int(token)
            if i >= self.num_ap:
                raise self.fail(f"AP number {i} out of range (AP: {self.num_ap})")
            return bdd.var(i)
        if token.startswith("@"):
            if token not in self.aliases:
                raise self.fail(f"unknown alias {token}")
            return self.aliases[token]
        raise self.fail(f"unexpected {token!r} in label")


def read_hoa(text: str, source: str = "<hoa>"):
    """The first automaton of ``text`` as a state-based Büchi automaton."""
    lines = text.splitlines()
    if not any(line.strip().startswith("HOA:") for line in lines):
        raise _fail(source, 1, "not a HOA file (no 'HOA: v1' header)")
    header, body_start = _header_lines(lines, source)
    head = _Header(header, source)
    states = _read_body(lines, body_start, head, source)
    if head.declared is not None and not head.declared[1].isdigit():
        raise _fail(source, head.declared[0], f"States: {head.declared[1]!r}")
    if not head.starts:
        raise _fail(source, 1, "no Start: state")
    initial, accepting, edges = _state_based(states, head.starts, head.all_accept)
    name = head.one("name", required=False)
    formula = name[1].strip('"') if name else f"HOA automaton {source}"
    return Buchi(formula, tuple(head.names), initial, accepting, edges)


def _header_lines(lines: list[str], source: str) -> tuple[dict[str, list[tuple[int, str]]], int]:
    """The header's items by name, each ``(line number, value)``, and the line number of
    ``--BODY--``."""
    header: dict[str, list[tuple[int, str]]] = {}
    for number, raw in enumerate(lines, 1):
        line = raw.strip()
        if line == "--BODY--":
            return header, number
        if not line:
            continue
        name, _, value = line.partition(":")
        header.setdefault(name.strip(), []).append((number, value.strip()))
    raise _fail(source, len(lines), "missing --BODY--")


class _Header:
    """What the header says: the atomic propositions (``names``), whether every run accepts
    (``0 t``) or Büchi ``Inf(0)`` applies, the start states, the aliases' guards and the
    ``States:`` line; anything unsupported is refused with its line number."""

    def __init__(self, header: dict[str, list[tuple[int, str]]], source: str):
        self.header = header
        self.source = source
        ap_line, ap_text = self.one("AP")
        ap_tokens = re.findall(r'"((?:[^"\\]|\\.)*)"|(\d+)', ap_text)
        if not ap_tokens:
            raise _fail(source, ap_line, "AP: expected a count and names")
        self.num_ap = int(ap_tokens[0][1])
        self.names = [re.sub(r"\\(.)", r"\1", s) for s, _n in ap_tokens[1:]]
        if len(self.names) != self.num_ap:
            raise _fail(source, ap_line,
                        f"AP: {self.num_ap} announced, {len(self.names)} names given")
        acc_line, acc_text = self.one("Acceptance")
        acceptance = " ".join(acc_text.split())
        if acceptance in ("0 t", "1 t"):
            self.all_accept = True
        elif acceptance == "1 Inf(0)":
            self.all_accept = False
        else:
            raise _fail(source, acc_line, f"acceptance {acc_text!r} is not supported "
                                          "(Büchi 'Acceptance: 1 Inf(0)' only; use autfilt -B)")
        self.starts: list[int] = []
        for number, value in header.get("Start", []):
            if not value.isdigit():
                raise _fail(source, number, f"Start: {value!r} (alternating automata are not "
                                            "supported)")
            self.starts.append(int(value))
        self.aliases: dict[str, Bdd] = {}
        for number, value in header.get("Alias", []):
            alias, _, expression = value.partition(" ")
            self.aliases[alias] = _Label(expression, self.aliases, self.num_ap,
                                         lambda what, n=number: _fail(source, n, what)).parse()
        self.declared = self.one("States", required=False)

    def one(self, name: str, required: bool = True) -> tuple[int, str] | None:
        """The first ``name:`` item; a missing required one is an error."""
        entries = self.header.get(name)
        if not entries:
            if required:
                raise _fail(self.source, 1, f"missing header {name}:")
            return None
        return entries[0]


_StateSpec = dict  # {"acc": state mark 0, "edges": [(dst, guard, edge mark 0), …]}
_Edges = tuple[tuple[tuple[int, Bdd], ...], ...]  # per state, (destination, guard)


def _read_body(lines: list[str], body_start: int, head: _Header, source: str
               ) -> dict[int, _StateSpec]:
    """The body's states: ``State: n ["name"] [{marks}]`` then edges ``[label] dst [{marks}]``
    or implicit ``dst`` (the k-th edge reads the k-th valuation)."""
    states: dict[int, _StateSpec] = {}
    current = None
    implicit_index = 0
    for number in range(body_start + 1, len(lines) + 1):
        line = lines[number - 1].strip()
        if not line:
            continue

        def fail(what: str, n: int = number) -> LtlError:
            return _fail(source, n, what)

        if line == "--END--":
            break
        if line.startswith("State:"):
            m = re.fullmatch(r'State:\s*(?:\[(?P<label>[^\]]*)\]\s*)?(?P<id>\d+)'
                             r'(?:\s*"(?:[^"\\]|\\.)*")?\s*(?:\{(?P<marks>[\d\s]*)\})?', line)
            if not m:
                raise fail(f"cannot read {line!r}")
            if m.group("label"):
                raise fail("state labels are not supported (use transition labels)")
            current = int(m.group("id"))
            marks = set(map(int, (m.group("marks") or "").split()))
            states[current] = {"acc": 0 in marks, "edges": []}
            implicit_index = 0
            continue
        if current is None:
            raise fail("edge before any 'State:'")
        m = re.fullmatch(r'(?:\[(?P<label>[^\]]*)\]\s*)?(?P<dst>\d+(?:\s*&\s*\d+)*)'
                         r'\s*(?:\{(?P<marks>[\d\s]*)\})?', line)
        if not m:
            raise fail(f"cannot read edge {line!r}")
        if "&" in m.group("dst"):
            raise fail("universal branching (alternating automata) is not supported")
        if m.group("label") is not None:
            guard = _Label(m.group("label"), head.aliases, head.num_ap, fail).parse()
        else:  # implicit labels: the k-th edge reads the k-th valuation
            v = implicit_index
            implicit_index += 1
            guard = bdd.cube(v, ((1 << head.num_ap) - 1) & ~v)
        marks = set(map(int, (m.group("marks") or "").split()))
        states[current]["edges"].append((int(m.group("dst")), guard, 0 in marks))
    return states


def _state_based(states: dict[int, _StateSpec], starts: list[int], all_accept: bool
                 ) -> tuple[tuple[int, ...], frozenset[int], _Edges]:
    """``(initial, accepting, edges)`` of the state-based automaton reachable from ``starts``.

    A state copy (q, 1) stands for "entered q by a marked edge"; a state's mark is a mark on
    all its outgoing edges (HOA semantics)."""
    transition_marks = any(m for s in states.values() for _d, _g, m in s["edges"])
    ids: dict[tuple[int, bool], int] = {}
    order: list[tuple[int, bool]] = []

    def intern(key: tuple[int, bool]) -> int:
        if key not in ids:
            ids[key] = len(order)
            order.append(key)
        return ids[key]

    initial = tuple(intern((q, False)) for q in starts)
    edges: list[tuple[tuple[int, Bdd], ...]] = []
    k = 0
    while k < len(order):
        q, _marked = order[k]
        spec = states.get(q, {"acc": False, "edges": []})
        grouped: dict[int, Bdd] = {}
        for dst, guard, mark in spec["edges"]:
            d = intern((dst, transition_marks and (mark or spec["acc"])))
            grouped[d] = grouped.get(d, FALSE) | guard
        edges.append(tuple((d, g) for d, g in grouped.items() if g is not FALSE))
        k += 1
    accepting = frozenset(
        i for i, (q, marked) in enumerate(order)
        if all_accept or marked or (not transition_marks and states.get(q, {}).get("acc"))
    )
    return initial, accepting, tuple(edges)


HOA_TASK_PREFIX = "hoa:"
"""A scenario task ``ltl = { hoa = "file.hoa" }`` is carried as the text ``hoa:<absolute path>``
(``tlfleet.agent.scenario.loader``); :func:`tlfleet.agent.ltl.task.task_automaton` reads the
file."""


def read_hoa_file(path: str | Path):
    """:func:`read_hoa` of a file; unreadable files are an :class:`tlfleet.bus.errors.LtlError`."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise LtlError(f"{path}: cannot read the HOA automaton: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise LtlError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    return read_hoa(text, str(path))
