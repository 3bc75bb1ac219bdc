"""The plain-text run summary: a pure function of a run directory's files (architecture.md §6).

:func:`summarise` takes the files of a run directory as read once by
:func:`tlfleet.coordinator.record.rundir.read_run` (shared with
``tlfleet.coordinator.report.run_report``) and returns
``(text, data)``; ``data`` holds numbers as numbers (an empty window's robustness is ±inf, a value
not evaluated None) and becomes ``summary.json`` only at the edge (:func:`write_summary`):

* per STL robot and sub-task, the **standard** robustness (min/max semantics, stl-funnel.md §3)
  recomputed offline from the trajectory with ``tlfleet.agent.stl.monitor``; ``r_least``, the least
  r in force over the sub-task (the bound r̄ of ρ^φ ≥ r̄, paper Alg. 2, docs/coupling.md §2
  invariant 3): the agent's ``subtask_done`` r, or while none was reported the least of the
  sub-task's status rows and its ``repair`` (r) and ``recovery`` (r_before) events; ``r_last``, the
  r of the last status row (the final funnel's; above ``r_least`` after a recovery); and the repair
  counts per stage (from the last status and from ``repair`` events);
* per LTL robot, visits per region (reported by the agent, and recounted from the trajectory as
  entries into the region disc), GF rounds, and whether every region of its plan was visited;
* contacts (robot–robot, robot–wall) from ``contact`` events, and the closest approach of two
  robots in the trajectory (centre distance minus both radii) [m];
* deadline statistics: ``deadline_miss``, ``watchdog_stop``, ``stale_mocap`` and
  ``malformed_message`` events (``data.count``, when present, is the running total of that
  source on ``data.key``: the last one counts), plus the malformed payloads the coordinator
  itself received; the simulator's ``sim_stats`` event (control deadlines due/missed, frame →
  command latency percentiles [ms]);
* process deaths (``process_died`` events).
"""

from __future__ import annotations

import logging
import math
import re
from collections import Counter, defaultdict
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from tlfleet.agent.model import Scenario
from tlfleet.agent.stl.monitor import Trajectory, evaluate_trajectory
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol.messages import Event, LtlStatus, StlStatus
from tlfleet.coordinator.record import rundir
from tlfleet.coordinator.record.run_record import (
    ClosestApproach,
    Contacts,
    Deadlines,
    LtlRobotSummary,
    ProcessDeath,
    RunSummary,
    SimStats,
    StlRobotSummary,
    StlSubtaskSummary,
    write_record,
)
from tlfleet.coordinator.record.rundir import RunFiles

logger = logging.getLogger(__name__)

REGION_HYSTERESIS = 0.05  # [m] a robot must leave a region by this much before re-entering counts


def region_entries(xy: np.ndarray, center: tuple[float, float], radius: float,
                   hysteresis: float = REGION_HYSTERESIS) -> int:
    """Entries of the points ``xy`` (N, 2) [m] into the disc (center, radius); starting inside
    counts as one; a re-entry counts only after leaving the disc by ``hysteresis``."""
    return len(region_entry_indices(xy, center, radius, hysteresis))


def region_entry_indices(xy: np.ndarray, center: tuple[float, float], radius: float,
                         hysteresis: float = REGION_HYSTERESIS) -> list[int]:
    """Sample indices of the entries counted by :func:`region_entries` (0 if starting inside)."""
    if len(xy) == 0:
        return []
    d = np.hypot(xy[:, 0] - center[0], xy[:, 1] - center[1])
    entries: list[int] = []
    inside = False
    for k, value in enumerate(d):
        if not inside and value <= radius:
            entries.append(k)
            inside = True
        elif inside and value > radius + hysteresis:
            inside = False
    return entries


def closest_approach(traj: Trajectory, radii: dict[int, float]) -> ClosestApproach | None:
    """Min over samples and pairs of ‖p_i − p_j‖ − r_i − r_j [m], with the pair and time."""
    ids = [r for r in traj.robot_ids if r in radii]
    best: ClosestApproach | None = None
    for k, i in enumerate(ids):
        for j in ids[k + 1:]:
            gap = (np.hypot(*(traj.states[i][:, :2] - traj.states[j][:, :2]).T)
                   - radii[i] - radii[j])
            n = int(np.argmin(gap))
            if best is None or gap[n] < best.gap:
                best = ClosestApproach((i, j), float(gap[n]), float(traj.t[n]))
    return best


def _count(event: Event) -> int:
    count = event.data.get("count", 1)
    return int(count) if isinstance(count, int | float) and count >= 0 else 1


def _evaluated(value: float) -> float | None:
    """A robustness value as the summary keeps it: ±inf (an empty window) as is, NaN (not
    evaluated) as None."""
    return None if math.isnan(value) else float(value)


