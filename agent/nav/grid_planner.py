"""Global planner: A* on the inflated occupancy grid, then line-of-sight smoothing.

This is the ``global_planner`` of the paper's ``move_base`` stack (paper §III-A, ltl-planning.md
§6): a shortest path on the 8-connected grid of free cells, turned into a few waypoints that the
DWA local planner follows. It also gives the LTL transition system its edge weights
(ltl-planning.md §3) through ``path_length_function``.

Search: A* with the octile heuristic ``h = max(Δx, Δy) + (√2 − 1)·min(Δx, Δy)`` [cells], which
is exact on an empty 8-connected grid, so on the paper's obstacle-free arena the search expands
little more than the path itself. Moves cost 1 (straight) and √2 (diagonal) cells; a diagonal
move may not cut the corner of a blocked cell. The loop runs on flat indices of a grid padded by
one blocked cell, so neighbours need no bounds checks.

**Clearance preference** (``prefer`` [m], docs/ltl-navigation.md §4; the inflation layer of Nav2's
costmap, which its planners read): a move into a cell of clearance ``d`` [m] (to the nearest
obstacle surface) costs its length times ``1 + w·((d_pref − d)/(d_pref − d_min))²`` for
``d_min ≤ d < d_pref``, with ``d_min`` the grid's inflation, ``d_pref = d_min + prefer`` and
``w = CLEARANCE_WEIGHT``; nothing beyond ``d_pref``. The path then runs down the middle of a
corridor narrower than ``2·d_pref`` and keeps ``prefer`` off wall ends and pillars where there is
room, instead of grazing the inflated obstacles (where a local planner's rollouts are cut off and
it stalls). The heuristic stays admissible (every factor ≥ 1). Smoothing keeps what the search
bought: a shortcut must keep, at every sample, the clearance ``min(d_pref, least clearance of the
cells it replaces)``.
"""

from __future__ import annotations

import heapq
import logging
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.nav.errors import NoPathError
from tlfleet.agent.nav.grid import (
    DEFAULT_MARGIN,
    DEFAULT_RESOLUTION,
    OccupancyGrid,
    grid_from_scenario,
)
from tlfleet.agent.nav.polyline import polyline_length

log = logging.getLogger(__name__)

SQRT2 = math.sqrt(2.0)
CLEARANCE_WEIGHT = 2.0  # w: a cell grazing the inflated obstacles costs (1 + w)× its length
Point = tuple[float, float]


@dataclass(frozen=True, eq=False)
class GridPath:
    """A planned path.

    ``cells`` (M, 2) int ``(ix, iy)`` is the raw 8-connected cell path; ``waypoints`` (W, 2) [m]
    the smoothed polyline from ``start`` to the goal point actually reached (``goal``, or the
    nearest free cell centre when the requested goal is blocked). ``grid_length`` [m] is the octile
    length of the cell path, ``length`` [m] the length of the smoothed polyline.
    """

    start: Point
    goal: Point
    cells: np.ndarray
    waypoints: np.ndarray
    grid_length: float
    length: float
    start_snapped: bool
    goal_snapped: bool


def nearest_free_cell(
    grid: OccupancyGrid, point: Sequence[float], toward: Sequence[float] | None = None
) -> tuple[int, int] | None:
    """The free cell ``(ix, iy)`` whose centre is nearest to ``point`` [m]; None if none is free.

    Among the cells within one resolution of the nearest distance, the one nearest to ``toward``
    (e.g. the start, when moving a blocked goal) is chosen, so a blocked goal is approached from
    the near side.
    """
    free_iy, free_ix = np.nonzero(~grid.blocked)
    if len(free_ix) == 0:
        return None
    centres = grid.center_of(np.stack([free_ix, free_iy], axis=-1))
    d = np.linalg.norm(centres - np.asarray(point[:2], dtype=float), axis=1)
    if toward is None:
        k = int(np.argmin(d))
    else:
        near = np.flatnonzero(d <= d.min() + grid.resolution)
        d_toward = np.linalg.norm(centres[near] - np.asarray(toward[:2], dtype=float), axis=1)
        k = int(near[np.argmin(d_toward)])
    return int(free_ix[k]), int(free_iy[k])


