"""Smooth n-ary conjunction (stl-funnel.md §3): values, weights, gradient, bounds, stability."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tlfleet.agent.stl.robustness import (
    smooth_and,
    smooth_and_array,
    smooth_and_grad,
    smooth_and_weights,
)

values = st.lists(st.floats(-50, 50, allow_nan=False), min_size=1, max_size=8)


def test_worked_values_11_6():
    assert smooth_and([0.7, 0.1], 10.0) == pytest.approx(0.0997524, abs=1e-6)
    assert smooth_and([1.0, 1.0], 10.0) == pytest.approx(0.9306853, abs=1e-6)
    rho = [-1.4811388, -1.3]
    assert smooth_and(rho, 10.0) == pytest.approx(-1.4962758, abs=1e-6)
    assert smooth_and_weights(rho, 10.0) == pytest.approx([0.8595296, 0.1404704], abs=1e-6)
    grads = [[1.0, 2.0, 0.0], [0.0, -1.0, 0.5]]
    value, grad = smooth_and_grad(rho, grads, 10.0)
    assert value == pytest.approx(-1.4962758, abs=1e-6)
    expected = 0.8595296 * np.array(grads[0]) + 0.1404704 * np.array(grads[1])
    assert grad == pytest.approx(expected, abs=1e-6)


@given(vs=values, eta=st.floats(0.5, 50))
def test_bounds_min_minus_log_n_over_eta(vs, eta):
    rho = smooth_and(vs, eta)
    assert min(vs) - math.log(len(vs)) / eta - 1e-9 <= rho <= min(vs) + 1e-12
    assert sum(smooth_and_weights(vs, eta)) == pytest.approx(1.0)


@given(a=values, b=values)
def test_nested_binary_conjunctions_flatten_exactly(a, b):
    nested = smooth_and([smooth_and(a, 10.0), smooth_and(b, 10.0)], 10.0)
    assert nested == pytest.approx(smooth_and(a + b, 10.0), abs=1e-9)


def test_stable_for_large_magnitudes_and_vectorised_form():
    assert smooth_and([1e4, 1e4 + 1.0], 10.0) == pytest.approx(1e4 - math.log1p(math.exp(-10)) / 10)
    assert smooth_and([-1e4, 5.0], 10.0) == pytest.approx(-1e4)
    assert smooth_and([], 10.0) == math.inf
    rows = [np.array([0.7, 1.0, -1e4]), np.array([0.1, 1.0, 3.0])]
    expected = [smooth_and([0.7, 0.1], 10), smooth_and([1.0, 1.0], 10), -1e4]
    assert smooth_and_array(rows, 10.0) == pytest.approx(expected)
