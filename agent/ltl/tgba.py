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
  (GO §4.2, iterated to a bisimulation quotient);
* transitions into a conjunction of VWAA states that contains two provably contradictory ones
  (``G !p`` and ``F p``; ``p`` and ``!p``: syntactic implication, ``tlfleet.agent.ltl.implication``)
  are dropped: no word satisfies that conjunction, so no accepting run goes there. A dropped
  transition only dominates transitions whose targets contain its own, dropped too, so dropping
  them after the domination steps above is the same as before.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from tlfleet.agent.ltl.alternating import Vwaa, is_acceptance_state
from tlfleet.agent.ltl.formula import Formula, children
from tlfleet.agent.ltl.guards import Guard
from tlfleet.agent.ltl.implication import Conflicts
from tlfleet.agent.ltl.truth_table import BddAlgebra, guard_algebra

# A partial product of a TGBA state's transitions, (cube, targets, bad) with bad the bitmask of
# acceptance marks whose chosen transition was not good, packed into one int (see _Layout).
_Partial = int


@dataclass(frozen=True)
class Tgba:
    """``edges[s]`` lists ``(dst, guard, marks)``; ``marks`` is a bitmask over ``num_marks``.

    ``deterministic`` is ``True`` only when the automaton is known to be deterministic (one
    initial state, pairwise disjoint guards in every state), as :func:`build_tgba` finds out
    on its truth tables; ``False`` means "not known" (the reductions then check)."""

    num_states: int
    initial: tuple[int, ...]
    edges: tuple[tuple[tuple[int, Guard, int], ...], ...]
    num_marks: int
    deterministic: bool = field(default=False, compare=False)


_CUBE_LIMIT = 64  # partial products handled cube by cube before switching to BDD groups
EAGER_MAX_STATES = 64
EAGER_MAX_EDGES = 256
"""Largest TGBA (states, edges) also returned with the eager marking (see :func:`build_tgba`).
On the benchmark's random formulas and Spot's table the eager marking gave the smaller
automaton only on TGBAs of at most 140 edges; above, it doubles the work after (random #50:
1 148 edges, an eager automaton of 112 states against 73)."""


