"""Robustness recovery: raise r again after repairs lowered it (paper §V, future work).

The repair scheme (paper Alg. 2, stl-funnel.md §7) only ever lowers r_i: stage 1 halves it,
stages 2–3 subtract δ, and after t* every repair yields a constant funnel (l = 0). Once the cause
has gone (the coupled robot slowed or stopped, a partner came back), nothing raises r again, and
the funnel controller (paper eq. (5)) keeps ρ^ψ in the middle of a wide, constant funnel, where
ε ≈ 0: the robot stands still far from what its task asks. The paper's conclusion (§V) announces
"a robustness recovery mechanism [...] integrated into the online detection and repair scheme".
This module is ours:

**Room.** The owner of a G sub-task (not following, not requesting: c_i = 0) has *room* while
ρ^ψ − r ≥ ``margin`` (default 2δ) and r is below its original value r_0 (r_frac·ρ_max at
activation, stl-funnel.md §5). ρ_low is the least ρ^ψ seen since the room began.

**Recovery.** When the room has lasted ``dwell`` seconds, the funnel is rebuilt at t_r = t with
the raised bound r' = min(r_0, ρ_low − δ), if r' ≥ r + δ:

    ρ_max' = ρ_max,   γ_0' = min((ρ_max − ρ)(1 + gamma0_margin), (ρ_max − ρ) + ½(ρ − r)),
    γ_∞' = ginf_frac·min(γ_0', ρ_max − r'),   l' = c / (γ_0' − γ_∞'),   t* := t_r

(the lower boundary reaches r' at t_r + ln((γ_0' − γ_∞')/(ρ_max − r' − γ_∞'))/l', ``reach_time``;
t* := t_r makes later repairs of this funnel "late", so they snap r below ρ, R4),

where c = ``rate_share``·(u_lin·‖∂ρ/∂z_i‖ + u_ang·|∂ρ/∂θ_i|) is a share of the rate at which the
robot's saturated input can raise ρ^ψ (paper §III-B). Invariants (property-tested):

1. Algorithm 2's funnel invariants (stl-funnel.md §5/§7.3): −1 < ζ(t_r) < 0, 0 < γ_∞' ≤ γ_0',
   γ_∞' < ρ_max − r', 0 ≤ l' < ∞ (``Funnel.check``);
2. r < r' ≤ r_0, and the lower boundary reaches r' (``reach_time``) and stays above it;
3. the lower boundary never drops below the old r (ρ_max − γ_0' ≥ ½(ρ + r) > r): a recovery
   cannot lose what the old funnel guaranteed, so ρ^φ ≥ r̄ with r̄ the least r in force during
   the window (what the agent reports);
4. no immediate new critical event: the lower boundary starts strictly below ρ and climbs no
   faster than c, so a robot that raises ρ^ψ at rate c stays inside.

**F sub-tasks.** An F task's funnel reaches r at t* (stl-funnel.md §5; t* = b after any repair,
R2), and the funnel controller keeps ρ^ψ near the funnel's middle, so ρ^φ = max_{[a,b]} ρ^ψ ends
near ½(ρ_max + r) at t = b: every δ that stage 3 took off r — often for the exponential funnel's
front-loaded contraction (stl-funnel.md §13 item 10), not for an infeasible task — is lost for
good (Scenario 1's φ″4: r̄ = −0.114, ρ^φ = −0.007 = ½(ρ_max + r̄)). Before its deadline an F task
is meant to be below r, so its *room* is time: no critical event for ``dwell`` seconds while
r < r_0, ρ < ρ_max and t < b − τ_min. Then (``recovered_f_funnel``) the funnel is rebuilt at
t_r = t with the same ρ_max and

    γ_0' = (ρ_max − ρ) + min(gamma0_margin·(ρ_max − ρ), ζ_l),
    γ_∞' = ginf_frac·min(γ_0', ρ_max − r'),
    l' = ln((γ_0' − γ_∞')/(ρ_max − r' − γ_∞')) / (t*' − t_r)     (lower boundary = r' at t*'),

or, when the lower boundary starts at or above r' already (γ_0' ≤ ρ_max − r'), l' = c/(γ_0' − γ_∞')
as for G. The deadline t*' is the sub-task's initial one a + f_tstar_frac·(b − a) if it admits
r_0, else the one of {that, b} (those after t) admitting the larger r'; r' is the largest value in
[r + δ, r_0] (bisection) for which the lower boundary's steepest climb, l'·(γ_0' − γ_∞') at t_r,
is at most c; no recovery if not even r + δ is admitted. Invariants (property-tested): (1) as for
G; (2') r + δ ≤ r' ≤ r_0, a ≤ t*' ≤ b and lower(t) ≥ r' for t ≥ t*', so a run that stays inside
the new funnel has ρ^φ ≥ ρ^ψ(t*') > r'; (4) as for G; and r' is maximal. Invariant 3 has no F
counterpart (before t* an F funnel's lower boundary is below r by design); r̄ is still the least r
in force. Like G, only the funnel-controlled owner recovers (c_i = 0): under the F-hold rule
(stl-funnel.md §6.1 step 5) a robot held above r is not recovered.

**Hysteresis.** A critical event ends the room. A critical event within ``probation`` seconds of
a recovery (the recovery failed) doubles the dwell (up to ``max_dwell``); a probation passed
without one resets it to ``dwell``. So a
cause that persists cannot make the agent oscillate between recovery and repair faster than
every ``max_dwell`` seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from tlfleet.agent.stl.funnel import Funnel, FunnelParams


@dataclass(frozen=True)
class RecoveryParams:
    """Recovery constants (module docstring); ``margin`` and the r step are in units of δ."""

    enabled: bool = True
    margin_deltas: float = 2.0  # room needs ρ − r ≥ margin_deltas·δ
    dwell: float = 2.0  # [s] room must last this long before a recovery
    probation: float = 5.0  # [s] a critical event this soon after a recovery doubles the dwell
    max_dwell: float = 16.0  # [s]
    rate_share: float = 0.5  # share of the robot's achievable dρ/dt the lower boundary may climb
    f_tasks: bool = True  # recover F sub-tasks too (module docstring, "F sub-tasks")


@dataclass(frozen=True, slots=True)
class RecoveryState:
    """Per-sub-task recovery memory (times [s], robustness in the units of ρ)."""

    r0: float  # the sub-task's original r
    dwell: float  # current dwell (doubles on a failed recovery)
    room_since: float = math.nan  # start of the current room interval (NaN: no room)
    rho_low: float = math.inf  # least ρ since room_since
    last_recovery: float = -math.inf
    probation_until: float = -math.inf  # end of the last recovery's probation (−inf: judged)
    count: int = 0
    r_floor: float = math.inf  # least r of the funnels replaced by recoveries

    @staticmethod
    def start(funnel: Funnel, fparams: FunnelParams, params: RecoveryParams) -> RecoveryState:
        """At activation (or re-initialisation) of a sub-task with its initial funnel. A
        saturation-aware funnel's r is planned (the level the speed limit lets it promise by its
        deadline, docs/stl-saturation.md §3): recovery restores that, never more."""
        # (its r is below r_frac·ρ_max only where it ramps: ``Funnel.init_saturated``)
        r0 = funnel.r if funnel.ramp > 0.0 else max(funnel.r, fparams.r_frac * funnel.rho_max)
        return RecoveryState(r0=r0, dwell=params.dwell)


def recovered_funnel(funnel: Funnel, rho: float, t: float, r_target: float, rate: float,
                     fparams: FunnelParams) -> Funnel | None:
    """The funnel of a recovery at ``t`` with ρ = ``rho`` towards ``r_target`` (module
    docstring), or None when none raises r (ρ not strictly between r and ρ_max, r_target ≤ r,
    rate ≤ 0)."""
    rho_max, r_old = funnel.rho_max, funnel.r
    if not (r_old < rho < rho_max) or rate <= 0.0 or not r_target > r_old:
        return None
    r_new = r_target
    gap = rho_max - rho
    gamma0 = min(gap * (1.0 + fparams.gamma0_margin), gap + 0.5 * (rho - r_old))
    gamma_inf = fparams.ginf_frac * min(gamma0, rho_max - r_new)
    if not 0.0 < gamma_inf < gamma0:
        return None
    l = rate / (gamma0 - gamma_inf)
    # t* := t_r: a later repair of this funnel is "late" (R4 snaps r below ρ, R6/R9 give a
    # constant funnel whose lower boundary stays above r), so ρ^φ ≥ r̄ survives repairs made
    # before the lower boundary has reached r' (reach_time).
    new = replace(funnel, r=r_new, gamma0=gamma0, gamma_inf=gamma_inf, l=l, t_star=t, t_r=t,
                  ramp=0.0, t_knee=0.0)
    new.check(rho, t, "recovery")
    return new


def _f_candidate(funnel: Funnel, rho: float, t: float, r_new: float, t_star: float,
                 rate: float, fparams: FunnelParams) -> Funnel | None:
    """The F funnel at t_r = ``t`` whose lower boundary is r_new at ``t_star`` (module
    docstring), or None when its steepest climb would exceed ``rate``."""
    rho_max = funnel.rho_max
    g_star = rho_max - r_new  # γ(t*') that puts the lower boundary on r'
    gap = rho_max - rho
    if not (g_star > 0.0 and gap > 0.0 and t_star - t > fparams.tau_min):
        return None
    gamma0 = gap + min(fparams.gamma0_margin * gap, fparams.zeta_l)
    if gamma0 <= g_star:  # the lower boundary starts at or above r' already
        gamma_inf = fparams.ginf_frac * gamma0
        l = rate / (gamma0 - gamma_inf)
    else:
        gamma_inf = fparams.ginf_frac * g_star
        l = math.log((gamma0 - gamma_inf) / (g_star - gamma_inf)) / (t_star - t)
        if l * (gamma0 - gamma_inf) > rate:
            return None
    if not 0.0 < gamma_inf < gamma0:
        return None
    return replace(funnel, r=r_new, gamma0=gamma0, gamma_inf=gamma_inf, l=l, t_star=t_star,
                   t_r=t, ramp=0.0, t_knee=0.0)


def f_deadlines(funnel: Funnel, t: float, fparams: FunnelParams) -> tuple[float, ...]:
    """The deadlines t*' an F recovery at ``t`` may use: the sub-task's initial one
    a + f_tstar_frac·(b − a) (stl-funnel.md §5) and b, those more than τ_min ahead."""
    first = funnel.a + fparams.f_tstar_frac * (funnel.b - funnel.a)
    return tuple(s for s in (first, funnel.b) if s - t > fparams.tau_min)


def recovered_f_funnel(funnel: Funnel, rho: float, t: float, r_target: float, rate: float,
                       fparams: FunnelParams, iterations: int = 48) -> Funnel | None:
    """The F funnel of a recovery at ``t`` with ρ = ``rho`` (module docstring, "F sub-tasks"): the
    largest r' ∈ [r + δ, ``r_target``] (bisection, ``iterations`` halvings) that some deadline of
    :func:`f_deadlines` admits with a climb no steeper than ``rate``, the earlier deadline on a
    tie; None when not even r + δ is admissible (or ρ ≥ ρ_max, rate ≤ 0, the window is over)."""
    r_min = funnel.r + fparams.delta
    if (funnel.kind != "F" or not rho < funnel.rho_max or rate <= 0.0
            or not r_target >= r_min):
        return None
    best: Funnel | None = None
    for t_star in f_deadlines(funnel, t, fparams):
        low = _f_candidate(funnel, rho, t, r_min if best is None else best.r, t_star, rate,
                           fparams)
        if low is None:
            continue
        top = _f_candidate(funnel, rho, t, r_target, t_star, rate, fparams)
        if top is not None:  # nothing can beat r_target: take it at the earliest deadline
            best = top
            break
        lo, hi = low.r, r_target  # admissible at lo, not at hi
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            cand = _f_candidate(funnel, rho, t, mid, t_star, rate, fparams)
            if cand is None:
                hi = mid
            else:
                lo, low = mid, cand
        if best is None or low.r > best.r:
            best = low
    if best is not None:
        best.check(rho, t, "F recovery")
    return best


def reach_time(funnel: Funnel, level: float) -> float:
    """First t ≥ t_r [s] with lower(t) ≥ ``level`` (inf if never)."""
    if funnel.lower(funnel.t_r) >= level:
        return funnel.t_r
    if funnel.ramp > 0.0:
        if funnel.lower(funnel.t_knee) >= level:  # on the ramp
            return funnel.t_r + (funnel.gamma0 - (funnel.rho_max - level)) / funnel.ramp
        knee = funnel.gamma(funnel.t_knee)
        target_gamma = funnel.rho_max - level
        if funnel.l <= 0.0 or target_gamma <= funnel.gamma_inf:
            return math.inf
        return funnel.t_knee + math.log((knee - funnel.gamma_inf)
                                        / (target_gamma - funnel.gamma_inf)) / funnel.l
    target_gamma = funnel.rho_max - level
    if funnel.l <= 0.0 or target_gamma <= funnel.gamma_inf:
        return math.inf
    return funnel.t_r + math.log((funnel.gamma0 - funnel.gamma_inf)
                                 / (target_gamma - funnel.gamma_inf)) / funnel.l


def on_critical(state: RecoveryState, t: float, params: RecoveryParams) -> RecoveryState:
    """A critical event (repair) at ``t``: the room ends; a failed recovery doubles the dwell."""
    dwell, until = state.dwell, state.probation_until
    if t <= until:  # the last recovery failed its probation
        dwell, until = min(2.0 * dwell, params.max_dwell), -math.inf
    return replace(state, room_since=math.nan, rho_low=math.inf, dwell=dwell,
                   probation_until=until)


def advance(state: RecoveryState, funnel: Funnel, rho: float, t: float, rate: float,
            fparams: FunnelParams, params: RecoveryParams
            ) -> tuple[RecoveryState, Funnel | None]:
    """One step without critical event: update the room; return a recovered funnel when due."""
    if state.probation_until < t and state.probation_until > -math.inf:
        # the last recovery passed its probation without a critical event: reset the hysteresis
        state = replace(state, dwell=params.dwell, probation_until=-math.inf)
    if funnel.kind == "F":
        return _advance_f(state, funnel, rho, t, rate, fparams, params)
    margin = params.margin_deltas * fparams.delta
    if not (rho - funnel.r >= margin and funnel.r < state.r0 and rho < funnel.rho_max):
        if not math.isnan(state.room_since):
            state = replace(state, room_since=math.nan, rho_low=math.inf)
        return state, None
    if math.isnan(state.room_since):
        return replace(state, room_since=t, rho_low=rho), None
    rho_low = min(state.rho_low, rho)
    state = replace(state, rho_low=rho_low)
    if t - state.room_since < state.dwell:
        return state, None
    target = min(state.r0, rho_low - fparams.delta)
    if target < funnel.r + fparams.delta:
        return state, None
    new = recovered_funnel(funnel, rho, t, target, rate, fparams)
    if new is None:
        return state, None
    return _recovered(state, funnel, t, params), new


def _recovered(state: RecoveryState, funnel: Funnel, t: float,
               params: RecoveryParams) -> RecoveryState:
    """The state after a recovery at ``t`` that replaced ``funnel`` (its r joins the floor)."""
    return replace(state, room_since=math.nan, rho_low=math.inf, last_recovery=t,
                   probation_until=t + params.probation, count=state.count + 1,
                   r_floor=min(state.r_floor, funnel.r))


def _advance_f(state: RecoveryState, funnel: Funnel, rho: float, t: float, rate: float,
               fparams: FunnelParams, params: RecoveryParams
               ) -> tuple[RecoveryState, Funnel | None]:
    """:func:`advance` for an F sub-task (module docstring, "F sub-tasks"): room is time without
    a critical event while r is below r_0, ρ below ρ_max and the window not yet over."""
    if not (funnel.r < state.r0 and rho < funnel.rho_max and t < funnel.b - fparams.tau_min):
        if not math.isnan(state.room_since):
            state = replace(state, room_since=math.nan, rho_low=math.inf)
        return state, None
    if math.isnan(state.room_since):
        return replace(state, room_since=t, rho_low=rho), None
    state = replace(state, rho_low=min(state.rho_low, rho))
    if t - state.room_since < state.dwell or state.r0 < funnel.r + fparams.delta:
        return state, None
    new = recovered_f_funnel(funnel, rho, t, state.r0, rate, fparams)
    if new is None:
        return state, None
    return _recovered(state, funnel, t, params), new


def achievable_rate(grad_own, max_lin: float, max_ang: float) -> float:
    """u_lin·‖∂ρ/∂z_i‖ + u_ang·|∂ρ/∂θ_i| for the own 3-block of the gradient (0 if None)."""
    if grad_own is None:
        return 0.0
    gx, gy, gth = grad_own[0], grad_own[1], grad_own[2]
    return max_lin * math.hypot(gx, gy) + max_ang * abs(gth)