def astar_cells(
    blocked: np.ndarray, start: tuple[int, int], goal: tuple[int, int],
    penalty: np.ndarray | None = None,
) -> tuple[list[tuple[int, int]], float] | None:
    """Cheapest 8-connected path between two free cells ``(ix, iy)`` of ``blocked`` (ny, nx).

    A move costs its length (1 or √2 cells) times ``1 + penalty[cell entered]`` (``penalty``
    (ny, nx) ≥ 0, the clearance preference of the module docstring; None: shortest path).
    Returns the cells from start to goal and the path's cost [cells], or None when the goal
    cannot be reached. No corner cutting past blocked cells.
    """
    blocked = np.asarray(blocked, dtype=bool)
    width = blocked.shape[1] + 2
    free, factor = _padded(blocked, penalty)
    s = (start[1] + 1) * width + start[0] + 1
    g_idx = (goal[1] + 1) * width + goal[0] + 1
    if not (free[s] and free[g_idx]):
        return None
    found = _search(free, factor, width, s, g_idx)
    if found is None:
        return None
    parent, cost = found
    cells = []
    u = g_idx
    while u != -1:
        uy, ux = divmod(u, width)
        cells.append((ux - 1, uy - 1))
        u = parent[u]
    cells.reverse()
    return cells, cost


def _padded(blocked: np.ndarray, penalty: np.ndarray | None) -> tuple[bytes, list[float] | None]:
    """The free mask with a blocked border of one cell, flattened row by row into bytes (a
    copy, not a 20 000-element list), and the move cost factor ``1 + penalty`` of every cell
    in the same layout (None without ``penalty``). The border spares the search its bounds
    tests: a neighbour off the grid is a blocked cell."""
    ny, nx = blocked.shape
    padded = np.zeros((ny + 2, nx + 2), dtype=bool)
    np.logical_not(blocked, out=padded[1:-1, 1:-1])
    if penalty is None:
        return padded.tobytes(), None
    grown = np.ones((ny + 2, nx + 2))
    grown[1:-1, 1:-1] += penalty
    return padded.tobytes(), grown.ravel().tolist()


def _search(free: bytes, factor: list[float] | None, width: int, s: int, g_idx: int
            ) -> tuple[dict[int, int], float] | None:
    """A* from flat cell ``s`` to ``g_idx`` of the padded grid (``width`` cells a row) under
    the octile heuristic: the parent of every cell reached (the start's is -1) and the goal's
    cost [cells], or None when the goal cannot be reached. One loop, its names local: it is
    the global planner's whole cost."""
    gy, gx = divmod(g_idx, width)
    # (flat offset, dx, dy, cost, the two orthogonal offsets a diagonal must not cut)
    moves = [
        (1, 1, 0, 1.0, 0, 0),
        (-1, -1, 0, 1.0, 0, 0),
        (width, 0, 1, 1.0, 0, 0),
        (-width, 0, -1, 1.0, 0, 0),
        (width + 1, 1, 1, SQRT2, 1, width),
        (width - 1, -1, 1, SQRT2, -1, width),
        (-width + 1, 1, -1, SQRT2, 1, -width),
        (-width - 1, -1, -1, SQRT2, -1, -width),
    ]
    inf = math.inf
    # g and parent as dicts of the cells reached (a search of a re-plan touches a few hundred)
    g = {}
    parent = {}
    openable = bytearray(free)  # free and not yet closed (one lookup instead of two per neighbour)
    k = SQRT2 - 1.0
    sy, sx = divmod(s, width)
    dx0, dy0 = abs(sx - gx), abs(sy - gy)
    h0 = max(dx0, dy0) + k * min(dx0, dy0)
    g[s] = 0.0
    parent[s] = -1
    g_of = g.get
    heap = [(h0, h0, s, sx, sy)]
    push, pop = heapq.heappush, heapq.heappop
    while heap:
        _, _, u, ux, uy = pop(heap)
        if not openable[u]:
            continue
        if u == g_idx:
            return parent, g[g_idx]
        openable[u] = False
        gu = g[u]
        for du, ddx, ddy, cost, o1, o2 in moves:
            v = u + du
            if not openable[v]:
                continue
            if o1 and not (free[u + o1] and free[u + o2]):
                continue
            ng = gu + (cost if factor is None else cost * factor[v])
            if ng < g_of(v, inf):
                g[v] = ng
                parent[v] = u
                vx, vy = ux + ddx, uy + ddy
                dx = vx - gx if vx > gx else gx - vx
                dy = vy - gy if vy > gy else gy - vy
                h = dx + k * dy if dx > dy else dy + k * dx
                push(heap, (ng + h, h, v, vx, vy))
    return None