class _Layout:
    """The packing of a partial product into one int: ``neg`` in bits ``[0, A)``, ``pos`` in
    ``[A, 2A)`` (A atoms), the ``bad`` marks in the next ``W`` bits (W bounds the number of
    acceptance states) and the ``targets`` above. Domination (GO §4.2: fewer targets, fewer
    unfulfilled marks, a cube with fewer literals) is then bitset subsumption, ``k & ~t == 0``,
    and the product of two partials is their ``|`` (inconsistent when ``pos & neg``)."""

    def __init__(self, atoms: int, marks: int):
        self.atoms = atoms
        self.marks = marks
        self.bad_shift = 2 * atoms
        self.targets_shift = 2 * atoms + marks
        self.atom_mask = (1 << atoms) - 1
        self.cube_mask = (1 << 2 * atoms) - 1
        self.bad_mask = (1 << marks) - 1

    def pack(self, pos: int, neg: int, targets: int, bad: int) -> _Partial:
        return targets << self.targets_shift | bad << self.bad_shift | pos << self.atoms | neg

    def unpack(self, x: _Partial) -> tuple[int, int, int, int]:
        """``(pos, neg, targets, bad)``."""
        return (x >> self.atoms & self.atom_mask, x & self.atom_mask, x >> self.targets_shift,
                x >> self.bad_shift & self.bad_mask)

    def product(self, partials: list[_Partial], delta: list[tuple[_Partial, int]]
                ) -> list[_Partial]:
        """The consistent unions of a partial and a packed transition, undominated ones only.
        ``delta`` pairs each packed transition with the targets (shifted into place) that
        contradict its own: a union with one of them is a conjunction no word satisfies."""
        a, mask = self.atoms, self.atom_mask
        out = []
        for x in partials:
            for d, clash in delta:
                if x & clash:  # contradictory targets
                    continue
                y = x | d
                if not (y >> a) & y & mask:  # pos & neg: an inconsistent cube
                    out.append(y)
        return self.prune(out)

    def prune(self, partials: list[_Partial]) -> list[_Partial]:
        """Drop partial products dominated by another. The survivors are the minimal elements;
        they are returned in GO's order (fewer targets, fewer unfulfilled marks, fewer
        literals), which the numbering of the TGBA's states follows."""
        if len(partials) < 2:
            return partials
        # By number of bits (stable): a dominator comes first, since subsumption with as many
        # bits is equality, and domination is transitive, so comparing with the kept ones only
        # is enough (a repeated partial is dominated by its first occurrence).
        ordered = sorted(partials, key=int.bit_count)
        kept: list[_Partial] = []
        for x in ordered:
            nx = ~x
            for k in kept:
                if not k & nx:
                    break
            else:
                kept.append(x)
        # GO's order; partials equal in it have as many bits, so they stay in the order of
        # their first occurrence.
        if len(kept) < 2:
            return kept
        ts, bs, bm, cm = self.targets_shift, self.bad_shift, self.bad_mask, self.cube_mask
        keys = [(x >> ts).bit_count() << 20 | (x >> bs & bm).bit_count() << 10
                | (x & cm).bit_count() for x in kept]
        return [kept[i] for i in sorted(range(len(kept)), key=keys.__getitem__)]

    def groups_of(self, partials: list[_Partial], algebra) -> list[_Group]:
        """Partial products grouped by (targets, bad), in order of first occurrence."""
        grouped: dict[int, list] = {}
        cube_of, a, am, cm, bs = (algebra.cube, self.atoms, self.atom_mask, self.cube_mask,
                                  self.bad_shift)
        for x in partials:
            lits = (x & cm).bit_count()
            guard = cube_of(x >> a & am, x & am)
            key = x >> bs
            entry = grouped.get(key)
            if entry is None:
                grouped[key] = [guard, lits]
            else:
                entry[0] = entry[0] | guard
                entry[1] = min(entry[1], lits)
        ms, bm = self.marks, self.bad_mask
        return [(key >> ms, key & bm, g, lits) for key, (g, lits) in grouped.items()]


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
    :data:`EAGER_MAX_STATES` states or :data:`EAGER_MAX_EDGES` edges only the lazy one is.
    """
    exploration = _Exploration(formula, index)
    exploration.run()
    return _marked_variants(exploration)


class _Exploration:
    """The reachable TGBA states (sets of VWAA states, as bitmasks) and their edges ``(dst,
    guard, bad)``, ``bad`` the marks whose chosen transition was not good; states are numbered
    in the order they are reached, breadth first from the initial ones."""

    def __init__(self, formula: Formula, index: dict[str, int]):
        self.vwaa = Vwaa(index)
        self.layout = _Layout(len(index), _acceptance_bound(formula))
        # Guards as truth tables over few atoms (the same automaton, faster), else BDDs.
        self.algebra = guard_algebra(len(index))
        self.mark_of: dict[int, int] = {}  # VWAA state number -> acceptance mark
        self.state_id: dict[int, int] = {}  # TGBA state (bitmask of VWAA states) -> number
        self.raw_edges: list[list[tuple[int, Guard, int]]] = []
        self.queue: deque[int] = deque()
        self.names: list[str] = []  # printed VWAA states: a hash-independent order
        self.members_of: list[list[int]] = []  # per TGBA state, its VWAA states in printed order
        # Conjunctions of VWAA states that no word satisfies (G !p & F p, p & !p, …) are never
        # entered: their states could not reach an accepting cycle anyway, and on formulas full
        # of <-> and xor they were most of the construction (e.g. 274 of 329 states). Partial
        # products are dropped as soon as their targets contain a contradiction (about half of
        # them on those formulas), before the domination steps, which they would not change.
        self.conflicts = Conflicts(self.vwaa.states, index)
        initial_sets = self.vwaa.bar(formula)
        for s in initial_sets:
            self.conflicts.register(s)
        self.initial = tuple(dict.fromkeys(
            self.intern(s) for s in initial_sets if not self.conflicts.empty(s)))
        self.option_cache: dict[int, tuple[list[_Group], bool]] = {}
        # The product after the first k members of a state, keyed by those members (a
        # bitmask): states share prefixes (every state of G(…) starts with the G state), and
        # the product of a prefix depends on nothing else.
        self.prefix_cache: dict[int, tuple[list[_Partial], list[_Group] | None, bool]] = {}
        self.delta_cache: dict[int, tuple[int, list[tuple[_Partial, int]]]] = {}
        self.deterministic = len(self.initial) <= 1  # so far: every state's groups disjoint

    def ordered(self, s: int) -> list[int]:
        """The VWAA states of TGBA state ``s`` in printed order."""
        names, states = self.names, self.vwaa.states
        while len(names) < len(states):
            names.append(str(states[len(names)]))
        members = []
        while s:
            low = s & -s
            members.append(low.bit_length() - 1)
            s ^= low
        return sorted(members, key=names.__getitem__)

    def intern(self, s: int) -> int:
        """The number of TGBA state ``s``, queued for exploration when new; its acceptance
        states get their marks."""
        sid = self.state_id.get(s)
        if sid is None:
            sid = len(self.state_id)
            self.state_id[s] = sid
            self.raw_edges.append([])
            self.queue.append(s)
            members = self.ordered(s)
            self.members_of.append(members)
            mark_of = self.mark_of
            for q in members:
                if is_acceptance_state(self.vwaa.states[q]) and q not in mark_of:
                    if len(mark_of) == self.layout.marks:
                        raise RuntimeError("build_tgba: more acceptance states than "
                                           "subformulas")
                    mark_of[q] = len(mark_of)
        return sid

    def packed_delta(self, q: int) -> list[tuple[_Partial, int]]:
        """VWAA state ``q``'s transitions as packed partials, each with the states that
        contradict its targets (shifted to the targets' place; recomputed when a registered
        state brought a new contradiction); transitions into a contradiction are left out."""
        conflicts, layout = self.conflicts, self.layout
        entry = self.delta_cache.get(q)
        if entry is None or entry[0] != conflicts.version:
            transitions = self.vwaa.state_delta(q)
            for _cube, targets, _good in transitions:
                conflicts.register(targets)
            bad_bit = 1 << self.mark_of[q] if q in self.mark_of else 0
            packed = []
            for (pos, neg), targets, good in transitions:
                clash = conflicts.of(targets)
                if not clash & targets:
                    packed.append((layout.pack(pos, neg, targets, 0 if good else bad_bit),
                                   clash << layout.targets_shift))
            entry = self.delta_cache[q] = (conflicts.version, packed)
        return entry[1]

    def options_of(self, q: int) -> tuple[list[_Group], bool]:
        """The groups of VWAA state ``q``'s transitions and whether they are disjoint."""
        options = self.option_cache.get(q)
        if options is None:
            transitions = self.vwaa.state_delta(q)
            for _cube, targets, _good in transitions:
                self.conflicts.register(targets)
            bad_bit = 1 << self.mark_of[q] if q in self.mark_of else 0
            options = self.option_cache[q] = _state_options(transitions, bad_bit, self.algebra)
        return options

    def run(self) -> None:
        """Explore every reachable state: its groups become its edges, whose targets are
        interned (and queued) unless they are a contradiction."""
        state_id, conflicts = self.state_id, self.conflicts
        while self.queue:
            sid = state_id[self.queue.popleft()]
            groups, disjoint = self.groups(self.members_of[sid])
            self.deterministic = self.deterministic and disjoint
            out = self.raw_edges[sid]
            for targets, bad, guard, _l in groups:
                dst = state_id.get(targets)
                if dst is None:
                    if conflicts.empty(targets):
                        continue
                    dst = self.intern(targets)
                out.append((dst, guard, bad))

    def groups(self, members: list[int]) -> tuple[list[_Group], bool]:
        """The product ⊗_{q ∈ members} δ(q) as undominated groups (targets, bad, guard,
        literals), and whether their guards are pairwise disjoint (only looked for while the
        automaton is still deterministic).

        Cube by cube (GO's products with domination pruning) while few; symbolic groups (one
        BDD guard per (targets, bad)) once the products pile up, e.g. the 2^n transitions of
        G F a1 & … & G F an, where pairwise pruning would cost 4^n."""
        algebra, layout, prefix_cache = self.algebra, self.layout, self.prefix_cache
        partials: list[_Partial] = [0]  # the true cube, no target, nothing unfulfilled
        groups: list[_Group] | None = None
        disjoint = False
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
            if members and all(self.options_of(q)[1] for q in members):
                # Every member's options partition the letters (F a1 & … & F an): their
                # product is a partition too, built symbolically with nothing to prune.
                groups, disjoint = [(0, 0, algebra.true, 0)], True
        for k in range(start, len(members)):
            q = members[k]
            prefix |= 1 << q
            if groups is None:
                partials = layout.product(partials, self.packed_delta(q))
                if len(partials) > _CUBE_LIMIT:
                    groups = _minimal_per_letter(layout.groups_of(partials, algebra))
                    disjoint = _disjoint(groups, algebra)
                    groups.sort(key=_group_order)
                prefix_cache[prefix] = (partials, groups, disjoint)
                continue
            options = self.options_of(q)
            groups = _combine(groups, options[0])
            disjoint = disjoint and options[1]
            # Dominated groups are removed at the end, and on the way when they pile up.
            if not disjoint and len(groups) > 24:
                groups = _minimal_per_letter(groups)
                disjoint = _disjoint(groups, algebra)
            groups.sort(key=_group_order)
            prefix_cache[prefix] = (partials, groups, disjoint)
        if groups is None:
            groups = _minimal_per_letter(layout.groups_of(partials, algebra))
            disjoint = self.deterministic and _disjoint(groups, algebra)
        elif not disjoint:  # (idempotent: a no-op on groups already minimal per letter)
            groups = _minimal_per_letter(groups)
            groups.sort(key=_group_order)
            disjoint = self.deterministic and _disjoint(groups, algebra)
        return groups, disjoint


