"""Guards as bit-parallel truth tables while a TGBA is built over few atoms (ltl-planning.md §2).

Over ``n`` atoms a guard is a set of the 2ⁿ letters; as a Python int with one bit per letter,
``&``, ``|`` and ``& ~`` are single machine-word loops and an empty guard is ``0``. For the few
atoms of most formulas (≤ :data:`MAX_TABLE_ATOMS`) this is several times cheaper than the BDD
operations of :mod:`tlfleet.agent.ltl.bdd` in the inner loops of
:func:`tlfleet.agent.ltl.tgba.build_tgba` (per-letter domination, grouping, bisimulation) and of the
direct simulation (:mod:`tlfleet.agent.ltl.simulation`); the finished automaton's guards are
converted to the canonical BDDs, so the result is the same automaton, edge for edge. Beyond that
many atoms the construction keeps the BDDs (a table grows as 2ⁿ).

Both algebras offer ``false``, ``true``, ``cube(pos, neg)``, ``to_bdd(guard)`` and
``from_bdd(bdd)``; guards of
either support ``&``, ``|``, ``~`` (``a & ~b`` is the difference) and truthiness (non-empty).

Layout: the letter with valuation ``v`` (bit ``i`` = atom ``i``) is bit ``rev(v)`` of the table,
``rev`` reversing the ``n`` bits, so that atom 0 — the BDD's top variable — splits the table into
its lower half (atom 0 false) and upper half (atom 0 true), atom 1 each half into quarters, and so
on: :meth:`TableAlgebra.to_bdd` is the Shannon expansion read off the halves.
"""

from __future__ import annotations

from tlfleet.agent.ltl import bdd
from tlfleet.agent.ltl.bdd import Bdd

MAX_TABLE_ATOMS = 10
"""Most atoms for which guards are built as truth tables (2¹⁰ = 1024-bit ints)."""

_CONVERSION_LIMIT = 1 << 16


class TableAlgebra:
    """Truth tables over ``n`` atoms (``n`` ≤ :data:`MAX_TABLE_ATOMS`)."""

    def __init__(self, n: int):
        if not 0 <= n <= MAX_TABLE_ATOMS:
            raise ValueError(f"truth tables over {n} atoms: 0..{MAX_TABLE_ATOMS} supported")
        self.n = n
        size = 1 << n
        self.false = 0
        self.true = (1 << size) - 1
        # Atom i is bit n-1-i of a letter's position: runs of 2^(n-1-i) letters alternate
        # between false and true.
        self._atom: list[int] = []
        for i in range(n):
            run = 1 << (n - 1 - i)
            block = ((1 << run) - 1) << run  # run zeros, then run ones
            pattern = 0
            for start in range(0, size, 2 * run):
                pattern |= block << start
            self._atom.append(pattern)
        self._cubes: dict[tuple[int, int], int] = {}
        self._bdds: dict[tuple[int, int], Bdd] = {}
        self._whole: dict[int, Bdd] = {}  # to_bdd's answers, one lookup per guard
        self._tables: dict[Bdd, int] = {}

    def cube(self, pos: int, neg: int) -> int:
        """The letters where every atom of bitmask ``pos`` holds and none of ``neg``."""
        key = (pos, neg)
        table = self._cubes.get(key)
        if table is None:
            table = self.true if not pos & neg else 0
            both = (pos | neg) if table else 0
            while both:
                low = both & -both
                i = low.bit_length() - 1
                table &= self._atom[i] if pos & low else ~self._atom[i]
                both ^= low
            self._cubes[key] = table
        return table

    def from_bdd(self, guard: Bdd) -> int:
        """The truth table of a BDD over atoms ``0..n-1``."""
        if guard is bdd.FALSE:
            return 0
        if guard is bdd.TRUE:
            return self.true
        table = self._tables.get(guard)
        if table is None:
            atom = self._atom[guard.var]
            table = (self.from_bdd(guard.low) & ~atom) | (self.from_bdd(guard.high) & atom)
            if len(self._tables) > _CONVERSION_LIMIT:
                self._tables.clear()
            self._tables[guard] = table
        return table

    def to_bdd(self, table: int) -> Bdd:
        """The canonical BDD of the same set of letters."""
        node = self._whole.get(table)
        if node is None:
            if len(self._bdds) > _CONVERSION_LIMIT:
                self._bdds.clear()
                self._whole.clear()
            node = self._whole[table] = self._convert(table, self.n)
        return node

    def _convert(self, table: int, k: int) -> Bdd:
        # ``table`` over the last k atoms (2^k bits): atoms n-k .. n-1.
        if table == 0:
            return bdd.FALSE
        half = 1 << (k - 1) if k else 0
        if k == 0 or table == (1 << (1 << k)) - 1:
            return bdd.TRUE
        key = (table, k)
        node = self._bdds.get(key)
        if node is None:
            low = self._convert(table & ((1 << half) - 1), k - 1)
            high = self._convert(table >> half, k - 1)
            node = self._bdds[key] = bdd.node(self.n - k, low, high)
        return node


class BddAlgebra:
    """The BDDs themselves (any number of atoms); ``to_bdd`` is the identity."""

    false = bdd.FALSE
    true = bdd.TRUE

    @staticmethod
    def cube(pos: int, neg: int) -> Bdd:
        return bdd.cube(pos, neg)

    @staticmethod
    def to_bdd(guard: Bdd) -> Bdd:
        return guard

    from_bdd = to_bdd


_tables: dict[int, TableAlgebra] = {}


def guard_algebra(n: int) -> TableAlgebra | BddAlgebra:
    """Truth tables for ``n`` ≤ :data:`MAX_TABLE_ATOMS` atoms (one shared instance per ``n``),
    BDDs beyond."""
    if n > MAX_TABLE_ATOMS:
        return BddAlgebra()
    algebra = _tables.get(n)
    if algebra is None:
        algebra = _tables[n] = TableAlgebra(n)
    return algebra
