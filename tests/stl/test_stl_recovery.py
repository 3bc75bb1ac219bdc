"""Robustness recovery (tlfleet.agent.stl.recovery): the invariants of its funnels (G and F
sub-tasks), its hysteresis, and the room rules."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.agent.stl.funnel import Funnel, FunnelParams
from tlfleet.agent.stl.recovery import (
    RecoveryParams,
    RecoveryState,
    advance,
    f_deadlines,
    on_critical,
    reach_time,
    recovered_f_funnel,
    recovered_funnel,
)

FP = FunnelParams()
RP = RecoveryParams()


def _relaxed_funnel(opt: float, rho0: float, t0: float, repairs: list[tuple[int, float, float]]):
    """A G funnel initialised at t0 and repaired a few times (what recovery starts from)."""
    f = Funnel.init("G", t0 + 1.0, t0 + 50.0, opt, rho0, t0, FP)
    t = t0
    for stage, dt, frac in repairs:
        t += dt
        rho = f.lower(t) - frac  # on or below the lower boundary: a critical event
        f = f.repair(stage, rho, t, FP)
    return f, t


@settings(max_examples=examples(300), deadline=None)
@given(opt=st.floats(0.05, 1.5), rho0=st.floats(-3.0, 1.0), t0=st.floats(0, 30),
       repairs=st.lists(st.tuples(st.sampled_from([1, 3]), st.floats(0.01, 5), st.floats(0, 0.05)),
                        min_size=1, max_size=8),
       up=st.floats(0.0, 1.0), target_frac=st.floats(0.0, 1.0), rate=st.floats(1e-3, 1.0),
       wait=st.floats(0.0, 20.0))
def test_recovered_funnel_keeps_algorithm_2_invariants(opt, rho0, t0, repairs, up, target_frac,
                                                      rate, wait):
    old, t_last = _relaxed_funnel(opt, rho0, t0, repairs)
    t = t_last + wait
    rho = old.r + up * (old.rho_max - old.r)  # somewhere between r and ρ_max
    assume(old.r + 1e-6 < rho < old.rho_max - 1e-6)
    target = old.r + 1e-3 + target_frac * (old.rho_max - old.r)
    target = min(target, old.rho_max - 1e-3)
    new = recovered_funnel(old, rho, t, target, rate, FP)
    assert new is not None
    # 1. Funnel.check ran inside; repeat the essentials explicitly
    assert -1.0 < new.zeta(rho, t) < 0.0
    assert 0.0 < new.gamma_inf <= new.gamma0
    assert new.gamma_inf < new.rho_max - new.r
    assert 0.0 <= new.l < math.inf
    # 2. r raised to the target, never above ρ_max; the boundary reaches it and stays above
    assert old.r < new.r == target < new.rho_max
    t_reach = reach_time(new, new.r)
    assert t_reach < math.inf
    # in time order: with a tiny rate the reach time can lie beyond the far sample t + 1e4
    times = t + np.sort(np.concatenate([np.linspace(0.0, 3 * (t_reach - t) + 1.0, 400), [1e4]]))
    lower = np.array([new.lower(s) for s in times])
    assert np.all(lower[times >= t_reach + 1e-9] >= new.r - 1e-9)
    # 3. the lower boundary never drops below the old r
    assert np.all(lower >= old.r)
    # 4. no immediate critical event: starts strictly below ρ, climbs no faster than the rate
    assert lower[0] < rho
    assert np.all(lower <= lower[0] + rate * (times - t) + 1e-9)
    assert np.all(np.diff(lower) >= -1e-12)


def test_no_recovery_without_room_or_gain():
    f = Funnel.init("G", 0.0, 60.0, 0.54, -4.0, 0.0, FP)
    assert recovered_funnel(f, f.r - 0.01, 1.0, f.r + 0.5, 0.1, FP) is None  # ρ below r
    assert recovered_funnel(f, f.rho_max + 0.1, 1.0, 0.1, 0.1, FP) is None  # ρ above ρ_max
    assert recovered_funnel(f, -1.0, 1.0, f.r, 0.1, FP) is None  # no gain
    assert recovered_funnel(f, -1.0, 1.0, 0.1, 0.0, FP) is None  # robot cannot raise ρ


def _late(rho0=-4.0):
    return Funnel.init("G", 0.0, 60.0, 0.6, rho0, 0.0, FP)


def test_room_must_last_the_dwell_and_targets_the_least_rho_seen():
    f = _late()  # the 6th-robot case: late start, r = ρ0 − δ, constant funnel
    state = RecoveryState.start(f, FP, RP)
    assert state.r0 == pytest.approx(FP.r_frac * f.rho_max)
    rhos = {0.0: -1.5, 1.0: -1.8, 1.9: -1.6}
    for t, rho in rhos.items():
        state, new = advance(state, f, rho, t, 0.1, FP, RP)
        assert new is None
    state, new = advance(state, f, -1.6, 2.0, 0.1, FP, RP)
    assert new is not None and state.count == 1
    assert new.r == pytest.approx(-1.8 - FP.delta)
    assert state.r_floor == f.r  # the replaced funnel's r stays the reported floor


@settings(max_examples=examples(100), deadline=None)
@given(seq=st.lists(st.tuples(st.floats(0.01, 3.0), st.floats(-3.5, 0.5), st.booleans()),
                    min_size=1, max_size=120))
def test_hysteresis_bounds_the_recovery_rate(seq):
    """Whatever ρ does, two recoveries are at least the base dwell apart, and after a failed one
    (critical event within the probation) the next waits at least twice as long."""
    f = _late()
    state = RecoveryState.start(f, FP, RP)
    t = 0.0
    recoveries: list[tuple[float, float]] = []  # (time, dwell in force)
    for dt, rho, critical in seq:
        t += dt
        if critical:
            state = on_critical(state, t, RP)
            continue
        dwell = state.dwell
        state, new = advance(state, f, rho, t, 0.1, FP, RP)
        if new is not None:
            recoveries.append((t, dwell))
            f = new
    for (t1, _), (t2, d2) in itertools.pairwise(recoveries):
        assert t2 - t1 >= RP.dwell - 1e-9
        assert t2 - t1 >= d2 - 1e-9
    assert state.dwell <= RP.max_dwell


def test_a_failed_recovery_doubles_the_dwell_and_a_passed_probation_resets_it():
    base = RecoveryState(r0=0.1, dwell=RP.dwell, last_recovery=10.0,
                         probation_until=10.0 + RP.probation, count=1)
    failed = on_critical(base, 12.0, RP)
    assert failed.dwell == 2 * RP.dwell
    assert on_critical(failed, 12.5, RP).dwell == 2 * RP.dwell  # judged once per recovery
    again = on_critical(replace(failed, probation_until=20.0), 19.0, RP)
    assert again.dwell == 4 * RP.dwell
    capped = replace(again, dwell=RP.max_dwell, probation_until=30.0)
    assert on_critical(capped, 29.0, RP).dwell == RP.max_dwell
    assert on_critical(base, 10.0 + RP.probation + 1.0, RP).dwell == RP.dwell  # too late
    f = _late()
    passed, _ = advance(replace(base, dwell=4 * RP.dwell), f, f.r - 1.0,
                        10.0 + RP.probation + 0.5, 0.1, FP, RP)
    assert passed.dwell == RP.dwell
    still_failed, _ = advance(failed, f, f.r - 1.0, 10.0 + RP.probation + 0.5, 0.1, FP, RP)
    assert still_failed.dwell == 2 * RP.dwell


# --------------------------------------------------------------------------- F sub-tasks


def _relaxed_f_funnel(opt: float, rho0: float, t0: float, a: float, b: float,
                      repairs: list[tuple[int, float, float]]):
    """An F funnel initialised at t0 and repaired a few times before b (t* := b, R2)."""
    f = Funnel.init("F", a, b, opt, rho0, t0, FP)
    t = t0
    for stage, dt, frac in repairs:
        if t + dt >= b - 0.5:
            break
        t += dt
        f = f.repair(stage, f.lower(t) - frac, t, FP)
    return f, t


def _steepest_climb(old: Funnel, rho: float, t: float, r_new: float, t_star: float) -> float:
    """The steepest climb of the F recovery funnel to r_new at t_star, from the module
    docstring's formulas (0 when its lower boundary starts at or above r_new)."""
    gap = old.rho_max - rho
    gamma0 = gap + min(FP.gamma0_margin * gap, FP.zeta_l)
    g_star = old.rho_max - r_new
    if gamma0 <= g_star:
        return 0.0
    gamma_inf = FP.ginf_frac * g_star
    return (gamma0 - gamma_inf) * math.log((gamma0 - gamma_inf) / (g_star - gamma_inf)) / (
        t_star - t)


