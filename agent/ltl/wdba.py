"""Minimal weak deterministic Büchi automata for obligation formulas (ltl-planning.md §2, "Small").

Dax, Eisinger & Klaedtke (ATVA 2007), "Mechanizing the powerset construction for restricted
classes of ω-automata", as Spot's ``minimize_obligation`` uses it:

1. the subset construction ``D`` of a Büchi automaton ``A`` (letters grouped by the successor
   set they lead to, so the cost follows the guards, not the 2ⁿ letters);
2. each cyclic SCC of ``D`` is marked accepting iff one of its cycles, read from one of its
   subsets, is accepted by ``A`` — for an obligation language all cycles of an SCC agree;
3. Löding's colouring (IPL 2001) makes the acceptance of equivalent states equal, then Moore's
   partition refinement quotients ``D`` into the minimal weak DBA ``M``;
4. **the check**: ``M`` is kept only if ``L(M) = L(A)``, decided exactly: ``A ⊗ ¬M`` and
   ``M ⊗ B`` are empty, where ``¬M`` is ``M`` completed with its acceptance flipped per SCC (``M``
   is weak and deterministic) and ``B`` is an automaton of the negated formula. When the
   formula is not an obligation the check fails and ``A`` is kept.

Automata are the translator's tuples ``(n, initial, accepting, edges)`` with
``edges[q] = [(q', guard), …]`` and BDD guards (``tlfleet.agent.ltl.bdd``). Every step is bounded
(``max_states``, letter classes); ``None`` means "not applicable or not smaller".
"""

from __future__ import annotations

import random
from collections import deque

from tlfleet.agent.ltl.bdd import FALSE, TRUE, Bdd, pick_valuation
from tlfleet.agent.ltl.graphs import nontrivial, reachable, strongly_connected_components

MAX_CLASSES = 256
"""Letter classes per subset before the construction gives up."""


def _grouped(edges_of_q) -> dict[int, Bdd]:
    grouped: dict[int, Bdd] = {}
    for dst, guard in edges_of_q:
        old = grouped.get(dst)
        grouped[dst] = guard if old is None else old | guard
    return grouped


def powerset(n, initial, edges, max_states: int, deterministic: bool = False):
    """Subset construction of a guarded automaton (empty subset left out: it rejects all).

    Returns ``(subsets, det_edges)`` with ``det_edges[i] = [(j, guard), …]`` (disjoint guards),
    or ``None`` beyond ``max_states`` subsets or :data:`MAX_CLASSES` letter classes.
    ``deterministic``: the automaton is known to be (else checked).
    """
    by_state = [_grouped(edges[q]) for q in range(n)]
    if len(initial) == 1 and (deterministic or all(_disjoint(out.values()) for out in by_state)):
        return _singletons(initial[0], by_state, max_states)
    start = frozenset(initial)
    ids = {start: 0}
    subsets = [start]
    det_edges: list[list[tuple[int, Bdd]]] = []
    queue = deque([start])
    while queue:
        subset = queue.popleft()
        classes: list[tuple[Bdd, frozenset[int]]] = [(TRUE, frozenset())]
        into: dict[int, Bdd] = {}  # letters leading from the subset to each state
        for q in subset:
            for dst, guard in by_state[q].items():
                into[dst] = into.get(dst, FALSE) | guard
        for dst, guard in into.items():
            refined = []
            for letters, targets in classes:
                inside = letters & guard
                if inside is letters:
                    refined.append((letters, targets | {dst}))
                elif inside is not FALSE:
                    refined.append((inside, targets | {dst}))
                    refined.append((letters - guard, targets))
                else:
                    refined.append((letters, targets))
            classes = refined
            if len(classes) > MAX_CLASSES:
                return None
        merged: dict[frozenset[int], Bdd] = {}
        for letters, targets in classes:
            if targets:
                merged[targets] = merged.get(targets, FALSE) | letters
        out = []
        for targets, letters in merged.items():
            j = ids.get(targets)
            if j is None:
                if len(subsets) >= max_states:
                    return None
                j = ids[targets] = len(subsets)
                subsets.append(targets)
                queue.append(targets)
            out.append((j, letters))
        det_edges.append(out)
    return subsets, det_edges


