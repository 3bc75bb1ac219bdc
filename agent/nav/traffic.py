"""Right of way between robots: who yields in a narrow passage or at a crossing
(docs/ltl-navigation.md §6).

Every LTL agent applies the same rule, each from the shared pose frame and its own global path,
so the decisions agree without a message. Two situations:

**Narrow passage (head-on).** A point of the own path is *narrow* when a robot of the other's
radius cannot pass beside this one there: its clearance (to walls, obstacles and keep-out zones)
is below ``r_self + 2·r_other + 2·passing_margin`` [m]. When the first narrow stretch of the path
ahead begins within ``mouth_distance`` (or the robot is in it), every other robot that is in the
stretch or within ``mouth_distance`` past its end, near the path (closer than that same width),
and not moving away along it (an oncoming or standing robot) is in conflict with this one. The
robot **inside** the stretch has the right of way over one outside it; between two inside or two
outside, the lower id does. A robot that is not an LTL agent (it does not apply this rule) always
has the right of way. The one without it **yields**: it stops before the stretch (at its mouth)
and waits until no conflict is left, at most ``max_wait`` [s]; where it stands is the other's
way out of the passage, so it first steps aside to a *refuge* (:func:`refuge`): the nearest
point off its own path by ``r_self + r_other + 2·passing_margin + refuge_gap`` with room around
it, reached in a straight line.

**Crossing (open space).** Each robot is assumed to drive on at ``cruise`` speed along its path's
direction (the own robot: towards its look-ahead point; another: its velocity from the last two
frames). When the closest approach of two robots within ``horizon`` [s] is nearer than
``r_i + r_j + crossing_gap`` [m], the one with the higher id waits while the lower id passes; the
ids order the robots totally, so no cycle of waiting robots (a deadlock) can form. A robot
closer than ``min_distance`` [m] to the predicted meeting point goes on (stopping there would
block the other), and a standing robot is no crossing; the local planner keeps them apart.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from tlfleet.agent.nav.grid import OccupancyGrid
from tlfleet.agent.nav.polyline import distance_to_polyline_xy, point_along_vertices


@dataclass(frozen=True)
class TrafficConfig:
    """Parameters of the right-of-way rule (lengths [m], times [s], speeds [m/s])."""

    enabled: bool = True
    passing_margin: float = 0.05  # [m] each side of two robots passing in a passage
    lookahead: float = 6.0  # [m] of own path searched for a narrow stretch
    mouth_distance: float = 1.0  # [m] wait this far before a narrow stretch
    moving_away: float = 0.05  # [m/s] along the path: a robot faster than this leaves
    max_wait: float = 15.0  # [s] longest yield; then the robot drives on (and may recover)
    sample: float = 0.05  # [m] spacing of the path samples
    crossing: bool = True
    crossing_gap: float = 0.35  # [m] wanted between two crossing robots' bodies
    horizon: float = 6.0  # [s] closest approaches further ahead do not count
    cruise: float = 0.25  # [m/s] assumed speed of a robot driving on
    min_distance: float = 0.6  # [m] to the meeting point: nearer than this, drive on
    crossing_range: float = 3.0  # [m] robots farther away are not considered
    min_yield: float = 1.0  # [s] a yield lasts at least this long (no begin/end flicker)
    refuge_gap: float = 0.1  # [m] beyond the passing width, between a refuge and the own path
    refuge_reach: float = 1.5  # [m] farthest refuge considered


@dataclass(frozen=True, eq=False)
class Traffic:
    """The other robots of one frame: ids (K,), positions (K, 2) [m], velocities (K, 2) [m/s],
    radii (K,) [m], and whether each applies this rule (an LTL agent) (K,)."""

    ids: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray
    ruled: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


def _samples(vertices: list[list[float]], length: float, step: float) -> np.ndarray:
    """Points (S, 2) every ``step`` [m] along the vertex list, up to ``length`` [m]."""
    out = [point_along_vertices(vertices, s) for s in np.arange(0.0, length + 1e-9, step)]
    return np.asarray(out, dtype=float)


def narrow_stretch(vertices: list[list[float]], grid: OccupancyGrid, width: float,
                   config: TrafficConfig) -> tuple[float, float] | None:
    """Arc lengths ``(a, b)`` [m] of the first stretch of the path ahead (its first vertex is
    the robot's projection) whose clearance is below ``width``, within ``lookahead``; None."""
    if len(vertices) < 2:
        return None
    total = 0.0
    for (ax, ay), (bx, by) in pairwise(vertices):
        total += math.hypot(bx - ax, by - ay)
    reach = min(total, config.lookahead)
    points = _samples(vertices, reach, config.sample)
    narrow = grid.clearance_at(points) < width
    if not narrow.any():
        return None
    first = int(np.argmax(narrow))
    rest = narrow[first:]
    last = first + (int(np.argmin(rest)) - 1 if not rest.all() else len(rest) - 1)
    return first * config.sample, last * config.sample


def narrow_conflict(robot_id: int, position: Sequence[float], radius: float,
                    vertices: list[list[float]], grid: OccupancyGrid, traffic: Traffic,
                    config: TrafficConfig) -> int | None:
    """The robot to give way to in a narrow passage (module docstring), or None."""
    if not config.enabled or not len(traffic) or len(vertices) < 2:
        return None
    widest = float(np.max(traffic.radii)) if len(traffic) else radius
    width = radius + 2.0 * widest + 2.0 * config.passing_margin
    stretch = narrow_stretch(vertices, grid, width, config)
    if stretch is None or stretch[0] > config.mouth_distance:
        return None
    a, b = stretch
    inside = a <= 0.0
    span = _samples(vertices, b + config.mouth_distance, config.sample)
    if len(span) < 2:
        return None
    near = distance_to_polyline_xy(traffic.positions[:, 0], traffic.positions[:, 1], span)
    # where each robot projects on the span, and the path's direction there
    best: int | None = None
    for k in np.flatnonzero(near < width).tolist():
        p = traffic.positions[k]
        d = np.hypot(span[:, 0] - p[0], span[:, 1] - p[1])
        m = int(np.argmin(d))
        if m * config.sample < a - 1e-9 and not inside:
            continue  # behind the stretch's mouth: not in the passage ahead
        j = min(m + 1, len(span) - 1)
        i = max(j - 1, 0)
        direction = span[j] - span[i]
        norm = float(np.hypot(*direction))
        along = float(traffic.velocities[k] @ direction) / norm if norm > 1e-9 else 0.0
        if along > config.moving_away:
            continue  # going our way: we follow it
        other_width = float(traffic.radii[k]) + 2.0 * radius + 2.0 * config.passing_margin
        other_inside = bool(grid.clearance_at(p) < other_width) and m * config.sample <= b
        other = int(traffic.ids[k])
        if not traffic.ruled[k]:
            we_go = False  # it does not yield: it has the right of way
        elif inside != other_inside:
            we_go = inside
        else:
            we_go = robot_id < other
        if not we_go and (best is None or other < best):
            best = other
    return best


def crossing_conflict(robot_id: int, position: Sequence[float], radius: float,
                      heading_point: Sequence[float], traffic: Traffic,
                      config: TrafficConfig) -> int | None:
    """The robot with a lower id to let pass first at a crossing (module docstring), or None.
    ``heading_point`` is the own path's look-ahead point."""
    if not (config.enabled and config.crossing) or not len(traffic):
        return None
    p = np.asarray(position[:2], dtype=float)
    direction = np.asarray(heading_point[:2], dtype=float) - p
    norm = float(np.hypot(*direction))
    if norm < 1e-6:
        return None
    v = direction / norm * config.cruise
    best: int | None = None
    for k in range(len(traffic)):
        other = int(traffic.ids[k])
        if traffic.ruled[k] and other > robot_id:
            continue  # we have the right of way over it
        q = traffic.positions[k]
        if float(np.hypot(*(q - p))) > config.crossing_range:
            continue
        u = traffic.velocities[k]
        dp, dv = q - p, u - v
        speed2 = float(dv @ dv)
        t_min = 0.0 if speed2 < 1e-9 else max(0.0, -float(dp @ dv) / speed2)
        if t_min > config.horizon or float(np.hypot(*u)) < 0.02:
            continue  # a standing robot is the local planner's (or the passage rule's)
        miss = float(np.hypot(*(dp + dv * t_min)))
        if miss >= radius + float(traffic.radii[k]) + config.crossing_gap:
            continue
        if t_min * config.cruise < config.min_distance:
            continue  # too close to stop short of the meeting point: the DWA keeps us apart
        if best is None or other < best:
            best = other
    return best


def refuge(position: Sequence[float], vertices: list[list[float]], grid: OccupancyGrid,
           radius: float, other_radius: float, config: TrafficConfig) -> tuple[float, float] | None:
    """Where to wait, out of an oncoming robot's way (module docstring): the point nearest to
    ``position`` [m] at least ``radius + other_radius + 2·passing_margin + refuge_gap`` from the
    own path ahead (``vertices``, up to ``lookahead``), with clearance ≥ ``radius +
    passing_margin`` on ``grid`` and free straight-line access; None when there is none within
    ``refuge_reach``."""
    p = np.asarray(position[:2], dtype=float)
    span = _samples(vertices, config.lookahead, config.sample) if len(vertices) >= 2 else \
        np.asarray(vertices, dtype=float).reshape(-1, 2)
    if len(span) == 0:
        return None
    away = radius + other_radius + 2.0 * config.passing_margin + config.refuge_gap
    step = grid.resolution * 2.0
    rings = np.arange(step, config.refuge_reach + 1e-9, step)
    angles = np.linspace(0.0, 2.0 * math.pi, 48, endpoint=False)
    candidates = (p[None, None, :] + rings[:, None, None]
                  * np.stack([np.cos(angles), np.sin(angles)], axis=-1)[None, :, :]).reshape(-1, 2)
    room = grid.clearance_at(candidates) >= radius + config.passing_margin
    off = distance_to_polyline_xy(candidates[:, 0], candidates[:, 1], span) >= away
    ok = np.flatnonzero(room & off & grid.is_free(candidates))
    for k in ok[np.argsort(np.hypot(*(candidates[ok] - p).T), kind="stable")].tolist():
        q = candidates[k]
        n = max(2, math.ceil(float(np.hypot(*(q - p))) / (grid.resolution / 2.0)) + 1)
        line = p[None, :] + np.linspace(0.0, 1.0, n)[:, None] * (q - p)[None, :]
        if np.all(grid.clearance_at(line[1:]) >= radius + config.passing_margin / 2.0):
            return float(q[0]), float(q[1])
    return None
