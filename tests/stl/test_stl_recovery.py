"""Robustness recovery (agent.stl.recovery): the invariants of its funnel, its hysteresis, and the
closed loop — an escort whose leader ran away recovers once the leader stops."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from agent.stl.funnel import Funnel, FunnelParams
from agent.stl.recovery import (
    RecoveryParams,
    RecoveryState,
    advance,
    on_critical,
    reach_time,
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


@settings(max_examples=300, deadline=None)
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


@settings(max_examples=100, deadline=None)
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
