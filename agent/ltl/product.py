"""On-the-fly weighted product ``T × A`` (ltl-planning.md §4; paper §II-A).

``⟨πn, qp⟩ ∈ Δ'(⟨πm, qo⟩)`` iff ``πm → πn`` in T and ``qp ∈ Δ(qo, L(πm))``: the Büchi guard is
evaluated on the label of the **source** region. Only the part reachable from the initial pairs
is built; product states are numbered in discovery order.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

from tlfleet.agent.ltl.buchi import Buchi
from tlfleet.agent.ltl.transition_system import TransitionSystem


@dataclass(frozen=True)
class ProductGraph:
    """The reachable product.

    ``pairs[k] = (region index, Büchi state)`` of product state ``k``; ``succ[k]`` lists
    ``(k', weight)``; ``initial`` are the start states and ``accepting[k]`` is ``q ∈ F``.
    """

    pairs: tuple[tuple[int, int], ...]
    succ: tuple[tuple[tuple[int, float], ...], ...]
    initial: tuple[int, ...]
    accepting: tuple[bool, ...]

    @property
    def num_states(self) -> int:
        return len(self.pairs)

    @property
    def num_edges(self) -> int:
        return sum(len(out) for out in self.succ)


def explore(
    ts: TransitionSystem, buchi: Buchi, initial: Iterable[tuple[int, int]]
) -> ProductGraph:
    """Build the product reachable from the ``(region index, Büchi state)`` pairs ``initial``."""
    num_q = buchi.num_states
    valuations = [buchi.valuation(label) for label in ts.labels]
    # Δ(q, L(π)) depends only on (q, π); computed once per pair actually met.
    step_cache: dict[int, tuple[int, ...]] = {}
    ids: dict[int, int] = {}
    pairs: list[tuple[int, int]] = []
    succ: list[tuple[tuple[int, float], ...]] = []
    queue: deque[int] = deque()

    def intern(region: int, q: int) -> int:
        key = region * num_q + q
        k = ids.get(key)
        if k is None:
            k = len(pairs)
            ids[key] = k
            pairs.append((region, q))
            succ.append(())
            queue.append(k)
        return k

    start = tuple(dict.fromkeys(intern(r, q) for r, q in initial))
    while queue:
        k = queue.popleft()
        region, q = pairs[k]
        key = region * num_q + q
        nexts = step_cache.get(key)
        if nexts is None:
            nexts = buchi.successors_by_valuation(q, valuations[region])
            step_cache[key] = nexts
        out = []
        for q2 in nexts:
            for r2, w in ts.edges[region]:
                j = ids.get(r2 * num_q + q2)  # (intern's lookup inlined: one call fewer)
                out.append((intern(r2, q2) if j is None else j, w))
        succ[k] = tuple(out)
    accepting = tuple(q in buchi.accepting for _r, q in pairs)
    return ProductGraph(tuple(pairs), tuple(succ), start, accepting)
