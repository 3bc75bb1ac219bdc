"""Per-sub-task verdicts of a run, independent of the paper's bounds.

Every STL sub-task gets one of

* ``satisfied``: its window lies within the run and ρ^φ > 0 (paper §II-B);
* ``violated``: its window lies within the run and ρ^φ ≤ 0, ``by`` = −ρ^φ;
* ``not evaluated``: the run ended before the window did (G: t_end < b; F: t_end < b and no
  satisfying sample yet), so no verdict exists — a run cut short must not report "met".

Beside it: ``held`` — the fraction of the samples of [a, min(b, t_end)] at which the predicate
ψ held (ρ^ψ ≥ 0, standard semantics), the figure that tells a formation kept 95 % of the time
from one never formed; ``stationary`` — episodes in which a robot stood still (moved < 5 cm and
turned < 0.1 rad over ``window`` seconds) while its task wanted it to move (LTL: before its plan
finished or its task was lost; time inside a ``yield`` is waiting for the right of way, so the
episode counts when it lasted ``window`` or more outside yields or waited longer than
``YIELD_LIMIT`` in them, docs/ltl-navigation.md §6; STL: ρ^ψ < −0.1 throughout, inside the
window, with ‖∂ρ^ψ/∂z_i‖ ≥ 0.5 so that moving would help), the symptom of a navigation
deadlock; and the run's switches: coupling-aware leaders (``[navigation] coupling_aware``,
docs/coupling.md) and robustness recovery
(``[stl] recovery``) with the number of recoveries.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import replace

import numpy as np
from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.stl.monitor import Trajectory
from tlfleet.agent.stl.parser import parse_task
from tlfleet.agent.stl.robustness import psi_array
from tlfleet.bus.protocol.messages import Event
from tlfleet.coordinator.record.run_record import (
    StationaryEpisode,
    StlDesign,
    StlRobotReport,
    SubtaskVerdict,
    Verdicts,
)

STILL_DISTANCE = 0.05  # [m]
STILL_TURN = 0.1  # [rad]
STL_WANTS_MOTION = -0.1  # ρ^ψ below this: the STL robot's task wants it to move
DEADLOCK_WINDOW = 5.0  # [s]
YIELD_LIMIT = 15.0  # [s] a head-on yield may wait this long: waiting, not a deadlock
STL_MIN_SLOPE = 0.5  # ‖∂ρ^ψ/∂z_i‖ (smooth ρ, per metre) at or above which moving helps


def _own_slope(phi, traj: Trajectory, robot: int, eta: float) -> np.ndarray:
    """‖∂ρ^ψ/∂z_robot‖ of the smooth ρ^ψ (what the funnel controller follows, eq. (5)) per sample,
    by central differences of 1 mm."""
    h = 1e-3
    grads = []
    for axis in (0, 1):
        values = []
        for sign in (1.0, -1.0):
            states = dict(traj.states)
            shifted = states[robot].copy()
            shifted[:, axis] += sign * h
            states[robot] = shifted
            values.append(psi_array(phi.body, states, smooth=True, eta=eta))
        grads.append((values[0] - values[1]) / (2 * h))
    return np.hypot(*grads)


def verdict(op: str, a: float, b: float, rho: float | None, t_end: float) -> SubtaskVerdict:
    """The verdict of one sub-task ``op[a, b]`` with robustness ``rho`` over a run ending at
    ``t_end`` [s] (module docstring)."""
    covered = t_end >= b - 1e-9
    if rho is None or (isinstance(rho, float) and math.isnan(rho)):
        return SubtaskVerdict("not evaluated", reason="no robustness (no trajectory)")
    if op == "F" and not covered and rho > 0.0 and t_end >= a:
        return SubtaskVerdict("satisfied")
    if not covered:
        return SubtaskVerdict("not evaluated",
                              reason=f"the run ended at t = {t_end:.2f} s, before the window "
                                     f"[{a:g}, {b:g}] closed")
    if rho > 0.0:
        return SubtaskVerdict("satisfied")
    return SubtaskVerdict("violated", by=float(-rho))


def held_fraction(scenario_task: str, traj: Trajectory, t_end: float) -> float | None:
    """Fraction of the trajectory samples in [a, min(b, t_end)] with ρ^ψ ≥ 0 (None if none)."""
    phi = parse_task(scenario_task)
    window = (traj.t >= phi.a) & (traj.t <= min(phi.b, t_end))
    if not window.any():
        return None
    states = {j: s[window] for j, s in traj.states.items()}
    try:
        values = psi_array(phi.body, states)
    except KeyError:
        return None
    return float(np.mean(values >= 0.0))


def stationary_episodes(scenario: Scenario, traj: Trajectory, events: Iterable[Event],
                        window: float = DEADLOCK_WINDOW) -> list[StationaryEpisode]:
    """Episodes of a robot standing still for more than ``window``
    seconds while its task wants it to move (module docstring)."""
    finished: dict[int, float] = {}
    yields: dict[int, list[tuple[float, float]]] = {}
    begun: dict[int, float] = {}
    for e in events:
        if not e.source.startswith("agent/"):
            continue
        try:
            robot = int(e.source.split("/", 1)[1])
        except ValueError:
            continue
        if e.kind in ("plan_finished", "task_lost"):
            finished.setdefault(robot, e.t)
        elif e.kind == "yield" and isinstance(e.data, dict):
            if e.data.get("state") == "begin":
                begun[robot] = e.t
            elif e.data.get("state") == "end" and robot in begun:
                yields.setdefault(robot, []).append((begun.pop(robot), e.t))
    for robot, start in begun.items():  # still yielding when the run ended
        yields.setdefault(robot, []).append((start, math.inf))
    t = traj.t
    if len(t) < 2:
        return []
    dt = float(np.median(np.diff(t)))
    n = max(1, round(window / dt))
    if len(t) <= n:
        return []
    out = []
    for robot in scenario.robots:
        if robot.id not in traj.states:
            continue
        s = traj.states[robot.id]
        moved = np.hypot(*(s[n:, :2] - s[:-n, :2]).T)
        turned = np.abs(np.unwrap(s[:, 2])[n:] - np.unwrap(s[:, 2])[:-n])
        still = (moved < STILL_DISTANCE) & (turned < STILL_TURN)  # window [k, k + n]
        if robot.is_ltl:
            wants = t[n:] <= finished.get(robot.id, math.inf)
        else:
            wants = np.zeros(len(still), dtype=bool)
            for text in robot.stl:
                phi = parse_task(text)
                try:
                    rho = psi_array(phi.body, traj.states)
                    slope = _own_slope(phi, traj, robot.id, scenario.stl.eta)
                except KeyError:
                    continue
                # violated, and moving would help: at a least-violating point (Scenario 1's
                # robot 4 between robots 3 and 5) the smooth ρ^ψ is flat and standing is right
                bad = (rho < STL_WANTS_MOTION) & (slope >= STL_MIN_SLOPE)
                # violated throughout the still window, which lies inside [a, b]
                run = np.convolve(bad.astype(float), np.ones(n + 1), "valid") >= n + 1
                inside = (t[:-n] >= phi.a) & (t[n:] <= phi.b)
                wants |= run[:len(still)] & inside
        flagged = still & wants
        k = 0
        while k < len(flagged):
            if not flagged[k]:
                k += 1
                continue
            j = k
            while j + 1 < len(flagged) and flagged[j + 1]:
                j += 1
            start, end = float(t[k]), float(t[j + n])
            waited = sum(max(0.0, min(end, b) - max(start, a))
                         for a, b in yields.get(robot.id, ()))
            if end - start - waited >= window or waited > YIELD_LIMIT:
                out.append(StationaryEpisode(robot.id, start, end))
            k = j + 1
    return out


def collect(scenario: Scenario, traj: Trajectory | None, events: Iterable[Event],
            t_end: float, stl: Mapping[int, StlRobotReport]) -> Verdicts:
    """Verdicts of every STL sub-task of the report's ``stl`` section, the switches and the
    stationary episodes (module docstring)."""
    recoveries: dict[str, int] = {}
    for e in events:
        if e.kind == "recovery":
            robot = e.source.split("/", 1)[-1]
            recoveries[robot] = recoveries.get(robot, 0) + 1
    subtasks: dict[int, tuple[SubtaskVerdict, ...]] = {}
    for rid, entry in stl.items():
        rows = []
        for s in entry.subtasks:
            window = s.window
            if window is None:
                row = SubtaskVerdict("not evaluated", reason="no window")
            else:
                row = verdict(s.op, window[0], window[1], s.robustness, t_end)
            rows.append(replace(row, label=s.label, held=(
                held_fraction(s.task, traj, t_end)
                if traj is not None and window is not None else None)))
        subtasks[rid] = tuple(rows)
    return Verdicts(
        coupling_aware=scenario.navigation.coupling_aware,
        coupling_share=scenario.navigation.coupling_share,
        recovery=scenario.stl.recovery,
        recoveries=recoveries,
        subtasks=subtasks,
        stationary=tuple(stationary_episodes(scenario, traj, events))
        if traj is not None else (),
        stl_design=stl_design(scenario))


def f_semantics(stl) -> str:
    """Which F-task semantics a scenario's ``[stl]`` switches select (docs/stl-saturation.md
    §6.1)."""
    if not stl.complete_f_on_satisfaction:
        return "the paper's Algorithm 2 (an F sub-task runs to its window's end)"
    if stl.hold_f_above_r and not stl.complete_f_at_goal:
        return "the authors' code (hold once ρ > r, done at the first r < ρ < ρ_max)"
    return ("tlfleet's (done once ρ reaches its first funnel's goal level"
            + (", or met and needed by the next sub-task" if stl.lookahead else "")
            + (", hold above r" if stl.hold_f_above_r else "") + ")")


def stl_design(scenario: Scenario) -> StlDesign:
    """The STL switches in force (docs/stl-saturation.md §9): funnels, F semantics, ρ_opt, the
    avoidance radii (per coupled pair) and the static term."""
    from tlfleet.agent.scenario import stl_setup

    p = scenario.stl
    pairs = {}
    if p.coupled_radii and any(r.is_stl for r in scenario.robots):
        for i, j in sorted(stl_setup.coupled_pairs(scenario)):
            pairs[f"{i}-{j}"] = stl_setup.pair_radii(scenario, i, j)
    return StlDesign(saturation_aware=p.saturation_aware, saturation_share=p.saturation_share,
                     f_semantics=f_semantics(p), rho_opt_from_arena=p.rho_opt_from_arena,
                     r1=p.r1, r_sense=p.r_sense, coupled_radii=pairs,
                     wall_avoidance=p.wall_avoidance, route_around=p.route_around)


def render_lines(v: Verdicts) -> list[str]:
    """A few console/markdown lines: switches, verdicts with held fractions, stationary."""
    total = sum(v.recoveries.values())
    lines = [f"navigation: coupling-aware leaders {'on' if v.coupling_aware else 'off'}"
             + (f" (share {v.coupling_share:g})" if v.coupling_aware else "")
             + f"; robustness recovery {'on' if v.recovery else 'off'}, "
             f"{total} recover{'y' if total == 1 else 'ies'}"]
    d = v.stl_design
    if d:
        radii = "; ".join(f"{pair} {r1:g}/{r:g} m" for pair, (r1, r) in d.coupled_radii.items())
        lines.append(
            f"STL design: saturation-aware funnels {'on' if d.saturation_aware else 'off'}"
            + (f" (share {d.saturation_share:g})" if d.saturation_aware else "")
            + f"; F sub-tasks: {d.f_semantics}; ρ_opt "
            + ("from the arena" if d.rho_opt_from_arena else "from the literals")
            + f"; avoidance R1/R {d.r1:g}/{d.r_sense:g} m"
            + (f", coupled pairs {radii}" if radii else "")
            + f"; walls and obstacles in eq. (6) {'on' if d.wall_avoidance else 'off'}, "
            f"routes {'on' if d.route_around else 'off'}")
    parts = []
    for rows in v.subtasks.values():
        for row in rows:
            text = row.verdict
            if row.verdict == "violated":
                text += f" by {row.by:.3f}"
            if row.held is not None:
                text += f", held {100 * row.held:.0f} %"
            parts.append(f"{row.label} {text}")
    if parts:
        lines.append("verdicts: " + "; ".join(parts))
    stationary = v.stationary
    lines.append("stationary > 5 s while the task wants motion: "
                 + (", ".join(f"r{e.robot} {e.t_start:.1f}–{e.t_end:.1f} s"
                              for e in stationary) if stationary else "none"))
    return lines
