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

**Crossing (open space), between two robots that apply this rule.** Each robot is assumed to
drive on at ``cruise`` speed along its path's direction (the own robot: towards its look-ahead
point; another: its velocity from the last two frames). When the closest approach of two robots
within ``horizon`` [s] is nearer than ``r_i + r_j + crossing_gap`` [m], the one with the higher id
waits while the lower id passes; the
ids order the robots totally, so no cycle of waiting robots (a deadlock) can form. A robot
closer than ``min_distance`` [m] to the predicted meeting point goes on (stopping there would
block the other), and a standing robot is no crossing; the local planner keeps them apart, as it
keeps an LTL robot apart from the STL robots, which steer by their own funnels and avoidance.
Robots whose tasks couple them to this one (an escort, a formation: its *followers*) move with
it and are left out of both rules: yielding to a follower would wait for itself.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from tlfleet.agent.nav.grid import OccupancyGrid
from tlfleet.agent.nav.polyline import distance_to_polyline_xy


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


Row = tuple[int, float, float, float, float, float, bool]  # id, x, y, vx, vy, radius, ruled


@dataclass(frozen=True, eq=False)
class Traffic:
    """The other robots of one frame, one row each: id, position x, y [m], velocity x, y [m/s],
    radius [m], and whether it applies this rule (an LTL agent). Plain floats: a control step
    reads a handful of rows; the passage rule turns them into arrays when it needs them."""

    rows: tuple[Row, ...]

    @staticmethod
    def of(ids, positions, velocities, radii, ruled) -> Traffic:
        """From arrays: ids (K,), positions (K, 2), velocities (K, 2), radii (K,), ruled (K,)."""
        return Traffic(tuple(
            (int(i), float(p[0]), float(p[1]), float(u[0]), float(u[1]), float(r), bool(g))
            for i, p, u, r, g in zip(ids, np.asarray(positions).reshape(-1, 2),
                                     np.asarray(velocities).reshape(-1, 2), radii, ruled,
                                     strict=True)))

    def __len__(self) -> int:
        return len(self.rows)

    def arrays(self) -> tuple[np.ndarray, ...]:
        """ids (K,), positions (K, 2), velocities (K, 2), radii (K,), ruled (K,)."""
        a = np.array([row[:6] for row in self.rows], dtype=float).reshape(-1, 6)
        return (a[:, 0].astype(np.int64), a[:, 1:3], a[:, 3:5], a[:, 5],
                np.array([row[6] for row in self.rows], dtype=bool))


def _samples(vertices: list[list[float]], length: float, step: float) -> np.ndarray:
    """Points (S, 2) every ``step`` [m] along the vertex list, up to ``length`` [m] (the last
    vertex where the polyline is shorter)."""
    pts = np.asarray(vertices, dtype=float).reshape(-1, 2)
    if len(pts) == 1:
        return pts.copy()
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    s = np.arange(0.0, min(length, float(arc[-1])) + 1e-9, step)
    return np.stack([np.interp(s, arc, pts[:, 0]), np.interp(s, arc, pts[:, 1])], axis=-1)


def narrow_intervals(vertices: list[list[float]], grid: OccupancyGrid, width: float,
                     step: float) -> tuple[tuple[float, float], ...]:
    """Arc-length intervals ``(a, b)`` [m] of the whole path whose clearance is below ``width``
    [m], sampled every ``step`` [m]: computed once per global path (the executor stores them
    with it), so a control step only looks them up."""
    points = _samples(vertices, math.inf, step)
    if len(points) < 2:
        return ()
    narrow = grid.clearance_at(points) < width
    out, start = [], None
    for k, flag in enumerate(narrow.tolist()):
        if flag and start is None:
            start = k
        elif not flag and start is not None:
            out.append((start * step, (k - 1) * step))
            start = None
    if start is not None:
        out.append((start * step, (len(narrow) - 1) * step))
    return tuple(out)


