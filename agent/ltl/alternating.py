"""Very weak alternating automaton of an NNF formula (Gastin & Oddoux, CAV 2001, §3).

The states of the VWAA are the temporal subformulas (and literals under ``X``) of the normalised
formula; a transition is a pair ``(cube, targets)``: read a letter satisfying ``cube``, then every
state in ``targets`` must accept the rest of the word (a conjunction). ``delta(f)`` is the
disjunction of such pairs for any NNF formula:

    δ(p) = {(p, ∅)}                        δ(x ∧ y) = δ(x) ⊗ δ(y)     δ(x ∨ y) = δ(x) ∪ δ(y)
    δ(X x) = {(⊤, e) | e ∈ x̄}              δ(x U y) = δ(y) ∪ δ(x) ⊗ {(⊤, {x U y})}
    δ(F x) = δ(x) ∪ {(⊤, {F x})}           δ(x R y) = δ(y) ⊗ (δ(x) ∪ {(⊤, {x R y})})
    δ(G x) = δ(x) ⊗ {(⊤, {G x})}

where x̄ is the DNF of ``x`` over states. Acceptance is on transitions (as in LTL3BA, Babiak et
al., TACAS 2012): a *good* transition of an ``U``/``F`` state is one that leaves it; ``G F x`` is
a single state whose good transitions are those that fulfil ``x`` now,
δ(G F x) = δ(x) ⊗ {(⊤, {G F x})} (good) ∪ {(⊤, {G F x})}, so that conjunctions of ``G F``
formulas give one generalised Büchi state instead of exponentially many. A run is accepting when
no branch stays forever in an acceptance state without taking its good transitions infinitely
often. Dominated transitions (weaker cube, more targets, worse acceptance) are dropped.

States are numbered in discovery order (``Vwaa.states[i]``) and sets of states are int bitmasks,
so unions and inclusion tests are single int operations.
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
)
from tlfleet.agent.ltl.guards import TRUE_CUBE, Cube, cube_and, cube_implies

StateSet = int  # bitmask over Vwaa.states
Transition = tuple[Cube, StateSet]
StateTransition = tuple[Cube, StateSet, bool]  # (cube, targets, good)


def is_acceptance_state(q: Formula) -> bool:
    """States that carry a Büchi obligation: ``U``, ``F`` and ``G F``."""
    return isinstance(q, Until | Finally) or (
        isinstance(q, Globally) and isinstance(q.arg, Finally)
    )


def _prune(transitions: list[Transition]) -> list[Transition]:
    """Drop transitions dominated by another one (cube implies it, targets include its)."""
    unique = list(dict.fromkeys(transitions))
    if len(unique) < 2:
        return unique
    unique.sort(key=lambda t: (t[1].bit_count(), (t[0][0] | t[0][1]).bit_count()))
    kept: list[Transition] = []
    for t in unique:
        cube, targets = t
        if not any(cube_implies(cube, k[0]) and not k[1] & ~targets for k in kept):
            kept.append(t)
    return kept


def _product(xs: list[Transition], ys: list[Transition]) -> list[Transition]:
    result = []
    for cx, ex in xs:
        for cy, ey in ys:
            c = cube_and(cx, cy)
            if c is not None:
                result.append((c, ex | ey))
    return _prune(result)


class Vwaa:
    """Transition function of the VWAA over the atoms numbered by ``index`` (memoised)."""

    def __init__(self, index: dict[str, int]):
        self.index = index
        self.states: list[Formula] = []
        self._ids: dict[Formula, int] = {}
        self._delta: dict[Formula, list[Transition]] = {}
        self._state_delta: dict[int, list[StateTransition]] = {}

    def state(self, f: Formula) -> StateSet:
        """The singleton set {f}, numbering ``f`` on first sight."""
        i = self._ids.get(f)
        if i is None:
            i = len(self.states)
            self._ids[f] = i
            self.states.append(f)
        return 1 << i

    def bar(self, f: Formula) -> list[StateSet]:
        """x̄: the DNF of ``f`` over VWAA states (each disjunct a set of states)."""
        match f:
            case Const(value):
                return [0] if value else []
            case And(args):
                result = [0]
                for arg in args:
                    result = [r | s for r in result for s in self.bar(arg)]
                return _minimal_sets(result)
            case Or(args):
                result = []
                for arg in args:
                    result.extend(self.bar(arg))
                return _minimal_sets(result)
        return [self.state(f)]

    def delta(self, f: Formula) -> list[Transition]:
        """δ(f) for an NNF formula ``f`` (see module docstring)."""
        cached = self._delta.get(f)
        if cached is None:
            cached = self._compute_delta(f)
            self._delta[f] = cached
        return cached

    def _compute_delta(self, f: Formula) -> list[Transition]:
        top: list[Transition] = [(TRUE_CUBE, 0)]
        match f:
            case Const(value):
                return top if value else []
            case Atom(name):
                return [((1 << self.index[name], 0), 0)]
            case Not(Atom(name)):
                return [((0, 1 << self.index[name]), 0)]
        stay: list[Transition] = [(TRUE_CUBE, self.state(f))]
        match f:
            case Next(x):
                return [(TRUE_CUBE, e) for e in self.bar(x)]
            case Finally(x):
                return _prune([*self.delta(x), *stay])
            case Globally(Finally(x)):
                return _prune([*_product(self.delta(x), stay), *stay])
            case Globally(x):
                return _product(self.delta(x), stay)
            case Until(x, y):
                return _prune([*self.delta(y), *_product(self.delta(x), stay)])
            case Release(x, y):
                return _product(self.delta(y), _prune([*self.delta(x), *stay]))
            case And(args):
                result = top
                for arg in args:
                    result = _product(result, self.delta(arg))
                return result
            case Or(args):
                result = []
                for arg in args:
                    result.extend(self.delta(arg))
                return _prune(result)
        raise TypeError(f"not a formula in negation normal form: {f}")

    def state_delta(self, i: int) -> list[StateTransition]:
        """Transitions of state number ``i`` with their acceptance (good) flag."""
        cached = self._state_delta.get(i)
        if cached is not None:
            return cached
        q = self.states[i]
        me = 1 << i
        if isinstance(q, Globally) and isinstance(q.arg, Finally):
            # Good: fulfil x now; bad: the plain wait (⊤, {G F x}), unless x is valid.
            stay = [(TRUE_CUBE, me)]
            fulfil = _product(self.delta(q.arg.arg), stay)
            result = [(c, e, True) for c, e in fulfil]
            if stay[0] not in fulfil:
                result.append((TRUE_CUBE, me, False))
        elif is_acceptance_state(q):
            result = [(c, e, not e & me) for c, e in self.delta(q)]
        else:
            result = [(c, e, True) for c, e in self.delta(q)]
        self._state_delta[i] = result
        return result


def _minimal_sets(sets: list[StateSet]) -> list[StateSet]:
    unique = sorted(set(sets), key=lambda s: (s.bit_count(), s))
    kept: list[StateSet] = []
    for s in unique:
        if not any(not k & ~s for k in kept):
            kept.append(s)
    return kept