def _marked_variants(exploration: _Exploration) -> tuple[Tgba, ...]:
    """The lazy and (when it differs and the automaton is small) the eager marking of the
    explored edges (see :func:`build_tgba`), each with bisimilar states merged and BDD guards.

    An edge gets mark j unless its chosen transition for φ_j was bad; the lazy marking also
    leaves out the marks of the acceptance states the edge spawns afresh (pending in the
    target, not in the source)."""
    raw_edges, mark_of, algebra = exploration.raw_edges, exploration.mark_of, exploration.algebra
    initial, deterministic = exploration.initial, exploration.deterministic
    all_marks = (1 << len(mark_of)) - 1
    pending = [0] * len(exploration.state_id)  # acceptance states in each state, as mark bits
    for s, sid in exploration.state_id.items():
        for q, mark in mark_of.items():
            if s >> q & 1:
                pending[sid] |= 1 << mark
    spawned = 0  # marks some good edge spawns afresh: where the two markings differ
    lazy_edges = []
    for src, out in enumerate(raw_edges):
        row = []
        for dst, guard, bad in out:
            fresh = pending[dst] & ~pending[src] & ~bad
            spawned |= fresh
            row.append((dst, guard, all_marks & ~bad & ~fresh))
        lazy_edges.append(tuple(row))
    lazy = tuple(lazy_edges)
    variants = [_merge_bisimilar(Tgba(len(lazy), initial, lazy, len(mark_of), deterministic),
                                 algebra)]
    too_large = (len(raw_edges) > EAGER_MAX_STATES
                 or sum(len(out) for out in raw_edges) > EAGER_MAX_EDGES)
    if spawned and not too_large:
        eager = tuple(tuple((dst, guard, all_marks & ~bad) for dst, guard, bad in out)
                      for out in raw_edges)
        variants.append(_merge_bisimilar(
            Tgba(len(eager), initial, eager, len(mark_of), deterministic), algebra))
    return tuple(_with_bdd_guards(tgba, algebra) for tgba in variants)


