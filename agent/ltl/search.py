"""Optimal prefix–suffix lasso in a weighted product graph (ltl-planning.md §5; paper Alg. 1).

Minimise ``cost(a) = d(init, a) + β · c(a)`` over accepting product states ``a``, where ``d`` is
the shortest-path distance from the initial states and ``c(a)`` the cheapest cycle through ``a``
(Guo & Dimarogonas; P_MAS_TG runs one Dijkstra per accepting and per initial state). Here:

1. one multi-source Dijkstra from the initial states gives ``d`` for every reachable state;
2. Tarjan's SCCs: only accepting states in SCCs that contain a cycle are candidates, and each
   cycle search stays inside the candidate's SCC;
3. candidates are tried by increasing ``d``; once ``d(a) ≥ best`` the rest cannot win;
4. each cycle search is a Dijkstra from ``a`` that stops as soon as ``d(a) + β·(distance popped)``
   reaches the best cost so far, or as soon as the cycle found cannot be improved;
5. a zero-weight self-loop closes a cycle at once, and every accepting state on a cycle found
   gets that cycle (rotated) as an upper bound, which tightens the pruning of later candidates.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from dataclasses import dataclass

from tlfleet.agent.ltl.graphs import nontrivial, strongly_connected_components

Succ = Sequence[Sequence[tuple[int, float]]]


@dataclass(frozen=True)
class Lasso:
    """``prefix`` runs from an initial state up to (excluding) ``cycle[0]``; ``cycle`` is the
    repeated part, starting at the accepting state and excluding the return to it."""

    prefix: tuple[int, ...]
    cycle: tuple[int, ...]
    prefix_cost: float
    cycle_cost: float


def shortest_paths(succ: Succ, sources: Sequence[int]) -> tuple[list[float], list[int]]:
    """Multi-source Dijkstra: distance and parent (``-1`` at sources/unreached) of every node."""
    n = len(succ)
    dist = [math.inf] * n
    parent = [-1] * n
    heap = []
    for s in sources:
        dist[s] = 0.0
        heap.append((0.0, s))
    heapq.heapify(heap)
    while heap:
        d, u = heapq.heappop(heap)
        if d > dist[u]:
            continue
        for v, w in succ[u]:
            nd = d + w
            if nd < dist[v]:
                dist[v] = nd
                parent[v] = u
                heapq.heappush(heap, (nd, v))
    return dist, parent


def _cheapest_cycle(
    succ: Succ, a: int, comp: Sequence[int], budget: float
) -> tuple[float, list[int]] | None:
    """Cheapest cycle through ``a`` inside ``a``'s SCC with cost < ``budget``, as a node list
    starting at ``a`` (without the final return), or ``None``."""
    c = comp[a]
    dist = {a: 0.0}
    parent: dict[int, int] = {}
    best = budget
    best_last = -1
    heap = [(0.0, a)]
    while heap:
        d, u = heapq.heappop(heap)
        if d >= best:
            break
        if d > dist[u]:
            continue
        for v, w in succ[u]:
            nd = d + w
            if v == a:
                if nd < best:
                    best = nd
                    best_last = u
                continue
            if comp[v] != c:
                continue
            if nd < dist.get(v, math.inf):
                dist[v] = nd
                parent[v] = u
                heapq.heappush(heap, (nd, v))
    if best_last < 0:
        return None
    path = [best_last]
    while path[-1] != a:
        path.append(parent[path[-1]])
    path.reverse()
    return best, path


def optimal_lasso(
    succ: Succ, initial: Sequence[int], accepting: Sequence[bool], beta: float
) -> Lasso | None:
    """The lasso minimising ``prefix_cost + beta · cycle_cost``, or ``None`` if there is none."""
    if beta < 0:
        raise ValueError(f"the suffix weight must be >= 0, got {beta}")
    n = len(succ)
    dist, parent = shortest_paths(succ, initial)
    plain_succ = [[v for v, _w in out] for out in succ]
    comp, components = strongly_connected_components(n, plain_succ)
    cyclic = nontrivial(comp, components, plain_succ)
    candidates = sorted(
        (dist[a], a) for a in range(n) if accepting[a] and cyclic[comp[a]] and dist[a] < math.inf
    )
    best_cost = math.inf
    best: tuple[int, float, list[int]] | None = None
    known_cycle: dict[int, tuple[float, list[int]]] = {}
    for d_a, a in candidates:
        if d_a >= best_cost:
            break
        zero_loop = any(v == a and w == 0.0 for v, w in succ[a])
        if zero_loop:
            found: tuple[float, list[int]] | None = (0.0, [a])
        else:
            budget = (best_cost - d_a) / beta if beta > 0 else math.inf
            upper = known_cycle.get(a)
            if upper is not None:
                budget = min(budget, upper[0] + 1e-12)
            found = _cheapest_cycle(succ, a, comp, budget)
            if found is None and upper is not None and d_a + beta * upper[0] < best_cost:
                found = upper
        if found is None:
            continue
        cycle_cost, cycle = found
        cost = d_a + beta * cycle_cost
        if cost < best_cost:
            best_cost = cost
            best = (a, cycle_cost, cycle)
        # Every accepting state on this cycle has a cycle at most this expensive.
        for i, b in enumerate(cycle):
            if b != a and accepting[b] and cycle_cost < known_cycle.get(b, (math.inf,))[0]:
                known_cycle[b] = (cycle_cost, cycle[i:] + cycle[:i])
    if best is None:
        return None
    a, cycle_cost, cycle = best
    path = [a]
    while parent[path[-1]] >= 0:
        path.append(parent[path[-1]])
    path.reverse()
    return Lasso(tuple(path[:-1]), tuple(cycle), dist[a], cycle_cost)
