"""Polyline geometry for path following: distances, projection, look-ahead point. Pure numpy.

A polyline is an array (M, 2) of vertices [m]; segment k joins vertices k and k+1.
"""

from __future__ import annotations

import numpy as np


def distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Euclidean distance [m] from each of ``points`` (P, 2) to the polyline (M, 2); shape (P,).

    For segment ``a→b`` and point ``p``: ``s = clip((p − a)·(b − a) / ‖b − a‖², 0, 1)``,
    ``d = ‖p − (a + s (b − a))‖``; the result is the minimum over segments, computed as one
    (P, M−1) array.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    poly = np.asarray(polyline, dtype=float).reshape(-1, 2)
    if len(poly) == 1:
        return np.linalg.norm(pts - poly[0], axis=1)
    a = poly[:-1]
    ab = poly[1:] - a  # (S, 2)
    len2 = np.maximum(np.sum(ab * ab, axis=1), 1e-12)  # (S,)
    ap = pts[:, None, :] - a[None, :, :]  # (P, S, 2)
    s = np.clip(np.sum(ap * ab[None], axis=2) / len2[None], 0.0, 1.0)  # (P, S)
    diff = ap - s[..., None] * ab[None]
    return np.sqrt(np.min(np.sum(diff * diff, axis=2), axis=1))


def project_on_polyline(point: np.ndarray, polyline: np.ndarray) -> tuple[int, np.ndarray]:
    """Closest point of the polyline to ``point`` (2,): (segment index, projected point (2,))."""
    p = np.asarray(point, dtype=float)[:2]
    poly = np.asarray(polyline, dtype=float).reshape(-1, 2)
    if len(poly) == 1:
        return 0, poly[0].copy()
    a = poly[:-1]
    ab = poly[1:] - a
    len2 = np.maximum(np.sum(ab * ab, axis=1), 1e-12)
    s = np.clip(np.sum((p - a) * ab, axis=1) / len2, 0.0, 1.0)
    proj = a + s[:, None] * ab
    k = int(np.argmin(np.sum((proj - p) ** 2, axis=1)))
    return k, proj[k]


def remaining_polyline(point: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """The part of the polyline ahead of ``point``'s projection: (projection, later vertices)."""
    poly = np.asarray(polyline, dtype=float).reshape(-1, 2)
    k, proj = project_on_polyline(point, poly)
    return np.vstack([proj[None, :], poly[k + 1 :]])


def point_along(polyline: np.ndarray, distance: float) -> np.ndarray:
    """The point (2,) at arc length ``distance`` [m] from the start (clamped to the end)."""
    poly = np.asarray(polyline, dtype=float).reshape(-1, 2)
    if len(poly) == 1 or distance <= 0.0:
        return poly[0].copy()
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if distance >= cum[-1]:
        return poly[-1].copy()
    k = int(np.searchsorted(cum, distance, side="right") - 1)
    s = (distance - cum[k]) / max(seg[k], 1e-12)
    return poly[k] + s * (poly[k + 1] - poly[k])


def polyline_length(polyline: np.ndarray) -> float:
    """Sum of segment lengths [m] of a polyline (M, 2)."""
    poly = np.asarray(polyline, dtype=float).reshape(-1, 2)
    if len(poly) < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.diff(poly, axis=0), axis=1)))