def narrow_stretch(vertices: list[list[float]], grid: OccupancyGrid, width: float,
                   config: TrafficConfig) -> tuple[float, float] | None:
    """Arc lengths ``(a, b)`` [m] of the first stretch of the path ahead (its first vertex is
    the robot's projection) whose clearance is below ``width``, within ``lookahead``; None."""
    points = _samples(vertices, config.lookahead, config.sample)
    if len(points) < 2:
        return None
    narrow = grid.clearance_at(points) < width
    if not narrow.any():
        return None
    first = int(np.argmax(narrow))
    rest = narrow[first:]
    last = first + (int(np.argmin(rest)) - 1 if not rest.all() else len(rest) - 1)
    return first * config.sample, last * config.sample


def passing_width(radius: float, other_radius: float, config: TrafficConfig) -> float:
    """The clearance [m] below which a robot of ``other_radius`` cannot pass beside one of
    ``radius``: ``r_self + 2·r_other + 2·passing_margin``."""
    return radius + 2.0 * other_radius + 2.0 * config.passing_margin


def narrow_conflict(robot_id: int, position: Sequence[float], radius: float,
                    vertices: list[list[float]], grid: OccupancyGrid, traffic: Traffic,
                    config: TrafficConfig,
                    stretch: tuple[float, float] | bool | None = False) -> int | None:
    """The robot to give way to in a narrow passage (module docstring), or None. ``stretch``:
    the first narrow stretch ``(a, b)`` of ``vertices`` if the caller knows it (None: there is
    none), else it is found here."""
    if not config.enabled or not len(traffic) or len(vertices) < 2:
        return None
    widest = max(row[5] for row in traffic.rows)
    width = passing_width(radius, widest, config)
    if stretch is False:
        stretch = narrow_stretch(vertices, grid, width, config)
    if stretch is None or stretch[0] > config.mouth_distance:
        return None
    a, b = stretch
    inside = a <= 0.0
    span = _samples(vertices, b + config.mouth_distance, config.sample)
    if len(span) < 2:
        return None
    ids, positions, velocities, radii, ruled = traffic.arrays()
    near = distance_to_polyline_xy(positions[:, 0], positions[:, 1], span)
    best: int | None = None
    for k in np.flatnonzero(near < width).tolist():
        p = positions[k]
        d = np.hypot(span[:, 0] - p[0], span[:, 1] - p[1])
        m = int(np.argmin(d))
        if m * config.sample < a - 1e-9 and not inside:
            continue  # behind the stretch's mouth: not in the passage ahead
        j = min(m + 1, len(span) - 1)
        i = max(j - 1, 0)
        direction = span[j] - span[i]
        norm = float(np.hypot(*direction))
        along = float(velocities[k] @ direction) / norm if norm > 1e-9 else 0.0
        if along > config.moving_away:
            continue  # going our way: we follow it
        other_width = passing_width(float(radii[k]), radius, config)
        other_inside = (grid.clearance_point(float(p[0]), float(p[1])) < other_width
                        and m * config.sample <= b)
        other = int(ids[k])
        if not ruled[k]:
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
    ``heading_point`` is the own path's look-ahead point. Plain floats over the few robots (a
    numpy call costs more than its arithmetic here)."""
    if not (config.enabled and config.crossing) or not len(traffic):
        return None
    px, py = float(position[0]), float(position[1])
    hx, hy = float(heading_point[0]) - px, float(heading_point[1]) - py
    norm = math.hypot(hx, hy)
    if norm < 1e-6:
        return None
    vx, vy = hx / norm * config.cruise, hy / norm * config.cruise
    best: int | None = None
    for other, qx, qy, ux, uy, r_other, ruled in traffic.rows:
        if not ruled or other > robot_id:
            continue  # it applies no rule (the local planner's), or we have the right of way
        dpx, dpy = qx - px, qy - py
        if math.hypot(dpx, dpy) > config.crossing_range or math.hypot(ux, uy) < 0.02:
            continue  # far, or standing: the local planner's (or the passage rule's)
        dvx, dvy = ux - vx, uy - vy
        speed2 = dvx * dvx + dvy * dvy
        t_min = 0.0 if speed2 < 1e-9 else max(0.0, -(dpx * dvx + dpy * dvy) / speed2)
        if t_min > config.horizon:
            continue
        miss = math.hypot(dpx + dvx * t_min, dpy + dvy * t_min)
        if miss >= radius + r_other + config.crossing_gap:
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