def _disjoint(guards) -> bool:
    seen = FALSE
    for guard in guards:
        if guard & seen is not FALSE:
            return False
        seen = seen | guard
    return True


def _singletons(start: int, by_state, max_states: int):
    """The subset construction of a deterministic automaton: its reachable part."""
    ids = {start: 0}
    order = [start]
    det_edges = []
    k = 0
    while k < len(order):
        out = []
        for dst, guard in by_state[order[k]].items():
            j = ids.get(dst)
            if j is None:
                if len(order) >= max_states:
                    return None
                j = ids[dst] = len(order)
                order.append(dst)
            out.append((j, guard))
        det_edges.append(out)
        k += 1
    return [frozenset((q,)) for q in order], det_edges


def _intern(node, ids: dict, nodes: list) -> int:
    """The number of ``node`` in an exploration (``ids`` numbers, ``nodes`` in order), adding
    it at the end when new: the caller's loop visits ``nodes`` up to its growing end."""
    j = ids.get(node)
    if j is None:
        j = ids[node] = len(nodes)
        nodes.append(node)
    return j


def _accepts_cycle(subset, letters: list[int], accepting, edges) -> bool:
    """Whether ``A`` has an accepting run on ``letters^ω`` from some state of ``subset``."""
    length = len(letters)
    start = [(q, 0) for q in subset]
    ids = {s: i for i, s in enumerate(start)}
    nodes = list(start)
    succ: list[list[int]] = []
    k = 0
    while k < len(nodes):
        q, i = nodes[k]
        v = letters[i]
        out = []
        for dst, guard in edges[q]:
            if guard.holds(v):
                out.append(_intern((dst, (i + 1) % length), ids, nodes))
        succ.append(out)
        k += 1
    comp, components = strongly_connected_components(len(nodes), succ)
    cyclic = nontrivial(comp, components, succ)
    return any(cyclic[c] and any(nodes[s][0] in accepting for s in members)
               for c, members in enumerate(components))


def _cycle_through(state: int, members: set[int], det_edges) -> list[int] | None:
    """Letters (valuations) of a cycle from ``state`` back to it inside ``members``."""
    parent: dict[int, tuple[int, Bdd]] = {}
    queue = deque([state])
    while queue:
        s = queue.popleft()
        for dst, guard in det_edges[s]:
            if dst not in members:
                continue
            if dst == state:
                path = [guard]
                while s != state:
                    s, g = parent[s]
                    path.append(g)
                path.reverse()
                return [pick_valuation(g) for g in path]
            if dst not in parent:
                parent[dst] = (s, guard)
                queue.append(dst)
    return None


def minimize_obligation(aut, negation_aut, max_states: int = 64, deterministic: bool = False):
    """The minimal weak DBA equivalent to ``aut``, if the check proves it equivalent and it has
    fewer states; else ``None``. ``negation_aut`` is a callable returning a Büchi automaton
    (same tuple shape and atoms) of the negated formula; it is called only when needed.
    ``deterministic``: ``aut`` is known to be deterministic (else checked)."""
    n, initial, accepting, edges = aut
    if deterministic and len(initial) == 1:
        # Its subset construction is itself (renumbered) when every state is reachable, and
        # the colouring does not depend on the numbering: when it agrees with the acceptance,
        # Moore's quotient is the bisimulation quotient ``aut`` already is. Decided here
        # without building the subset construction.
        succ = [[d for d, _g in out] for out in edges]
        if len(reachable(initial, succ)) == n and _loding_final(
                n, succ, lambda members: any(s in accepting for s in members)) == accepting:
            return None
    built = powerset(n, initial, edges, max_states, deterministic)
    if built is None:
        return None
    subsets, det_edges = built
    m = len(subsets)
    deterministic = all(len(subset) == 1 for subset in subsets)
    succ = [[d for d, _g in out] for out in det_edges]

    def cycle_accepts(members: list[int]) -> bool:
        if deterministic:  # D is A: the SCC's cycles accept iff it holds an accepting state
            return any(next(iter(subsets[s])) in accepting for s in members)
        letters = _cycle_through(members[0], set(members), det_edges)
        return letters is not None and _accepts_cycle(
            subsets[members[0]], letters, accepting, edges)

    final = _loding_final(m, succ, cycle_accepts)
    if deterministic and m == n and all((s in final) == (next(iter(subsets[s])) in accepting)
                                        for s in range(m)):
        return None  # Moore's quotient would be the bisimulation quotient ``aut`` already is
    quotient = _moore(m, final, det_edges)
    if quotient[0] >= n:
        return None
    if not _is_weak(quotient) or _differ_on_a_constant_word(aut, quotient):
        return None  # the cheap refutation first: it spares translating the negation
    if not _equivalent(aut, quotient, negation_aut):
        return None
    return quotient


