"""Small graph algorithms on integer-numbered graphs, shared by the translator and the planner.

Graphs are adjacency lists ``succ[v] -> iterable of w`` over nodes ``0..n-1``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Sequence


def strongly_connected_components(
    n: int, succ: Sequence[Iterable[int]]
) -> tuple[list[int], list[list[int]]]:
    """Tarjan's algorithm, iterative. Returns ``(component_of_node, components)``.

    Components come out in reverse topological order (sinks first).
    """
    index = [-1] * n
    low = [0] * n
    on_stack = [False] * n
    comp = [-1] * n
    components: list[list[int]] = []
    stack: list[int] = []
    counter = 0
    for root in range(n):
        if index[root] != -1:
            continue
        work = [(root, iter(succ[root]))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack[root] = True
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if index[w] == -1:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack[w] = True
                    work.append((w, iter(succ[w])))
                    advanced = True
                    break
                if on_stack[w] and index[w] < low[v]:
                    low[v] = index[w]
            if advanced:
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                if low[v] < low[parent]:
                    low[parent] = low[v]
            if low[v] == index[v]:
                members = []
                while True:
                    w = stack.pop()
                    on_stack[w] = False
                    comp[w] = len(components)
                    members.append(w)
                    if w == v:
                        break
                components.append(members)
    return comp, components


def nontrivial(comp: Sequence[int], components: Sequence[Sequence[int]],
               succ: Sequence[Iterable[int]]) -> list[bool]:
    """For each component: does it contain a cycle (several nodes, or a self-loop)?"""
    result = []
    for members in components:
        if len(members) > 1:
            result.append(True)
        else:
            v = members[0]
            result.append(v in succ[v])
    return result


def reachable(sources: Iterable[int], succ: Sequence[Iterable[int]]) -> set[int]:
    """Nodes reachable from ``sources`` (sources included)."""
    seen = set(sources)
    queue = deque(seen)
    while queue:
        v = queue.popleft()
        for w in succ[v]:
            if w not in seen:
                seen.add(w)
                queue.append(w)
    return seen


def bfs_path(source: int, targets: set[int], succ: Sequence[Iterable[int]],
             *, nonempty: bool = False) -> list[int] | None:
    """Shortest (fewest edges) path from ``source`` to a node of ``targets``, as a node list.

    With ``nonempty`` the path has at least one edge (used to close cycles).
    """
    parent: dict[int, int] = {}
    queue = deque([source])
    seen = {source} if not nonempty else set()
    if not nonempty and source in targets:
        return [source]
    while queue:
        v = queue.popleft()
        for w in succ[v]:
            if w in targets:
                path = [w, v]
                while path[-1] != source:
                    path.append(parent[path[-1]])
                path.reverse()
                return path
            if w not in seen:
                seen.add(w)
                parent[w] = v
                queue.append(w)
    return None
