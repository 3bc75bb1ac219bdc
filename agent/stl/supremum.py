"""The supremum ρ_opt of ρ^ψ over the arena and a state attaining it (docs/stl-saturation.md §5).

The funnel needs ρ_opt = sup ρ^ψ (stl-funnel.md §3, §5: ρ_max = max(0, ρ_0) + 0.9·(ρ_opt − …)).
Taken literal by literal (``tlfleet.agent.stl.task.default_rho_opt``) it is infinite for
half-planes (``x2 >= 1.5``) and far too large for boxes, whose literals cannot all peak at once;
and for two robots that should be near each other (``dist(p2, p3) <= 0.5``) it asks the bodies to
coincide. Inside the arena, with bodies of finite size, every predicate is bounded:

    ρ_opt = sup { ρ^ψ(x̄) : z_j ∈ W_j for every participant j,  ‖z_i − z_j‖ ≥ s_ij }

where W_j is the arena shrunk by robot j's clearance c_j (its radius plus the margin the
wall-and-obstacle avoidance keeps, so the funnel never aims into the avoidance zone) with each
static obstacle grown by c_j, and s_ij the distance below which the mutual avoidance of two coupled
robots pushes them apart (``tlfleet.agent.control.collision``). Headings are free.

ρ^ψ is the smooth conjunction (what the funnel controls), concave in the positions when the
literals are (paper Assumption 1), so over the convex box an ascent finds the global maximum;
obstacles and separations make the set non-convex, so :func:`maximize` runs a normalised
projected gradient ascent with backtracking from several starts (the scenario's start poses and a
3 × 3 grid of the first robot's box) and keeps the best. The result is a lower bound of the true
supremum within the ascent's tolerance (1e-5 of a step) wherever a start lies in the basin of the
maximum; ``tests/stl/test_stl_supremum.py`` checks it against a grid search.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from tlfleet.agent.model.scenario import Arena, DiscObstacle, RectObstacle
from tlfleet.agent.stl.compiled import StraightLinePsi
from tlfleet.agent.stl.syntax import Psi

ValueGrad = Callable[[Sequence[float]], tuple[float, Sequence[float] | None]]


@dataclass(frozen=True)
class Workspace:
    """Where the robots' centres can be: the ``arena`` (its walls and obstacles), each robot's
    clearance c_j [m] from walls and obstacles (``clearance``: (robot, c_j) pairs; others get
    ``default_clearance``) and the least centre distance s_ij [m] of coupled pairs
    (``separation``: (i, j, s_ij) with i < j; other pairs are unconstrained)."""

    arena: Arena
    clearance: tuple[tuple[int, float], ...] = ()
    separation: tuple[tuple[int, int, float], ...] = ()
    default_clearance: float = 0.0

    def clearance_of(self, robot: int) -> float:
        for j, c in self.clearance:
            if j == robot:
                return c
        return self.default_clearance

    def separation_of(self, i: int, j: int) -> float:
        a, b = min(i, j), max(i, j)
        for p, q, s in self.separation:
            if (p, q) == (a, b):
                return s
        return 0.0


@dataclass(frozen=True)
class Supremum:
    """sup ρ^ψ found and a stacked state x̄ = [x_j1, y_j1, θ_j1, …] that attains it."""

    value: float
    state: tuple[float, ...]


class _Projector:
    """Projection of a stacked state onto the workspace (approximate for the non-convex parts:
    out of each grown obstacle along its normal, pairs pushed apart along their line)."""

    def __init__(self, robots: Sequence[int], workspace: Workspace, free: Sequence[bool]):
        arena = workspace.arena
        self.robots = tuple(robots)
        self.free = tuple(free)
        self.boxes = []
        for j in self.robots:
            c = workspace.clearance_of(j)
            lo_x, hi_x = arena.xmin + c, arena.xmax - c
            lo_y, hi_y = arena.ymin + c, arena.ymax - c
            if lo_x > hi_x:
                lo_x = hi_x = 0.5 * (arena.xmin + arena.xmax)
            if lo_y > hi_y:
                lo_y = hi_y = 0.5 * (arena.ymin + arena.ymax)
            self.boxes.append((lo_x, hi_x, lo_y, hi_y, c))
        self.obstacles = arena.obstacles
        self.pairs = [(a, b, s) for a in range(len(self.robots)) for b in range(a + 1, len(robots))
                      if (s := workspace.separation_of(self.robots[a], self.robots[b])) > 0.0
                      and (self.free[a] or self.free[b])]

    def __call__(self, s: list[float]) -> list[float]:
        for _ in range(3):
            for k, (lo_x, hi_x, lo_y, hi_y, c) in enumerate(self.boxes):
                if not self.free[k]:
                    continue
                x, y = s[3 * k], s[3 * k + 1]
                for obstacle in self.obstacles:
                    x, y = _push_out(obstacle, x, y, c)
                s[3 * k] = min(max(x, lo_x), hi_x)
                s[3 * k + 1] = min(max(y, lo_y), hi_y)
            moved = False
            for a, b, sep in self.pairs:
                dx, dy = s[3 * a] - s[3 * b], s[3 * a + 1] - s[3 * b + 1]
                d = math.hypot(dx, dy)
                if d >= sep:
                    continue
                moved = True
                ux, uy = (dx / d, dy / d) if d > 0.0 else (1.0, 0.0)
                deficit = sep - d
                share_a = 0.5 if self.free[a] and self.free[b] else (1.0 if self.free[a] else 0.0)
                share_b = 1.0 - share_a
                s[3 * a] += share_a * deficit * ux
                s[3 * a + 1] += share_a * deficit * uy
                s[3 * b] -= share_b * deficit * ux
                s[3 * b + 1] -= share_b * deficit * uy
            if not moved:
                break
        return s


def _push_out(obstacle: RectObstacle | DiscObstacle, x: float, y: float,
              grow: float) -> tuple[float, float]:
    """(x, y) moved out of the obstacle grown by ``grow`` [m] along its normal (unchanged when
    outside)."""
    if isinstance(obstacle, DiscObstacle):
        cx, cy = obstacle.center
        d = math.hypot(x - cx, y - cy)
        need = obstacle.radius + grow
        if d >= need:
            return x, y
        if d == 0.0:
            return cx + need, cy
        return cx + (x - cx) * need / d, cy + (y - cy) * need / d
    qx = min(max(x, obstacle.xmin), obstacle.xmax)
    qy = min(max(y, obstacle.ymin), obstacle.ymax)
    d = math.hypot(x - qx, y - qy)
    if d >= grow and d > 0.0:
        return x, y
    if d > 0.0:
        return qx + (x - qx) * grow / d, qy + (y - qy) * grow / d
    # inside the rectangle: out through the nearest face
    left, right = x - obstacle.xmin, obstacle.xmax - x
    bottom, top = y - obstacle.ymin, obstacle.ymax - y
    nearest = min(left, right, bottom, top)
    if nearest == left:
        return obstacle.xmin - grow, y
    if nearest == right:
        return obstacle.xmax + grow, y
    if nearest == bottom:
        return x, obstacle.ymin - grow
    return x, obstacle.ymax + grow


def maximize(value_grad: ValueGrad, robots: Sequence[int], workspace: Workspace,
             starts: Sequence[Sequence[float]], *, free: Sequence[bool] | None = None,
             step: float = 0.5, tolerance: float = 1e-5, iterations: int = 400) -> Supremum:
    """Best of a normalised projected gradient ascent of ``value_grad`` over the stacked state of
    ``robots`` from every start (module docstring). ``free[k]``: robot k's block may move
    (default: all); a fixed block stays where its start has it."""
    mask = tuple(free) if free is not None else (True,) * len(robots)
    project = _Projector(robots, workspace, mask)
    best = Supremum(-math.inf, ())
    for start in starts:
        s = project([float(v) for v in start])
        value, grad = value_grad(s)
        h = step
        for _ in range(iterations):
            if grad is None:
                break
            direction = [g if mask[k // 3] else 0.0 for k, g in enumerate(grad)]
            norm = math.sqrt(sum(g * g for g in direction))
            if norm == 0.0 or not math.isfinite(norm):
                break
            candidate = project([v + h * g / norm for v, g in zip(s, direction, strict=True)])
            c_value, c_grad = value_grad(candidate)
            if c_value > value:
                s, value, grad = candidate, c_value, c_grad
                h = min(1.5 * h, step)
            else:
                h *= 0.5
                if h < tolerance:
                    break
        if value > best.value:
            best = Supremum(value, tuple(s))
    return best


def grid_starts(robots: Sequence[int], workspace: Workspace,
                poses: Mapping[int, Sequence[float]], robot: int | None = None,
                n: int = 3) -> list[tuple[float, ...]]:
    """Starts of :func:`maximize`: the stacked ``poses`` (robots without a pose at the arena's
    centre), then an n × n grid over ``robot``'s box (default: the first robot) with the others
    at their poses."""
    arena = workspace.arena
    centre = (0.5 * (arena.xmin + arena.xmax), 0.5 * (arena.ymin + arena.ymax), 0.0)
    base = []
    for j in robots:
        base.extend(float(v) for v in poses.get(j, centre)[:3])
    starts = [tuple(base)]
    k = robots.index(robot) if robot is not None else 0
    c = workspace.clearance_of(robots[k])
    for ix in range(n):
        for iy in range(n):
            s = list(base)
            s[3 * k] = arena.xmin + c + (ix + 0.5) * (arena.width - 2 * c) / n
            s[3 * k + 1] = arena.ymin + c + (iy + 0.5) * (arena.height - 2 * c) / n
            starts.append(tuple(s))
    return starts


@functools.lru_cache(maxsize=256)
def psi_supremum(psi: Psi, robots: tuple[int, ...], eta: float, workspace: Workspace,
                 poses: tuple[tuple[int, tuple[float, float, float]], ...] = ()) -> Supremum:
    """sup of the smooth ρ^ψ over the workspace (module docstring), every participant free;
    ``poses``: (robot, (x, y, θ)) start poses to begin the ascent from (cached per arguments)."""
    compiled = StraightLinePsi(psi, robots, eta)
    starts = grid_starts(robots, workspace, dict(poses))
    best = maximize(compiled.value_grad, robots, workspace, starts)
    if len(robots) > 1:
        # a joint step that a separation pushes back moves the partner too, off its optimum:
        # rounds of one robot at a time (the others fixed) slide along the constraint
        for _ in range(3):
            before = best.value
            for k in range(len(robots)):
                free = [j == k for j in range(len(robots))]
                found = maximize(compiled.value_grad, robots, workspace, [best.state], free=free,
                                 step=0.1)
                if found.value > best.value:
                    best = found
            if best.value - before < 1e-9:
                break
    return best