def _loding_final(m: int, succ, cycle_accepts) -> frozenset[int]:
    """Löding's colouring of a deterministic automaton's SCCs, sinks first (Tarjan's order):
    a cyclic SCC takes the largest colour ≤ its successors' least, even iff its cycles
    accept (``cycle_accepts(members)``); a transient one its successors' least. Returns the
    states of even colour (accepting in the minimal weak automaton)."""
    comp, components = strongly_connected_components(m, succ)
    cyclic = nontrivial(comp, components, succ)
    k = 2 * len(components) + 2
    colour = [0] * len(components)
    for c, members in enumerate(components):
        lowest = k
        for s in members:
            for d in succ[s]:
                if comp[d] != c and colour[comp[d]] < lowest:
                    lowest = colour[comp[d]]
        if not cyclic[c]:
            colour[c] = lowest if lowest < k else k - 1
        elif cycle_accepts(members):
            colour[c] = lowest & ~1
        else:
            colour[c] = (lowest - 1) | 1
    return frozenset(s for s in range(m) if colour[comp[s]] % 2 == 0)


def _differ_on_a_constant_word(a, b, max_letters: int = 16) -> bool:
    """Whether ``a`` and ``b`` disagree on some word ``σ^ω`` (every letter ``σ`` when there
    are at most ``max_letters``, else the empty and the full letter)."""
    support = 0
    for aut in (a, b):
        for out in aut[3]:
            for _d, g in out:
                support |= g.support()
    bits = [i for i in range(support.bit_length()) if support >> i & 1]
    if 1 << len(bits) <= max_letters:
        letters = [sum(1 << bits[i] for i in range(len(bits)) if k >> i & 1)
                   for k in range(1 << len(bits))]
    else:
        letters = [0, support]
    if any(accepts_constant(a, v) != accepts_constant(b, v) for v in letters):
        return True
    # A few lassos u·v^ω with short random u, v (a fixed seed: the same on every run).
    rng = random.Random(len(bits))
    for _ in range(RANDOM_LASSOS):
        prefix = [rng.choice(letters) for _ in range(rng.randrange(3))]
        loop = [rng.choice(letters) for _ in range(1 + rng.randrange(3))]
        if accepts_lasso(a, prefix, loop) != accepts_lasso(b, prefix, loop):
            return True
    return False


RANDOM_LASSOS = 12
"""Random lasso words tried before the exact check (which translates the negated formula)."""


def accepts_constant(aut, v: int) -> bool:
    """Whether the automaton tuple accepts ``σ^ω`` for the letter with bitmask ``v``."""
    n, initial, accepting, edges = aut
    succ = [[d for d, g in out if g.holds(v)] for out in edges]
    live = reachable(initial, succ)
    comp, components = strongly_connected_components(n, succ)
    cyclic = nontrivial(comp, components, succ)
    return any(cyclic[comp[q]] for q in accepting if q in live)


