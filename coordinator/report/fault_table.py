"""The faults of a run as the report lists them ("the report lists each fault with
its detection time and the robots' minimum clearance during it").

From ``events.jsonl`` (``fault_start`` / ``fault_end``, :mod:`tlfleet.coordinator.faults.schedule`)
and
``trajectory.csv``: per fault its spec, start and end (sim time), how long it lasted (wall), the
coordinator's first detection of it — the first ``link_lost``, ``process_died`` or
``agent_silent`` about its target after the start, with the delay in sim time and, where both
events carry it, in wall time — and the minimum clearance ‖p_i − p_j‖ − r_i − r_j [m] over every
robot pair during the fault (for a kill or restart, which end at once: the ``RECOVERY_WINDOW``
seconds of sim time after it). A partition leaves every process connected to the coordinator,
so it is detected by its targets themselves: the first ``stale_mocap`` of a target agent (at its
last frame's time plus the silence it measured) or a target agent releasing a partner it lost
(``collab_follow`` with requester −1), whichever the coordinator's own signs do not precede.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from tlfleet.agent.model import Scenario
from tlfleet.bus.protocol.messages import Event
from tlfleet.coordinator.record.run_record import Detection, FaultRow
from tlfleet.coordinator.record.rundir import Trajectory

RECOVERY_WINDOW = 5.0  # [s] sim time after an instantaneous fault (kill, restart)
DETECTIONS = ("link_lost", "process_died", "agent_silent")


def _about(event: Event, target: str) -> bool:
    data = event.data if isinstance(event.data, dict) else {}
    if data.get("process") == target:
        return True
    robot = data.get("robot")
    return isinstance(robot, int) and target == f"agent-{robot}"


def _partition_sign(event: Event, targets: list[str]) -> float | None:
    """Sim time [s] at which a target agent noticed a partition, per ``event`` (None: not
    such an event)."""
    source = event.source
    if not (source.startswith("agent/") and f"agent-{source[6:]}" in targets):
        return None
    data = event.data if isinstance(event.data, dict) else {}
    if event.kind == "stale_mocap" and isinstance(data.get("silence"), int | float):
        return event.t + float(data["silence"])
    if event.kind == "collab_follow" and data.get("requester") == -1:
        return event.t
    return None


def min_clearance(traj: Trajectory | None, radii: dict[int, float], a: float, b: float
                  ) -> float | None:
    """Min over the samples with a ≤ t ≤ b and the robot pairs of the gap [m] (None: none)."""
    if traj is None:
        return None
    window = (traj.t >= a) & (traj.t <= b)
    ids = [r for r in traj.robot_ids if r in radii]
    if not window.any() or len(ids) < 2:
        return None
    best = np.inf
    for k, i in enumerate(ids):
        for j in ids[k + 1:]:
            d = np.hypot(*(traj.states[i][window, :2] - traj.states[j][window, :2]).T)
            best = min(best, float(np.min(d - radii[i] - radii[j])))
    return best


def fault_rows(scenario: Scenario, events: Iterable[Event], traj: Trajectory | None
               ) -> list[FaultRow]:
    """One row per ``fault_start`` (see the module docstring)."""
    events = list(events)
    radii = {r.id: r.radius for r in scenario.robots}
    rows = []
    for n, start in enumerate(events):
        if start.kind == "fault_skipped":  # never injected: a row with the reason, no times
            data = start.data if isinstance(start.data, dict) else {}
            kind = data.get("kind")
            rows.append(FaultRow(
                spec=str(data.get("spec")), kind=kind if isinstance(kind, str) else None,
                targets=tuple(t for t in _list(data.get("targets")) if isinstance(t, str)),
                start_t=None, end_t=None, lasted=None,
                error=f"skipped: {data.get('reason', '')}", detection=None,
                min_clearance=None))
            continue
        if start.kind != "fault_start":
            continue
        data = start.data if isinstance(start.data, dict) else {}
        spec = data.get("spec")
        end = next((e for e in events[n + 1:] if e.kind == "fault_end"
                    and isinstance(e.data, dict) and e.data.get("spec") == spec), None)
        targets = [t for t in _list(data.get("targets")) if isinstance(t, str)]
        started = _float(data.get("wall"))
        # the whole record: a kill's death is written while the fault starts, before its
        # fault_start (same sim time; later in wall time when both carry it)
        found = next((e for e in events if e.kind in DETECTIONS and e.t >= start.t
                      and any(_about(e, t) for t in targets) and _not_before(e, started)), None)
        end_t = end.t if end is not None else None
        until = end_t if end_t is not None and end_t > start.t else start.t + RECOVERY_WINDOW
        detection: Detection | None = None
        if found is not None:
            wall = _float(found.data.get("wall") if isinstance(found.data, dict) else None)
            detection = Detection(found.kind, found.t, found.t - start.t, after_wall=(
                wall - started if wall is not None and started is not None else None))
        if data.get("kind") == "partition":
            signs = [(t, e) for e in events[n + 1:]
                     if (t := _partition_sign(e, targets)) is not None and t >= start.t]
            if signs:
                t, sign = min(signs, key=lambda pair: pair[0])
                if detection is None or t < detection.t:
                    detection = Detection(sign.kind, t, t - start.t, by=sign.source)
        lasted = end.data.get("lasted") if end is not None else None
        kind, error = data.get("kind"), data.get("error")
        rows.append(FaultRow(
            spec=str(spec), kind=kind if isinstance(kind, str) else None,
            targets=tuple(targets), start_t=start.t, end_t=end_t,
            lasted=_float(lasted),
            error=None if error is None else str(error), detection=detection,
            min_clearance=min_clearance(traj, radii, start.t, until)))
    return rows


def _not_before(event: Event, started_wall: float | None) -> bool:
    """Whether ``event`` did not happen before a fault that began at ``started_wall`` [s, wall
    clock] (true when either time is unknown)."""
    wall = _float(event.data.get("wall") if isinstance(event.data, dict) else None)
    return wall is None or started_wall is None or wall >= started_wall


def _float(value: object) -> float | None:
    """A number of an event's data as a float; None for anything else."""
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) \
        else None


def _list(value: object) -> list[object]:
    return value if isinstance(value, list) else []


def render_fault_lines(rows: Sequence[FaultRow]) -> list[str]:
    """Markdown of the report's "Faults" section (empty without faults)."""
    if not rows:
        return []

    def num(value: float | None, spec: str) -> str:
        return "—" if value is None else format(value, spec)

    out = ["## Faults", "",
           "| fault | start t [s] | end t [s] | lasted [s wall] | detected as | after [s] | "
           "min clearance [m] |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        d = r.detection
        after = None if d is None else (d.after_wall if d.after_wall is not None
                                        else d.after_sim)
        why = "" if not r.error else f" ({r.error})" if r.error.startswith("skipped") \
            else f" (failed: {r.error})"
        out.append(f"| `{r.spec}`{why} | "
                   f"{num(r.start_t, '.2f')} | {num(r.end_t, '.2f')} | "
                   f"{num(r.lasted, '.2f')} | {d.kind if d else 'not detected'} | "
                   f"{num(after, '.2f')} | {num(r.min_clearance, '+.3f')} |")
    return [*out, "", "Detection: the coordinator's first link_lost / process_died / "
            "agent_silent about the fault's target after its start (delay in wall time where both "
            "events carry it, else sim time); clearance: centre distance minus both radii over "
            "every robot pair during the fault.", ""]
