"""Syntactic implication and contradiction between LTL formulas in negation normal form.

``implies(f, g)`` is a sound, incomplete test of ``f ⇒ g`` (every word satisfying ``f``
satisfies ``g``) by structural rules, after Somenzi & Bloem, "Efficient Büchi automata from LTL
formulae" (CAV 2000), §4, whose relation ⪯ uses the same kind of rules, and the syntactic
implication of Spot's formula simplifier. It answers ``False`` when no rule applies, so a
``True`` is a proof and a ``False`` is no information.

``contradict(f, g)`` proves ``f ∧ g`` unsatisfiable: ``f ⇒ ¬g`` or ``g ⇒ ¬f``, with ``¬`` the
dual in negation normal form (:func:`negate`). The TGBA construction uses it to drop transitions
into conjunctions of VWAA states that no word satisfies (``tlfleet.agent.ltl.tgba``).

The rules, each a one-line argument on words (``e`` eventual: ``e ≡ F e``; ``u`` universal:
``u ≡ G u``; ``tlfleet.agent.ltl.rewrite``):

* ``f ⇒ f``; ``f ⇒ true``; ``false ⇒ g``;
* ``f ⇒ g1 ∧ g2`` if both hold; ``f1 ∨ f2 ⇒ g`` if both hold; ``f ⇒ g1 ∨ g2`` if ``f ⇒ g1`` or
  ``f ⇒ g2``; ``f1 ∧ f2 ⇒ g`` if ``f1 ⇒ g`` or ``f2 ⇒ g``;
* monotonicity: ``X``, ``F``, ``G``, ``U`` and ``R`` are monotone in every argument;
* ``f ⇒ F g1`` if ``f ⇒ g1``; ``f ⇒ g1 U g2`` if ``f ⇒ g2``; ``f ⇒ g1 R g2`` if
  ``f ⇒ g1`` and ``f ⇒ g2``, or if ``f ⇒ G g2``;
* for universal ``f``: ``f ⇒ G g1`` and ``f ⇒ X g1`` if ``f ⇒ g1``;
* ``G f1 ⇒ g`` and ``f2 R f1 ⇒ g`` if ``f1 ⇒ g``; ``f1 U f2 ⇒ g`` if ``f1 ⇒ g`` and
  ``f2 ⇒ g``;
* for eventual ``g``: ``F f1 ⇒ g``, ``X f1 ⇒ g`` and ``f2 U f1 ⇒ g`` if ``f1 ⇒ g``.
"""

from __future__ import annotations

from tlfleet.agent.ltl.formula import (
    And,
    Atom,
    Const,
    Finally,
    Formula,
    Globally,
    Next,
    Not,
    Or,
    Release,
    Until,
    children,
)
from tlfleet.agent.ltl.rewrite import is_eventual, is_universal


def negate(f: Formula) -> Formula:
    """``¬f`` in negation normal form, by duality (no simplification)."""
    return Implication({}).negation(f)


