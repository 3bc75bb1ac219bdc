"""Random DWA inputs shared by the reference and the native-kernel tests (tests/nav)."""

from __future__ import annotations

import math

import numpy as np
from tlfleet.agent.model.scenario import Arena
from tlfleet.agent.nav.coupling_limits import CouplingConstraint, VelocityLimits
from tlfleet.agent.nav.dwa import DwaConfig, MovingDiscs
from tlfleet.agent.nav.grid import grid_from_arena

GRID = grid_from_arena(Arena(), inflation=0.25)
ROBOT_RADIUS = 0.2
PYTHON = DwaConfig(kernel="python")  # the numpy form, whatever $TLFLEET_DWA says


def numpy_is_libm() -> bool:
    """Whether numpy's float64 sin, cos and exp give libm's values (``math`` calls libm) on
    100 000 arguments over the ranges the DWA uses: headings and the inflation's exponents.
    False where numpy uses its own SIMD forms (x86-64 with AVX-512), which are a few ulp apart."""
    rng = np.random.default_rng(7)
    angles = rng.uniform(-12.0, 12.0, 100_000)
    exponents = rng.uniform(-25.0, 0.0, 100_000)
    return (np.sin(angles).tolist() == [math.sin(a) for a in angles.tolist()]
            and np.cos(angles).tolist() == [math.cos(a) for a in angles.tolist()]
            and np.exp(exponents).tolist() == [math.exp(e) for e in exponents.tolist()])


EXACT = numpy_is_libm()  # computed once per test session


def random_path(rng: np.random.Generator, start: np.ndarray) -> np.ndarray:
    """1–20 vertices ahead of ``start`` (mostly up to 6), some legs of zero length."""
    n = int(rng.integers(1, 7) if rng.random() < 0.8 else rng.integers(7, 21))
    legs = rng.normal(scale=rng.choice([0.05, 0.5, 1.5]), size=(n, 2))
    legs[rng.random(n) < 0.1] = 0.0
    return np.clip(start + np.cumsum(legs, axis=0), -3.4, 3.4)


def random_others(rng: np.random.Generator, position: np.ndarray) -> MovingDiscs:
    k = int(rng.integers(0, 7))
    spread = rng.choice([0.4, 1.0, 3.0], size=(k, 1))
    centers = position + rng.normal(size=(k, 2)) * spread
    velocities = rng.normal(scale=0.2, size=(k, 2)) * (rng.random((k, 1)) < 0.7)
    return MovingDiscs(centers, velocities, rng.choice([0.15, 0.2, 0.25], size=k))


def random_limits(rng: np.random.Generator) -> VelocityLimits | None:
    if rng.random() < 0.6:
        return None
    n = int(rng.integers(1, 3))
    return VelocityLimits(tuple(
        CouplingConstraint(float(rng.uniform(0, 1.5)), float(rng.uniform(0, 0.8)),
                           float(rng.uniform(0.02, 0.4)), "random")
        for _ in range(n)))


def random_cycle(rng: np.random.Generator
                 ) -> tuple[np.ndarray, tuple[float, float], np.ndarray, MovingDiscs,
                            VelocityLimits | None]:
    """One DWA cycle's inputs (pose, last command, path, other robots, coupling limits): poses
    mostly inside the arena, some at its edge and beyond (the off-grid lookups)."""
    position = rng.uniform(-3.6, 3.6, size=2) * rng.choice([0.6, 1.0, 1.05])
    pose = np.array([*position, rng.uniform(-math.pi, math.pi)])
    velocity = (float(rng.choice([0.0, rng.uniform(0, 0.3)])),
                float(rng.choice([0.0, rng.uniform(-1, 1), 1e-10])))
    path = random_path(rng, position)
    others = random_others(rng, position)
    return pose, velocity, path, others, random_limits(rng)