def line_of_sight(grid: OccupancyGrid, a: np.ndarray, b: np.ndarray,
                  clearance: np.ndarray | float | None = None) -> np.ndarray:
    """Whether the segments from ``a`` (2,) to each ``b`` (K, 2) [m] stay in free c-space; (K,).

    Samples every segment at spacing ≤ res/2 (the same number of samples for all, set by the
    longest) and looks the samples up in ``grid.blocked``; vectorised over all K segments.
    ``clearance`` [m] (scalar or (K,)): every sample must also have at least that clearance.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float).reshape(-1, 2)
    longest = float(np.max(np.linalg.norm(b - a, axis=1))) if len(b) else 0.0
    n = max(2, math.ceil(longest / (grid.resolution / 2.0)) + 1)
    s = np.linspace(0.0, 1.0, n)
    pts = a[None, None, :] + s[None, :, None] * (b - a)[:, None, :]  # (K, n, 2)
    free = np.all(grid.is_free(pts), axis=1)
    if clearance is None:
        return free
    least = np.min(grid.clearance_at(pts), axis=1)
    return free & (least >= np.asarray(clearance, dtype=float) - 1e-9)


def smooth_path(grid: OccupancyGrid, points: np.ndarray, prefer: float = 0.0) -> np.ndarray:
    """Line-of-sight shortcutting of a polyline (M, 2) [m] → waypoints (W, 2), W ≤ M.

    Greedy: from the current waypoint, jump to the farthest later point visible in free c-space
    (all candidates tested at once with ``line_of_sight``). Endpoints are kept. With ``prefer``
    [m] > 0, a shortcut from point i to point j must keep the clearance ``min(d_pref, least
    clearance of points i..j)`` (module docstring), so it never runs closer to an obstacle than
    the points it replaces, where they kept less than ``d_pref``.
    """
    pts = np.asarray(points, dtype=float)
    if len(pts) <= 2:
        return pts.copy()
    keep = None
    if prefer > 0.0:
        keep = np.minimum(grid.clearance_at(pts), grid.inflation + prefer)
    out = [0]
    i = 0
    last = len(pts) - 1
    while i < last:
        need = None if keep is None else np.minimum.accumulate(keep[i:])  # points i..j
        if line_of_sight(grid, pts[i], pts[last:],
                         None if need is None else need[-1])[0]:  # the rest is in sight
            out.append(last)
            break
        visible = line_of_sight(grid, pts[i], pts[i + 1:], None if need is None else need[1:])
        # The next point is always kept, even if sampling clips a blocked corner.
        visible[0] = True
        j = i + 1 + int(np.flatnonzero(visible)[-1])
        out.append(j)
        i = j
    return pts[out]


def clearance_penalty(grid: OccupancyGrid, prefer: float) -> np.ndarray:
    """Per-cell cost factor excess (ny, nx) of the clearance preference (module docstring)."""
    d_min = grid.inflation
    short = np.clip((d_min + prefer - grid.clearance) / prefer, 0.0, 1.0)
    return CLEARANCE_WEIGHT * short * short


def plan_path(
    grid: OccupancyGrid, start: Sequence[float], goal: Sequence[float], smooth: bool = True,
    prefer: float = 0.0,
) -> GridPath:
    """Shortest collision-free path from ``start`` to ``goal`` (world points [m]; extra pose
    components such as θ are ignored).

    A start or goal in blocked c-space (inside an inflated obstacle, or off the grid) is moved
    to the nearest free cell (for the goal, on the side nearer the start); the path then begins
    at the true start and ends at that cell's centre, and ``start_snapped``/``goal_snapped``
    say so. Raises ``NoPathError`` (naming start
    and goal) when no free cell exists or the goal's free component is not the start's.
    ``prefer`` [m] > 0: the clearance preference of the module docstring (then ``grid_length``
    is the length of the cell path found, not the search's cost).
    """
    p0 = (float(start[0]), float(start[1]))
    p1 = (float(goal[0]), float(goal[1]))
    start_free = grid.is_free_point(*p0)
    goal_free = grid.is_free_point(*p1)
    c0 = grid.cell_of_point(*p0) if start_free else None
    c1 = grid.cell_of_point(*p1) if goal_free else None
    if c0 is None:
        c0 = nearest_free_cell(grid, p0)
    if c1 is None:
        c1 = nearest_free_cell(grid, p1, toward=p0)
    if c0 is None or c1 is None:
        raise NoPathError(p0, p1, "the grid has no free cell")
    penalty = clearance_penalty(grid, prefer) if prefer > 0.0 else None
    result = astar_cells(grid.blocked, c0, c1, penalty)
    if result is None:
        raise NoPathError(p0, p1, "the goal is not reachable from the start in free space")
    cells, length_cells = result
    cell_arr = np.asarray(cells, dtype=np.int64)
    if penalty is not None:
        steps = np.abs(np.diff(cell_arr, axis=0)).sum(axis=1)
        length_cells = float(np.count_nonzero(steps == 1) + SQRT2 * np.count_nonzero(steps == 2))
    centres = grid.center_of(cell_arr)
    end = np.array(p1) if goal_free else centres[-1]
    head = [np.array(p0)] if start_free else [np.array(p0), centres[0]]
    raw = np.vstack([*head, centres[1:-1], end[None, :]])
    keep = np.ones(len(raw), dtype=bool)
    keep[1:] = np.any(np.diff(raw, axis=0) != 0.0, axis=1)
    raw = raw[keep]
    # A blocked start sees nothing, so smoothing keeps the escape leg to the first free cell.
    waypoints = smooth_path(grid, raw, prefer) if smooth else raw
    return GridPath(
        start=p0,
        goal=(float(end[0]), float(end[1])),
        cells=cell_arr,
        waypoints=waypoints,
        grid_length=length_cells * grid.resolution,
        length=polyline_length(waypoints),
        start_snapped=not start_free,
        goal_snapped=not goal_free,
    )


def path_length_function(
    scenario_or_grid: Scenario | OccupancyGrid,
    robot_radius: float | None = None,
    margin: float = DEFAULT_MARGIN,
    resolution: float = DEFAULT_RESOLUTION,
) -> Callable[[Sequence[float], Sequence[float]], float]:
    """Edge weights for the LTL transition system (ltl-planning.md §3): ``distance(p, q)`` [m].

    ``distance(p, q)`` is the length of the smoothed global-planner path from p to q (points or
    poses; only x, y are used), which equals ``‖p − q‖`` when the straight segment is free, as on
    the paper's obstacle-free arena. Results are cached per unordered pair (rounded to 1 mm) in
    the returned closure. An unreachable pair is ``math.inf``: no transition between those regions
    (the LTL planner drops infinite edges and names what is then missing).
    """
    if isinstance(scenario_or_grid, OccupancyGrid):
        grid = scenario_or_grid
        if robot_radius is not None:
            grid = grid.inflated(robot_radius + margin)
    else:
        grid = grid_from_scenario(scenario_or_grid, robot_radius, margin, resolution)
    cache: dict[tuple[Point, Point], float] = {}

    def distance(p: Sequence[float], q: Sequence[float]) -> float:
        a = (round(float(p[0]), 3), round(float(p[1]), 3))
        b = (round(float(q[0]), 3), round(float(q[1]), 3))
        key = (a, b) if a <= b else (b, a)
        if key not in cache:
            if a == b:
                cache[key] = 0.0
            elif (
                grid.is_free(np.array(a))
                and grid.is_free(np.array(b))
                and bool(line_of_sight(grid, np.array(a), np.array([b]))[0])
            ):
                cache[key] = math.dist(a, b)
            else:
                try:
                    cache[key] = plan_path(grid, key[0], key[1]).length
                except NoPathError:
                    cache[key] = math.inf
            log.debug("distance %s -> %s = %.3f m", key[0], key[1], cache[key])
        return cache[key]

    return distance


def with_penalised_edges(
    distance: Callable[[Sequence[float], Sequence[float]], float],
    edges: Iterable[tuple[Sequence[float], Sequence[float]]],
    penalty: float,
) -> Callable[[Sequence[float], Sequence[float]], float]:
    """``distance`` with ``penalty`` [m] added on the directed edges ``(p, q)`` given (points
    matched to 1 mm): how a ``ReplanRequest`` (blocked edge from region centre p to q) becomes
    edge weights for the LTL planner's replanning (ltl-planning.md §5)."""

    def key(p: Sequence[float]) -> Point:
        return (round(float(p[0]), 3), round(float(p[1]), 3))

    blocked = frozenset((key(p), key(q)) for p, q in edges)

    def penalised(p: Sequence[float], q: Sequence[float]) -> float:
        extra = penalty if (key(p), key(q)) in blocked else 0.0
        return distance(p, q) + extra

    return penalised
