"""Boolean guards over the atomic propositions (ltl-planning.md §2).

Atoms are numbered ``0..n-1`` (their order in the automaton's ``atoms`` tuple); a letter
σ ⊆ AP is encoded as its *valuation*, the int bitmask with bit ``i`` set iff atom ``i`` ∈ σ.

Two representations:

* a **cube** (conjunction of literals) is the pair ``(pos, neg)`` of disjoint atom bitmasks; the
  alternating-automaton construction works on cubes;
* a **guard** on an automaton edge is a *truth table*: an int with ``2^n`` bits whose bit ``v``
  is set iff the guard holds on the letter with valuation ``v``. Union, intersection, difference
  and equality are single int operations and evaluation is ``guard >> v & 1``, which keeps the
  reductions and the product construction fast. Robot missions have a handful of atoms; at
  ``n = 16`` a table is 8 KiB.

``Alphabet.cubes(guard)`` turns a table back into an irredundant sum of cubes (Minato–Morreale
ISOP) for printing (HOA, text, dot).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

Cube = tuple[int, int]
Guard = int

MAX_ATOMS = 20  # a guard is then a 2^20-bit (128 KiB) int; robot missions use a handful


class TooManyPropositions(ValueError):
    """A formula with more atomic propositions than truth-table guards support."""

    def __init__(self, count: int):
        self.count = count
        super().__init__(
            f"the formula has {count} atomic propositions; at most {MAX_ATOMS} are supported "
            f"(edge guards are truth tables over the 2^n letters)"
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
    return bool(guard >> valuation & 1)


def valuation(letter: Iterable[str], index: dict[str, int]) -> int:
    """Bitmask of the letter ``letter`` (a set of atom names); atoms outside ``index`` ignored."""
    mask = 0
    for name in letter:
        i = index.get(name)
        if i is not None:
            mask |= 1 << i
    return mask


class Alphabet:
    """Truth tables over ``n`` atoms: ``full`` (true), the atoms' tables, cubes ↔ tables."""

    def __init__(self, n: int):
        if n > MAX_ATOMS:
            raise TooManyPropositions(n)
        self.n = n
        width = 1 << n
        self.full = (1 << width) - 1
        self.atom = []
        for i in range(n):
            half = 1 << i
            block = ((1 << half) - 1) << half  # the upper half of a 2^(i+1)-bit block
            repeat = self.full // ((1 << (2 * half)) - 1)
            self.atom.append(block * repeat)

    def cube(self, cube: Cube) -> Guard:
        """Truth table of a cube."""
        table = self.full
        pos, neg = cube
        i = 0
        while pos or neg:
            if pos & 1:
                table &= self.atom[i]
            elif neg & 1:
                table &= ~self.atom[i]
            pos >>= 1
            neg >>= 1
            i += 1
        return table & self.full

    def cubes(self, guard: Guard) -> list[Cube]:
        """An irredundant sum of cubes equal to ``guard`` (Minato–Morreale ISOP)."""
        cubes, _cover = self._isop(guard, guard, self.n - 1)
        return sorted(cubes, key=self._literal_order)

    def _literal_order(self, cube: Cube) -> tuple[int, ...]:
        """Sort key: by atom index, positive before negative before absent."""
        return tuple(0 if cube[0] >> i & 1 else 1 if cube[1] >> i & 1 else 2
                     for i in range(self.n))

    def _cofactors(self, f: int, i: int) -> tuple[int, int]:
        """(f with atom i false, f with atom i true), each as a table not depending on atom i."""
        t = self.atom[i]
        shift = 1 << i
        low = f & ~t & self.full
        high = f & t
        return low | (low << shift), high | (high >> shift)

    def _isop(self, lower: int, upper: int, i: int) -> tuple[list[Cube], int]:
        if lower == 0:
            return [], 0
        if upper == self.full:
            return [TRUE_CUBE], self.full
        # Skip atoms both bounds ignore.
        while i >= 0:
            l0, l1 = self._cofactors(lower, i)
            u0, u1 = self._cofactors(upper, i)
            if l0 != l1 or u0 != u1:
                break
            i -= 1
        t = self.atom[i]
        c0, r0 = self._isop(l0 & ~u1 & self.full, u0, i - 1)
        c1, r1 = self._isop(l1 & ~u0 & self.full, u1, i - 1)
        rest_lower = (l0 & ~r0 | l1 & ~r1) & self.full
        cs, rs = self._isop(rest_lower, u0 & u1, i - 1)
        bit = 1 << i
        cubes = [(p, n | bit) for p, n in c0] + [(p | bit, n) for p, n in c1] + cs
        cover = (r0 & ~t | r1 & t | rs) & self.full
        return cubes, cover

    def to_string(self, guard: Guard, atoms: Sequence[str]) -> str:
        """Spot-syntax text of a guard (``true``/``false`` for the constants)."""
        if guard == 0:
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
        """A letter satisfying ``guard`` with as few atoms as possible (guard must be non-zero)."""
        best = min((v for v in range(1 << self.n) if guard >> v & 1), key=int.bit_count)
        return frozenset(atoms[i] for i in range(self.n) if best >> i & 1)


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
