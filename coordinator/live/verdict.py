"""The verdict of a run: ``clean``, ``degraded``, ``failed`` or ``interrupted``.

``tlfleet run`` exits with the verdict's code (README "Exit codes"):

* ``clean`` → 0: the mission ran to its end, every process ended cleanly, nothing below happened;
* ``failed`` → 3: a process died (or the router was lost), a process did not stop cleanly, or
  the run ended early (simulator gone, wall-clock timeout);
* ``degraded`` → 4: it ran to the end without a failure, but with missed control deadlines
  (lockstep: any; realtime: above ``max_missed_fraction`` of those due), watchdog stops, stale
  commands ignored, stale mocap during the mission, malformed or implausible input, flagged events
  (claimed identity does not hold), silent (frozen/partitioned) agents, agents that resumed or
  recovered — each listed;
* ``interrupted`` → 130: Ctrl-C, SIGTERM or the caller's stop.

Invalid scenarios and launch failures exit 1 before a verdict exists; 2 is a usage error.
:func:`classify` is pure: it reads what the run recorded (the summary's counters, the events'
kinds, the supervisor's findings) and returns a :class:`Verdict` with the reasons.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from tlfleet.agent.model.scenario import Scenario
from tlfleet.coordinator.record.run_record import Deadlines
from tlfleet.coordinator.record.rundir import AFTER_SIM_DONE

EXIT_CODES = {"clean": 0, "failed": 3, "degraded": 4, "interrupted": 130}
MAX_MISSED_FRACTION = 0.05  # realtime: missed control deadlines / due above this → degraded
FINISHED = ("sim_done", "duration", "sim_ended")


@dataclass(frozen=True)
class RunEnd:
    """Where and why the supervised run ended: sim time ``t`` [s] of its ``duration`` [s]."""

    t: float
    duration: float
    reason: str  # sim_done | duration | wall_timeout | interrupted | sim_died | router_lost

    @property
    def text(self) -> str:
        return f"ended at t = {self.t:.2f} s of {self.duration:g} s: {self.reason}"

    def to_json(self) -> dict[str, Any]:
        return {"t": self.t, "duration": self.duration, "reason": self.reason}


@dataclass(frozen=True)
class Verdict:
    label: str  # clean | degraded | failed | interrupted
    reasons: tuple[str, ...] = field(default_factory=tuple)
    end: RunEnd | None = None

    @property
    def exit_code(self) -> int:
        return EXIT_CODES[self.label]

    @property
    def line(self) -> str:
        """One line for the summary and the console: ``outcome: degraded (ended at t = 90.00 s
        of 90 s: sim_done; 3 watchdog stop(s))``."""
        parts = ([self.end.text] if self.end is not None else []) + list(self.reasons)
        return f"outcome: {self.label}" + (f" ({'; '.join(parts)})" if parts else "")

    def to_json(self) -> dict[str, Any]:
        out = {"label": self.label, "exit_code": self.exit_code, "reasons": list(self.reasons)}
        if self.end is not None:
            out["end"] = self.end.to_json()
        return out


def classify(*, reason: str, deaths: Iterable[str], exit_codes: Mapping[str, int | None],
             router_clean: bool, mode: str, deadlines: Deadlines | None,
             event_kinds: Mapping[str, int], findings: Iterable[str] = (),
             lingering: Iterable[str] = (),
             max_missed_fraction: float = MAX_MISSED_FRACTION,
             end: RunEnd | None = None, tolerance: float = 0.0,
             sim_reached: float | None = None) -> Verdict:
    """The verdict of a run (see the module docstring).

    ``reason``: how supervision ended; ``deaths``: processes reported dead (recovered ones
    excluded); ``exit_codes``: the children's codes after ``Control(stop)``; ``deadlines``: the
    summary's deadline counts (None: no summary); ``event_kinds``:
    events per kind *during the mission*; ``findings``: extra degradations already worded
    (silent agents, recoveries, flagged sim_done…); ``lingering``: processes this coordinator
    did not start (``tlfleet supervise``) whose liveliness token outlived ``Control(stop)``.

    ``end``: where the run ended (its last recorded frame) of its duration; a run that ends more
    than ``tolerance`` [s] before its duration is never clean — *failed* when the simulator did
    not get there either, *degraded* when it did (``sim_reached``: the sim time of its own
    ``sim_done``) and only the frames of the end were not recorded.
    """
    verdict = _classify(reason=reason, deaths=deaths, exit_codes=exit_codes,
                        router_clean=router_clean, mode=mode, deadlines=deadlines,
                        event_kinds=event_kinds, findings=findings, lingering=lingering,
                        max_missed_fraction=max_missed_fraction)
    if end is None:
        return verdict
    short = end.t < end.duration - tolerance
    if verdict.label == "interrupted" or not short or reason not in FINISHED:
        return Verdict(verdict.label, verdict.reasons, end)
    if sim_reached is not None and sim_reached >= end.duration - tolerance:
        label = "degraded" if verdict.label == "clean" else verdict.label
        return Verdict(label, (f"the frames after t = {end.t:.2f} s were not recorded (the "
                               f"simulator reached t = {sim_reached:.2f} s)", *verdict.reasons),
                       end)
    return Verdict("failed", (f"the run ended {end.duration - end.t:.2f} s before its duration",
                              *verdict.reasons), end)


def _classify(*, reason: str, deaths: Iterable[str], exit_codes: Mapping[str, int | None],
              router_clean: bool, mode: str, deadlines: Deadlines | None,
              event_kinds: Mapping[str, int], findings: Iterable[str],
              lingering: Iterable[str], max_missed_fraction: float) -> Verdict:
    if reason == "interrupted":
        return Verdict("interrupted", (f"stopped at the user's request ({reason})",))
    failures: list[str] = []
    deaths = list(deaths)
    if deaths:
        failures.append(f"process died: {', '.join(deaths)}")
    if reason not in FINISHED:
        failures.append(f"the run ended early ({reason})")
    unclean = {n: c for n, c in exit_codes.items() if c != 0 and n not in deaths}
    if unclean:
        failures.append("did not stop cleanly: " + ", ".join(f"{n} ({c})"
                                                            for n, c in sorted(unclean.items())))
    if not router_clean and "router" not in deaths:
        failures.append("the router did not stop cleanly")
    lingering = sorted(lingering)
    if lingering:
        failures.append(f"still alive after stop: {', '.join(lingering)}")
    if failures:
        return Verdict("failed", tuple(failures))
    degraded: list[str] = []
    stats = deadlines.sim_stats if deadlines is not None else None
    missed, due = (stats.missed, stats.due) if stats is not None else (0, 0)
    lockstep_misses = deadlines.deadline_miss if deadlines is not None else 0
    if mode == "lockstep" and lockstep_misses:
        degraded.append(f"{lockstep_misses} missed deadline(s)")
    elif due and missed / due > max_missed_fraction:
        degraded.append(f"{missed} of {due} control deadlines missed "
                        f"({100.0 * missed / due:.1f} % > {100.0 * max_missed_fraction:g} %)")
    kinds = Counter(event_kinds)
    for kind, what in (("watchdog_stop", "watchdog stop(s)"),
                       ("stale_command", "stale-command episode(s)"),
                       ("tracking_lost", "hardware halt(s): a mocap body lost, every robot "
                                         "held at zero"),
                       ("geofence", "hardware halt(s): a robot left the geofence, every robot "
                                    "held at zero"),
                       ("stale_mocap", "stale-mocap episode(s) during the mission"),
                       ("flagged_event", "flagged event(s): claimed identity does not hold"),
                       ("resumed", "agent resume(s) after a freeze or partition"),
                       ("process_recovered", "process recovery(ies)"),
                       ("token_blip", "liveliness blip(s): a token gone and back at once"),
                       ("agent_silent", "silent agent episode(s)"),
                       ("process_unreachable", "unreachable process episode(s) (token gone, "
                                               "process running)"),
                       ("link_lost", "link loss(es)")):
        if kinds[kind]:
            degraded.append(f"{kinds[kind]} {what}")
    malformed = deadlines.malformed if deadlines is not None else 0
    if malformed:
        by_source = deadlines.malformed_by_source if deadlines is not None else {}
        degraded.append(f"{malformed} malformed or implausible message(s)"
                        + (f" ({', '.join(f'{k}: {v}' for k, v in sorted(by_source.items()))})"
                           if by_source else ""))
    degraded.extend(findings)
    return Verdict("degraded", tuple(degraded)) if degraded else Verdict("clean")


def control_periods(scenario: Scenario) -> dict[str, float]:
    """Each agent's control period [s] by event source (``agent/<id>``): d_r / mocap_rate
    (:meth:`tlfleet.agent.model.scenario.Scenario.control_divider`)."""
    return {f"agent/{r}": scenario.control_divider(r) / scenario.sim.mocap_rate
            for r in scenario.robot_ids}


def mission_event_kinds(events: Iterable[Mapping[str, Any]], t_end: float,
                        end_slack: float = 0.05,
                        periods: Mapping[str, float] | None = None) -> Counter[str]:
    """Events per kind *during the mission*: without the events marked :data:`AFTER_SIM_DONE`,
    and without an agent's ``stale_mocap`` whose last frame was the last one it was due (its
    ``t`` is that frame's time, so ``t + period > t_end - end_slack``): the simulator has
    stopped publishing, which is expected at the end, not a degradation. ``periods``: each
    event source's control period [s] (``agent/1`` → 0.2 for a 5 Hz LTL robot); a source not
    in it counts as ``end_slack``."""
    periods = periods or {}
    kinds: Counter[str] = Counter()
    for e in events:
        kind = e.get("kind")
        data = e.get("data")
        if isinstance(data, Mapping) and data.get(AFTER_SIM_DONE) is True:
            continue
        if kind == "stale_mocap":
            period = periods.get(str(e.get("source")), 0.0)
            if float(e.get("t", 0.0)) + period >= t_end - end_slack:
                continue
        kinds[str(kind)] += 1
    return kinds
