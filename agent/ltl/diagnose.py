"""Why a task has no accepting run on a transition system (ltl-planning.md §5, "Unsatisfiable").

Four causes, checked in order:

1. the formula itself is unsatisfiable (its Büchi automaton accepts no word);
2. the automaton needs letters that no region supplies: with only the regions' labels as the
   alphabet, no accepting cycle is left. The missing letters are read off the guards that became
   dead: for the paper's literal ``GF(a11 & a12)`` the accepting cycle needs ``a11 & a12`` in one
   letter, and no region carries both;
3. the run fails on its very first letter (e.g. ``G a`` for a robot that starts outside ``a``);
4. the letters exist but the accepting cycles are not reachable from the robot's start over the
   transitions available (blocked edges, unreachable regions).
"""

from __future__ import annotations

from tlfleet.agent.ltl.buchi import Buchi, buchi_step
from tlfleet.agent.ltl.emptiness import find_accepting_lasso
from tlfleet.agent.ltl.graphs import nontrivial, reachable, strongly_connected_components
from tlfleet.agent.ltl.guards import Cube
from tlfleet.agent.ltl.transition_system import TransitionSystem


def _names(mask: int, atoms: tuple[str, ...]) -> list[str]:
    return [atoms[i] for i in range(len(atoms)) if mask >> i & 1]


def _join(names: list[str]) -> str:
    if len(names) == 1:
        return names[0]
    return ", ".join(names[:-1]) + " and " + names[-1]


def _has_accepting_cycle(buchi: Buchi, letters: list[int]) -> bool:
    """Does an accepting cycle reachable from the initial states survive when edges may only
    read the letters (valuations) ``letters``?"""
    succ = [[dst for dst, g in out if any(g.holds(v) for v in letters)] for out in buchi.edges]
    comp, components = strongly_connected_components(buchi.num_states, succ)
    cyclic = nontrivial(comp, components, succ)
    live = reachable(buchi.initial, succ)
    return any(
        q in live and cyclic[comp[q]] for q in buchi.accepting
    )


def _missing_letters(buchi: Buchi, letters: list[int]) -> list[str]:
    """Descriptions of the cubes on dead edges that no available letter satisfies."""
    atoms = buchi.atoms
    missing: dict[Cube, str] = {}
    for out in buchi.edges:
        for _dst, guard in out:
            if any(guard.holds(v) for v in letters):
                continue
            for pos, neg in buchi.alphabet.cubes(guard):
                if not any(v & pos == pos for v in letters):
                    names = _names(pos, atoms)
                    if len(names) > 1:
                        missing[(pos, 0)] = f"no region carries {_join(names)} together"
                    else:
                        missing[(pos, 0)] = f"no region carries {names[0]}"
                elif pos:
                    without = _join(_names(neg, atoms))
                    missing[(pos, neg)] = (
                        f"no region carries {_join(_names(pos, atoms))} without {without}"
                    )
    # Report only the weakest requirements (a missing {a, b} makes {a, b, c} redundant).
    keys = sorted(missing, key=lambda c: ((c[0] | c[1]).bit_count(), c))
    kept: list[Cube] = []
    for c in keys:
        if not any((c[0] & k[0]) == k[0] and (c[1] & k[1]) == k[1] for k in kept):
            kept.append(c)
    return [missing[c] for c in kept]


def explain_unsatisfiable(
    buchi: Buchi,
    ts: TransitionSystem,
    initial_region: str,
    initial_states: frozenset[int] | None = None,
) -> str:
    """A sentence saying what is missing for ``buchi`` to have an accepting run on ``ts`` from
    ``initial_region`` with the automaton in ``initial_states`` (default: its initial states)."""
    if initial_states is None:
        initial_states = frozenset(buchi.initial)
    if find_accepting_lasso(buchi) is None:
        return "the formula is unsatisfiable: no infinite word satisfies it"
    region_letters = sorted({buchi.valuation(label) for label in ts.labels})
    if not _has_accepting_cycle(buchi, region_letters):
        reasons = _missing_letters(buchi, region_letters)
        if reasons:
            return "; ".join(reasons)
        return "no sequence of region labels is accepted by the task's automaton"
    label = ts.labels[ts.index(initial_region)]
    if not buchi_step(buchi, initial_states, label):
        carried = "{" + ", ".join(sorted(label)) + "}"
        return (
            f"the run already fails where it starts: {initial_region!r} carries {carried} "
            "and the task does not allow that as its first letter"
        )
    return (
        f"no accepting cycle is reachable from {initial_region!r} over the available "
        "transitions (blocked or missing edges between regions)"
    )

