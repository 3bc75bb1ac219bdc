"""Negation normal form and language-preserving simplification (ltl-planning.md §2, "Small").

``normalize(f)`` returns an equivalent formula built only from ``true``, ``false``, atoms,
negated atoms, n-ary ``And``/``Or``, ``X``, ``F``, ``G``, ``U`` and ``R`` (``W``, ``M``, ``->``,
``<->``, ``xor`` are expanded), simplified bottom-up by smart constructors that apply rules of
Somenzi & Bloem (CAV 2000) and Etessami & Holzmann (CONCUR 2000), using the classes of
*eventual* formulas (e ≡ F e) and *universal* formulas (u ≡ G u):

* ``F F x = F x``, ``F(x & s) = F x & s`` and ``F s = s`` for
  suspendable s (eventual and universal), duals for ``G``;
* ``G F (x & e1 & …) = G F x & G F e1 & …`` for eventual ``ei``, dually
  ``F G (x | u1 | …) = F G x | F G u1 | …``; hence ``GF(a1 & F(a2 & … F an))`` becomes
  ``GF a1 & … & GF an``, whose automaton has n+1 states instead of exponentially many;
* ``X x & X y = X(x & y)``, ``X x | X y = X(x | y)``, ``F x | F y = F(x | y)`` (Spot's
  ``tl_simplifier``): the automaton chooses the disjunct in one
  state instead of starting with one state per ``F``;
* ``a U (b | G a) = (a U b) | G a = a W b`` and dually ``a R (b & F a) = (a R b) & F a =
  a M b`` (Spot);
* ``x U e = e`` for eventual e, ``x R u = u`` for universal u, ``true U x = F x``,
  ``false R x = G x``; Boolean constant folding, flattening, duplicate and complement removal.

Every rule is an equivalence; the property tests compare automata with exact lasso evaluation.
"""

from __future__ import annotations

from tlfleet.agent.ltl.formula import (
    FALSE,
    TRUE,
    And,
    Atom,
    Const,
    Equiv,
    Finally,
    Formula,
    Globally,
    Implies,
    Next,
    Not,
    Or,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
    Xor,
)


def is_eventual(f: Formula) -> bool:
    """Purely eventual: ``f ≡ F f`` (holds now iff it holds at some later step)."""
    match f:
        case Const() | Finally():
            return True
        case And(args) | Or(args):
            return all(is_eventual(a) for a in args)
        case Next(a) | Globally(a):
            return is_eventual(a)
        case Until(_, b):
            return is_eventual(b)
    return False


def is_universal(f: Formula) -> bool:
    """Purely universal: ``f ≡ G f`` (holds now iff it holds at every later step)."""
    match f:
        case Const() | Globally():
            return True
        case And(args) | Or(args):
            return all(is_universal(a) for a in args)
        case Next(a) | Finally(a):
            return is_universal(a)
        case Release(_, b):
            return is_universal(b)
    return False


def is_suspendable(f: Formula) -> bool:
    return is_eventual(f) and is_universal(f)


def _complement(f: Formula) -> Formula | None:
    """The complementary literal of a literal, else ``None``."""
    match f:
        case Atom():
            return Not(f)
        case Not(Atom() as a):
            return a
    return None


def mk_and(args) -> Formula:
    """Flattened, constant-folded, duplicate-free conjunction."""
    flat: list[Formula] = []
    seen: set[Formula] = set()
    stack = list(reversed(list(args)))
    while stack:
        a = stack.pop()
        if isinstance(a, And):
            stack.extend(reversed(a.args))
            continue
        if a == TRUE or a in seen:
            continue
        if a == FALSE:
            return FALSE
        comp = _complement(a)
        if comp is not None and comp in seen:
            return FALSE
        seen.add(a)
        flat.append(a)
    if not flat:
        return TRUE
    nexts = [a for a in flat if isinstance(a, Next)]
    if len(nexts) > 1:  # X x & X y = X(x & y)
        return _merged(flat, nexts, mk_next(mk_and(a.arg for a in nexts)), mk_and)
    for r in flat:  # (a R b) & F a = a M b = b U (a & b)
        if isinstance(r, Release) and Finally(r.left) in seen:
            strong = mk_until(r.right, mk_and([r.left, r.right]))
            return _merged(flat, [r, Finally(r.left)], strong, mk_and)
    if len(flat) == 1:
        return flat[0]
    return And(tuple(flat))


