"""Polyline geometry for path following: distances, projection, look-ahead point.

A polyline is an array (M, 2) of vertices [m]; segment k joins vertices k and k+1.

Paths here have a handful of vertices and are read once per 5 Hz control step, so everything
but the distance of many points is computed in plain floats over the vertex list (a
numpy call costs 1–13 µs here, more than the arithmetic). The operations and their order are
those of the array form (``s = clip((p − a)·(b − a) / ‖b − a‖², 0, 1)`` with the dot product
summed x then y, ``‖·‖ = sqrt(x² + y²)``, cumulative sums left to right, numpy's pairwise sum
for a length of 8 segments or more), so the values are the same to the last bit
(tests/nav/test_nav_dwa_reference.py checks them against the array form).
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np


def _vertices(polyline: np.ndarray) -> list[list[float]]:
    return np.asarray(polyline, dtype=float).reshape(-1, 2).tolist()


def distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Euclidean distance [m] from each of ``points`` (P, 2) to the polyline (M, 2); shape (P,)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    return distance_to_polyline_xy(pts[:, 0], pts[:, 1], polyline)


def distance_to_polyline_xy(x: np.ndarray, y: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """``distance_to_polyline`` of points given as coordinate arrays ``x``, ``y`` (P,) [m].

    For segment ``a→b`` and point ``p``: ``s = clip((p − a)·(b − a) / ‖b − a‖², 0, 1)``,
    ``d = ‖p − (a + s (b − a))‖``; the result is the minimum over segments, one segment at a
    time on (P,) arrays.
    """
    vertices = _vertices(polyline)
    if len(vertices) == 1:
        (vx, vy), = vertices
        dx, dy = x - vx, y - vy
        return np.sqrt(dx * dx + dy * dy)
    least = None
    for (ax, ay), (bx, by) in pairwise(vertices):
        abx, aby = bx - ax, by - ay
        len2 = max(abx * abx + aby * aby, 1e-12)
        apx, apy = x - ax, y - ay
        s = apx * abx
        s += apy * aby
        s /= len2
        np.maximum(s, 0.0, out=s)  # np.clip's values, without its Python wrapper
        np.minimum(s, 1.0, out=s)
        dx = apx - s * abx
        dy = apy - s * aby
        dx *= dx
        dy *= dy
        dx += dy
        least = dx if least is None else np.minimum(least, dx, out=least)
    return np.sqrt(least, out=least)


def _project(px: float, py: float, vertices: list[list[float]]) -> tuple[int, float, float]:
    """Closest point of the polyline (a vertex list, ≥ 2 vertices) to (px, py): (segment index,
    x, y); the first segment on ties."""
    best, best_k, best_x, best_y = math.inf, 0, 0.0, 0.0
    for k, ((ax, ay), (bx, by)) in enumerate(pairwise(vertices)):
        abx, aby = bx - ax, by - ay
        len2 = max(abx * abx + aby * aby, 1e-12)
        s = min(max(((px - ax) * abx + (py - ay) * aby) / len2, 0.0), 1.0)
        qx, qy = ax + s * abx, ay + s * aby
        dx, dy = qx - px, qy - py
        d2 = dx * dx + dy * dy
        if d2 < best:
            best, best_k, best_x, best_y = d2, k, qx, qy
    return best_k, best_x, best_y


def project_on_polyline(point: np.ndarray, polyline: np.ndarray) -> tuple[int, np.ndarray]:
    """Closest point of the polyline to ``point`` (2,): (segment index, projected point (2,))."""
    vertices = _vertices(polyline)
    if len(vertices) == 1:
        return 0, np.array(vertices[0])
    k, qx, qy = _project(float(point[0]), float(point[1]), vertices)
    return k, np.array([qx, qy])


def remaining_polyline(point: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """The part of the polyline ahead of ``point``'s projection: (projection, later vertices)."""
    return np.array(remaining_vertices(float(point[0]), float(point[1]), _vertices(polyline)))


def remaining_vertices(px: float, py: float, vertices: list[list[float]]) -> list[list[float]]:
    """``remaining_polyline`` on a vertex list: [projection of (px, py), later vertices…]."""
    if len(vertices) == 1:
        return [list(vertices[0])]
    k, qx, qy = _project(px, py, vertices)
    return [[qx, qy], *vertices[k + 1:]]


def point_along(polyline: np.ndarray, distance: float) -> np.ndarray:
    """The point (2,) at arc length ``distance`` [m] from the start (clamped to the end)."""
    return np.array(point_along_vertices(_vertices(polyline), distance))


def point_along_vertices(vertices: list[list[float]], distance: float) -> tuple[float, float]:
    """``point_along`` on a vertex list."""
    if len(vertices) == 1 or distance <= 0.0:
        return vertices[0][0], vertices[0][1]
    travelled = 0.0
    for (ax, ay), (bx, by) in pairwise(vertices):
        dx, dy = bx - ax, by - ay
        seg = math.sqrt(dx * dx + dy * dy)
        reached = travelled + seg
        if distance < reached:
            s = (distance - travelled) / max(seg, 1e-12)
            return ax + s * dx, ay + s * dy
        travelled = reached
    return vertices[-1][0], vertices[-1][1]


def polyline_length(polyline: np.ndarray) -> float:
    """Sum of segment lengths [m] of a polyline (M, 2)."""
    return vertices_length(_vertices(polyline))


def vertices_length(vertices: list[list[float]]) -> float:
    """``polyline_length`` on a vertex list."""
    lengths = []
    for (ax, ay), (bx, by) in pairwise(vertices):
        dx, dy = bx - ax, by - ay
        lengths.append(math.sqrt(dx * dx + dy * dy))
    if len(lengths) >= 8:  # numpy sums 8 terms or more pairwise: the array form's order
        return float(np.sum(lengths))
    total = 0.0
    for length in lengths:
        total += length
    return total
