"""LTL → state-based Büchi automaton (ltl-planning.md §2; paper §II-A).

``translate(f)`` runs, with no external tool:

1. parsing and simplification into negation normal form (``tlfleet.agent.ltl.rewrite``);
2. the very weak alternating automaton of Gastin & Oddoux (``tlfleet.agent.ltl.alternating``);
3. the transition-based generalised Büchi automaton with GO's simplifications
   (``tlfleet.agent.ltl.tgba``);
4. direct simulation on the TGBA (``tlfleet.agent.ltl.tgba_simulation``), then SCC-aware
   degeneralisation into a state-based Büchi automaton (``tlfleet.agent.ltl.degeneralize``), for the
   two sound markings of the TGBA (lazy/eager, see ``build_tgba``) and both orders of the marks,
   keeping the smaller;
5. removal of useless states (unreachable, or unable to reach an accepting cycle), a
   bisimulation quotient (equal acceptance, equal guarded edges to equal classes), and the
   merging of *transient* states (on no cycle, so visited at most once and their acceptance
   is irrelevant) into a state with the same outgoing edges; direct-simulation rounds
   (``tlfleet.agent.ltl.simulation``); on small automata, the removal of states that fair simulation
   proves unnecessary, each removal checked by a fair-simulation game
   (``tlfleet.agent.ltl.fair_simulation``);
6. for obligation formulas, the minimal weak DBA when it is smaller and provably equivalent
   (``tlfleet.agent.ltl.wdba``).

The result ``A = (Q, 2^AP, Δ, Q0, F)`` has states ``0..num_states-1``; ``edges[q]`` lists
``(q', guard)`` with guards over ``atoms`` (see ``tlfleet.agent.ltl.guards``).
"""

from __future__ import annotations

import gc
from collections import deque
from collections.abc import Iterable
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property

from tlfleet.agent.ltl.bdd import TRUE, disjoin
from tlfleet.agent.ltl.branching import postpone_branching
from tlfleet.agent.ltl.degeneralize import degeneralize, mark_order_matters
from tlfleet.agent.ltl.fair_simulation import remove_fair_little_brothers
from tlfleet.agent.ltl.formula import Atom, Formula, Not, children, recursion_headroom
from tlfleet.agent.ltl.graphs import nontrivial, reachable, strongly_connected_components
from tlfleet.agent.ltl.guards import MAX_ATOMS, Alphabet, Guard, TooManyPropositions, valuation
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.printer import to_string
from tlfleet.agent.ltl.recurrence import (
    MIN_RECURRENCES,
    TRIVIAL,
    propositional_guard,
    round_robin,
    split_recurrences,
)
from tlfleet.agent.ltl.rewrite import normalize
from tlfleet.agent.ltl.simulation import (
    is_deterministic,
    reduce_by_simulation,
    saturate_acceptance,
    single_initial,
)
from tlfleet.agent.ltl.tgba import build_tgba
from tlfleet.agent.ltl.tgba_simulation import reduce_tgba
from tlfleet.agent.ltl.wdba import accepts_constant, minimize_obligation

Edge = tuple[int, Guard]
REVERSED_DEGEN_MAX_STATES = 32
REVERSED_DEGEN_MAX_MARKS = 4
REVERSED_DEGEN_MAX_EDGES = 256
"""Largest TGBA (states, acceptance marks, edges) also degeneralised with the marks in reverse
order: the second order pays on small automata with few marks (the patterns of Spot's table);
on large ones it doubles the cost of degeneralisation for, in our measurements, no state."""
WDBA_MAX_INPUT = 40
"""Largest reduced automaton (states) for which the minimal weak DBA is tried."""
WDBA_MAX_STATES = 64
"""Largest subset construction (states) the weak-DBA minimisation builds."""


