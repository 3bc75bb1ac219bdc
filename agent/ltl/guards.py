"""Boolean guards over the atomic propositions (ltl-planning.md §2).

Atoms are numbered ``0..n-1`` (their order in the automaton's ``atoms`` tuple); a letter
σ ⊆ AP is encoded as its *valuation*, the int bitmask with bit ``i`` set iff atom ``i`` ∈ σ.

Two representations:

* a **cube** (conjunction of literals) is the pair ``(pos, neg)`` of disjoint atom bitmasks; the
  alternating-automaton construction works on cubes;
* a **guard** on an automaton edge is a reduced ordered BDD (``tlfleet.agent.ltl.bdd``): canonical,
  so equal guards are the same object; union ``|``, intersection ``&``, difference ``-`` and
  complement ``~`` cost in the size of the diagrams, not in the 2ⁿ letters, and
  ``guard.holds(v)`` evaluates it on a letter in at most ``n`` steps. (A guard as a 2ⁿ-bit truth
  table would limit a task to about 20 atoms.)

``Alphabet.cubes(guard)`` turns a guard into an irredundant sum of cubes (Minato–Morreale ISOP
on the BDD) for printing (HOA, text, dot).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from tlfleet.agent.ltl import bdd
from tlfleet.agent.ltl.bdd import FALSE, TRUE, Bdd
from tlfleet.bus.errors import LtlError

Cube = tuple[int, int]
Guard = Bdd

MAX_ATOMS = 4096
"""Atomic propositions per formula; far beyond any mission, a guard's cost is its BDD size."""


class TooManyPropositions(LtlError):
    """A formula with more atomic propositions than :data:`MAX_ATOMS`."""

    def __init__(self, count: int):
        self.count = count
        super().__init__(
            f"the formula has {count} atomic propositions; at most {MAX_ATOMS} are supported"
        )


TRUE_CUBE: Cube = (0, 0)


def cube_and(a: Cube, b: Cube) -> Cube | None:
    """Conjunction of two cubes, ``None`` when it is unsatisfiable."""
    pos = a[0] | b[0]
    neg = a[1] | b[1]
    if pos & neg:
        return None
    return (pos, neg)


def cube_implies(a: Cube, b: Cube) -> bool:
    """``a ⇒ b``: every literal of ``b`` is in ``a``."""
    return (a[0] & b[0]) == b[0] and (a[1] & b[1]) == b[1]


def guard_holds(guard: Guard, valuation: int) -> bool:
    """Whether the letter with bitmask ``valuation`` satisfies ``guard``."""
    return guard.holds(valuation)


def valuation(letter: Iterable[str], index: dict[str, int]) -> int:
    """Bitmask of the letter ``letter`` (a set of atom names); atoms outside ``index`` ignored."""
    mask = 0
    for name in letter:
        i = index.get(name)
        if i is not None:
            mask |= 1 << i
    return mask


class Alphabet:
    """Guards over ``n`` atoms: ``full`` (true), the atoms' guards, cubes ↔ guards."""

    def __init__(self, n: int):
        if n > MAX_ATOMS:
            raise TooManyPropositions(n)
        self.n = n
        self.full = TRUE
        self.empty = FALSE
        self.atom = [bdd.var(i) for i in range(n)]

    @staticmethod
    def cube(cube: Cube) -> Guard:
        """The guard of a cube."""
        return bdd.cube(cube[0], cube[1])

    def cubes(self, guard: Guard) -> list[Cube]:
        """An irredundant sum of cubes equal to ``guard`` (Minato–Morreale ISOP on the BDD)."""
        memo: dict[tuple[int, int], tuple[list[Cube], Bdd]] = {}
        cubes, _cover = _isop(guard, guard, memo)
        return sorted(cubes, key=self._literal_order)

    def _literal_order(self, cube: Cube) -> tuple[int, ...]:
        """Sort key: by atom index, positive before negative before absent."""
        both = cube[0] | cube[1]
        top = both.bit_length()
        return (*(0 if cube[0] >> i & 1 else 1 if cube[1] >> i & 1 else 2
                  for i in range(top)), 3)

    def to_string(self, guard: Guard, atoms: Sequence[str]) -> str:
        """Spot-syntax text of a guard (``true``/``false`` for the constants)."""
        if guard is FALSE:
            return "false"
        cubes = self.cubes(guard)
        parts = [cube_to_string(c, atoms) for c in cubes]
        if len(parts) == 1:
            return parts[0]
        return " | ".join(
            f"({p})" if (c[0] | c[1]).bit_count() > 1 else p
            for p, c in zip(parts, cubes, strict=True)
        )

    def smallest_letter(self, guard: Guard, atoms: Sequence[str]) -> frozenset[str]:
        """A letter satisfying ``guard`` with as few atoms as possible (guard must be non-zero):
        a shortest path to ``true`` counting only the ``high`` edges."""
        if guard is FALSE:
            raise ValueError("the guard false has no letter")
        cost: dict[int, tuple[int, int]] = {}  # uid -> (atoms needed, valuation)

        def best(node: Bdd) -> tuple[int, int]:
            if node is TRUE:
                return 0, 0
            if node is FALSE:
                return 1 << 30, 0
            found = cost.get(node.uid)
            if found is None:
                lo = best(node.low)
                hi = best(node.high)
                found = lo if lo[0] <= hi[0] + 1 else (hi[0] + 1, hi[1] | 1 << node.var)
                cost[node.uid] = found
            return found

        _count, v = best(guard)
        return frozenset(atoms[i] for i in range(self.n) if v >> i & 1)


def _cofactors(f: Bdd, v: int) -> tuple[Bdd, Bdd]:
    if f.var == v:
        return f.low, f.high
    return f, f


def _isop(lower: Bdd, upper: Bdd, memo) -> tuple[list[Cube], Bdd]:
    """Minato–Morreale: an irredundant cover C with lower ≤ C ≤ upper, and its BDD."""
    if lower is FALSE:
        return [], FALSE
    if upper is TRUE:
        return [TRUE_CUBE], TRUE
    key = (lower.uid, upper.uid)
    found = memo.get(key)
    if found is not None:
        return found
    v = min(lower.var, upper.var)
    l0, l1 = _cofactors(lower, v)
    u0, u1 = _cofactors(upper, v)
    c0, r0 = _isop(l0 - u1, u0, memo)
    c1, r1 = _isop(l1 - u0, u1, memo)
    rest_lower = (l0 - r0) | (l1 - r1)
    cs, rs = _isop(rest_lower, u0 & u1, memo)
    bit = 1 << v
    cubes = [(p, n | bit) for p, n in c0] + [(p | bit, n) for p, n in c1] + cs
    x = bdd.var(v)
    cover = (r0 - x) | (r1 & x) | rs
    memo[key] = (cubes, cover)
    return cubes, cover


def cube_to_string(cube: Cube, atoms: Sequence[str], *, and_: str = " & ",
                   not_: str = "!") -> str:
    """``a & !b`` (``true`` for the empty cube)."""
    parts = []
    for i, name in enumerate(atoms):
        if cube[0] >> i & 1:
            parts.append(name)
        elif cube[1] >> i & 1:
            parts.append(not_ + name)
    return and_.join(parts) if parts else "true"
