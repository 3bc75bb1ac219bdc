"""Prescribed-performance funnel: initial parameters, γ(t), ζ, ε and the repair R1–R10.

stl-funnel.md §4 (funnel and transformed error), §5 (initial parameters), §7.3 (repair with the
[OUR CHOICE] guards). Funnel (absolute mission time t [s], ρ dimensionless like h)::

    γ(t) = (γ_0 − γ_∞)·exp(−l·(t − t_r)) + γ_∞,        ρ_max − γ(t) < ρ^ψ(x̄(t)) < ρ_max
    ζ = (ρ − ρ_max)/γ(t) ∈ (−1, 0),                    ε = ln(−(ζ + 1)/ζ)          (eq. (4))

A critical event is ζ ∉ (−1, 0) (§7.1). Every funnel built here is checked against the invariants of
§5/§7.3 and a violation raises :class:`FunnelInvariantError` (an internal error, never ``assert``).
The random draws of the authors' code are replaced by fixed fractions unless a
``numpy.random.Generator`` is passed (then U(0,1) is drawn as the code does, §13 item 2).

**Saturation-aware funnels** (docs/stl-saturation.md). Given the rate v [1/s] at which the robot can
raise ρ at its speed limit (times a share κ < 1), :meth:`Funnel.init` and :meth:`Funnel.repair`
build a funnel whose lower boundary never climbs faster than v: a linear *ramp*
γ(t) = γ_0 − v·(t − t_r) until the knee t_k, where the lower boundary reaches the goal level, then
the exponential tail with the same slope at the knee (l = v/(γ_k − γ_∞), C¹)::

    γ(t) = γ_0 − v·(t − t_r)                          t_r ≤ t < t_k
    γ(t) = (γ_k − γ_∞)·exp(−l·(t − t_k)) + γ_∞        t ≥ t_k,   γ_k = γ_0 − v·(t_k − t_r)

``ramp = 0`` is the exponential funnel of §4.1 (t_k plays no part).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from tlfleet.agent.stl.errors import FunnelInvariantError


@dataclass(frozen=True)
class FunnelParams:
    """Funnel constants (stl-funnel.md §15); scenario values from §10.1."""

    n_stage1: int = 2  # K = N_i, stage-1 repairs before stage 2/3 [AUTHORS' CODE]
    delta: float = 0.02  # δ, r decrement and stage-3 margin
    zeta_l: float = 0.2  # ζ_l, lower margin after a stage-1/2 repair
    rho_max_frac: float = 0.9  # ρ_max = max(0,ρ_0) + frac·(ρ_opt − max(0,ρ_0)) [AUTHORS' CODE]
    r_frac: float = 0.25  # r = r_frac·ρ_max [OUR CHOICE] (code: U(0,1)/2)
    gamma0_margin: float = 0.2  # γ_0 = (ρ_max − ρ_0)·(1 + margin) [AUTHORS' CODE]
    ginf_frac: float = 0.5  # γ_∞ = frac·min(γ_0, ρ_max − r) [OUR CHOICE] (code: U(0,1))
    late_frac: float = 0.5  # late start / R6 fraction [OUR CHOICE] (code: U(0,1))
    tau_min: float = 0.01  # [s] "late" threshold on t* − t [AUTHORS' CODE, applied uniformly]
    f_tstar_frac: float = 1.0 / 3.0  # F: t* = a + frac·(b − a) [AUTHORS' CODE]
    r_snap: float = 0.001  # R4 snap of r below ρ [AUTHORS' CODE]
    rho_max_cap_eps: float = 1e-4  # R3 cap ρ_max ≤ ρ_opt + eps [AUTHORS' CODE]
    guard_a_eps: float = 1e-4  # Guard A: ρ_max := ρ + eps if ρ ≥ ρ_max [OUR CHOICE]
    guard_b_margin: float = 1e-3  # Guard B margin [OUR CHOICE]
    zeta_clip: float = 1e-9  # ζ clipped to [−1 + clip, −clip] for ε [OUR CHOICE]
    # docs/stl-saturation.md: with a rate bound the funnel's lower boundary climbs at most at
    # ``saturation_share``·(the rate the speed limit allows); False: the authors' exponential
    # design whatever the limit (§5, §7.3)
    saturation_aware: bool = True
    saturation_share: float = 0.9  # κ: share of the achievable dρ/dt the lower boundary may ask
    saturation_cap: float = 0.98  # ... and the most of it, when the deadline needs more than κ
    ramp_margin: float = 0.05  # cap on the initial gap ρ_0 − lower(t_r) of a ramped funnel


def _draw(rng: np.random.Generator | None, fraction: float) -> float:
    return fraction if rng is None else float(rng.uniform())


@dataclass(frozen=True)
class Funnel:
    """Funnel parameters of one task φ = G/F_[a,b] ψ (names as in stl-funnel.md §5).

    ``gamma0`` is γ at ``t_r`` (anchored form, cannot overflow); ``zeta_u`` the ρ_max increment per
    repair; ``rho_opt`` the sup of ρ^ψ.
    """

    kind: Literal["G", "F"]
    a: float  # [s]
    b: float  # [s]
    rho_opt: float
    rho_max: float
    r: float
    gamma0: float
    gamma_inf: float
    l: float  # [1/s] decay rate
    t_star: float  # [s]
    t_r: float  # [s]
    zeta_u: float
    ramp: float = 0.0  # [1/s] v, climb of the lower boundary before the knee (0: no ramp)
    t_knee: float = 0.0  # [s] t_k, end of the ramp (read only when ramp > 0)

    # ----------------------------------------------------------------- §5

    @classmethod
    def init(cls, kind: Literal["G", "F"], a: float, b: float, rho_opt: float, rho0: float,
             t_r: float, params: FunnelParams = FunnelParams(),
             rng: np.random.Generator | None = None, *, rate: float | None = None,
             deadline: float | None = None) -> Funnel:
        """Initial parameters at time ``t_r`` with ρ_0 = ρ^ψ(x̄(t_r)) (stl-funnel.md §5).

        With ``rate`` (v [1/s], the share κ already applied), ``params.saturation_aware`` and no
        ``rng``: the saturation-aware funnel of :meth:`init_saturated`; ``deadline`` [s] (F only)
        is the latest time the sub-task may be met for the next one to stay feasible."""
        if (params.saturation_aware and rng is None and rate is not None
                and math.isfinite(rate) and rate > 0.0):
            return cls.init_saturated(kind, a, b, rho_opt, rho0, t_r, rate, params,
                                      deadline=deadline)
        p = params
        shift = _shift(rho_opt, p)
        rho_max = _top(rho_opt - shift, rho0 - shift, p) + shift
        zeta_u = max(0.0, rho_opt - rho_max) / max(p.n_stage1, 2)
        r = shift + (rho_max - shift) * (0.5 * float(rng.uniform()) if rng is not None
                                         else p.r_frac)
        t_star = a if kind == "G" else a + p.f_tstar_frac * (b - a)
        late = t_star - t_r <= p.tau_min
        if late:
            if rho0 <= r:
                r = rho0 - p.delta  # already violated: straight to a least-violating r
            gamma0 = (rho_max - rho0) + _draw(rng, p.late_frac) * (rho0 - r)
        else:
            gamma0 = (rho_max - rho0) + p.gamma0_margin * abs(rho_max - rho0)
        gamma_inf = _draw(rng, p.ginf_frac) * min(gamma0, rho_max - r)
        l = 0.0
        if rho_max - gamma0 < r and not late:
            l = -math.log((r + gamma_inf - rho_max) / (gamma_inf - gamma0)) / (t_star - t_r)
        funnel = cls(kind, a, b, rho_opt, rho_max, r, gamma0, gamma_inf, l, t_star, t_r, zeta_u)
        funnel.check(rho0, t_r, "initialisation")
        return funnel

    # ----------------------------------------------------------------- §4

    def gamma(self, t: float) -> float:
        """γ(t) = (γ_0 − γ_∞)·e^{−l(t − t_r)} + γ_∞, after the ramp γ_0 − v·(t − t_r) if any."""
        if self.ramp > 0.0:
            if t < self.t_knee:
                return self.gamma0 - self.ramp * (t - self.t_r)
            knee = self.gamma0 - self.ramp * (self.t_knee - self.t_r)
            return (knee - self.gamma_inf) * math.exp(-self.l * (t - self.t_knee)) + self.gamma_inf
        return (self.gamma0 - self.gamma_inf) * math.exp(-self.l * (t - self.t_r)) + self.gamma_inf

    def climb(self) -> float:
        """Steepest climb of the lower boundary, max_t −γ̇(t) [1/s] (at t_r, or on the ramp)."""
        if self.ramp > 0.0:
            return self.ramp
        return self.l * (self.gamma0 - self.gamma_inf)

    def lower(self, t: float) -> float:
        """Lower funnel boundary ρ_max − γ(t)."""
        return self.rho_max - self.gamma(t)

    def zeta(self, rho: float, t: float) -> float:
        """Normalised error ζ = (ρ − ρ_max)/γ(t); inside the funnel iff −1 < ζ < 0."""
        return (rho - self.rho_max) / self.gamma(t)

    # ----------------------------------------------------------------- §7.3

    def repair(self, stage: Literal[1, 2, 3], rho: float, t: float,
               params: FunnelParams = FunnelParams(),
               rng: np.random.Generator | None = None, *, rate: float | None = None) -> Funnel:
        """New funnel after a critical event at time ``t`` with ρ = ρ^ψ(x̄(t)): R1–R10 + guards.

        With ``rate`` (v [1/s]) and ``params.saturation_aware`` (no ``rng``), a new funnel whose
        exponential decay would climb faster than v gets a ramp instead (docs/stl-saturation.md
        §4): its lower boundary climbs at v to the r of R5 by t*, or, when v cannot reach it by
        then, to the level it can reach, which becomes r."""
        p = params
        t_r = t  # R1
        t_star = self.b if self.kind == "F" else self.t_star  # R2
        rho_max = self.rho_max + self.zeta_u  # R3
        if rho_max > self.rho_opt:
            rho_max = self.rho_opt + p.rho_max_cap_eps
        if rho >= rho_max:  # Guard A
            rho_max = rho + p.guard_a_eps
        late = t_star - t <= p.tau_min
        r = self.r
        if late and rho < r:  # R4 (late predicate instead of the code's t_r > t*)
            r = rho - p.r_snap
        # R5: stage 1 keeps r positive while it can ("r_i remains positive" [PAPER])
        r = (r / 2.0 if r > 0 else r - p.delta) if stage == 1 else r - p.delta
        zeta_l = _draw(rng, p.late_frac) * (rho - r) if late else p.zeta_l  # R6
        gamma_tr = rho_max - rho + (zeta_l if stage in (1, 2) else p.delta)  # R7
        gamma_inf = _draw(rng, p.ginf_frac) * min(gamma_tr, rho_max - r)  # R8
        l = 0.0  # R9
        if rho_max - gamma_tr < r:
            if late:  # Guard B
                r = min(r, rho_max - gamma_tr - p.guard_b_margin)
            else:
                l = -math.log((r + gamma_inf - rho_max) / (gamma_inf - gamma_tr)) / (t_star - t)
        funnel = replace(self, rho_max=rho_max, r=r, gamma0=gamma_tr, gamma_inf=gamma_inf, l=l,
                         t_star=t_star, t_r=t_r, ramp=0.0, t_knee=0.0)  # R10: γ_0 := γ_tr
        if (p.saturation_aware and rng is None and rate is not None and math.isfinite(rate)
                and rate > 0.0 and l > 0.0 and funnel.climb() > rate):
            funnel = funnel._ramped(rate, p)
        funnel.check(rho, t, f"stage-{stage} repair")
        return funnel

    def _ramped(self, rate: float, p: FunnelParams) -> Funnel:
        """This decaying funnel (l > 0: its lower boundary reaches r at t* > t_r) with a ramp of
        slope ``rate`` instead (docs/stl-saturation.md §4): r lowered to what the ramp reaches
        by t* when it cannot reach r earlier; the knee at the level r; the tail as in §3."""
        lower0 = self.rho_max - self.gamma0
        reach = lower0 + rate * (self.t_star - self.t_r)
        r = self.r if reach >= self.r else reach - p.r_snap
        gamma_knee = self.rho_max - max(r, min(self.r, reach))
        gamma_inf = min(self.gamma_inf, p.ginf_frac * gamma_knee)
        if not self.gamma0 > gamma_knee > gamma_inf > 0.0:
            return self
        t_knee = self.t_r + (self.gamma0 - gamma_knee) / rate
        return replace(self, r=r, gamma_inf=gamma_inf, l=rate / (gamma_knee - gamma_inf),
                       ramp=rate, t_knee=t_knee)

    @classmethod
    def init_saturated(cls, kind: Literal["G", "F"], a: float, b: float, rho_opt: float,
                       rho0: float, t_r: float, rate: float,
                       params: FunnelParams = FunnelParams(), *,
                       deadline: float | None = None) -> Funnel:
        """Saturation-aware initial funnel at ``t_r`` (docs/stl-saturation.md §3).

        ρ_max and ζ_u as in §5; the goal r_g = r_frac·ρ_max; γ_0 = (ρ_max − ρ_0) + m with
        m = min(gamma0_margin·(ρ_max − ρ_0), ramp_margin); the lower boundary ramps up at
        v = ``rate`` (κ·c) from ρ_0 − m and reaches r_g at the knee t_k = t_r + (r_g − ρ_0 + m)/v,
        as early as v allows; a deadline D that v cannot meet raises v to what D needs, at most
        ``saturation_cap``·c. The deadline D is a for G, min(b, ``deadline``) for F: if t_k ≤ D,
        r = r_g; otherwise r is the level the ramp reaches at D (less r_snap), the least
        violation v can promise. A late start (D − t_r ≤ τ_min) gets r = min(r_g, ρ_0 − m −
        r_snap). t* = a for G, the time the lower boundary reaches r for F (≤ D). After the knee
        the tail γ_∞ = ginf_frac·(ρ_max − r_g), l = v/(γ_k − γ_∞) (C¹ at t_k)."""
        p = params
        shift = _shift(rho_opt, p)
        rho_max = _top(rho_opt - shift, rho0 - shift, p) + shift
        zeta_u = max(0.0, rho_opt - rho_max) / max(p.n_stage1, 2)
        r_goal = shift + p.r_frac * (rho_max - shift)
        gap = rho_max - rho0
        margin = min(p.gamma0_margin * gap, p.ramp_margin)
        gamma0 = gap + margin
        lower0 = rho0 - margin
        due = a if kind == "G" else (b if deadline is None else min(b, deadline))
        if due - t_r > p.tau_min and lower0 < r_goal:
            # a deadline that κ·c cannot meet may ask more of the limit, up to saturation_cap·c
            needed = (r_goal - lower0) / (due - t_r)
            rate = min(max(rate, needed), p.saturation_cap * rate / p.saturation_share)
        if due - t_r <= p.tau_min:  # late: the window is open (G) or closing (F) already
            r = min(r_goal, lower0 - p.r_snap)
            t_star = due
        elif lower0 >= r_goal:
            r = r_goal
            t_star = a if kind == "G" else t_r
        else:
            t_goal = t_r + (r_goal - lower0) / rate
            if t_goal <= due:
                r = r_goal
                t_star = a if kind == "G" else t_goal
            else:
                r = lower0 + rate * (due - t_r) - p.r_snap
                t_star = due
        gamma_knee = rho_max - r_goal
        if gamma0 > gamma_knee:
            gamma_inf = p.ginf_frac * gamma_knee
            t_knee = t_r + (gamma0 - gamma_knee) / rate
            funnel = cls(kind, a, b, rho_opt, rho_max, r, gamma0, gamma_inf,
                         rate / (gamma_knee - gamma_inf), t_star, t_r, zeta_u, rate, t_knee)
        else:  # the lower boundary starts at or above r_g: the tail alone, climbing at v
            gamma_inf = p.ginf_frac * min(gamma0, rho_max - r)
            funnel = cls(kind, a, b, rho_opt, rho_max, r, gamma0, gamma_inf,
                         rate / (gamma0 - gamma_inf), t_star, t_r, zeta_u)
        funnel.check(rho0, t_r, "saturation-aware initialisation")
        return funnel

    def check(self, rho: float, t: float, what: str) -> None:
        """Invariants of §5/§7.3 at t = t_r; raises :class:`FunnelInvariantError`."""
        problems = []
        z = self.zeta(rho, t)
        if not -1.0 < z < 0.0:
            problems.append(f"zeta(t_r) = {z:.6g} not in (-1, 0)")
        if not 0.0 < self.gamma_inf <= self.gamma0:
            problems.append(f"need 0 < gamma_inf = {self.gamma_inf:.6g} <= gamma0 = "
                            f"{self.gamma0:.6g}")
        if not self.gamma_inf < self.rho_max - self.r:
            problems.append(f"need gamma_inf = {self.gamma_inf:.6g} < rho_max - r = "
                            f"{self.rho_max - self.r:.6g}")
        if not (0.0 <= self.l < math.inf):
            problems.append(f"need 0 <= l = {self.l!r} < inf")
        if self.ramp > 0.0 and not (math.isfinite(self.ramp) and self.t_knee >= self.t_r
                                    and self.gamma(self.t_knee) > self.gamma_inf):
            problems.append(f"ramp {self.ramp!r} needs t_knee = {self.t_knee!r} >= t_r and "
                            f"gamma(t_knee) > gamma_inf")
        if problems:
            raise FunnelInvariantError(f"{what} at t = {t:.4f} with rho = {rho:.6g}: "
                                       + "; ".join(problems) + f" ({self})")


def received_funnel_problem(funnel: Funnel, kind: str, a: float, b: float) -> str | None:
    """Why a funnel received from a requester cannot be followed for its sub-task φ = kind_[a,b]
    ψ, or None: it must be that sub-task's (kind and window), with finite parameters and the
    invariants of §5/§7.3 that keep γ(t) ≥ γ_∞ > 0 and ζ finite (:meth:`Funnel.check` but the
    ζ at t_r, which only the sender can evaluate)."""
    if (funnel.kind, funnel.a, funnel.b) != (kind, a, b):
        return (f"funnel of {funnel.kind}[{funnel.a:g},{funnel.b:g}], the sub-task is "
                f"{kind}[{a:g},{b:g}]")
    values = (funnel.rho_opt, funnel.rho_max, funnel.r, funnel.gamma0, funnel.gamma_inf,
              funnel.l, funnel.t_star, funnel.t_r, funnel.zeta_u, funnel.ramp, funnel.t_knee)
    if not all(math.isfinite(v) for v in values):
        return "funnel with a value that is not finite"
    if not 0.0 < funnel.gamma_inf <= funnel.gamma0:
        return f"funnel needs 0 < gamma_inf = {funnel.gamma_inf:.6g} <= gamma0"
    if not funnel.gamma_inf < funnel.rho_max - funnel.r:
        return "funnel needs gamma_inf < rho_max - r"
    if funnel.l < 0.0:
        return f"funnel needs l = {funnel.l:.6g} >= 0"
    if funnel.ramp < 0.0 or (funnel.ramp > 0.0 and funnel.t_knee < funnel.t_r):
        return "funnel needs ramp >= 0, and t_knee >= t_r with a ramp"
    return None


def _top(rho_opt: float, rho0: float, p: FunnelParams) -> float:
    """ρ_max = max(0, ρ_0) + rho_max_frac·(ρ_opt − max(0, ρ_0)) (§5), lifted just above ρ_0 when
    ρ_0 is at (or numerically above) the supremum: no admissible ρ_max in (ρ_0, ρ_opt) exists
    then, so it is lifted as Guard A does (§7.3) [OUR CHOICE]."""
    base = max(0.0, rho0)
    rho_max = base + p.rho_max_frac * (rho_opt - base)
    return max(rho_max, rho0 + p.guard_a_eps)


def _shift(rho_opt: float, p: FunnelParams) -> float:
    """0 for a satisfiable ψ (ρ_opt > 0). A ψ that holds nowhere (ρ_opt ≤ 0: contradictory
    conjuncts, a goal inside an obstacle, two robots asked to be closer than they may;
    docs/stl-saturation.md §5) gets the design of a ψ whose supremum is δ, shifted down by
    ρ_opt − δ, so that its goal r and ρ_max sit within δ under the supremum: the least
    violation."""
    if rho_opt > 0.0:
        return 0.0
    return rho_opt - p.delta


def epsilon(zeta: float, clip: float = 1e-9) -> float:
    """Transformed error ε = ln(−(ζ + 1)/ζ) with ζ clipped to [−1 + clip, −clip] (§6.1 step 3)."""
    if zeta < -1.0 + clip:
        zeta = -1.0 + clip
    elif zeta > -clip:
        zeta = -clip
    return math.log(-(zeta + 1.0) / zeta)


def is_critical(zeta: float) -> bool:
    """Critical event ⇔ not (−1 < ζ < 0) (stl-funnel.md §7.1)."""
    return not -1.0 < zeta < 0.0