def mk_or(args) -> Formula:
    """Flattened, constant-folded, duplicate-free disjunction."""
    flat: list[Formula] = []
    seen: set[Formula] = set()
    stack = list(reversed(list(args)))
    while stack:
        a = stack.pop()
        if isinstance(a, Or):
            stack.extend(reversed(a.args))
            continue
        if a == FALSE or a in seen:
            continue
        if a == TRUE:
            return TRUE
        comp = _complement(a)
        if comp is not None and comp in seen:
            return TRUE
        seen.add(a)
        flat.append(a)
    if not flat:
        return FALSE
    eventually = [a for a in flat if isinstance(a, Finally)]
    if len(eventually) > 1:  # F x | F y = F(x | y): one state chooses instead of several
        return _merged(flat, eventually, mk_finally(mk_or(a.arg for a in eventually)), mk_or)
    nexts = [a for a in flat if isinstance(a, Next)]
    if len(nexts) > 1:  # X x | X y = X(x | y)
        return _merged(flat, nexts, mk_next(mk_or(a.arg for a in nexts)), mk_or)
    for u in flat:  # (a U b) | G a = a W b = b R (a | b)
        if isinstance(u, Until) and Globally(u.left) in seen:
            weak = mk_release(u.right, mk_or([u.left, u.right]))
            return _merged(flat, [u, Globally(u.left)], weak, mk_or)
    for g in flat:
        # G a | F(!a & e) = a W (!a & e) for a literal a and eventual e: F(!a & e) = a U (!a & e)
        # (e holding at some !a-position holds at the first one, e being eventual).
        comp = _complement(g.arg) if isinstance(g, Globally) else None
        if comp is None:
            continue
        for f in flat:
            if (isinstance(f, Finally) and isinstance(f.arg, And) and comp in f.arg.args
                    and all(x == comp or is_eventual(x) for x in f.arg.args)):
                weak = mk_release(f.arg, mk_or([g.arg, f.arg]))
                return _merged(flat, [g, f], weak, mk_or)
    if len(flat) == 1:
        return flat[0]
    return Or(tuple(flat))


def _merged(flat: list[Formula], parts: list[Formula], merged: Formula, mk) -> Formula:
    """``flat`` with ``parts`` replaced by ``merged`` at the place of the first part."""
    first = flat.index(parts[0])
    dropped = set(parts)  # ``flat`` is duplicate-free
    rest = [a for a in flat if a not in dropped]
    position = sum(1 for a in flat[:first] if a not in dropped)
    return mk([*rest[:position], merged, *rest[position:]])


def mk_next(a: Formula) -> Formula:
    if isinstance(a, Const) or is_suspendable(a):
        return a
    return Next(a)


def mk_finally(a: Formula) -> Formula:
    match a:
        case Const() | Finally():
            return a
        case Until(_, b):
            return mk_finally(b)
        case And(args):
            suspendable = [x for x in args if is_suspendable(x)]
            if suspendable:
                rest = [x for x in args if not is_suspendable(x)]
                return mk_and([mk_finally(mk_and(rest)), *suspendable])
        case Globally(Finally() as inner):
            return Globally(inner)  # F G F x = G F x
    if is_suspendable(a):
        return a
    return Finally(a)


def mk_globally(a: Formula) -> Formula:
    match a:
        case Const() | Globally():
            return a
        case Release(_, b):
            return mk_globally(b)
        case And(args):
            return mk_and(mk_globally(x) for x in args)
        case Or(args):
            suspendable = [x for x in args if is_suspendable(x)]
            if suspendable:
                rest = [x for x in args if not is_suspendable(x)]
                return mk_or([mk_globally(mk_or(rest)), *suspendable])
        case Finally(Globally() as inner):
            return Finally(inner)  # G F G x = F G x
        case Finally(And(args)):
            eventual = [x for x in args if is_eventual(x)]
            if eventual:
                rest = [x for x in args if not is_eventual(x)]
                parts = [mk_globally(mk_finally(e)) for e in eventual]
                if rest:
                    parts.append(mk_globally(mk_finally(mk_and(rest))))
                return mk_and(parts)
    if is_suspendable(a):
        return a
    return Globally(a)


def _mk_fg(a: Formula) -> Formula:
    """``F G a`` with ``F G (x | u1 | …) = F G x | F G u1 | …`` for universal ``ui``."""
    if isinstance(a, Or):
        universal = [x for x in a.args if is_universal(x)]
        if universal:
            rest = [x for x in a.args if not is_universal(x)]
            parts = [mk_finally(mk_globally(u)) for u in universal]
            if rest:
                parts.append(mk_finally(mk_globally(mk_or(rest))))
            return mk_or(parts)
    return mk_finally(mk_globally(a))


