"""Fair simulation, and the states it lets go (ltl-planning.md §2, "Small").

Etessami, Wilke & Schuller (SIAM J. Comput. 2005), "Fair simulation relations, parity games,
and state space reduction for Büchi automata": ``p ≼f q`` when Duplicator, answering Spoiler's
moves from ``p`` letter for letter from ``q``, builds an accepting run whenever Spoiler's run is
accepting. It implies ``L(p) ⊆ L(q)`` and, unlike direct simulation, it does not ask the two
runs to accept at the same steps — it sees through the accepting copies that degeneralisation
adds, where direct simulation does not.

:func:`remove_fair_little_brothers` removes a state ``p`` when every edge ``s → p`` (``s ≠ p``)
can be replaced, letter for letter, by an edge ``s → q`` of the same state to a strict fair
simulator ``q`` of ``p`` (``p ≼f q``, not ``q ≼f p``). Pruning with fair simulation is **not
sound in general** (Clemente & Mayr, POPL 2013: the run through ``q`` may keep postponing
acceptance), so each pruned automaton ``A'`` is kept only if the initial state of ``A`` is fair-
simulated by that of ``A'`` — a proof of ``L(A) ⊆ L(A')``; ``L(A') ⊆ L(A)`` holds because
``A'`` only lost edges.

The game: positions ``(p, q)``; priority 2 where ``q`` accepts, 1 where only ``p`` accepts, 0
elsewhere; Duplicator wins a play iff the largest priority seen infinitely often is even (or
Spoiler gets stuck): a parity game with three priorities, solved by the nested fixpoint
``νZ2. μZ1. νZ0. ⋃ᵢ (Pᵢ ∩ CPre(Zᵢ))`` (Emerson & Jutla 1991). Spoiler's moves from ``(p, q)``
are precomputed symbolically: for each edge ``p –g→ p'`` the cells of ``g`` cut by ``q``'s
guards, each with the answers ``q'`` it allows.

Automata are the translator's tuples ``(n, initial, accepting, edges)`` with BDD guards.
"""

from __future__ import annotations

from tlfleet.agent.ltl.bdd import FALSE, TRUE, disjoin

MAX_STATES = 10
"""Largest automaton (states) for which the games are played (positions: states²)."""
MAX_CELLS = 64
"""Letter cells per Duplicator state (its guards cut the letters) before giving up."""

def remove_fair_little_brothers(aut):
    """``aut`` with the states that fair simulation proves unnecessary cut off (still listed
    but unreachable: the caller removes useless states), or ``None`` when none is."""
    n, initial, accepting, edges = aut
    if n < 3 or n > MAX_STATES or len(initial) != 1:
        return None
    # Only states whose every entry has an alternative on the same letters can go.
    alternatives = _alternatives(n, initial, edges)
    if not alternatives:
        return None
    moves = _Moves(edges, edges)
    asked = {(p, q) for p, entries in alternatives.items() for s in entries
             for q, _g in edges[s] if q != p}
    try:
        return _remove(n, initial, accepting, edges, alternatives, moves, asked)
    except _TooManyCells:
        return None


def _remove(n, initial, accepting, edges, alternatives, moves, asked):
    """One candidate state at a time: its entries go to strict fair simulators; kept if the
    original automaton's initial state is fair-simulated by the pruned one's."""
    win = fair_simulation_positions(n, n, accepting, accepting, moves,
                                    starts=sorted(asked | {(q, p) for p, q in asked}))
    current = [list(out) for out in edges]
    changed = False
    for p, entries in alternatives.items():
        trial = [list(out) for out in current]
        for s in entries:
            sims = [g for q, g in current[s]
                    if q != p and (p, q) in win and (q, p) not in win]
            cover = disjoin(sims)
            into = disjoin(g for d, g in current[s] if d == p)
            if into is FALSE or not into.implies(cover):
                break
            trial[s] = [(d, g) for d, g in trial[s] if d != p]
        else:
            check = _Moves(edges, trial, base=moves, changed=set(entries))
            start = (initial[0], initial[0])
            if start in fair_simulation_positions(n, n, accepting, accepting, check,
                                                  starts=[start]):
                current = trial
                moves = check
                changed = True
    return (n, initial, accepting, current) if changed else None


def _alternatives(n, initial, edges) -> dict[int, list[int]]:
    """Non-initial states ``p`` whose entries ``s → p`` (``s ≠ p``) all overlap another edge of
    ``s``: ``p`` → the states ``s`` entering it."""
    entries: dict[int, list[int]] = {}
    blocked = set(initial)
    for s in range(n):
        for p, g in edges[s]:
            if p == s or p in blocked:
                continue
            others = disjoin(h for q, h in edges[s] if q != p)
            if not g.implies(others):
                blocked.add(p)
                entries.pop(p, None)
            elif s not in entries.setdefault(p, []):
                entries[p].append(s)
    return {p: ss for p, ss in entries.items() if p not in blocked}


class _TooManyCells(Exception):
    """A Duplicator state's guards cut the letters into more than :data:`MAX_CELLS` cells."""