def _ltl_regions(scenario: Scenario, formula: str) -> list[str]:
    names = {r.name for r in scenario.regions}
    return sorted({tok for tok in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", formula) if tok in names})


def summarise_run(run_dir: str | Path) -> tuple[str, RunSummary]:
    """(text, record) summary of the run in ``run_dir``; see the module docstring."""
    return summarise(rundir.read_run(run_dir))


def summarise(files: RunFiles) -> tuple[str, RunSummary]:
    """(text, record) summary of a run directory's files (read by :func:`rundir.read_run`)."""
    run_dir, scenario, info = files.run_dir, files.scenario, files.info
    events, statuses = files.events, files.statuses
    traj = files.trajectory
    t_end = 0.0 if traj is None else float(traj.t[-1])
    mode, wall_time = info.get("mode"), info.get("wall_time")
    radii = {r.id: r.radius for r in scenario.robots}
    info_t_end = info.get("t_end")
    summary = RunSummary(
        scenario=scenario.name, run_dir=run_dir,
        mode=mode if isinstance(mode, str) else None,
        wall_time=float(wall_time) if _finite(wall_time) else None,
        frames=0 if traj is None else len(traj.t), t_end=t_end,
        trajectory_error=files.trajectory_error,
        stl=_stl_section(scenario, run_dir, traj, statuses, events),
        ltl=_ltl_section(scenario, traj, statuses),
        contacts=_contacts(events),
        closest_approach=None if traj is None else closest_approach(traj, radii),
        deadlines=_deadlines(events, info, scenario,
                             float(info_t_end) if _finite(info_t_end) and info_t_end else t_end),
        process_deaths=tuple(_death(e) for e in events if e.kind == "process_died"))
    return format_summary(summary), summary


def _death(event: Event) -> ProcessDeath:
    data = event.data
    process, how = data.get("process"), data.get("how")
    code, wall = data.get("returncode"), data.get("wall")
    return ProcessDeath(event.t, str(process), how if isinstance(how, str) else "",
                        code if isinstance(code, int) and not isinstance(code, bool) else None,
                        float(wall) if _finite(wall) else None)


def _stl_section(scenario: Scenario, run_dir: Path, traj: Trajectory | None,
                 statuses: tuple[LtlStatus | StlStatus, ...], events: tuple[Event, ...]
                 ) -> dict[int, StlRobotSummary]:
    last: dict[tuple[int, int], StlStatus] = {}
    least: dict[tuple[int, int], float] = {}
    for status in statuses:
        if isinstance(status, StlStatus):
            last[(status.robot, status.subtask)] = status
            _lower(least, (status.robot, status.subtask), status.r)
    done: dict[tuple[int, int], float] = {}
    for e in events:
        robot = _agent_id(e.source)
        sub = e.data.get("subtask")
        if robot is None or not isinstance(sub, int):
            continue
        value = {"repair": "r", "recovery": "r_before", "subtask_done": "r"}.get(e.kind)
        if value is not None:
            _lower(least, (robot, sub), e.data.get(value))
        r = e.data.get("r")
        if e.kind == "subtask_done" and _finite(r):
            done[(robot, sub)] = float(r)  # type: ignore[arg-type]
    repairs: dict[int, Counter[int]] = defaultdict(Counter)
    for e in events:
        if e.kind == "repair" and e.source.startswith("agent/"):
            robot = _agent_id(e.source)
            stage = e.data.get("stage")
            if robot is not None and isinstance(stage, int):
                repairs[robot][stage] += 1
    robust: dict = {}
    error = ""
    if traj is not None:
        try:
            robust = evaluate_trajectory(scenario, traj, run_dir / rundir.TRAJECTORY)
        except (TlfleetError, KeyError) as exc:
            error = str(exc)
    out: dict[int, StlRobotSummary] = {}
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        if not robot.is_stl:
            continue
        entry = robust.get(robot.id)
        subtasks = []
        texts = entry["subtasks"] if entry else [{"task": t, "window": None,
                                                  "robustness": math.nan} for t in robot.stl]
        for index, sub in enumerate(texts):
            status = last.get((robot.id, index))
            window = sub["window"]
            subtasks.append(StlSubtaskSummary(
                task=sub["task"],
                window=None if window is None else (float(window[0]), float(window[1])),
                robustness=_evaluated(sub["robustness"]),
                r_least=done.get((robot.id, index), least.get((robot.id, index))),
                r_last=_evaluated(status.r) if status else None,
                repairs_status=tuple(status.events) if status else (0, 0, 0)))
        out[robot.id] = StlRobotSummary(
            robustness=_evaluated(entry["robustness"]) if entry else None,
            subtasks=tuple(subtasks),
            repair_events=dict(sorted(repairs[robot.id].items())), error=error)
    return out


def _finite(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _lower(least: dict[tuple[int, int], float], key: tuple[int, int], value: object) -> None:
    """least[key] = min(least[key], value) for a finite number ``value`` (NaN: idle, skipped)."""
    if _finite(value):
        least[key] = min(least.get(key, math.inf), float(value))


def _agent_id(source: str) -> int | None:
    """``agent/4`` → 4; None for any other source."""
    head, _, tail = source.partition("/")
    return int(tail) if head == "agent" and tail.isdigit() else None


def _ltl_section(scenario: Scenario, traj: Trajectory | None,
                 statuses: tuple[LtlStatus | StlStatus, ...]) -> dict[int, LtlRobotSummary]:
    last: dict[int, LtlStatus] = {}
    for status in statuses:
        if isinstance(status, LtlStatus):
            last[status.robot] = status
    regions = {r.name: r for r in scenario.regions}
    out: dict[int, LtlRobotSummary] = {}
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        if robot.ltl is None:
            continue
        status = last.get(robot.id)
        reported: dict[str, int] = {}
        plan: list[str] = []
        rounds = None
        if status:
            reported = {name: count for name, count in status.visits}
            plan = [name for name in status.prefix + status.suffix if name in regions]
            rounds = status.rounds
        names = sorted(set(plan) | set(_ltl_regions(scenario, robot.ltl)))
        recount: dict[str, int] = {}
        if traj is not None and robot.id in traj.states:
            xy = traj.states[robot.id][:, :2]
            recount = {n: region_entries(xy, regions[n].center, regions[n].radius)
                       for n in names}
        plan_regions = sorted(set(plan)) or names
        out[robot.id] = LtlRobotSummary(
            task=robot.ltl, plan_regions=tuple(plan_regions), visits_reported=reported,
            visits_trajectory=recount, rounds=rounds,
            all_plan_regions_visited=bool(plan_regions) and all(
                max(reported.get(n, 0), recount.get(n, 0)) > 0 for n in plan_regions))
    return out


def _contacts(events: tuple[Event, ...]) -> Contacts:
    pairs: Counter[str] = Counter()
    robot_robot = robot_wall = 0
    for e in events:
        if e.kind != "contact":
            continue
        a, b = e.data.get("a"), e.data.get("b")
        if "wall" in (a, b):
            robot_wall += 1
            pairs[f"{a if b == 'wall' else b}-wall"] += 1
        else:
            robot_robot += 1
            pairs["-".join(str(x) for x in sorted((a, b), key=str))] += 1
    return Contacts(robot_robot, robot_wall, dict(pairs))


def _deadlines(events: tuple[Event, ...], info: Mapping[str, object], scenario: Scenario,
               t_end: float) -> Deadlines:
    """Deadline, watchdog, stale-mocap and malformed counts; ``stale_mocap`` counts the episodes
    during the mission only, as the verdict does
    (:func:`tlfleet.coordinator.live.verdict.mission_event_kinds`), and ``stale_mocap_at_end``
    the others (the frames stopped at the end of the run: expected)."""
    from tlfleet.coordinator.live.verdict import control_periods, mission_event_kinds

    misses: Counter[str] = Counter()
    malformed: Counter[str] = Counter()
    counts: Counter[str] = Counter()
    running: dict[tuple[str, str], int] = {}
    for e in events:
        kind = e.kind
        if kind == "deadline_miss":
            misses[str(e.data.get("robot"))] += _count(e)
        elif kind == "malformed_message":
            source, data = e.source, e.data
            count = data.get("count")
            if isinstance(count, int) and count >= 0:  # a running total per (source, key)
                key = (source, str(data.get("key")))
                running[key] = max(running.get(key, 0), count)
            else:
                malformed[source] += 1
        elif kind in ("watchdog_stop", "stale_mocap"):
            counts[kind] += 1
    for (source, _key), n in running.items():
        malformed[source] += n
    received = info.get("malformed_received")
    for what, n in (received.items() if isinstance(received, Mapping) else ()):
        malformed[f"coordinator ({what})"] += int(n)
    stats = next((e.data for e in reversed(events) if e.kind == "sim_stats"), None)
    mission = mission_event_kinds(
        ({"t": e.t, "kind": e.kind, "source": e.source, "data": e.data} for e in events
         if e.kind == "stale_mocap"), t_end, periods=control_periods(scenario))["stale_mocap"]
    return Deadlines(
        deadline_miss=sum(misses.values()), deadline_miss_by_robot=dict(misses),
        sim_stats=None if stats is None else SimStats.from_event(stats),
        watchdog_stop=counts["watchdog_stop"], stale_mocap=mission,
        stale_mocap_at_end=counts["stale_mocap"] - mission,
        malformed=sum(malformed.values()), malformed_by_source=dict(malformed))


def _fmt(value: object, spec: str = "+.4f") -> str:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return format(value, spec) if math.isfinite(value) else str(value)
    return str(value)


def format_summary(summary: RunSummary) -> str:
    """The text of ``summary.txt`` from the record of :func:`summarise`."""
    lines = [f"run {summary.scenario}  ({summary.run_dir})"]
    head = f"  {summary.frames} frames, t_end = {summary.t_end:.2f} s"
    if summary.mode:
        head += f", {summary.mode}"
    if summary.wall_time is not None:
        head += f", wall {summary.wall_time:.1f} s"
    lines.append(head)
    if summary.trajectory_error:
        lines.append(f"  trajectory: {summary.trajectory_error}")
    if summary.stl:
        lines.append("STL robots (standard robustness from trajectory.csv):")
    for rid, stl in summary.stl.items():
        stages = ", ".join(f"stage {s}: {n}" for s, n in stl.repair_events.items())
        lines.append(f"  robot {rid}: rho = {_fmt(stl.robustness)}"
                     + (f"   repair events {stages}" if stages else ""))
        for sub in stl.subtasks:
            extra = ""
            if sub.r_least is not None or sub.r_last is not None:
                extra = (f"   r̄ (least r in force) = {_fmt(sub.r_least)}, final r = "
                         f"{_fmt(sub.r_last)}   repairs per stage "
                         f"{'/'.join(str(n) for n in sub.repairs_status)}")
            lines.append(f"    {_fmt(sub.robustness)}  {sub.task}{extra}")
        if stl.error:
            lines.append(f"    ({stl.error})")
    if summary.ltl:
        lines.append("LTL robots (visits: reported by the agent / entries in the trajectory):")
    for rid, ltl in summary.ltl.items():
        visits = ", ".join(f"{n} {ltl.visits_reported.get(n, 0)}/"
                           f"{ltl.visits_trajectory.get(n, '-')}"
                           for n in ltl.plan_regions)
        ok = "all plan regions visited" if ltl.all_plan_regions_visited else \
            "NOT all plan regions visited"
        rounds = "" if ltl.rounds is None else f", GF rounds {ltl.rounds}"
        lines.append(f"  robot {rid}: {ltl.task}: {visits}{rounds}; {ok}")
    c = summary.contacts
    lines.append(f"contacts: robot-robot {c.robot_robot}, robot-wall {c.robot_wall}"
                 + (f" ({', '.join(f'{k}: {v}' for k, v in sorted(c.pairs.items()))})"
                    if c.pairs else ""))
    ca = summary.closest_approach
    if ca:
        lines.append(f"closest approach: robots {ca.pair[0]} and {ca.pair[1]}, gap "
                     f"{ca.gap:+.3f} m at t = {ca.t:.2f} s")
    d = summary.deadlines
    by_robot = ", ".join(f"{k}: {v}" for k, v in sorted(d.deadline_miss_by_robot.items()))
    by_source = ", ".join(f"{k}: {v}" for k, v in sorted(d.malformed_by_source.items()))
    lines.append(f"deadlines: {d.deadline_miss} missed" + (f" ({by_robot})" if by_robot else "")
                 + f", watchdog stops {d.watchdog_stop}, stale-mocap {d.stale_mocap}"
                 + (f" (and {d.stale_mocap_at_end} once the frames stopped at the end)"
                    if d.stale_mocap_at_end else ""))
    stats = d.sim_stats
    if stats and stats.due:
        timing = (f"control deadlines (sim): {stats.missed} of {stats.due} missed "
                  f"({100.0 * stats.missed / stats.due:.3f} %)")
        if stats.latency_p50_ms is not None:
            timing += (f", frame→command latency p50 {stats.latency_p50_ms:.2f} ms, "
                       f"p99 {_fmt(stats.latency_p99_ms, '.2f')} ms")
        lines.append(timing)
    lines.append(f"malformed messages: {d.malformed}" + (f" ({by_source})" if by_source else ""))
    deaths = summary.process_deaths
    lines.append(f"process deaths: {len(deaths)}" + "".join(
        f"\n  {x.process} at t = {_fmt(x.t, '.2f')} s ({x.how})" for x in deaths))
    return "\n".join(lines)


def write_summary(files: RunFiles | str | Path) -> tuple[str, RunSummary]:
    """Compute the summary of a run directory (its files as read by :func:`rundir.read_run`,
    or its path) and write ``summary.txt`` and ``summary.json`` into it."""
    if not isinstance(files, RunFiles):
        files = rundir.read_run(files)
    text, summary = summarise(files)
    (files.run_dir / rundir.SUMMARY_TEXT).write_text(text + "\n", encoding="utf-8")
    write_record(files.run_dir / rundir.SUMMARY_JSON, summary)
    return text, summary