def mk_until(a: Formula, b: Formula) -> Formula:
    if b in (TRUE, FALSE) or a in (FALSE, b):
        return b
    if a == TRUE:
        return mk_finally(b)
    if is_eventual(b):
        return b
    if isinstance(b, Or) and Globally(a) in b.args:
        # a U (b' | G a) = a W b' = b' R (a | b')
        rest = mk_or(x for x in b.args if x != Globally(a))
        return mk_release(rest, mk_or([a, rest]))
    if isinstance(b, And) and a in b.args:
        rest = [x for x in b.args if x != a]
        if is_universal(a):  # a U (a & x) = a & F x: a holds now, hence forever
            return mk_and([a, mk_finally(mk_and(rest))])
        if all(is_eventual(x) for x in rest):  # a U (a & e) = e M a = a & e
            return b
    return Until(a, b)


def mk_release(a: Formula, b: Formula) -> Formula:
    if b in (TRUE, FALSE) or a in (TRUE, b):
        return b
    if a == FALSE:
        return mk_globally(b)
    if is_universal(b):
        return b
    if isinstance(b, And) and Finally(a) in b.args:
        # a R (b' & F a) = a M b' = b' U (a & b')
        rest = mk_and(x for x in b.args if x != Finally(a))
        return mk_until(rest, mk_and([a, rest]))
    if isinstance(b, Or) and a in b.args:
        rest = [x for x in b.args if x != a]
        if is_eventual(a):  # a R (a | x) = a | G x: a fails now, hence forever
            return mk_or([a, mk_globally(mk_or(rest))])
        if all(is_universal(x) for x in rest):  # a R (a | u) = u W a = a | u
            return b
    return Release(a, b)


def normalize(f: Formula) -> Formula:
    """Equivalent simplified formula in negation normal form (see module docstring)."""
    return _nnf(f, negate=False, memo={})


def _nnf(f: Formula, negate: bool, memo: dict) -> Formula:
    key = (f, negate)
    if key in memo:
        return memo[key]
    result = _nnf_uncached(f, negate, memo)
    memo[key] = result
    return result


def _nnf_uncached(f: Formula, neg: bool, memo: dict) -> Formula:
    def pos(x: Formula) -> Formula:
        return _nnf(x, False, memo)

    def negd(x: Formula) -> Formula:
        return _nnf(x, True, memo)

    match f:
        case Const(value):
            return Const(value != neg)
        case Atom():
            return Not(f) if neg else f
        case Not(a):
            return _nnf(a, not neg, memo)
        case Next(a):
            return mk_next(negd(a) if neg else pos(a))
        case Finally(a):
            if neg:
                return mk_globally(negd(a))
            inner = pos(a)
            if isinstance(inner, Globally):
                return _mk_fg(inner.arg)
            return mk_finally(inner)
        case Globally(a):
            if neg:
                inner = negd(a)
                if isinstance(inner, Globally):
                    return _mk_fg(inner.arg)
                return mk_finally(inner)
            return mk_globally(pos(a))
        case And(args):
            if neg:
                return mk_or(negd(a) for a in args)
            return mk_and(pos(a) for a in args)
        case Or(args):
            if neg:
                return mk_and(negd(a) for a in args)
            return mk_or(pos(a) for a in args)
        case Implies(a, b):
            if neg:
                return mk_and([pos(a), negd(b)])
            return mk_or([negd(a), pos(b)])
        case Equiv(a, b) | Xor(a, b):
            if isinstance(f, Xor):
                neg = not neg
            if neg:
                return mk_or([mk_and([pos(a), negd(b)]), mk_and([negd(a), pos(b)])])
            return mk_or([mk_and([pos(a), pos(b)]), mk_and([negd(a), negd(b)])])
        case Until(a, b):
            if neg:
                return mk_release(negd(a), negd(b))
            return mk_until(pos(a), pos(b))
        case Release(a, b):
            if neg:
                return mk_until(negd(a), negd(b))
            return mk_release(pos(a), pos(b))
        case WeakUntil(a, b):
            # a W b = b R (a | b);  !(a W b) = !b U (!a & !b)
            if neg:
                return mk_until(negd(b), mk_and([negd(a), negd(b)]))
            return mk_release(pos(b), mk_or([pos(a), pos(b)]))
        case StrongRelease(a, b):
            # a M b = b U (a & b);  !(a M b) = !b R (!a | !b)
            if neg:
                return mk_release(negd(b), mk_or([negd(a), negd(b)]))
            return mk_until(pos(b), mk_and([pos(a), pos(b)]))
    raise TypeError(f"not an LTL formula: {f!r}")