@settings(max_examples=examples(300), deadline=None)
@given(opt=st.floats(0.05, 1.5), rho0=st.floats(-3.0, 0.5), t0=st.floats(0, 30),
       lead=st.floats(1.0, 30.0), width=st.floats(0.5, 10.0),
       repairs=st.lists(st.tuples(st.sampled_from([1, 3]), st.floats(0.01, 5), st.floats(0, 0.05)),
                        min_size=1, max_size=8),
       wait=st.floats(0.0, 20.0), below=st.floats(0.0, 3.0), target_frac=st.floats(0.0, 1.0),
       rate=st.floats(1e-3, 1.0))
def test_f_recovery_keeps_algorithm_2_invariants_and_is_the_largest_admissible(
        opt, rho0, t0, lead, width, repairs, wait, below, target_frac, rate):
    a = t0 + lead
    b = a + width
    old, t_last = _relaxed_f_funnel(opt, rho0, t0, a, b, repairs)
    t = t_last + wait
    assume(t < b - 0.1)
    rho = old.rho_max - 1e-3 - below  # anywhere below ρ_max: before t*, ρ < r is normal
    r_min = old.r + FP.delta
    assume(r_min < old.rho_max - 2e-3)
    target = r_min + target_frac * (old.rho_max - 1e-3 - r_min)
    new = recovered_f_funnel(old, rho, t, target, rate, FP)
    deadlines = f_deadlines(old, t, FP)
    if new is None:  # not even r + δ is admissible at any deadline
        assert all(_steepest_climb(old, rho, t, r_min, d) > rate for d in deadlines)
        return
    # 1. Funnel.check ran inside; repeat the essentials explicitly
    assert -1.0 < new.zeta(rho, t) < 0.0
    assert 0.0 < new.gamma_inf <= new.gamma0
    assert new.gamma_inf < new.rho_max - new.r
    assert 0.0 <= new.l < math.inf
    assert new.rho_max == old.rho_max and new.t_r == t and new.kind == "F"
    # 2'. r raised by at least δ, at most to the target; reached at a deadline inside [a, b]
    assert old.r + FP.delta - 1e-12 <= new.r <= target + 1e-12
    assert new.t_star in deadlines and a <= new.t_star <= b and new.t_star > t
    times = np.sort(np.concatenate([np.linspace(t, b, 400), [new.t_star, b + 100.0]]))
    lower = np.array([new.lower(s) for s in times])
    assert new.lower(new.t_star) >= new.r - 1e-9
    assert np.all(lower[times >= new.t_star] >= new.r - 1e-9)
    assert np.all(np.diff(lower) >= -1e-12)
    # 4. no immediate critical event: starts strictly below ρ, climbs no faster than the rate
    assert lower[0] < rho
    assert np.all(lower <= lower[0] + rate * (times - t) + 1e-9)
    # the largest admissible r': a little more is too steep at every deadline
    if new.r < target - 1e-9:
        bump = new.r + 1e-7 * max(1.0, abs(new.r))
        assert all(_steepest_climb(old, rho, t, bump, d) > rate * (1 - 1e-6) for d in deadlines)