@dataclass(frozen=True)
class Buchi:
    """A state-based Büchi automaton with guarded edges (paper §II-A).

    ``formula`` is the text it was translated from, ``atoms`` the AP in guard-bit order.
    A letter (set of atom names) ``σ`` enables edge ``(q', g)`` of ``q`` iff ``g`` holds on σ;
    atoms outside ``atoms`` are ignored.
    """

    formula: str
    atoms: tuple[str, ...]
    initial: tuple[int, ...]
    accepting: frozenset[int]
    edges: tuple[tuple[Edge, ...], ...]

    # derived from ``atoms``, computed on first use and kept in the instance's __dict__ (not
    # fields: they take no part in equality, hashing or repr)
    @cached_property
    def index(self) -> dict[str, int]:
        """Guard bit of every atom."""
        return {a: i for i, a in enumerate(self.atoms)}

    @cached_property
    def alphabet(self) -> Alphabet:
        """The letters over ``atoms`` (guard operations)."""
        return Alphabet(len(self.atoms))

    @property
    def num_states(self) -> int:
        return len(self.edges)

    @property
    def num_edges(self) -> int:
        return sum(len(out) for out in self.edges)

    def valuation(self, letter: Iterable[str]) -> int:
        """Bitmask of a letter over ``atoms``."""
        return valuation(letter, self.index)

    def successors(self, state: int, letter: Iterable[str]) -> tuple[int, ...]:
        """Δ(state, letter)."""
        return self.successors_by_valuation(state, self.valuation(letter))

    def successors_by_valuation(self, state: int, v: int) -> tuple[int, ...]:
        return tuple(dst for dst, guard in self.edges[state] if guard.holds(v))

    def guard_text(self, guard: Guard) -> str:
        return self.alphabet.to_string(guard, self.atoms)


def buchi_step(buchi: Buchi, states: frozenset[int], label: Iterable[str]) -> frozenset[int]:
    """The Büchi states reachable from ``states`` by reading one letter ``label``.

    The LTL agent tracks its automaton state with this: starting from ``buchi.initial``, call it
    with the label of the region the robot is *leaving* (the product reads the source label,
    ltl-planning.md §4). An empty result means the executed path already violates the task.
    """
    v = buchi.valuation(label)
    return frozenset(dst for q in states for dst, guard in buchi.edges[q]
                     if guard.holds(v))


def buchi_stutter_step(buchi: Buchi, states: frozenset[int], label: Iterable[str]
                       ) -> frozenset[int]:
    """The Büchi states reachable from ``states`` by reading the letter ``label`` once or more
    (``buchi_step`` to a fixpoint): the states consistent with a robot that stayed in a region
    for a while, the way the run's word reads a region (docs/ltl-navigation.md §1). For
    stutter-invariant (X-free) tasks, reading a letter once more changes no acceptance."""
    reached = buchi_step(buchi, states, label)
    frontier = reached
    while frontier:
        frontier = buchi_step(buchi, frontier, label) - reached
        reached = reached | frontier
    return reached


def _atoms_in_order(f: Formula) -> tuple[str, ...]:
    """Atoms by first occurrence (as Spot numbers them)."""
    order: dict[str, None] = {}
    stack = [f]
    while stack:
        g = stack.pop()
        if isinstance(g, Atom):
            order.setdefault(g.name, None)
        stack.extend(reversed(children(g)))
    return tuple(order)


def translate(formula: Formula | str) -> Buchi:
    """Translate an LTL formula (tree or Spot-syntax text) into a small state-based Büchi automaton.

    Raises :class:`tlfleet.bus.errors.FormulaSyntaxError` for text that does not parse. (A
    scenario's task may also name an HOA file: :func:`tlfleet.agent.ltl.task.task_automaton` tells
    them apart.)
    """
    with recursion_headroom(), _collector_paused():
        candidates = translation_candidates(formula, only_best=True)
    return min(candidates, key=lambda b: (b.num_states, b.num_edges))


