"""Separate linear/angular saturation (stl-funnel.md §6.1 step 4) and the mixed law (6)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from tlfleet.agent.control.mixing import mix
from tlfleet.agent.control.saturation import saturate

velocities = st.floats(-50, 50, allow_nan=False)


def test_saturate_keeps_direction_and_clips_omega_separately():
    assert saturate((-1.138044, -1.138044, 0.0), 0.2, 6.28) == pytest.approx(
        (-0.1414214, -0.1414214, 0.0), abs=1e-6)
    assert saturate((0.1, 0.0, 10.0), 0.2, 6.28) == (0.1, 0.0, 6.28)
    assert saturate((0.0, 0.3, -7.0), 0.2, 6.28) == pytest.approx((0.0, 0.2, -6.28))


@given(vx=velocities, vy=velocities, w=velocities)
def test_saturate_bounds_and_identity_inside(vx, vy, w):
    sx, sy, sw = saturate((vx, vy, w), 0.2, 6.28)
    assert math.hypot(sx, sy) <= 0.2 + 1e-12 and abs(sw) <= 6.28
    if math.hypot(vx, vy) <= 0.2:
        assert (sx, sy) == (vx, vy)
    else:
        assert sx * vy == pytest.approx(sy * vx, abs=1e-9)  # same direction
        assert sx * vx + sy * vy > 0


def test_mix_is_eq6():
    # β·ū_col + ū_nom, then saturation: head-on collision term dominates a weak nominal command
    assert mix((0.1, 0.0, 0.5), (-0.2, 0.0, 0.0), 2.0, 0.2, 6.28) == pytest.approx(
        (-0.2, 0.0, 0.5))
    assert mix((0.05, 0.0, 0.0), (0.0, 0.01, 0.0), 2.0, 0.2, 6.28) == pytest.approx(
        (0.05, 0.02, 0.0))


def test_norm_mode_is_the_papers_single_norm():
    u = saturate((0.3, 0.0, 0.4), 0.2, 6.28, mode="norm")
    assert u == pytest.approx((0.12, 0.0, 0.16))
    assert saturate((0.1, 0.0, 0.1), 0.2, 6.28, mode="norm") == (0.1, 0.0, 0.1)
    assert mix((0.3, 0.0, 0.4), (0.0, 0.0, 0.0), 2.0, 0.2, 6.28, mode="norm") == pytest.approx(
        (0.12, 0.0, 0.16))