def test_no_f_recovery_without_time_gain_or_rate():
    f, _ = _relaxed_f_funnel(0.1, -2.5, 58.0, 83.0, 87.0, [(1, 1.7, 0.0), (1, 1.0, 0.0),
                                                         (3, 1.2, 0.0), (3, 0.2, 0.0)])
    assert f.t_star == 87.0 and f.r < 0.0
    assert recovered_f_funnel(f, -0.3, 70.0, 0.0225, 0.1, FP) is not None
    assert recovered_f_funnel(f, -0.3, 87.0, 0.0225, 0.1, FP) is None  # window over
    assert recovered_f_funnel(f, f.rho_max, 70.0, 0.0225, 0.1, FP) is None  # ρ at ρ_max
    assert recovered_f_funnel(f, -0.3, 70.0, f.r + 0.5 * FP.delta, 0.1, FP) is None  # < δ gain
    assert recovered_f_funnel(f, -0.3, 70.0, 0.0225, 0.0, FP) is None  # cannot raise ρ
    assert recovered_f_funnel(f, -2.5, 62.0, 0.0225, 0.1, FP) is None  # too far: too steep
    g = Funnel.init("G", 83.0, 87.0, 0.1, -2.5, 58.0, FP)
    assert recovered_f_funnel(g, -0.3, 70.0, 0.0225, 0.1, FP) is None  # F only


def test_f_room_is_time_without_critical_event_and_targets_r0():
    f, _ = _relaxed_f_funnel(0.1, -2.5, 58.0, 83.0, 87.0, [(1, 1.7, 0.0), (1, 1.0, 0.0),
                                                         (3, 1.2, 0.0), (3, 0.2, 0.0)])
    state = RecoveryState.start(Funnel.init("F", 83.0, 87.0, 0.1, -2.5, 58.0, FP), FP, RP)
    r0 = state.r0
    assert r0 == pytest.approx(FP.r_frac * 0.09) and f.r < r0 - FP.delta
    # far below r and still no recovery before the dwell has passed
    state, new = advance(state, f, -0.3, 70.0, 0.1, FP, RP)
    assert new is None and state.room_since == 70.0
    state, new = advance(state, f, -0.28, 70.0 + RP.dwell - 0.01, 0.1, FP, RP)
    assert new is None
    # a critical event ends the room: the dwell starts again
    state = on_critical(state, 72.0, RP)
    state, new = advance(state, f, -0.25, 72.01, 0.1, FP, RP)
    assert new is None and state.room_since == 72.01
    state, new = advance(state, f, -0.2, 72.01 + RP.dwell, 0.1, FP, RP)
    assert new is not None and new.r == pytest.approx(r0) and state.count == 1
    assert state.r_floor == f.r and new.t_star == pytest.approx(83.0 + 4.0 / 3.0)
    # r back at r_0: no further recovery
    later, again = advance(state, new, -0.1, 80.0, 0.1, FP, RP)
    assert again is None and math.isnan(later.room_since)
    # the G path is untouched by the F rule: a G funnel below r has no room
    g = _late()
    gs = RecoveryState.start(g, FP, RP)
    gs, gnew = advance(gs, g, g.r - 0.1, 1.0, 0.1, FP, RP)
    assert gnew is None and math.isnan(gs.room_since)
