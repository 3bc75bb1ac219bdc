"""Transition-based generalised Büchi automaton from the VWAA (Gastin & Oddoux 2001, §4).

A TGBA state is a set ``S`` of VWAA states (a conjunction). Its transitions ``S → S'`` are the
products ⊗_{q ∈ S} δ(q); a transition belongs to acceptance set ``j`` (for the j-th acceptance
state φ_j of the VWAA) when φ_j ∈ S and the transition chosen for φ_j was good, or when φ_j is
in neither S nor S' — not when φ_j is pending and not fulfilled. A run is accepting iff no
branch of the VWAA run stays in φ_j forever without fulfilling it: after a fresh spawn φ_j stays
pending until it is fulfilled, so whether spawning edges are marked does not change the language
(see ``build_tgba`` for the two variants).

Reductions applied, all language-preserving:

* dominated transitions are dropped while building products (GO §4.2: t' dominates t when t's
  cube implies t''s, t' has fewer targets and at least t's acceptance);
* *per letter* domination: a letter is removed from a transition's guard when a dominating
  transition with fewer targets and better acceptance reads it too — this makes most automata of
  robot missions deterministic and keeps the product small;
* states with the same outgoing transitions (guard, destination class, acceptance) are merged
  (GO §4.2, iterated to a bisimulation quotient).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from agent.ltl.alternating import Vwaa, is_acceptance_state
from agent.ltl.formula import Formula
from agent.ltl.guards import TRUE_CUBE, Alphabet, Cube, Guard, cube_and, cube_implies

# (cube, targets, bad) where bad is the bitmask of acceptance states whose chosen
# transition was not good.
_Partial = tuple[Cube, int, int]  # targets: bitmask over Vwaa.states


@dataclass(frozen=True)
class Tgba:
    """``edges[s]`` lists ``(dst, guard, marks)``; ``marks`` is a bitmask over ``num_marks``."""

    num_states: int
    initial: tuple[int, ...]
    edges: tuple[tuple[tuple[int, Guard, int], ...], ...]
    num_marks: int


def _prune(partials: list[_Partial]) -> list[_Partial]:
    unique = list(dict.fromkeys(partials))
    if len(unique) < 2:
        return unique
    unique.sort(key=lambda t: (t[1].bit_count(), t[2].bit_count(), (t[0][0] | t[0][1]).bit_count()))
    kept: list[_Partial] = []
    for t in unique:
        cube, targets, bad = t
        dominated = False
        for k in kept:
            if not k[1] & ~targets and not k[2] & ~bad and cube_implies(cube, k[0]):
                dominated = True
                break
        if not dominated:
            kept.append(t)
    return kept


def build_tgba(formula: Formula, index: dict[str, int]) -> tuple[Tgba, ...]:
    """TGBA of an NNF ``formula`` over the atoms numbered by ``index``, in one or two variants.

    Both have the same states and edges; they differ only in the marks of the edges that
    spawn an acceptance state afresh (φ_j ∉ S, φ_j ∈ S'): unmarked in the first (*lazy*,
    GO-like), marked in the second (*eager*, as if φ_j ∉ S sufficed). Any marking between the
    two is sound and complete (the lazy marks already are, and the eager ones only add marks on
    steps where φ_j was not pending). Which one degeneralises into fewer states depends on the
    formula (``G(a -> F b)`` prefers lazy), so the caller may try both. When no edge spawns an
    acceptance state the variants coincide and only one is returned.
    """
    vwaa = Vwaa(index)
    alphabet = Alphabet(len(index))
    mark_of: dict[int, int] = {}  # VWAA state number -> acceptance mark
    state_id: dict[int, int] = {}  # TGBA state (bitmask of VWAA states) -> number
    raw_edges: list[list[tuple[int, Guard, int]]] = []
    queue: deque[int] = deque()
    names: list[str] = []  # printed VWAA states: a hash-independent order

    def ordered(s: int) -> list[int]:
        while len(names) < len(vwaa.states):
            names.append(str(vwaa.states[len(names)]))
        members = []
        while s:
            low = s & -s
            members.append(low.bit_length() - 1)
            s ^= low
        return sorted(members, key=names.__getitem__)

    def intern(s: int) -> int:
        sid = state_id.get(s)
        if sid is None:
            sid = len(state_id)
            state_id[s] = sid
            raw_edges.append([])
            queue.append(s)
            for q in ordered(s):
                if is_acceptance_state(vwaa.states[q]) and q not in mark_of:
                    mark_of[q] = len(mark_of)
        return sid

    initial = tuple(dict.fromkeys(intern(s) for s in vwaa.bar(formula)))
    while queue:
        s = queue.popleft()
        sid = state_id[s]
        partials: list[_Partial] = [(TRUE_CUBE, 0, 0)]
        for q in ordered(s):
            bad_bit = 1 << mark_of[q] if q in mark_of else 0
            product: list[_Partial] = []
            for cube, targets, bad in partials:
                for c2, e2, good in vwaa.state_delta(q):
                    c = cube_and(cube, c2)
                    if c is not None:
                        product.append((c, targets | e2, bad if good else bad | bad_bit))
            partials = _prune(product)
        raw_edges[sid] = [
            (intern(e), g, b) for e, g, b in _per_letter_domination(partials, alphabet)
        ]
    all_marks = (1 << len(mark_of)) - 1
    pending = [0] * len(state_id)  # acceptance states in each TGBA state, as mark bits
    for s, sid in state_id.items():
        for q, mark in mark_of.items():
            if s >> q & 1:
                pending[sid] |= 1 << mark
    lazy = tuple(
        tuple((dst, guard, all_marks & ~bad & ~(pending[dst] & ~pending[src]))
              for dst, guard, bad in out)
        for src, out in enumerate(raw_edges)
    )
    eager = tuple(
        tuple((dst, guard, all_marks & ~bad) for dst, guard, bad in out) for out in raw_edges
    )
    variants = [_merge_bisimilar(Tgba(len(lazy), initial, lazy, len(mark_of)))]
    if eager != lazy:
        variants.append(_merge_bisimilar(Tgba(len(eager), initial, eager, len(mark_of))))
    return tuple(variants)


def _per_letter_domination(
    partials: list[_Partial], alphabet: Alphabet
) -> list[tuple[int, Guard, int]]:
    """Group transitions by (targets, bad) and remove letters read by a dominating group."""
    groups: dict[tuple[int, int], Guard] = {}
    for cube, targets, bad in partials:
        key = (targets, bad)
        groups[key] = groups.get(key, 0) | alphabet.cube(cube)
    result = []
    for key, table in groups.items():
        targets, bad = key
        guard = table
        for other, other_table in groups.items():
            if other is not key and not other[0] & ~targets and not other[1] & ~bad:
                guard &= ~other_table
        if guard:
            result.append((targets, guard, bad))
    return result


def _merge_bisimilar(tgba: Tgba) -> Tgba:
    """Quotient by the coarsest partition where merged states have equal outgoing edges."""
    n = tgba.num_states
    block = [0] * n
    num_blocks = 1
    while True:
        signatures: dict[tuple, int] = {}
        new_block = []
        for s in range(n):
            sig = (block[s], frozenset(_signature(tgba.edges[s], block)))
            new_block.append(signatures.setdefault(sig, len(signatures)))
        if len(signatures) == num_blocks:
            break
        block, num_blocks = new_block, len(signatures)
    if num_blocks == n:
        return tgba
    edges: list[dict[tuple[int, int], Guard]] = [{} for _ in range(num_blocks)]
    done = set()
    for s in range(n):
        b = block[s]
        if b in done:
            continue
        done.add(b)
        for dst, guard, marks in tgba.edges[s]:
            key = (block[dst], marks)
            edges[b][key] = edges[b].get(key, 0) | guard
    out = tuple(tuple((dst, guard, marks) for (dst, marks), guard in e.items()) for e in edges)
    initial = tuple(dict.fromkeys(block[i] for i in tgba.initial))
    return Tgba(num_blocks, initial, out, tgba.num_marks)


def _signature(edges, block):
    grouped: dict[tuple[int, int], Guard] = {}
    for dst, guard, marks in edges:
        key = (block[dst], marks)
        grouped[key] = grouped.get(key, 0) | guard
    return grouped.items()