def accepts_lasso(aut, prefix: list[int], loop: list[int]) -> bool:
    """Whether the automaton tuple accepts ``prefix · loop^ω`` (letters as bitmasks)."""
    _n, initial, accepting, edges = aut
    current = set(initial)
    for v in prefix:
        current = {d for q in current for d, g in edges[q] if g.holds(v)}
        if not current:
            return False
    return _accepts_cycle(current, loop, accepting, edges)


def _moore(m, final, det_edges):
    """Moore's partition refinement of a deterministic automaton (final / non-final)."""
    block = [1 if s in final else 0 for s in range(m)]
    count = len(set(block))
    while True:
        signatures: dict[tuple, int] = {}
        new_block = []
        for s in range(m):
            grouped: dict[int, Bdd] = {}
            for dst, guard in det_edges[s]:
                b = block[dst]
                old = grouped.get(b)
                grouped[b] = guard if old is None else old | guard
            sig = (block[s], frozenset(grouped.items()))
            new_block.append(signatures.setdefault(sig, len(signatures)))
        block = new_block
        stable = len(signatures) == count
        count = len(signatures)
        if stable or count == m:  # every state apart is stable too
            break
    edges: list[list[tuple[int, Bdd]] | None] = [None] * count
    for s in range(m):
        if edges[block[s]] is None:
            grouped = {}
            for dst, guard in det_edges[s]:
                b = block[dst]
                old = grouped.get(b)
                grouped[b] = guard if old is None else old | guard
            edges[block[s]] = sorted(grouped.items(), key=lambda e: e[0])
    return count, (block[0],), frozenset(block[s] for s in final), edges


def _is_weak(aut) -> bool:
    """Every cyclic SCC wholly accepting or wholly rejecting."""
    n, _initial, accepting, edges = aut
    succ = [[d for d, _g in out] for out in edges]
    comp, components = strongly_connected_components(n, succ)
    cyclic = nontrivial(comp, components, succ)
    return all(not cyclic[c] or len({s in accepting for s in members}) == 1
               for c, members in enumerate(components))


def _complement_weak(aut):
    """Complement of a weak deterministic Büchi automaton: completed with a sink, acceptance
    flipped on every cyclic SCC (transient states' acceptance is irrelevant)."""
    n, initial, accepting, edges = aut
    sink = n
    new_edges = []
    for out in edges:
        covered = FALSE
        for _d, g in out:
            covered = covered | g
        rest = ~covered
        new_edges.append(list(out) + ([(sink, rest)] if rest is not FALSE else []))
    new_edges.append([(sink, TRUE)])
    flipped = frozenset(s for s in range(n + 1) if s not in accepting)
    return n + 1, initial, flipped, new_edges


def _product_empty(left, right) -> bool:
    """Whether no word is accepted by both Büchi automata, ``right`` weak (so on a cycle of the
    product the right component stays in one SCC and its acceptance is constant)."""
    _n1, init1, acc1, edges1 = left
    _n2, init2, acc2, edges2 = right
    nodes = [(p, q) for p in init1 for q in init2]
    ids = {s: i for i, s in enumerate(nodes)}
    succ: list[list[int]] = []
    k = 0
    while k < len(nodes):
        p, q = nodes[k]
        out = []
        for d1, g1 in edges1[p]:
            for d2, g2 in edges2[q]:
                if (g1 & g2) is FALSE:
                    continue
                out.append(_intern((d1, d2), ids, nodes))
        succ.append(out)
        k += 1
    comp, components = strongly_connected_components(len(nodes), succ)
    cyclic = nontrivial(comp, components, succ)
    for c, members in enumerate(components):
        if not cyclic[c]:
            continue
        if any(nodes[s][0] in acc1 for s in members) and all(
                nodes[s][1] in acc2 for s in members):
            return False
    return True


def _equivalent(aut, weak_det, negation_aut) -> bool:
    """``L(aut) = L(weak_det)``: ``aut ⊗ ¬weak_det`` and ``weak_det ⊗ negation`` are empty."""
    if not _product_empty(aut, _complement_weak(weak_det)):
        return False
    return _product_empty(negation_aut(), weak_det)
