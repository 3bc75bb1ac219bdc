"""Nominal funnel law u_nom = −k_ε·ε·∇ with gradient normalisation (stl-funnel.md §6.1)."""

from __future__ import annotations

import math

import pytest
from tlfleet.agent.stl.control_law import nominal_velocity


def test_normalised_direction_and_magnitude_epsilon():
    eps = math.log(0.2)
    u = nominal_velocity(eps, [-0.7071068, -0.7071068, 0.0])
    assert u == pytest.approx((-1.138044, -1.138044, 0.0), abs=1e-6)
    assert nominal_velocity(2.0, [3.0, 0.0, 4.0]) == pytest.approx((-1.2, 0.0, -1.6))
    assert nominal_velocity(2.0, [3.0, 0.0, 4.0], normalize=False, k_eps=0.5) == pytest.approx(
        (-3.0, 0.0, -4.0))


def test_zero_and_non_finite_gradients_give_zero():
    assert nominal_velocity(1.0, None) == (0.0, 0.0, 0.0)
    assert nominal_velocity(1.0, [0.0, 0.0, 0.0]) == (0.0, 0.0, 0.0)
    assert nominal_velocity(1.0, [math.nan, 0.0, 0.0]) == (0.0, 0.0, 0.0)
    assert nominal_velocity(1.0, [math.inf, 1.0, 0.0]) == (0.0, 0.0, 0.0)
