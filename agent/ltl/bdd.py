"""A small reduced ordered BDD package for edge guards (ltl-planning.md §2, "symbolic guards").

Bryant (1986), "Graph-based algorithms for Boolean function manipulation": a guard is a node of
a shared, hash-consed DAG; variable ``i`` is atom ``i`` of the automaton and variables are
ordered by index (the atoms' order of first occurrence). Reduced and shared, so two guards are
equal iff they are the *same object*: ``==``, ``hash`` and dict keys are O(1), which the
reductions (signatures of states, grouping of edges) rely on. Cost grows with the size of the
diagrams, not with the 2ⁿ letters.

Why not the ``dd`` package: its fast backend (CUDD) is a compiled extension that is not always
installable, and its pure-Python backend does the same work as this module behind a more
general API (dynamic reordering, reference counting) that the translator does not need; here a
guard is a plain Python object with ``& | ~ -`` and evaluation on a letter's bitmask.

Nodes are never freed (the table only grows, by a few thousand nodes per formula); the
operation caches are cleared when they grow large.
"""

from __future__ import annotations

__all__ = ["FALSE", "TRUE", "Bdd", "conjoin", "cube", "disjoin", "node", "pick_valuation", "var"]

_TERMINAL_VAR = 1 << 30


class Bdd:
    """A node: ``var`` (atom index), ``low`` (var false) and ``high`` (var true) children.

    Terminals have ``var == 2**30``. Use the module's :data:`TRUE`, :data:`FALSE`, :func:`var`
    and the operators; never build nodes directly.
    """

    __slots__ = ("high", "low", "uid", "var")

    def __init__(self, var: int, low: Bdd | None, high: Bdd | None, uid: int):
        self.var = var
        self.low = low
        self.high = high
        self.uid = uid

    # Identity semantics: canonical nodes, so equal functions are the same object.
    __hash__ = object.__hash__

    def __eq__(self, other: object) -> bool:
        return self is other

    def __bool__(self) -> bool:
        return self is not FALSE

    def __and__(self, other: Bdd) -> Bdd:
        return _apply(self, other, TRUE, FALSE, _and_cache)

    def __or__(self, other: Bdd) -> Bdd:
        return _apply(self, other, FALSE, TRUE, _or_cache)

    def __invert__(self) -> Bdd:
        return _not(self)

    def __sub__(self, other: Bdd) -> Bdd:
        return _apply(self, _not(other), TRUE, FALSE, _and_cache)

    def __repr__(self) -> str:
        if self is TRUE:
            return "Bdd(true)"
        if self is FALSE:
            return "Bdd(false)"
        return f"Bdd(#{self.uid}: x{self.var} ? #{self.high.uid} : #{self.low.uid})"

    def holds(self, valuation: int) -> bool:
        """Whether the letter with bitmask ``valuation`` (bit i = atom i) satisfies the guard."""
        node = self
        while node.var != _TERMINAL_VAR:
            node = node.high if valuation >> node.var & 1 else node.low
        return node is TRUE

    def implies(self, other: Bdd) -> bool:
        """``self ⇒ other`` (every letter of ``self`` satisfies ``other``), without building
        ``self & ~other``."""
        return _leq(self, other)

    def support(self) -> int:
        """Bitmask of the variables the guard depends on."""
        seen: set[int] = set()
        mask = 0
        stack = [self]
        while stack:
            node = stack.pop()
            if node.var == _TERMINAL_VAR or node.uid in seen:
                continue
            seen.add(node.uid)
            mask |= 1 << node.var
            stack.append(node.low)
            stack.append(node.high)
        return mask


FALSE = Bdd(_TERMINAL_VAR, None, None, 0)
TRUE = Bdd(_TERMINAL_VAR, None, None, 1)

_unique: dict[tuple[int, int, int], Bdd] = {}
_and_cache: dict[tuple[int, int], Bdd] = {}
_or_cache: dict[tuple[int, int], Bdd] = {}
_not_cache: dict[int, Bdd] = {}
_CACHE_LIMIT = 1 << 18


def _mk(v: int, low: Bdd, high: Bdd) -> Bdd:
    if low is high:
        return low
    key = (v, low.uid, high.uid)
    node = _unique.get(key)
    if node is None:
        node = Bdd(v, low, high, len(_unique) + 2)
        _unique[key] = node
    return node


def node(i: int, low: Bdd, high: Bdd) -> Bdd:
    """The guard "if atom ``i`` then ``high`` else ``low``", for ``low`` and ``high`` over atoms
    after ``i`` only (so the node is in order; :mod:`tlfleet.agent.ltl.truth_table` builds BDDs
    so)."""
    if low.var <= i or high.var <= i:
        raise ValueError(f"bdd.node: children must not test atom {i} or an earlier one")
    return _mk(i, low, high)