class Implication:
    """Memoised :meth:`implies` and :meth:`contradict` over the formulas of one translation.

    Formulas are first made canonical (hash-consed bottom-up: structurally equal formulas
    become one object, whose children are canonical too), so that equality is identity and
    every memo is keyed by identity (hashing or comparing a formula walks its whole tree).
    The instance keeps every formula it was asked about alive, so an identity is never reused
    while it lives. ``index`` numbers the atoms."""

    def __init__(self, index: dict[str, int]) -> None:
        self._index = index
        self._canonical: dict[tuple, Formula] = {}  # (kind, name or children's ids) -> node
        self._canonical_of: dict[int, tuple[Formula, Formula]] = {}  # id -> (formula, node)
        self._implies: dict[tuple[int, int], bool] = {}
        self._negation: dict[int, Formula] = {}
        self._polarity: dict[int, tuple[int, int]] = {}
        self._eventual: dict[int, bool] = {}
        self._universal: dict[int, bool] = {}

    def canonical(self, f: Formula) -> Formula:
        """The one object of this instance structurally equal to the NNF formula ``f``."""
        entry = self._canonical_of.get(id(f))
        if entry is not None:
            return entry[1]
        canon = self.canonical
        match f:
            case Atom(name):
                key, make = ("atom", name), lambda: f
            case Const(value):
                key, make = ("const", value), lambda: f
            case And(args) | Or(args):
                parts = tuple(canon(a) for a in args)
                key, make = (type(f), *map(id, parts)), lambda: type(f)(parts)
            case Until(a, b) | Release(a, b):
                left, right = canon(a), canon(b)
                key, make = (type(f), id(left), id(right)), lambda: type(f)(left, right)
            case Not(a) | Next(a) | Finally(a) | Globally(a):
                part = canon(a)
                key, make = (type(f), id(part)), lambda: type(f)(part)
            case _:
                raise TypeError(f"not a formula in negation normal form: {f}")
        node = self._canonical.get(key)
        if node is None:
            node = self._canonical[key] = make()
            self._canonical_of[id(node)] = (node, node)
        self._canonical_of[id(f)] = (f, node)
        return node

    def negation(self, f: Formula) -> Formula:
        """``¬f`` in negation normal form (:func:`negate`), canonical."""
        f = self.canonical(f)
        n = self._negation.get(id(f))
        if n is None:
            n = self._negation[id(f)] = self.canonical(self._negate(f))
        return n

    def _negate(self, f: Formula) -> Formula:
        neg = self.negation
        match f:
            case Const(value):
                return Const(not value)
            case Atom():
                return Not(f)
            case Not(Atom() as a):
                return a
            case And(args):
                return Or(tuple(neg(a) for a in args))
            case Or(args):
                return And(tuple(neg(a) for a in args))
            case Next(a):
                return Next(neg(a))
            case Finally(a):
                return Globally(neg(a))
            case Globally(a):
                return Finally(neg(a))
            case Until(a, b):
                return Release(neg(a), neg(b))
            case Release(a, b):
                return Until(neg(a), neg(b))
        raise TypeError(f"not a formula in negation normal form: {f}")

    def polarity(self, f: Formula) -> tuple[int, int]:
        """Bitmasks of the atoms occurring positively and negatively in ``f`` (canonical); a
        constant inside counts as every atom in both polarities."""
        entry = self._polarity.get(id(f))
        if entry is None:
            match f:
                case Atom(name):
                    entry = (1 << self._index[name], 0)
                case Not(Atom(name)):
                    entry = (0, 1 << self._index[name])
                case Const():
                    entry = ((1 << len(self._index)) - 1, (1 << len(self._index)) - 1)
                case _:
                    pos = neg = 0
                    for child in children(f):
                        p, n = self.polarity(child)
                        pos |= p
                        neg |= n
                    entry = (pos, neg)
            self._polarity[id(f)] = entry
        return entry

    def contradict(self, f: Formula, g: Formula) -> bool:
        """Whether ``f ∧ g`` is provably unsatisfiable (``f ⇒ ¬g`` needs a literal of ``f``
        whose complement is in ``g``: see :meth:`_prove`)."""
        f, g = self.canonical(f), self.canonical(g)
        pf, nf = self.polarity(f)
        pg, ng = self.polarity(g)
        if not (pf & ng or nf & pg):
            return False
        return self._imp(f, self.negation(g)) or self._imp(g, self.negation(f))

    def _is_eventual(self, f: Formula) -> bool:
        e = self._eventual.get(id(f))
        if e is None:
            e = self._eventual[id(f)] = is_eventual(f)
        return e

    def _is_universal(self, f: Formula) -> bool:
        u = self._universal.get(id(f))
        if u is None:
            u = self._universal[id(f)] = is_universal(f)
        return u

    def implies(self, f: Formula, g: Formula) -> bool:
        """Whether ``f ⇒ g`` follows from the rules of the module docstring."""
        return self._imp(self.canonical(f), self.canonical(g))

    def _imp(self, f: Formula, g: Formula) -> bool:
        key = (id(f), id(g))
        result = self._implies.get(key)
        if result is None:
            result = self._implies[key] = self._prove(f, g)
        return result

    def _prove(self, f: Formula, g: Formula) -> bool:
        """``f ⇒ g`` by the rules, for canonical ``f`` and ``g`` (equal iff identical)."""
        if f is g or (isinstance(g, Const) and g.value) or (isinstance(f, Const) and not f.value):
            return True
        # Every proof ends in axioms x ⇒ x (x a subformula of both, so a literal of the same
        # polarity in both) or ones with a constant (counted as every literal): without a
        # shared literal no rule can succeed.
        pf, nf = self.polarity(f)
        pg, ng = self.polarity(g)
        if not (pf & pg or nf & ng):
            return False
        imp = self._imp
        if isinstance(g, And):
            return all(imp(f, x) for x in g.args)
        if isinstance(f, Or):
            return all(imp(x, g) for x in f.args)
        if isinstance(g, Or) and any(imp(f, x) for x in g.args):
            return True
        if isinstance(f, And) and any(imp(x, g) for x in f.args):
            return True
        match g:
            case Finally(g1):
                if imp(f, g1) or (isinstance(f, Finally) and imp(f.arg, g1)):
                    return True
            case Globally(g1):
                if isinstance(f, Globally) and imp(f.arg, g1):
                    return True
                if self._is_universal(f) and imp(f, g1):
                    return True
            case Next(g1):
                if isinstance(f, Next) and imp(f.arg, g1):
                    return True
                if self._is_universal(f) and imp(f, g1):
                    return True
            case Until(g1, g2):
                if imp(f, g2):
                    return True
                if isinstance(f, Until) and imp(f.left, g1) and imp(f.right, g2):
                    return True
            case Release(g1, g2):
                if imp(f, g2) and imp(f, g1):
                    return True
                if isinstance(f, Release) and imp(f.left, g1) and imp(f.right, g2):
                    return True
                if isinstance(f, Globally) and imp(f.arg, g2):
                    return True
                if self._is_universal(f) and imp(f, g2):
                    return True
        match f:
            case Globally(f1):
                return imp(f1, g)
            case Release(_, f2):
                return imp(f2, g)
            case Until(f1, f2):
                if imp(f1, g) and imp(f2, g):
                    return True
                return self._is_eventual(g) and imp(f2, g)
            case Finally(f1) | Next(f1):
                return self._is_eventual(g) and imp(f1, g)
        return False