@contextmanager
def _collector_paused():
    """Python's cyclic garbage collector off while one formula is translated.

    The translation allocates many short-lived lists and tuples, which trigger collections,
    and each full one walks every object alive — the BDD nodes and caches included — costing
    up to ~20 ms on a slow formula (measured with ``gc.callbacks``). Its data are acyclic (BDD
    nodes and formulas are DAGs), so reference counting frees them as before; a cycle, if
    any, is collected after. Re-enabled only if it was enabled."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def translation_candidates(formula: Formula | str, only_best: bool = False, *,
                           index: dict[str, int] | None = None) -> list[Buchi]:
    """Equivalent automata of ``formula``: the smallest of the TGBA variants (the one or two
    markings of ``build_tgba``, each also with postponed branching, ``tlfleet.agent.ltl.branching``,
    when it has several initial states)
    fully reduced by simulation, first; then every variant with the cheap reductions only.

    All are equivalent to the formula; :func:`translate` keeps the smallest (and asks for
    ``only_best``, the first). Exposed so tests can check every candidate, not only the one
    that happens to win.
    """
    tree = parse(formula) if isinstance(formula, str) else formula
    if index is None:
        atoms = _atoms_in_order(tree)
        if len(atoms) > MAX_ATOMS:
            raise TooManyPropositions(len(atoms))
        index = {a: i for i, a in enumerate(atoms)}
    else:  # a part of a larger formula: its guards over the whole formula's atoms
        atoms = tuple(sorted(index, key=index.__getitem__))
    text = to_string(tree)
    rest, recurrences = split_recurrences(normalize(tree))
    if len(recurrences) >= MIN_RECURRENCES:  # G F φ_1 ∧ … ∧ G F φ_n: linear, not 2^n edges
        base = TRIVIAL if rest is None else _as_tuple(
            translation_candidates(rest, only_best=True, index=index)[0])
        aut = round_robin(base, [propositional_guard(phi, index) for phi in recurrences])
        return [_renumbered(text, atoms, *_cheap_reduce(_remove_useless(*aut))[1:])]
    variants = [reduce_tgba(tgba, len(atoms)) for tgba in build_tgba(normalize(tree), index)]
    for tgba in list(variants):
        # Several initial states (a disjunction at the top): merge the choice into one state.
        if len(tgba.initial) > 1 and tgba.num_states <= 32:
            merged = postpone_branching(tgba, limit=2 * tgba.num_states + 4)
            if merged is not None:
                variants.append(merged)
    cheap = [_cheap_reduce(_remove_useless(*degeneralize(tgba))) for tgba in variants]
    best = min(cheap, key=lambda aut: (aut[0], sum(len(out) for out in aut[3])))
    # Degeneralisation and the cheap reductions keep a deterministic TGBA deterministic.
    deterministic = variants[cheap.index(best)].deterministic
    # The other order of the marks (Spot's degen-order); kept only when it saves states.
    for tgba in variants:
        if (1 < tgba.num_marks <= REVERSED_DEGEN_MAX_MARKS
                and tgba.num_states <= REVERSED_DEGEN_MAX_STATES
                and sum(len(out) for out in tgba.edges) <= REVERSED_DEGEN_MAX_EDGES
                and mark_order_matters(tgba)):
            other = _cheap_reduce(_remove_useless(*degeneralize(tgba, reverse=True)))
            cheap.append(other)
            if other[0] < best[0]:
                best, deterministic = other, tgba.deterministic
    full = _reduce(best, len(atoms), deterministic)
    if len(full[1]) > 1:  # one initial state, when that costs no state
        single = _reduce(_cheap_reduce(_remove_useless(*single_initial(*full))), len(atoms))
        if single[0] <= full[0]:
            full, deterministic = single, False
    lighter = remove_fair_little_brothers(full)  # states that fair simulation proves useless
    if lighter is not None:
        lighter = _reduce(_cheap_reduce(_remove_useless(*lighter)), len(atoms))
        if lighter[0] < full[0]:
            full, deterministic = lighter, False
    negated: list = []  # the negation's automaton, built at most once (weak DBA, validity)

    def negation():
        if not negated:
            negated.append(_remove_useless(*degeneralize(
                build_tgba(normalize(Not(tree)), index)[0])))
        return negated[0]

    if 2 < full[0] <= WDBA_MAX_INPUT:  # obligation formulas: the minimal weak DBA, if smaller
        wdba = minimize_obligation(full, negation, max_states=WDBA_MAX_STATES,
                                   deterministic=deterministic)
        if wdba is not None:
            full = _merge_transient(*_remove_useless(*wdba))
    result = [_renumbered(text, atoms, *aut[1:])
              for aut in ((full,) if only_best else (full, *cheap))]
    if 1 < min(b.num_states for b in result) <= 8 and _is_valid(result[0], negation):
        return [Buchi(text, atoms, (0,), frozenset({0}), (((0, TRUE),),))]
    return result


def _as_tuple(buchi: Buchi):
    return (buchi.num_states, buchi.initial, buchi.accepting,
            [list(out) for out in buchi.edges])


def _is_valid(buchi: Buchi, negation) -> bool:
    """Whether every word satisfies the formula (``negation()``, its negation's automaton, is
    empty). Only tried for small automata (≤ 8 states) whose initial state reads every letter,
    a necessary condition, so that it costs little."""
    if disjoin(g for q in buchi.initial for _d, g in buchi.edges[q]) is not TRUE:
        return False
    n = len(buchi.atoms)
    for v in (0, (1 << n) - 1):  # a constant word the automaton rejects: not valid
        if not accepts_constant((buchi.num_states, buchi.initial, buchi.accepting,
                                 buchi.edges), v):
            return False
    return negation()[0] == 0


def _cheap_reduce(aut):
    """Acceptance saturation, bisimulation quotient, transient-state merging."""
    return _merge_transient(*_merge_bisimilar(*saturate_acceptance(*aut)))


def _reduce(aut, atoms: int | None = None, deterministic: bool = False):
    """Direct-simulation rounds, then transient-state merging (after :func:`_cheap_reduce`).

    A deterministic automaton is returned as it is: simulation has nothing to prune there, and
    :func:`_cheap_reduce` already removed what the other two steps would. ``deterministic``:
    known to be (else checked)."""
    if deterministic or is_deterministic(aut[1], aut[3]):
        return aut
    for _round in range(3):
        before = (aut[0], sum(len(out) for out in aut[3]))
        aut = _remove_useless(*reduce_by_simulation(*aut, atoms=atoms))
        if (aut[0], sum(len(out) for out in aut[3])) == before:
            break
    return _merge_transient(*aut)


def _remove_useless(n, initial, accepting, edges):
    """Keep states reachable from ``initial`` that can reach an accepting cycle."""
    succ = [[dst for dst, _g in out] for out in edges]
    comp, components = strongly_connected_components(n, succ)
    cyclic = nontrivial(comp, components, succ)
    good = {
        s
        for c, members in enumerate(components)
        if cyclic[c] and any(s in accepting for s in members)
        for s in members
    }
    pred: list[list[int]] = [[] for _ in range(n)]
    for s in range(n):
        for dst in succ[s]:
            pred[dst].append(s)
    live = reachable(good, pred) & reachable(initial, succ)
    if live == set(range(n)):
        return n, initial, accepting, edges
    new_id = {s: i for i, s in enumerate(sorted(live))}
    new_edges = [
        [(new_id[dst], g) for dst, g in edges[s] if dst in new_id] for s in sorted(live)
    ]
    return (
        len(new_id),
        tuple(new_id[s] for s in initial if s in new_id),
        frozenset(new_id[s] for s in accepting if s in new_id),
        new_edges,
    )


def _merge_bisimilar(n, initial, accepting, edges):
    """Quotient by the coarsest bisimulation that respects acceptance and guards."""
    if n == 0:
        return n, initial, accepting, edges
    flags = {flag: i for i, flag in enumerate(dict.fromkeys(s in accepting for s in range(n)))}
    block = [flags[s in accepting] for s in range(n)]  # numbered 0..k-1
    num_blocks = len(flags)
    while True:
        signatures: dict[tuple, int] = {}
        new_block = []
        for s in range(n):
            grouped: dict[int, Guard] = {}
            for dst, guard in edges[s]:
                b = block[dst]
                old = grouped.get(b)
                grouped[b] = guard if old is None else old | guard
            sig = (block[s], frozenset(grouped.items()))
            new_block.append(signatures.setdefault(sig, len(signatures)))
        if len(signatures) == n:  # every state apart: nothing left to refine or merge
            return n, initial, accepting, edges
        if len(signatures) == num_blocks:
            break
        block, num_blocks = new_block, len(signatures)
    merged: list[dict[int, Guard] | None] = [None] * num_blocks
    for s in range(n):
        if merged[block[s]] is None:
            grouped = {}
            for dst, guard in edges[s]:
                b = block[dst]
                old = grouped.get(b)
                grouped[b] = guard if old is None else old | guard
            merged[block[s]] = grouped
    new_edges = [list(grouped.items()) for grouped in merged]
    return (
        num_blocks,
        tuple(dict.fromkeys(block[s] for s in initial)),
        frozenset(block[s] for s in accepting),
        new_edges,
    )


def _merge_transient(n, initial, accepting, edges):
    """Redirect every transient state onto a state with identical outgoing edges.

    A transient state lies on no cycle, so no run visits it twice and its acceptance does not
    matter; if another state has the same successors and guards, the two accept the same
    words from there on. No cycle is created: a predecessor of the transient state that could
    be reached again from the shared successors would put the transient state on a cycle.
    """
    alive = set(range(n))
    target = list(range(n))
    while True:
        succ = [[dst for dst, _g in edges[s]] for s in range(n)]
        comp, components = strongly_connected_components(n, succ)
        cyclic = nontrivial(comp, components, succ)
        by_signature: dict[frozenset, int] = {}
        merged = False
        # Prefer keeping states on cycles: visit them first.
        for s in sorted(alive, key=lambda s: (not cyclic[comp[s]], s)):
            signature = frozenset(edges[s])
            keep = by_signature.get(signature)
            if keep is None:
                by_signature[signature] = s
            elif not cyclic[comp[s]]:
                target[s] = keep
                alive.discard(s)
                merged = True
        if not merged:
            break

        def find(s: int) -> int:
            while target[s] != s:
                s = target[s]
            return s

        new_edges = []
        for s in range(n):
            grouped: dict[int, Guard] = {}
            for dst, guard in edges[s]:
                d = find(dst)
                old = grouped.get(d)
                grouped[d] = guard if old is None else old | guard
            new_edges.append(sorted(grouped.items()))
        edges = new_edges
        initial = tuple(dict.fromkeys(find(s) for s in initial))
    keep = sorted(alive)
    new_id = {s: i for i, s in enumerate(keep)}
    return (
        len(keep),
        tuple(new_id[s] for s in initial),
        frozenset(new_id[s] for s in accepting if s in new_id),
        [[(new_id[d], g) for d, g in edges[s]] for s in keep],
    )


def _renumbered(text, atoms, initial, accepting, edges) -> Buchi:
    """Number states in BFS order from the initial states; empty language → one dead state."""
    if not initial:
        return Buchi(text, atoms, (0,), frozenset(), ((),))
    order: dict[int, int] = {}
    queue = deque()
    for s in initial:
        if s not in order:
            order[s] = len(order)
            queue.append(s)
    while queue:
        s = queue.popleft()
        for dst, _g in sorted(edges[s], key=lambda e: e[0]):
            if dst not in order:
                order[dst] = len(order)
                queue.append(dst)
    new_edges: list[tuple[Edge, ...]] = [()] * len(order)
    for s, i in order.items():
        new_edges[i] = tuple(sorted(((order[d], g) for d, g in edges[s]), key=lambda e: e[0]))
    return Buchi(
        text,
        atoms,
        tuple(order[s] for s in initial),
        frozenset(order[s] for s in accepting if s in order),
        tuple(new_edges),
    )


def to_text(buchi: Buchi) -> str:
    """Human-readable listing: one line per state, then its guarded edges."""
    lines = [
        f"Büchi automaton for {buchi.formula}",
        f"  {buchi.num_states} states, {buchi.num_edges} edges, atoms: {', '.join(buchi.atoms)}",
    ]
    alphabet = buchi.alphabet
    for q, out in enumerate(buchi.edges):
        flags = []
        if q in buchi.initial:
            flags.append("initial")
        if q in buchi.accepting:
            flags.append("accepting")
        lines.append(f"state {q}" + (f" ({', '.join(flags)})" if flags else ""))
        for dst, guard in out:
            lines.append(f"  --[{alphabet.to_string(guard, buchi.atoms)}]--> {dst}")
    return "\n".join(lines) + "\n"


def to_dot(buchi: Buchi, name: str = "buchi") -> str:
    """Graphviz rendering: accepting states double-circled, initial states with an arrow in."""
    lines = [f'digraph "{name}" {{', "  rankdir=LR;", '  node [shape=circle];']
    lines.append(f'  label="{_dot_escape(buchi.formula)}"; labelloc=t;')
    for q in range(buchi.num_states):
        shape = "doublecircle" if q in buchi.accepting else "circle"
        lines.append(f'  {q} [shape={shape}];')
    for i, q in enumerate(buchi.initial):
        lines.append(f'  init{i} [shape=point]; init{i} -> {q};')
    alphabet = buchi.alphabet
    for q, out in enumerate(buchi.edges):
        for dst, guard in out:
            label = _dot_escape(alphabet.to_string(guard, buchi.atoms))
            lines.append(f'  {q} -> {dst} [label="{label}"];')
    lines.append("}")
    return "\n".join(lines) + "\n"


def _dot_escape(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"')