def var(i: int) -> Bdd:
    """The guard "atom ``i`` holds"."""
    return _mk(i, FALSE, TRUE)


def _apply(a: Bdd, b: Bdd, unit: Bdd, zero: Bdd, cache: dict[tuple[int, int], Bdd]) -> Bdd:
    """Bryant's apply for a commutative operator with neutral ``unit`` and absorbing ``zero``
    (``&``: TRUE, FALSE; ``|``: FALSE, TRUE), memoised in ``cache``."""
    if a is b or b is unit:
        return a
    if a is unit:
        return b
    if a is zero or b is zero:
        return zero
    if a.uid > b.uid:
        a, b = b, a
    key = (a.uid, b.uid)
    r = cache.get(key)
    if r is not None:
        return r
    va, vb = a.var, b.var
    if va == vb:
        r = _mk(va, _apply(a.low, b.low, unit, zero, cache),
                _apply(a.high, b.high, unit, zero, cache))
    elif va < vb:
        r = _mk(va, _apply(a.low, b, unit, zero, cache), _apply(a.high, b, unit, zero, cache))
    else:
        r = _mk(vb, _apply(a, b.low, unit, zero, cache), _apply(a, b.high, unit, zero, cache))
    if len(cache) > _CACHE_LIMIT:
        cache.clear()
    cache[key] = r
    return r


def _not(a: Bdd) -> Bdd:
    if a is TRUE:
        return FALSE
    if a is FALSE:
        return TRUE
    r = _not_cache.get(a.uid)
    if r is None:
        r = _mk(a.var, _not(a.low), _not(a.high))
        if len(_not_cache) > _CACHE_LIMIT:
            _not_cache.clear()
        _not_cache[a.uid] = r
    return r


_leq_cache: dict[tuple[int, int], bool] = {}


def _leq(a: Bdd, b: Bdd) -> bool:
    if a is FALSE or b is TRUE or a is b:
        return True
    if a is TRUE or b is FALSE:
        return False
    key = (a.uid, b.uid)
    r = _leq_cache.get(key)
    if r is None:
        va, vb = a.var, b.var
        if va == vb:
            r = _leq(a.low, b.low) and _leq(a.high, b.high)
        elif va < vb:
            r = _leq(a.low, b) and _leq(a.high, b)
        else:
            r = _leq(a, b.low) and _leq(a, b.high)
        if len(_leq_cache) > _CACHE_LIMIT:
            _leq_cache.clear()
        _leq_cache[key] = r
    return r


def cube(pos: int, neg: int) -> Bdd:
    """The conjunction of the atoms in bitmask ``pos`` and the negations of those in ``neg``."""
    if pos & neg:
        return FALSE
    result = TRUE
    both = pos | neg
    while both:  # highest variable first, so each step adds one node on top
        i = both.bit_length() - 1
        bit = 1 << i
        result = _mk(i, FALSE, result) if pos & bit else _mk(i, result, FALSE)
        both ^= bit
    return result


def disjoin(guards) -> Bdd:
    """OR of many guards, combined pairwise (balanced) to keep intermediate diagrams small."""
    items = [g for g in guards if g is not FALSE]
    if not items:
        return FALSE
    if len(items) > 8:  # neighbours in variable order first: small intermediate diagrams
        items.sort(key=_first_path)
    while len(items) > 1:
        items = [items[i] | items[i + 1] if i + 1 < len(items) else items[i]
                 for i in range(0, len(items), 2)]
    return items[0]


def _first_path(g: Bdd) -> tuple[int, ...]:
    """The first path to ``true`` (low branch preferred) as (var·2 + branch) steps."""
    steps = []
    node = g
    while node.var != _TERMINAL_VAR:
        if node.low is not FALSE:
            steps.append(2 * node.var)
            node = node.low
        else:
            steps.append(2 * node.var + 1)
            node = node.high
    return tuple(steps)


def pick_valuation(g: Bdd) -> int:
    """One letter (bitmask) satisfying ``g``: the first path to ``true``, other atoms false.
    ``g`` must not be :data:`FALSE`."""
    if g is FALSE:
        raise ValueError("pick_valuation of the false guard")
    v = 0
    node = g
    while node.var != _TERMINAL_VAR:
        if node.low is not FALSE:
            node = node.low
        else:
            v |= 1 << node.var
            node = node.high
    return v


def conjoin(guards) -> Bdd:
    result = TRUE
    for g in guards:
        result = result & g
        if result is FALSE:
            break
    return result
