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
from agent.ltl.guards import TRUE_CUBE, Cube, Guard
from agent.ltl.truth_table import BddAlgebra, guard_algebra

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


_CUBE_LIMIT = 64  # partial products handled cube by cube before switching to BDD groups
EAGER_MAX_STATES = 64
"""Largest TGBA (states) also returned with the eager marking (see :func:`build_tgba`)."""


def _prune(partials: list[_Partial]) -> list[_Partial]:
    """Drop partial products dominated by another (GO §4.2: a weaker cube, fewer targets and
    fewer unfulfilled marks)."""
    unique = list(dict.fromkeys(partials))
    if len(unique) < 2:
        return unique
    unique.sort(key=lambda t: (t[1].bit_count(), t[2].bit_count(),
                               (t[0][0] | t[0][1]).bit_count()))
    # Domination test inlined (the hot loop of large translations): k dominates t when
    # k's targets ⊆ t's, k's bad ⊆ t's and t's cube implies k's (cube_implies).
    shift = max(t[2] for t in unique).bit_length()
    kept: list[_Partial] = []
    keys: list[tuple[int, int, int]] = []
    for t in unique:
        (pos, neg), targets, bad = t
        key = targets << shift | bad
        for kkey, kpos, kneg in keys:
            if not kkey & ~key and pos & kpos == kpos and neg & kneg == kneg:
                break
        else:
            kept.append(t)
            keys.append((key, pos, neg))
    return kept


def _groups_of(partials: list[_Partial], algebra) -> list[_Group]:
    """Partial products grouped by (targets, bad), in order of first occurrence."""
    grouped: dict[tuple[int, int], list] = {}
    cube_of = algebra.cube
    for cube, targets, bad in partials:
        lits = (cube[0] | cube[1]).bit_count()
        entry = grouped.get((targets, bad))
        if entry is None:
            grouped[(targets, bad)] = [cube_of(*cube), lits]
        else:
            entry[0] = entry[0] | cube_of(*cube)
            entry[1] = min(entry[1], lits)
    return [(t, b, g, lits) for (t, b), (g, lits) in grouped.items()]


def _disjoint(groups: list[_Group], algebra) -> bool:
    """Whether no letter is read by two groups."""
    seen = algebra.false
    for _t, _b, guard, _l in groups:
        if guard & seen:
            return False
        seen = seen | guard
    return True


