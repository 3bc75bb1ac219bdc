"""Paths between regions that enter no third region: the keep-out rule (docs/ltl-navigation.md §2).

The word of a run is the sequence of regions the robot's centre enters (docs/ltl-navigation.md
§1). For the plan's word to be the run's word, a transition ``π_m →_i π_n`` of the weighted
transition system (paper §II-A) must be driven along a path that enters no region but ``π_m`` and
``π_n``. So every other region is a **keep-out zone** of that transition: a disc obstacle of the
region's own radius, which the global planner's grid inflates by the robot's radius and margin
like any obstacle (the robot's body stays off the region, its centre at least ``radius +
robot radius + margin`` [m] from the region's centre), and which the local planner's rollouts may
not come within ``robot radius + collision margin`` of.

:class:`RegionPaths` plans those paths (A* with the clearance preference of
``grid_planner``) and gives the transition system its weights: ``W(π_m, π_n)`` = the length of
the path [m], and no edge when there is none (:meth:`RegionPaths.length` is ``inf``). The keep-out
grids are cached per allowed pair; the region discs' distances are computed once (the three
nearest regions of every cell), so a pair's grid costs one pass over the cells.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from tlfleet.agent.model.scenario import Region, Scenario
from tlfleet.agent.nav.errors import NoPathError
from tlfleet.agent.nav.grid import (
    DEFAULT_MARGIN,
    DEFAULT_RESOLUTION,
    OccupancyGrid,
    grid_from_arena,
)
from tlfleet.agent.nav.grid_planner import GridPath, line_of_sight, plan_path

Point = tuple[float, float]
START = "start"  # the LTL planner's virtual state outside every region
NEAREST = 3  # region distances kept per cell: enough for any pair of allowed regions
GRID_CACHE = 64  # keep-out grids kept (one per allowed pair in use)
DEFAULT_PREFER = 0.3  # [m] the global path's clearance preference (grid_planner)


def _allowed(names: Iterable[str | None]) -> frozenset[str]:
    return frozenset(n for n in names if n is not None and n != START)


@dataclass(frozen=True, eq=False)
class RegionPaths:
    """Keep-out paths over ``regions`` on the static ``grid`` (inflated by the robot's radius +
    margin); ``prefer`` [m] is the global planner's clearance preference."""

    regions: tuple[Region, ...]
    grid: OccupancyGrid
    prefer: float = DEFAULT_PREFER
    # caches that fill as the paths are asked for: no part in repr or comparison
    _grids: OrderedDict = field(default_factory=OrderedDict, init=False, repr=False,
                                compare=False)
    _lengths: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @cached_property
    def _nearest(self) -> tuple[np.ndarray, np.ndarray]:
        """``(order, dist)``, both ``(k, ny, nx)``: the indices of every cell's ``k =
        min(NEAREST, regions)`` nearest regions, nearest first, and its distances [m] to their
        discs (computed once: a pair's keep-out grid is then one pass over the cells)."""
        ny, nx = self.grid.shape
        ox, oy = self.grid.origin
        res = self.grid.resolution
        xs = ox + (np.arange(nx) + 0.5) * res
        ys = oy + (np.arange(ny) + 0.5) * res
        if not self.regions:
            return np.zeros((0, ny, nx), dtype=np.int64), np.zeros((0, ny, nx))
        dist = np.stack([np.hypot(xs[None, :] - r.center[0], ys[:, None] - r.center[1])
                         - r.radius for r in self.regions])
        k = min(NEAREST, len(self.regions))
        order = np.argsort(dist, axis=0, kind="stable")[:k]
        return order, np.take_along_axis(dist, order, axis=0)

    @staticmethod
    def from_scenario(scenario: Scenario, robot_id: int, margin: float = DEFAULT_MARGIN,
                      resolution: float = DEFAULT_RESOLUTION,
                      prefer: float = DEFAULT_PREFER) -> RegionPaths:
        """The keep-out paths of robot ``robot_id``: its radius + ``margin`` inflates the map."""
        robot = scenario.robot(robot_id)
        grid = grid_from_arena(scenario.arena, robot.radius + margin, resolution)
        return RegionPaths(tuple(scenario.regions), grid, prefer)

    def region(self, name: str) -> Region:
        for region in self.regions:
            if region.name == name:
                return region
        known = ", ".join(r.name for r in self.regions)
        raise KeyError(f"no region {name!r} (regions: {known})")

    def keep_out(self, allowed: Iterable[str | None]) -> tuple[str, ...]:
        """The regions a transition between the ``allowed`` ones must not enter."""
        ok = _allowed(allowed)
        return tuple(r.name for r in self.regions if r.name not in ok)

    def grid_for(self, allowed: Iterable[str | None]) -> OccupancyGrid:
        """The static grid with every region but the ``allowed`` ones as a disc obstacle
        (clearance, occupied and blocked layers), cached (a control step asks every time: a
        tuple it asked before is found without building its set)."""
        if isinstance(allowed, tuple):
            cached = self._grids.get(allowed)
            if cached is not None:
                return cached
        key = _allowed(allowed)
        cached = self._grids.get(key)
        if cached is None:
            cached = self._build(key)
            self._grids[key] = cached
            if len(self._grids) > GRID_CACHE:
                self._grids.popitem(last=False)
        if isinstance(allowed, tuple):
            self._grids[allowed] = cached  # the same grid under the caller's own key
        return cached

    def _build(self, allowed: frozenset[str]) -> OccupancyGrid:
        base = self.grid
        if not self.regions or len(allowed) >= len(self.regions):
            return base
        index = {r.name: k for k, r in enumerate(self.regions)}
        skip = [index[name] for name in allowed if name in index]
        order, dist = self._nearest
        if len(skip) < len(order):
            # the nearest region of every cell that is not allowed (at most len(skip) are)
            chosen = np.full(base.shape, np.inf)
            for layer in range(len(order) - 1, -1, -1):
                keep = ~np.isin(order[layer], skip)
                chosen = np.where(keep, dist[layer], chosen)
        else:  # more allowed regions than kept layers: every region's disc, the long way
            chosen = np.full(base.shape, np.inf)
            ny, nx = base.shape
            ox, oy = base.origin
            res = base.resolution
            xs = ox + (np.arange(nx) + 0.5) * res
            ys = oy + (np.arange(ny) + 0.5) * res
            for k, r in enumerate(self.regions):
                if k not in skip:
                    chosen = np.minimum(chosen, np.hypot(xs[None, :] - r.center[0],
                                                         ys[:, None] - r.center[1]) - r.radius)
        clearance = np.minimum(base.clearance, chosen)
        return OccupancyGrid(base.origin, base.resolution, base.occupied | (clearance <= 0.0),
                             clearance, base.blocked | (clearance < base.inflation),
                             base.inflation)

    def _point(self, source: str | Sequence[float]) -> Point:
        if isinstance(source, str):
            centre = self.region(source).center
            return float(centre[0]), float(centre[1])
        return float(source[0]), float(source[1])

    def path(self, source: str | Sequence[float] | None, target: str,
             start: Sequence[float] | None = None) -> GridPath | None:
        """The keep-out path from region ``source`` (its centre, or ``start`` [m] when given;
        a point: from there, outside every region) to region ``target``'s centre, or None when
        every way enters a third region or the goal the planner reaches lies outside ``target``
        (a region covered by another one's keep-out zone)."""
        name = source if isinstance(source, str) else None
        p = self._point(start if start is not None else source)
        grid = self.grid_for((name, target))
        goal = self._point(target)
        try:
            path = plan_path(grid, p, goal, prefer=self.prefer)
        except NoPathError:
            return None
        if not self.region(target).contains(*path.goal):
            return None
        return path

    def length(self, source: str | Sequence[float] | None, target: str) -> float:
        """``W(source, target)`` [m]: the keep-out path's length, ``inf`` when there is none;
        cached per unordered pair (points to 1 mm)."""
        if source == target:
            return 0.0
        a = source if isinstance(source, str) else self._point(source)
        a_key = a if isinstance(a, str) else (round(a[0], 3), round(a[1], 3))
        key = frozenset((a_key, target)) if isinstance(a, str) else (a_key, target)
        if key in self._lengths:
            return self._lengths[key]
        value = self._straight(a, target)
        if value is None:
            path = self.path(a, target)
            value = math.inf if path is None else path.length
        self._lengths[key] = value
        return value

    def _straight(self, source: str | Point, target: str) -> float | None:
        """The straight segment's length when the planner would keep it: both ends free, the
        target's centre inside its region and every sample clear of the keep-out grid by
        ``min(d_pref, clearance of the ends)``; None otherwise."""
        name = source if isinstance(source, str) else None
        p = np.array(self._point(source))
        q = np.array(self._point(target))
        grid = self.grid_for((name, target))
        if not (grid.is_free_point(*p) and grid.is_free_point(*q)):
            return None
        need = min(grid.inflation + self.prefer, float(grid.clearance_at(p)),
                   float(grid.clearance_at(q)))
        if not bool(line_of_sight(grid, p, q[None, :], need)[0]):
            return None
        return float(math.dist(p, q))

    def blockers(self, source: str | Sequence[float] | None, target: str) -> tuple[str, ...]:
        """The regions in the way of ``source → target``: each keep-out region whose zone,
        lifted alone, lets a path through (empty when the map itself, or several regions
        together, close the way)."""
        name = source if isinstance(source, str) else None
        out = []
        for other in self.keep_out((name, target)):
            grid = self.grid_for((name, target, other))
            try:
                path = plan_path(grid, self._point(source), self._point(target))
            except NoPathError:
                continue
            if self.region(target).contains(*path.goal):
                out.append(other)
        return tuple(out)

    def edge_length(self, source: Region | Sequence[float], target: Region) -> float:
        """``length`` over the transition system's states: a region or the start point."""
        return self.length(source.name if isinstance(source, Region) else source, target.name)