class _Moves:
    """Spoiler's moves, computed on demand: ``moves(p, q)`` = the choices ``(p', answers)``
    from ``(p, q)``, keeping per ``p'`` only the cells with the fewest answers (more answers
    only help Duplicator). With ``base`` (the moves against the same Spoiler automaton), the
    Duplicator states outside ``changed`` are answered from it."""

    def __init__(self, spoiler_edges, duplicator_edges, base: _Moves | None = None,
                 changed: set[int] = frozenset()):
        self.spoiler = spoiler_edges
        self.duplicator = duplicator_edges
        self.base = base
        self.changed = changed
        self._cells: dict[int, list] = {}
        self._moves: dict[tuple[int, int], list[tuple[int, tuple[int, ...]]]] = {}

    def cells(self, q: int):
        """The letters cut by ``q``'s guards, each cell with the answers ``q'`` it allows."""
        cells = self._cells.get(q)
        if cells is None:
            cells = [(TRUE, frozenset())]
            for q2, h in self.duplicator[q]:
                split = []
                for cell, answers in cells:
                    inside = cell & h
                    if inside is not FALSE:
                        split.append((inside, answers | {q2}))
                    outside = cell - h
                    if outside is not FALSE:
                        split.append((outside, answers))
                cells = split
                if len(cells) > MAX_CELLS:
                    raise _TooManyCells
            self._cells[q] = cells
        return cells

    def __call__(self, p: int, q: int) -> list[tuple[int, tuple[int, ...]]]:
        if self.base is not None and q not in self.changed:
            return self.base(p, q)
        hit = self._moves.get((p, q))
        if hit is None:
            choices: dict[int, list[frozenset[int]]] = {}
            for p2, g in self.spoiler[p]:
                found = choices.setdefault(p2, [])
                for cell, answers in self.cells(q):
                    if answers not in found and g & cell is not FALSE:
                        found.append(answers)
            hit = self._moves[(p, q)] = [
                (p2, tuple(sorted(a))) for p2, sets in choices.items()
                for a in sets if not any(b < a for b in sets)]
        return hit


def fair_simulation_positions(n: int, m: int, acc_a, acc_b, moves,
                              starts=None) -> set[tuple[int, int]]:
    """The positions ``(p, q)`` (``p`` of the Spoiler automaton, ``q`` of Duplicator's) from
    which Duplicator wins the fair-simulation game, i.e. ``p ≼f q``; ``moves(p, q)`` lists
    Spoiler's choices (:class:`_Moves`). With ``starts``, only
    among the positions reachable from those (the others are not decided).

    The nested fixpoint over the positions numbered in discovery order; each ``ν`` level is
    refined with a worklist (a position that leaves a set re-examines only the positions whose
    moves reach it).
    """
    if starts is None:
        starts = [(p, q) for p in range(n) for q in range(m)]
    number: dict[tuple[int, int], int] = {}
    positions: list[tuple[int, int]] = []
    for x in starts:
        if x not in number:
            number[x] = len(positions)
            positions.append(x)
    # choices[x] = list of answer lists (position numbers); Duplicator needs one answer in
    # each list inside the target set.
    choices: list[list[list[int]]] = []
    k = 0
    while k < len(positions):
        p, q = positions[k]
        lists = []
        for p2, answers in moves(p, q):
            row = []
            for q2 in answers:
                y = number.get((p2, q2))
                if y is None:
                    y = number[(p2, q2)] = len(positions)
                    positions.append((p2, q2))
                row.append(y)
            lists.append(row)
        choices.append(lists)
        k += 1
    count = len(positions)
    priority = [2 if q in acc_b else (1 if p in acc_a else 0) for p, q in positions]
    pred: list[set[int]] = [set() for _ in range(count)]
    for x, lists in enumerate(choices):
        for answers in lists:
            for y in answers:
                pred[y].add(x)

    def inner(z2: bytearray, z1: bytearray) -> bytearray:
        """νZ0: positions that can stay in Z_priority; refined from everything."""
        z0 = bytearray(b"\x01") * count
        levels = (z0, z1, z2)
        pending = list(range(count))
        queued = bytearray(b"\x01") * count
        while pending:
            x = pending.pop()
            queued[x] = 0
            if not z0[x]:
                continue
            if _answers_all(choices[x], levels[priority[x]]):
                continue
            z0[x] = 0
            for w in pred[x]:
                if z0[w] and not queued[w] and priority[w] == 0:
                    queued[w] = 1
                    pending.append(w)
        return z0

    z2 = bytearray(b"\x01") * count
    while True:
        z1 = bytearray(count)
        while True:
            z0 = inner(z2, z1)
            if z0 == z1:
                break
            z1 = z0
        if z1 == z2:
            return {positions[x] for x in range(count) if z2[x]}
        z2 = z1


def _answers_all(lists: list[list[int]], target: bytearray) -> bool:
    """Whether every Spoiler choice has an answer in ``target`` (plain loops: the hot path)."""
    for answers in lists:
        for y in answers:
            if target[y]:
                break
        else:
            return False
    return True
