"""Weighted transition system over a scenario's regions (ltl-planning.md §3; paper §II-A).

``T = (Π, →, Π0, L, W)``: the states are the regions of interest (plus, when the robot starts
outside every region, a virtual ``start`` state with label ∅ and an edge to every region and no
way back). Every region has a zero-cost self-loop. Weights are the Euclidean distance between
region centres [m] unless the caller passes ``distance(p, q)`` over centre points ``(x, y)``, or
``edge_length(source, target)`` over the states themselves (``source`` a region or the start
point, ``target`` a region): the navigation stack's keep-out path length, which depends on which
regions the path may enter (docs/ltl-navigation.md §2). A weight of ``math.inf`` (or ``None``)
means "no path" and drops the edge.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import cached_property

from tlfleet.agent.model.scenario import Region, Scenario

Point = tuple[float, float]
Distance = Callable[[Point, Point], float | None]
EdgeLength = Callable[[Region | Point, Region], float | None]

START = "start"


@dataclass(frozen=True)
class TransitionSystem:
    """``edges[i]`` lists ``(j, weight)``: the robot can drive from state ``i`` to ``j``.

    ``names[i]`` and ``labels[i]`` are the name and the propositions of state ``i``;
    ``initial`` is the index of the state the robot starts in.
    """

    names: tuple[str, ...]
    labels: tuple[frozenset[str], ...]
    edges: tuple[tuple[tuple[int, float], ...], ...]
    initial: int

    @cached_property
    def _index(self) -> dict[str, int]:
        """State index by name, built on first use (not a field: no part in equality)."""
        return {name: i for i, name in enumerate(self.names)}

    @property
    def num_states(self) -> int:
        return len(self.names)

    @property
    def num_edges(self) -> int:
        return sum(len(out) for out in self.edges)

    def index(self, name: str) -> int:
        """Index of the state called ``name``; ``KeyError`` naming the known states otherwise."""
        try:
            return self._index[name]
        except KeyError:
            known = ", ".join(self.names)
            raise KeyError(f"no region {name!r} in the transition system ({known})") from None

    def weight(self, source: str, target: str) -> float:
        """Weight of the edge ``source → target``; ``KeyError`` when there is none."""
        j = self.index(target)
        for k, w in self.edges[self.index(source)]:
            if k == j:
                return w
        raise KeyError(f"no transition {source} -> {target}")

    def without_edges(self, blocked: Iterable[tuple[str, str]]) -> TransitionSystem:
        """A copy without the given ``(source, target)`` transitions (e.g. a blocked corridor)."""
        drop = {(self.index(a), self.index(b)) for a, b in blocked}
        edges = tuple(
            tuple((j, w) for j, w in out if (i, j) not in drop) for i, out in enumerate(self.edges)
        )
        return TransitionSystem(self.names, self.labels, edges, self.initial)


def euclidean(p: Point, q: Point) -> float:
    """Straight-line distance [m]."""
    return math.hypot(q[0] - p[0], q[1] - p[1])


def from_regions(
    regions: Sequence[Region],
    start: Point,
    distance: Distance | None = None,
    *,
    edge_length: EdgeLength | None = None,
) -> TransitionSystem:
    """Transition system over ``regions`` for a robot starting at ``start`` [m]: every edge whose
    weight is finite (all of them with the default Euclidean distance).

    The initial state is the region containing ``start`` (the one with the nearest centre if
    several do), else a virtual ``start`` state. ``edge_length`` (module docstring) takes
    precedence over ``distance``.
    """
    if not regions:
        raise ValueError("a transition system needs at least one region")
    dist = distance or euclidean
    names = [r.name for r in regions]
    labels = [frozenset(r.labels) for r in regions]
    centres = [(float(r.center[0]), float(r.center[1])) for r in regions]

    def weight(i: int | None, j: int) -> float | None:
        source = regions[i] if i is not None else (float(start[0]), float(start[1]))
        if edge_length is not None:
            return edge_length(source, regions[j])
        return dist(centres[i] if i is not None else source, centres[j])

    edges: list[tuple[tuple[int, float], ...]] = []
    for i in range(len(regions)):
        out = [(i, 0.0)]
        for j in range(len(regions)):
            if i != j:
                w = weight(i, j)
                if w is not None and math.isfinite(w):
                    out.append((j, float(w)))
        edges.append(tuple(out))
    inside = [i for i, r in enumerate(regions) if r.contains(start[0], start[1])]
    if inside:
        initial = min(inside, key=lambda i: euclidean(start, centres[i]))
    else:
        if START in names:
            raise ValueError(f"a region may not be called {START!r} (reserved for the start)")
        out = []
        for j in range(len(regions)):
            w = weight(None, j)
            if w is not None and math.isfinite(w):
                out.append((j, float(w)))
        names.append(START)
        labels.append(frozenset())
        edges.append(tuple(out))
        initial = len(names) - 1
    return TransitionSystem(tuple(names), tuple(labels), tuple(edges), initial)


def from_scenario(
    scenario: Scenario, robot_id: int, distance: Distance | None = None, *,
    edge_length: EdgeLength | None = None,
) -> TransitionSystem:
    """The transition system of robot ``robot_id`` over the scenario's regions."""
    robot = scenario.robot(robot_id)
    return from_regions(scenario.regions, (robot.pose[0], robot.pose[1]), distance,
                        edge_length=edge_length)