def build_tgba(formula: Formula, index: dict[str, int]) -> tuple[Tgba, ...]:
    """TGBA of an NNF ``formula`` over the atoms numbered by ``index``, in one or two variants.

    Both have the same states and edges; they differ only in the marks of the edges that
    spawn an acceptance state afresh (φ_j ∉ S, φ_j ∈ S'): unmarked in the first (*lazy*,
    GO-like), marked in the second (*eager*, as if φ_j ∉ S sufficed). Any marking between the
    two is sound and complete (the lazy marks already are, and the eager ones only add marks on
    steps where φ_j was not pending). Which one degeneralises into fewer states depends on the
    formula (``G(a -> F b)`` prefers lazy), so the caller may try both. When no edge spawns an
    acceptance state the variants coincide and only one is returned; beyond
    :data:`EAGER_MAX_STATES` states only the lazy one is (on the benchmark's random formulas
    the eager marking never gave the smaller automaton there, and it doubles the work after).
    """
    vwaa = Vwaa(index)
    # Guards as truth tables over few atoms (the same automaton, faster), else BDDs.
    algebra = guard_algebra(len(index))
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
    option_cache: dict[int, tuple[list[_Group], bool]] = {}
    # The product after the first k members of a state, keyed by those members (a bitmask):
    # states share prefixes (every state of G(…) starts with the G state), and the product of
    # a prefix depends on nothing else.
    prefix_cache: dict[int, tuple[list[_Partial], list[_Group] | None, bool]] = {}

    def options_of(q: int) -> tuple[list[_Group], bool]:
        """The groups of VWAA state ``q``'s transitions and whether they are disjoint."""
        options = option_cache.get(q)
        if options is None:
            bad_bit = 1 << mark_of[q] if q in mark_of else 0
            options = option_cache[q] = _state_options(vwaa.state_delta(q), bad_bit, algebra)
        return options
    while queue:
        s = queue.popleft()
        sid = state_id[s]
        # Cube by cube (GO's products with domination pruning) while few; symbolic groups
        # (one BDD guard per (targets, bad)) once the products pile up, e.g. the 2^n
        # transitions of G F a1 & … & G F an, where pairwise pruning would cost 4^n.
        partials: list[_Partial] = [(TRUE_CUBE, 0, 0)]
        groups: list[_Group] | None = None
        disjoint = False
        members = ordered(s)
        start, prefix = 0, 0
        masks = [0]
        for q in members:
            masks.append(masks[-1] | 1 << q)
        for k in range(len(members), 0, -1):
            cached = prefix_cache.get(masks[k])
            if cached is not None:
                partials, groups, disjoint = cached
                start, prefix = k, masks[k]
                break
        else:
            if members and all(options_of(q)[1] for q in members):
                # Every member's options partition the letters (F a1 & … & F an): their
                # product is a partition too, built symbolically with nothing to prune.
                groups, disjoint = [(0, 0, algebra.true, 0)], True
        for k in range(start, len(members)):
            q = members[k]
            prefix |= 1 << q
            if groups is None:
                bad_bit = 1 << mark_of[q] if q in mark_of else 0
                product: list[_Partial] = []
                delta = vwaa.state_delta(q)
                for (pos, neg), targets, bad in partials:
                    for (pos2, neg2), e2, good in delta:
                        p = pos | pos2
                        n = neg | neg2
                        if not p & n:  # cube_and, inlined
                            product.append(((p, n), targets | e2,
                                            bad if good else bad | bad_bit))
                partials = _prune(product)
                if len(partials) > _CUBE_LIMIT:
                    groups = _minimal_per_letter(_groups_of(partials, algebra))
                    disjoint = _disjoint(groups, algebra)
                    groups.sort(key=_group_order)
                prefix_cache[prefix] = (partials, groups, disjoint)
                continue
            options = options_of(q)
            groups = _combine(groups, options[0])
            disjoint = disjoint and options[1]
            # Dominated groups are removed at the end, and on the way when they pile up.
            if not disjoint and len(groups) > 24:
                groups = _minimal_per_letter(groups)
                disjoint = _disjoint(groups, algebra)
            groups.sort(key=_group_order)
            prefix_cache[prefix] = (partials, groups, disjoint)
        if groups is None:
            groups = _minimal_per_letter(_groups_of(partials, algebra))
        elif not disjoint:  # (idempotent: a no-op on groups already minimal per letter)
            groups = _minimal_per_letter(groups)
            groups.sort(key=_group_order)
        raw_edges[sid] = [(intern(targets), guard, bad) for targets, bad, guard, _l in groups]
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
    variants = [_merge_bisimilar(Tgba(len(lazy), initial, lazy, len(mark_of)), algebra)]
    if eager != lazy and len(raw_edges) <= EAGER_MAX_STATES:
        variants.append(_merge_bisimilar(Tgba(len(eager), initial, eager, len(mark_of)),
                                         algebra))
    return tuple(_with_bdd_guards(tgba, algebra) for tgba in variants)


def _with_bdd_guards(tgba: Tgba, algebra) -> Tgba:
    """The automaton with its guards as BDDs (they were truth tables while it was built)."""
    if isinstance(algebra, BddAlgebra):
        return tgba
    to_bdd = algebra.to_bdd
    edges = tuple(tuple((dst, to_bdd(guard), marks) for dst, guard, marks in out)
                  for out in tgba.edges)
    return Tgba(tgba.num_states, tgba.initial, edges, tgba.num_marks)


# A group of transitions of a TGBA state under construction: (targets, bad, guard, literals),
# every letter of ``guard`` leading to the conjunction ``targets`` of VWAA states with the
# acceptance states ``bad`` not fulfilled; ``literals`` (the fewest literals of a cube of the
# group, estimated) only orders the edges, hence the numbering of the states.
_Group = tuple[int, int, Guard, int]