class Conflicts:
    """The contradictions (:meth:`Implication.contradict`) among the states of a VWAA that have
    been registered, as bitmasks: ``masks[q]`` has bit ``r`` when ``q ∧ r`` is provably empty.

    A conjunction of states (a bitmask) containing such a pair accepts no word. States are
    registered as they appear (the VWAA numbers them lazily); each new one is checked against
    all registered ones, so the masks are always complete for the registered states.
    ``version`` counts the changes, for callers that cache unions of masks."""

    def __init__(self, states: list[Formula], index: dict[str, int]):
        self._states = states
        self._implication = Implication(index)
        self.masks: dict[int, int] = {}
        self._registered = 0
        self.version = 0

    def register(self, targets: int) -> None:
        """Register every state of the bitmask ``targets``."""
        new = targets & ~self._registered
        states, masks, contradict = self._states, self.masks, self._implication.contradict
        while new:
            low = new & -new
            new ^= low
            r = low.bit_length() - 1
            mask = 0
            known = self._registered
            while known:
                bit = known & -known
                known ^= bit
                q = bit.bit_length() - 1
                if contradict(states[r], states[q]):
                    mask |= bit
                    masks[q] |= low
                    self.version += 1
            masks[r] = mask
            self._registered |= low

    def of(self, targets: int) -> int:
        """The states contradicting some state of ``targets`` (registered ones)."""
        result = 0
        masks = self.masks
        while targets:
            low = targets & -targets
            targets ^= low
            result |= masks[low.bit_length() - 1]
        return result

    def empty(self, targets: int) -> bool:
        """Whether the conjunction ``targets`` (registered states) contains a contradiction."""
        return bool(self.of(targets) & targets)
