"""Funnel initialisation (§5), ζ/ε (§4.2) and repairs R1–R10 (§7.3): worked vectors of §11 and the
invariants after every repair."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.agent.stl.errors import FunnelInvariantError
from tlfleet.agent.stl.funnel import Funnel, FunnelParams, epsilon, is_critical

TOL = 1e-6


def approx(value):
    return pytest.approx(value, abs=TOL)


@pytest.fixture
def funnel_11_1() -> Funnel:
    return Funnel.init("G", 21, 30, 0.1, 0.1 - math.sqrt(2), 0.0)


@pytest.fixture
def funnel_11_2() -> Funnel:
    return Funnel.init("F", 44, 47, 0.1, 0.1 - math.sqrt(3.25), 0.0)


def test_11_1_g_task_initial_parameters(funnel_11_1):
    f = funnel_11_1
    assert (f.rho_max, f.zeta_u, f.r, f.t_star) == (approx(0.09), approx(0.005), approx(0.0225), 21)
    assert f.gamma0 == approx(1.6850563)
    assert f.gamma_inf == approx(0.03375)
    assert f.l == approx(0.1852544)
    for t, gamma in [(0, 1.685056), (5, 0.687713), (10, 0.292737), (15, 0.136316),
                     (20, 0.074369), (21, 0.0675), (25, 0.049836), (30, 0.040121)]:
        assert f.gamma(t) == approx(gamma)
    assert f.lower(21) == approx(0.0225)
    rho0 = 0.1 - math.sqrt(2)
    assert f.zeta(rho0, 0.0) == approx(-0.8333333)
    assert epsilon(f.zeta(rho0, 0.0)) == approx(math.log(0.2))


def test_11_2_f_task_initial_parameters(funnel_11_2):
    f = funnel_11_2
    assert (f.rho_max, f.r, f.zeta_u) == (approx(0.09), approx(0.0225), approx(0.005))
    assert f.t_star == approx(45.0)
    assert f.gamma0 == approx(2.1513308)
    assert f.gamma_inf == approx(0.03375)
    assert f.l == approx(0.0919789)
    for t, gamma in [(0, 2.151331), (10, 0.877825), (20, 0.370201), (30, 0.167860),
                     (40, 0.087207), (44, 0.070752), (45, 0.0675), (47, 0.061829)]:
        assert f.gamma(t) == approx(gamma)
    assert f.lower(45) == approx(0.0225)


def test_11_3_stage1_repair_at_t40(funnel_11_2):
    rho = funnel_11_2.lower(40)
    assert rho == approx(0.0027932)
    f = funnel_11_2.repair(1, rho, 40.0)
    assert f.t_star == 47 and f.t_r == 40.0
    assert f.rho_max == approx(0.095)
    assert f.r == approx(0.01125)
    assert f.gamma0 == approx(0.2922068)
    assert f.gamma_inf == approx(0.041875)
    assert f.l == approx(0.2554426)
    assert f.lower(40) == approx(-0.1972068)
    assert f.gamma(47) == approx(0.08375)
    assert f.lower(47) == approx(0.01125)


def test_11_4_stage3_repair_late(funnel_11_1):
    f = funnel_11_1.repair(3, -0.05, 25.0)
    assert f.rho_max == approx(0.095)
    assert f.r == approx(-0.071)
    assert f.gamma0 == approx(0.165)
    assert f.gamma_inf == approx(0.0825)
    assert f.l == 0.0
    assert f.lower(25) == approx(-0.07) and f.lower(1e6) == approx(-0.07)


def test_late_start_with_violated_task_goes_to_least_violating_r():
    # G with a = 0 and ρ_0 ≤ r: r := ρ_0 − δ, γ_0 = (ρ_max − ρ_0) + 0.5(ρ_0 − r), l = 0.
    f = Funnel.init("G", 0, 90, 0.6, -1.0, 0.0)
    assert f.r == approx(-1.02)
    assert f.gamma0 == approx(f.rho_max + 1.0 + 0.01)
    assert f.l == 0.0
    assert f.lower(0.0) > f.r


def test_epsilon_and_critical():
    assert epsilon(-0.5) == 0.0
    assert epsilon(-1.5) == approx(math.log((1 - 1e-9) / 1e-9) * -1)
    assert epsilon(0.3) == approx(math.log((1 - 1e-9) / 1e-9))
    assert is_critical(-1.0) and is_critical(0.0) and is_critical(0.2)
    assert not is_critical(-0.999) and not is_critical(-1e-6)


def test_invariant_violation_raises_internal_error(funnel_11_1):
    broken = Funnel(**{**funnel_11_1.__dict__, "gamma_inf": 2.0})
    with pytest.raises(FunnelInvariantError, match="gamma_inf"):
        broken.check(-1.0, 0.0, "test")


def _assert_invariants(f: Funnel, rho: float, t: float, opt: float):
    assert -1.0 < f.zeta(rho, t) < 0.0
    assert 0.0 < f.gamma_inf <= f.gamma0
    assert f.gamma_inf < f.rho_max - f.r
    assert 0.0 <= f.l < math.inf
    assert f.rho_max <= max(opt + 1e-4, rho + 1e-4) + 1e-12
    if f.l > 0:  # decaying funnel: its lower boundary reaches r exactly at t*
        assert f.t_star - t > 0.01
        assert f.lower(f.t_star) == pytest.approx(f.r, abs=1e-9)
    else:  # constant funnel (late, or already above r): lower boundary stays above r
        assert f.lower(t) >= f.r


@settings(max_examples=examples(300))
@given(
    kind=st.sampled_from(["G", "F"]),
    a=st.floats(0, 40), length=st.floats(0, 20),
    opt=st.floats(0.05, 1.5),
    rho0=st.floats(-3, 1.5),
    t0=st.floats(0, 30),
    events=st.lists(st.tuples(st.sampled_from([1, 2, 3]), st.floats(0, 1), st.floats(-2, 1.5),
                              st.floats(-0.3, 1.3)), max_size=12),
)
def test_invariants_after_every_repair(kind, a, length, opt, rho0, t0, events):
    """Random event sequences: after init and after every repair (§7.3 'Assert after repair')."""
    assume(rho0 < opt * 0.999)
    b = a + length
    f = Funnel.init(kind, a, b, opt, rho0, t0)
    _assert_invariants(f, rho0, t0, opt)
    t = t0
    for stage, dt, _rho_free, pos in events:
        t = t + 0.01 + dt * 3
        # A critical event happens on a boundary or outside: pick ρ on/below the lower boundary
        # (pos ≤ 0), or on/above ρ_max (pos ≥ 1), or anywhere (the repair must re-contain it).
        lower, upper = f.lower(t), f.rho_max
        rho = lower + pos * (upper - lower)
        rho = min(rho, opt)
        f = f.repair(stage, rho, t)
        _assert_invariants(f, rho, t, opt)


def test_rng_mode_draws_uniform_fractions():
    rng = np.random.default_rng(7)
    f = Funnel.init("G", 21, 30, 0.1, 0.1 - math.sqrt(2), 0.0, FunnelParams(), rng)
    assert 0 < f.r < 0.5 * f.rho_max
    g = f.repair(1, f.lower(10.0), 10.0, FunnelParams(), rng)
    assert g.t_r == 10.0 and g.l >= 0