def _with_bdd_guards(tgba: Tgba, algebra) -> Tgba:
    """The automaton with its guards as BDDs (they were truth tables while it was built)."""
    if isinstance(algebra, BddAlgebra):
        return tgba
    to_bdd = algebra.to_bdd
    edges = tuple(tuple((dst, to_bdd(guard), marks) for dst, guard, marks in out)
                  for out in tgba.edges)
    return Tgba(tgba.num_states, tgba.initial, edges, tgba.num_marks, tgba.deterministic)


# A group of transitions of a TGBA state under construction: (targets, bad, guard, literals),
# every letter of ``guard`` leading to the conjunction ``targets`` of VWAA states with the
# acceptance states ``bad`` not fulfilled; ``literals`` (the fewest literals of a cube of the
# group, estimated) only orders the edges, hence the numbering of the states.
_Group = tuple[int, int, Guard, int]


def _acceptance_bound(formula: Formula) -> int:
    """The number of distinct subformulas: the VWAA's states, hence its acceptance states,
    are among them."""
    seen: set[Formula] = set()
    stack = [formula]
    while stack:
        f = stack.pop()
        if f not in seen:
            seen.add(f)
            stack.extend(children(f))
    return len(seen)


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
    # Domination = strict subset of this key (keys are distinct: one group per (targets, bad)),
    # so a dominator has fewer bits: each group is compared with those of fewer bits only.
    # The difference does not depend on the order in which the dominators are subtracted.
    keyed = sorted(((t << shift | b).bit_count(), t << shift | b, g) for t, b, g, _l in groups)
    result = []
    for targets, bad, guard, lits in groups:
        ki = targets << shift | bad
        size, nki = ki.bit_count(), ~ki
        # Dominator by dominator, only those that share letters: cheaper than one union of
        # them all (most share none).
        for kbits, kj, g in keyed:
            if kbits >= size:
                break
            if not kj & nki and guard & g:
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
        if len(signatures) == n:  # every state apart: nothing left to refine or merge
            return tgba
        if len(signatures) == num_blocks:
            break
        block, num_blocks = new_block, len(signatures)
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
    # A quotient of a deterministic automaton is deterministic: each block keeps the edges of
    # one member, grouped by destination block.
    return Tgba(num_blocks, initial, out, tgba.num_marks, tgba.deterministic)


def _signature(edges, block, false):
    grouped: dict[tuple[int, int], Guard] = {}
    for dst, guard, marks in edges:
        key = (block[dst], marks)
        grouped[key] = grouped.get(key, false) | guard
    return grouped.items()