def _group_order(group: _Group) -> tuple[int, int, int]:
    """Fewer targets, fewer unfulfilled marks, fewer literals first (GO's order of
    transitions); it decides the order in which successor states are numbered."""
    return group[0].bit_count(), group[1].bit_count(), group[3]


def _state_options(transitions, bad_bit: int, algebra) -> tuple[list[_Group], bool]:
    """The transitions of one VWAA state grouped by (targets, bad), minimal per letter; and
    whether their guards are pairwise disjoint."""
    grouped: dict[tuple[int, int], list] = {}
    for cube, targets, good in transitions:
        key = (targets, 0 if good else bad_bit)
        entry = grouped.get(key)
        lits = (cube[0] | cube[1]).bit_count()
        if entry is None:
            grouped[key] = [algebra.cube(*cube), lits]
        else:
            entry[0] = entry[0] | algebra.cube(*cube)
            entry[1] = min(entry[1], lits)
    groups = _minimal_per_letter([(t, b, g, lits) for (t, b), (g, lits) in grouped.items()])
    return groups, _disjoint(groups, algebra)


def _combine(xs: list[_Group], ys: list[_Group]) -> list[_Group]:
    """The product of two sets of groups: union of targets and of bad marks, conjunction of
    guards, merging equal (targets, bad). If, for every letter, each side's groups are minimal,
    the minimal groups of the product are among these (union is monotone), so only the
    non-minimal ones may have to be removed afterwards (:func:`_minimal_per_letter`); when both
    sides are partitions of the letters the product is one too and nothing is removed."""
    out: dict[tuple[int, int], list] = {}
    for tx, bx, gx, lx in xs:
        for ty, by, gy, ly in ys:
            g = gx & gy
            if not g:
                continue
            key = (tx | ty, bx | by)
            entry = out.get(key)
            if entry is None:
                out[key] = [g, lx + ly]
            else:
                entry[0] = entry[0] | g
                entry[1] = min(entry[1], lx + ly)
    return [(t, b, g, lits) for (t, b), (g, lits) in out.items()]


def _minimal_per_letter(groups: list[_Group]) -> list[_Group]:
    """Remove from each group's guard the letters read by a *dominating* group (fewer targets
    and fewer unfulfilled acceptance states, GO §4.2 applied letter by letter); this makes most
    automata of robot missions deterministic and keeps the product small."""
    if len(groups) < 2:
        return groups
    shift = max(b for _t, b, _g, _l in groups).bit_length()
    # Domination = subset of this mask; keys are distinct (one group per (targets, bad)).
    keyed = [(t << shift | b, g) for t, b, g, _l in groups]
    result = []
    for (ki, _g), (targets, bad, guard, lits) in zip(keyed, groups, strict=True):
        # Dominator by dominator, only those that share letters: cheaper than one union of
        # them all (most share none).
        for kj, g in keyed:
            if kj != ki and not kj & ~ki and guard & g:
                guard = guard & ~g
                if not guard:
                    break
        if guard:
            result.append((targets, bad, guard, lits))
    return result


def _merge_bisimilar(tgba: Tgba, algebra) -> Tgba:
    """Quotient by the coarsest partition where merged states have equal outgoing edges."""
    n = tgba.num_states
    block = [0] * n
    num_blocks = 1
    while True:
        signatures: dict[tuple, int] = {}
        new_block = []
        for s in range(n):
            sig = (block[s], frozenset(_signature(tgba.edges[s], block, algebra.false)))
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
            edges[b][key] = edges[b].get(key, algebra.false) | guard
    out = tuple(tuple((dst, guard, marks) for (dst, marks), guard in e.items()) for e in edges)
    initial = tuple(dict.fromkeys(block[i] for i in tgba.initial))
    return Tgba(num_blocks, initial, out, tgba.num_marks)


def _signature(edges, block, false):
    grouped: dict[tuple[int, int], Guard] = {}
    for dst, guard, marks in edges:
        key = (block[dst], marks)
        grouped[key] = grouped.get(key, false) | guard
    return grouped.items()
