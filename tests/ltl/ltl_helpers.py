"""Shared test helpers for the LTL core: Hypothesis strategies and independent reference checks.

The reference checks deliberately share no code with the translator or the planner: they use
only the automaton's public data (``initial``, ``accepting``, ``edges`` with truth-table guards)
and networkx.
"""

from __future__ import annotations

import itertools
import math

import networkx as nx
from hypothesis import strategies as st
from tlfleet.agent.ltl import bdd
from tlfleet.agent.ltl.buchi import Buchi
from tlfleet.agent.ltl.formula import (
    FALSE,
    TRUE,
    Atom,
    Equiv,
    Finally,
    Formula,
    Globally,
    Implies,
    Next,
    Not,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
    Xor,
    conj,
    disj,
)
from tlfleet.agent.ltl.transition_system import TransitionSystem

ATOMS = ("a", "b", "c", "d")
UNARY = (Not, Next, Finally, Globally)
BINARY = (Implies, Equiv, Xor, Until, Release, WeakUntil, StrongRelease)


def formulas(atoms: tuple[str, ...] = ATOMS, max_depth: int = 5) -> st.SearchStrategy[Formula]:
    """Random formulas over ``atoms`` with every operator, nesting depth ≤ ``max_depth``,
    shaped as the parser builds them (flattened n-ary ``And``/``Or``)."""
    leaves = st.sampled_from([Atom(a) for a in atoms] + [TRUE, FALSE])

    def extend(children: st.SearchStrategy[Formula]) -> st.SearchStrategy[Formula]:
        return st.one_of(
            st.builds(lambda op, x: op(x), st.sampled_from(UNARY), children),
            st.builds(conj, children, children),
            st.builds(disj, children, children),
            st.builds(lambda op, x, y: op(x, y), st.sampled_from(BINARY), children, children),
        )

    strategy = leaves
    for _ in range(max_depth):
        strategy = st.one_of(leaves, extend(strategy))
    return strategy


def letters(atoms: tuple[str, ...] = ATOMS) -> st.SearchStrategy[frozenset[str]]:
    return st.frozensets(st.sampled_from(atoms))


def lasso_words(atoms: tuple[str, ...] = ATOMS):
    """``(prefix, loop)`` with |prefix| ≤ 3 and 1 ≤ |loop| ≤ 4."""
    return st.tuples(
        st.lists(letters(atoms), max_size=3), st.lists(letters(atoms), min_size=1, max_size=4)
    )


def random_lasso(rng, atoms) -> tuple[list[frozenset[str]], list[frozenset[str]]]:
    """A random lasso word over ``atoms``: a prefix of 0–3 letters and a loop of 1–4, each atom
    in a letter with probability 1/2 (``rng``: a ``random.Random``, drawn in that order)."""
    prefix = [frozenset(a for a in atoms if rng.random() < 0.5) for _ in range(rng.randrange(4))]
    loop = [frozenset(a for a in atoms if rng.random() < 0.5)
            for _ in range(1 + rng.randrange(4))]
    return prefix, loop


def guard_holds(guard, v: int) -> bool:
    """Evaluate a BDD guard on the letter with bitmask ``v`` by walking its nodes (the guard's
    public ``var``/``low``/``high`` fields; independent of the library's evaluation)."""
    node = guard
    while node.low is not None:
        node = node.high if v >> node.var & 1 else node.low
    return node is bdd.TRUE


def automaton_accepts(buchi: Buchi, prefix, loop) -> bool:
    """Does ``buchi`` accept ``prefix · loop^ω``? Product of the automaton with the lasso's
    positions, then an accepting state on a cycle within the loop part (networkx SCCs)."""
    word = [*prefix, *loop]
    n = len(word)
    index = {a: i for i, a in enumerate(buchi.atoms)}

    def valuation(letter) -> int:
        return sum(1 << index[a] for a in letter if a in index)

    graph = nx.DiGraph()
    start = [(q, 0) for q in buchi.initial]
    graph.add_nodes_from(start)
    stack = list(start)
    seen = set(start)
    while stack:
        q, i = stack.pop()
        v = valuation(word[i])
        j = i + 1 if i + 1 < n else len(prefix)
        for dst, guard in buchi.edges[q]:
            if guard_holds(guard, v):
                graph.add_edge((q, i), (dst, j))
                if (dst, j) not in seen:
                    seen.add((dst, j))
                    stack.append((dst, j))
    for component in nx.strongly_connected_components(graph):
        nodes = list(component)
        if len(nodes) == 1 and not graph.has_edge(nodes[0], nodes[0]):
            continue
        if any(q in buchi.accepting for q, _i in nodes):
            return True
    return False


def brute_force_optimum(buchi: Buchi, ts: TransitionSystem, beta: float) -> float:
    """min over accepting product states a of d(init, a) + β·c(a), on the *full* product
    ``|Π|·|Q|`` with networkx all-pairs Dijkstra (no pruning, no SCCs)."""
    graph = nx.DiGraph()
    nodes = list(itertools.product(range(ts.num_states), range(buchi.num_states)))
    graph.add_nodes_from(nodes)
    for r, q in nodes:
        v = sum(1 << buchi.atoms.index(a) for a in ts.labels[r] if a in buchi.atoms)
        for dst, guard in buchi.edges[q]:
            if guard_holds(guard, v):
                for r2, w in ts.edges[r]:
                    if not graph.has_edge((r, q), (r2, dst)) or graph[(r, q)][(r2, dst)][
                        "weight"
                    ] > w:
                        graph.add_edge((r, q), (r2, dst), weight=w)
    dist = dict(nx.all_pairs_dijkstra_path_length(graph))
    best = math.inf
    for q0 in buchi.initial:
        source = (ts.initial, q0)
        for (r, q), d in dist[source].items():
            if q not in buchi.accepting:
                continue
            cycle = min(
                (
                    dist[(r, q)].get(u, math.inf) + data["weight"]
                    for u, _a, data in graph.in_edges((r, q), data=True)
                ),
                default=math.inf,
            )
            best = min(best, d + beta * cycle)
    return best
