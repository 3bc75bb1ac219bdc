"""The coordinator's own part of a run, with or without the launcher.

``tlfleet run`` (:mod:`tlfleet.coordinator.run`) launches the router, the simulator and the agents
and then does what this module does; ``tlfleet supervise`` (:func:`supervise_fleet`) does only this,
joining a fleet whose processes were started elsewhere (by hand, on other machines, as compose
services). Both go through the same three pieces, so both record, judge and report alike:

1. :func:`prepare_run` — load the scenario (``ScenarioError`` first; with ``secure`` the keys are
   checked), create the run directory, copy the scenario, write the first ``run.json``;
2. :class:`Supervision` — over an open client session: declare ``alive/coordinator/0``,
   subscribe the recorder tap with its plausibility checks
   (:mod:`tlfleet.coordinator.record.trust`), watch the agents' health
   (:mod:`tlfleet.coordinator.live.health`), wait for the liveliness token of every process the
   scenario needs (saying which ones are still missing, every ``waiting_period``), send
   ``Control(start)``, supervise until the end of the mission and send ``Control(stop)``
   (:mod:`tlfleet.coordinator.live.supervisor`); :meth:`Supervision.close` is guarded step by step
   (:class:`tlfleet.coordinator.launch.cleanup.Cleanup`);
3. :func:`finish_run` — the closing fields of ``run.json``, then ``summary.txt`` with the run's
   verdict (:mod:`tlfleet.coordinator.live.verdict`), the report and ``run.rrd``
   (:mod:`tlfleet.coordinator.report.outputs`).

A client session to an endpoint with no router fails within ``connect_timeout`` (default 1 s)
with a :class:`SuperviseError` that names the endpoint.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tlfleet.agent.model import Scenario
from tlfleet.agent.model.faults import Fault
from tlfleet.agent.policy.preflight import check_launch
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.limits import bounded
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.bounds import FleetBounds
from tlfleet.bus.protocol.plausibility import max_jump_ticks
from tlfleet.bus.transport import Transport, TransportConfig
from tlfleet.bus.zenoh.config import clean_reason
from tlfleet.bus.zenoh.security import fingerprints, secure_transport
from tlfleet.bus.zenoh.transport import open_transport
from tlfleet.coordinator.launch.cleanup import Cleanup
from tlfleet.coordinator.launch.processes import group_alive
from tlfleet.coordinator.live.health import Health
from tlfleet.coordinator.live.supervisor import ChildLike, Outcome, Supervisor, SupervisorConfig
from tlfleet.coordinator.live.verdict import (
    RunEnd,
    Verdict,
    classify,
    control_periods,
    mission_event_kinds,
)
from tlfleet.coordinator.record.recorder import Recorder, RecorderTap
from tlfleet.coordinator.record.run_record import Report, RunSummary
from tlfleet.coordinator.record.rundir import (
    RunDirLock,
    RunFiles,
    claim_run_dir,
    default_run_dir,
)
from tlfleet.coordinator.record.trust import RecordCheck
from tlfleet.coordinator.report.outputs import OutputSettings, write_outputs
from tlfleet.coordinator.report.task_tally import TASKS_NOT_MET, TaskTally

logger = logging.getLogger(__name__)

Say = Callable[[str], None]
CLEAN_ENDS = ("sim_done", "duration")
#: mocap periods a run's last recorded frame may fall short of its duration and still be at its
#: end (the simulator's last tick is the last whole period)
END_TOLERANCE = 1.5


class SuperviseError(TlfleetError, RuntimeError):
    """The coordinator cannot join the fleet (no router at the endpoint, …)."""


@dataclass(frozen=True)
class SuperviseConfig:
    """Everything ``tlfleet supervise`` needs; ``None`` means "the scenario's value"."""

    scenario_path: Path
    connect: tuple[str, ...] = ("tcp/127.0.0.1:7447",)  # the fleet's router(s)
    mode: str = "lockstep"  # what the simulator was started with (recorded in run.json)
    out: Path | None = None
    duration: float | None = None  # [s] sim time
    seed: int | None = None  # the simulator's seed, for run.json (default: the scenario's)
    supervisor: SupervisorConfig = field(default_factory=SupervisorConfig)
    connect_timeout: float = 1.0  # [s] wall, for the client session to reach a router
    zenoh_config: Path | None = None  # JSON5 file merged under tlfleet's own settings
    secure: Path | None = None  # key directory (`tlfleet keys`): mutual TLS as "coordinator"
    lease_ms: int | None = None  # [ms] zenoh link lease of the session (None: zenoh's 10 s)
    silence: float = 2.0  # [s] wall: an agent without status this long is silent (health)
    close_timeout: float = 5.0  # [s] wall: closing the coordinator's session, at most
    report: bool = True
    figures: bool = True
    figure_format: str = "png"  # png | pdf | svg
    rrd: bool = True
    rrd_every: int = 5
    viewer: bool = False
    grpc_port: int = 0
    web_port: int = 0
    faults: tuple[Fault, ...] = ()  # injected with the actuator of fault_plan
    # tlfleet.coordinator.faults.on_hosts (written by tlfleet run --hosts)
    fault_plan: Path | None = None
    # tlfleet.coordinator.faults.handoff: the host's executor's directory
    fault_handoff: Path | None = None


@dataclass
class PreparedRun:
    scenario: Scenario
    run_dir: Path
    recorder: Recorder
    info: dict[str, Any]  # run.json, rewritten as the run goes on
    duration: float  # [s] sim time
    lock: RunDirLock | None = None  # the claim on run_dir, released when the run is written


@dataclass
class RunResult:
    """What a run (``tlfleet run`` or ``tlfleet supervise``) leaves to its caller."""

    run_dir: Path
    outcome: Outcome
    exit_codes: dict[str, int | None]  # the launched children's final codes (supervise: none)
    clean: bool
    summary_text: str = ""
    summary: RunSummary | None = None  # None: the run ended before its summary was written
    info: dict[str, Any] = field(default_factory=dict)
    report: Report | None = None  # when written
    rrd: Path | None = None  # run.rrd, when written
    viewer: Any = None  # tlfleet.coordinator.report.viewer.LiveView, still serving (close() it)
    verdict: Verdict = field(default_factory=lambda: Verdict("failed", ("no verdict",)))
    tasks: TaskTally | None = None  # what the run achieved (None: not computed)

    def exit_code(self, require_tasks: bool = False) -> int:
        """The verdict's exit code; with ``require_tasks``, :data:`TASKS_NOT_MET` (5) instead
        of 0 or 4 when a task was not met (or the tally could not be computed)."""
        code = self.verdict.exit_code
        if require_tasks and self.verdict.label in ("clean", "degraded") and not (
                self.tasks is not None and self.tasks.all_met):
            return TASKS_NOT_MET
        return code


#: the identities whose keys ``tlfleet supervise`` needs: its own
COORDINATOR_KEYS = ("coordinator",)


def load_checked(scenario_path: Path, secure: Path | None = None,
                 identities: Sequence[str] | None = None) -> Scenario:
    """The scenario (``ScenarioError`` names file and field; every agent built as its process
    would, :func:`tlfleet.agent.policy.preflight.check_launch`, an LTL robot's plan included:
    the reason names the region in the way when the keep-out rule leaves none,
    docs/ltl-navigation.md §2); with ``secure``, its key directory checked against it
    (``KeyError`` of :mod:`tlfleet.coordinator.security.authority`) for ``identities``
    (default: every process's, which ``tlfleet run`` starts): all before anything starts."""
    with bounded(str(scenario_path)):  # a task may ask for exponential work: bounded
        scenario = load_scenario(scenario_path)
        check_launch(scenario)  # what would stop an agent at launch, refused before any starts
    if secure is not None:
        from tlfleet.coordinator.security.authority import (
            check_keys,  # cryptography: imported for secured runs only
        )

        check_keys(scenario, secure, identities)
    return scenario


def prepare_run(scenario: Scenario, scenario_path: Path, out: Path | None, *, mode: str,
                duration: float | None, seed: int | None, endpoint: str,
                secure: Path | None = None, lease_ms: int | None = None) -> PreparedRun:
    """Step 1 for ``scenario`` (loaded from ``scenario_path`` by :func:`load_checked`): a fresh
    run directory with ``scenario.toml`` and the first ``run.json``."""
    total = float(duration or scenario.duration)
    run_dir = Path(out) if out else default_run_dir(scenario.name)
    lock = claim_run_dir(run_dir)  # RunDirectoryError: never overwrite a run, one run at once
    try:
        recorder = Recorder(run_dir, [r.id for r in scenario.robots])
        recorder.copy_scenario(Path(scenario_path))
    except BaseException:
        lock.release()
        raise
    info: dict[str, Any] = {
        "scenario": scenario.name, "scenario_path": str(scenario_path),
        "mode": mode, "duration": total,
        "seed": scenario.sim.seed if seed is None else seed,
        "endpoint": endpoint, "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "secure": secure is not None,
    }
    if secure is not None:
        from tlfleet.coordinator.security.policy import identities

        info["keys"] = str(Path(secure).resolve())
        # the certificates at hand: all of them for `tlfleet run`, the coordinator's (and any
        # other public one present) for `tlfleet supervise`, which needs no other key
        info["fingerprints"] = fingerprints(secure, [
            name for name in identities(scenario) if (Path(secure) / f"{name}.pem").is_file()])
    if lease_ms:
        info["lease_ms"] = lease_ms
    recorder.write_run_info(info)
    return PreparedRun(scenario, run_dir, recorder, info, total, lock)


def tap_checks(scenario: Scenario, duration: float) -> dict[str, Any]:
    """The recorder tap's plausibility checks for this run."""
    a = scenario.arena
    dividers = [scenario.control_divider(r) for r in scenario.robot_ids]
    rate = scenario.sim.mocap_rate
    return {"bounds": FleetBounds((a.xmin, a.xmax, a.ymin, a.ymax), duration, rate,
                                  scenario.speed_limits()),
            "max_jump": max_jump_ticks(rate, dividers),
            "robot_ids": scenario.robot_ids,
            "record_check": RecordCheck({r.id: r.radius for r in scenario.robots}, rate,
                                        round(duration * rate))}


class Supervision:
    """Step 2 over an open transport: the coordinator's token, the recorder tap, the agents'
    health and the supervisor.

    ``children`` are the processes this coordinator started itself (none for ``supervise``);
    more can be added to :attr:`supervisor` ``.children`` before :meth:`run`. ``on_message`` (the
    live viewer's) sees every message the tap accepted.
    """

    def __init__(self, transport: Transport, prepared: PreparedRun, *,
                 config: SupervisorConfig, silence: float = 2.0,
                 children: Mapping[str, ChildLike] | None = None, report: Say | None = None,
                 on_message: Callable[[str, Any], None] | None = None):
        self.prepared = prepared
        scenario = prepared.scenario
        say = report or (lambda text: logger.warning("%s", text))
        self.health = Health(scenario.robot_ids, prepared.recorder.on_event, say,
                             silence=silence)
        self._on_message = on_message
        self._token = transport.declare_alive(keys.alive(scenario.fleet, "coordinator", 0))
        self.tap = RecorderTap(transport, scenario.fleet, prepared.recorder,
                               on_message=self._message, **tap_checks(scenario, prepared.duration))
        self.supervisor = Supervisor(transport, scenario, self.tap, dict(children or {}),
                                     duration=prepared.duration, config=config, report=report)
        self.wall_start = time.monotonic()

    def _message(self, what: str, message: Any) -> None:
        self.health.on_message(what, message)
        if self._on_message is not None:
            self._on_message(what, message)

    def run(self, stop: threading.Event | None = None,
            progress: Callable[[float, float], None] | None = None,
            waiting: Callable[[list[str]], None] | None = None) -> tuple[Outcome, dict]:
        """Wait for the fleet, start, supervise to the end, stop → (outcome, exit codes of the
        children after ``Control(stop)``). The prepared ``info`` gets ``ready_time`` and
        ``wall_time``."""
        info, supervisor = self.prepared.info, self.supervisor

        def step(t: float, d: float) -> None:
            self.health.poll()
            if progress is not None:
                progress(t, d)

        info["ready_time"] = supervisor.wait_ready(stop, waiting=waiting)
        supervisor.start()
        self.health.start()
        self.wall_start = time.monotonic()
        try:
            outcome = supervisor.supervise(stop, step)
        except KeyboardInterrupt:
            outcome = Outcome("interrupted", supervisor.sim_time, list(supervisor.deaths.values()))
        info["wall_time"] = time.monotonic() - self.wall_start
        return outcome, supervisor.finish()

    def wait_gone(self, grace: float) -> dict[str, bool]:
        """After ``Control(stop)``: wait up to ``grace`` [s] for every process token to go →
        {process: its token is gone}."""
        supervisor = self.supervisor
        deadline = time.monotonic() + grace
        names = list(supervisor.tokens.values())
        while time.monotonic() < deadline:
            supervisor.check()
            if not any(name in supervisor.alive for name in names):
                break
            time.sleep(0.02)
        return {name: name not in supervisor.alive for name in names}

    def close(self, cleanup: Cleanup) -> None:
        """Drain and close the tap (its malformed counts and flagged events go to ``info``),
        close the supervisor, withdraw the token; every step guarded by ``cleanup``."""
        info, tap = self.prepared.info, self.tap
        cleanup.step("drain the recorder tap", tap.drain)
        cleanup.step("close the recorder tap", tap.close)
        info["malformed_received"] = dict(tap.malformed)
        info["malformed_received_by_source"] = {
            f"{what} from {source}": n for (what, source), n in tap.malformed_by_source.items()}
        info["flagged_events"] = tap.flagged
        info["replayed_events"] = {"recorded": tap.dedup.replayed,
                                   "duplicates_dropped": tap.dedup.duplicates}
        cleanup.step("close the supervisor", self.supervisor.close)
        info["recovered"] = [d.process for d in self.supervisor.recovered]
        cleanup.step("withdraw the coordinator's token", self._token.close)

    def findings(self) -> list[str]:
        """The agents' health findings, and each stretch of ``trajectory.csv`` the backfill
        could not recover."""
        return self.health.findings() + self.supervisor.findings() + [
            f"trajectory.csv misses {r['frames']} frames (seq {r['first']}–{r['last']}, "
            f"t = {r['t_first']:.2f}–{r['t_last']:.2f} s): lost on a link, and "
            + ("the simulator did not answer the backfill" if r["oldest_held"] is None else
               f"older than the simulator's backfill ring (oldest seq {r['oldest_held']})")
            for r in self.prepared.recorder.backfill_summary()["unrecovered_ranges"]]


def end_info(prepared: PreparedRun, outcome: Outcome, wall_start: float,
             cleanup: Cleanup) -> None:
    """The closing fields of ``run.json`` common to ``run`` and ``supervise`` (written by the
    caller, after the recorder is closed)."""
    info = prepared.info
    info.update(reason=outcome.reason, t_end=outcome.t_end,
                frames=prepared.recorder.frames_written)
    backfill = prepared.recorder.backfill_summary()
    if backfill["gaps"]:  # every gap of the live stream, and what stayed missing
        info["backfill"] = backfill
    info.setdefault("wall_time", time.monotonic() - wall_start)
    if info["wall_time"] > 0:
        info["speedup"] = outcome.t_end / info["wall_time"]
    if cleanup.errors:
        info["cleanup_errors"] = cleanup.errors


def finish_run(prepared: PreparedRun, config: OutputSettings, outcome: Outcome, *,
               codes: dict[str, int | None], final: dict[str, int | None],
               router_clean: bool = True, findings: list[str] | None = None,
               lingering: tuple[str, ...] = (), viewer: Any = None, note: Say, say: Say,
               ) -> RunResult:
    """Step 3: ``clean`` into ``run.json``, then the summary, the verdict, the report and
    ``run.rrd`` (:func:`tlfleet.coordinator.report.outputs.write_outputs`).

    ``codes``: the launched children's exit codes after ``Control(stop)``; ``final``: after the
    clean-up; ``lingering``: processes not started here whose tokens outlived ``Control(stop)``.
    """
    info, recorder, scenario = prepared.info, prepared.recorder, prepared.scenario
    clean = (outcome.reason in CLEAN_ENDS and not outcome.deaths and not lingering
             and all(code == 0 for code in codes.values()) and router_clean)
    info["clean"] = clean
    recorder.write_run_info(info)
    note(f"writing summary.json{', report.md/json' if config.report else ''}"
         f"{' and figures' if config.report and config.figures else ''} in {prepared.run_dir} …")

    def judge(files: RunFiles, summary: RunSummary) -> Verdict:
        events = [{"t": e.t, "kind": e.kind, "source": e.source, "data": e.data}
                  for e in files.events]  # read once (lenient)
        extra = list(findings or []) + [f"clean-up: {e}" for e in info.get("cleanup_errors", [])]
        return classify(reason=outcome.reason, deaths=[d.process for d in outcome.deaths],
                        exit_codes=codes, router_clean=router_clean, mode=str(info.get("mode")),
                        deadlines=summary.deadlines,
                        event_kinds=mission_event_kinds(events, outcome.t_end,
                                                        periods=control_periods(scenario)),
                        findings=extra, lingering=lingering,
                        end=RunEnd(outcome.t_end, prepared.duration, outcome.reason),
                        tolerance=END_TOLERANCE / prepared.scenario.sim.mocap_rate,
                        sim_reached=outcome.sim_reached)

    try:
        text, summary, report, rrd, verdict, tally = write_outputs(
            prepared.run_dir, prepared.scenario, config, info, recorder.write_run_info, note,
            say, judge=judge)
    finally:
        if prepared.lock is not None:
            prepared.lock.release()
    return RunResult(prepared.run_dir, outcome, final, clean, text, summary, info, report, rrd,
                     viewer, verdict, tally)


def client_config(connect: tuple[str, ...], *, secure: Path | None = None,
                  lease_ms: int | None = None, zenoh_config: Path | None = None,
                  extra: Mapping[str, Any] | None = None) -> TransportConfig:
    """The coordinator's client session: to ``connect``, secured as ``coordinator`` with the
    keys of ``secure``."""
    config = TransportConfig(mode="client", connect=tuple(connect), lease_ms=lease_ms,
                             extra=dict(extra or {}), zenoh_config=zenoh_config)
    return config if secure is None else secure_transport(config, secure, "coordinator")


def open_client(config: TransportConfig, timeout: float,
                given_up: Callable[[], bool] = lambda: False) -> Transport:
    """A client session to the fleet's router; :class:`SuperviseError` naming the endpoints when
    none answers within ``timeout`` [s] or once ``given_up()`` (a zenoh client fails at once
    when no router listens; this retries until then, for a router that is still starting)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return open_transport(config)
        except TlfleetError:
            raise  # a bad --zenoh-config: retrying cannot help
        except Exception as exc:  # zenoh raises ZError, not a stable type
            if given_up() or time.monotonic() > deadline:
                raise SuperviseError(
                    f"no zenoh router answers at {', '.join(config.connect)} (tried for "
                    f"{timeout:g} s: {clean_reason(str(exc))}); start one with `tlfleet router "
                    f"--listen ENDPOINT` or give the right --connect") from exc
            time.sleep(0.05)


def supervise_fleet(config: SuperviseConfig, stop: threading.Event | None = None,
                    progress: Callable[[float, float], None] | None = None,
                    report: Say | None = None,
                    waiting: Callable[[list[str]], None] | None = None,
                    scenario: Scenario | None = None) -> RunResult:
    """``tlfleet supervise``: join the fleet at ``config.connect``, record one run to its end.
    ``scenario``: the file as the caller loaded and checked it (:func:`load_checked`).

    Nothing is written when the scenario is invalid or no router answers."""
    say = report or (lambda text: logger.warning("%s", text))
    note = report or (lambda text: logger.info("%s", text))
    if scenario is None:
        # before connecting; least privilege: the CA and the coordinator's own pair only
        scenario = load_checked(config.scenario_path, config.secure, COORDINATOR_KEYS)
    faults = fault_plan_checked(scenario, config)  # bad faults fail here too
    transport = open_client(client_config(config.connect, secure=config.secure,
                                          lease_ms=config.lease_ms,
                                          zenoh_config=config.zenoh_config),
                            config.connect_timeout)
    try:
        prepared = prepare_run(scenario, config.scenario_path, config.out, mode=config.mode,
                               duration=config.duration, seed=config.seed,
                               endpoint=", ".join(config.connect), secure=config.secure,
                               lease_ms=config.lease_ms)
    except BaseException:
        transport.close()
        raise
    prepared.info["coordinator"] = "supervise"
    outcome = Outcome("error", 0.0)
    left: dict[str, bool] = {}
    codes: dict[str, int | None] = {}
    viewer = None
    if config.viewer:
        from tlfleet.coordinator.report.outputs import start_viewer

        viewer = start_viewer(prepared.scenario, config, say)
    session: Supervision | None = None
    schedule = None
    wall_start = time.monotonic()
    cleanup = Cleanup()
    try:
        session = Supervision(transport, prepared, config=config.supervisor,
                              silence=config.silence, report=report,
                              on_message=None if viewer is None else viewer.on_message)
        if faults:
            schedule = hosts_schedule(faults, config, session, say)
            progress = schedule.progress(progress)
        outcome, codes = session.run(stop, progress, waiting)
        wall_start = session.wall_start
        left = session.wait_gone(config.supervisor.stop_grace)
    except BaseException:
        if viewer is not None:
            Cleanup().step("viewer", viewer.close)
        if prepared.lock is not None:
            prepared.lock.release()
        raise
    finally:
        if schedule is not None:  # every cut restored, every frozen process thawed
            cleanup.step("end the faults", schedule.close)
            prepared.info["faults"] = schedule.log
        if session is not None:
            session.close(cleanup)
        cleanup.step("close the session", transport.close, timeout=config.close_timeout)
        cleanup.step("close the recorder", prepared.recorder.close)
        end_info(prepared, outcome, wall_start, cleanup)
        prepared.info["left_after_stop"] = left
        cleanup.step("write run.json", lambda: prepared.recorder.write_run_info(prepared.info))
    lingering = tuple(name for name, gone in left.items() if not gone)
    findings = session.findings() + (schedule.findings() if schedule is not None else [])
    return finish_run(prepared, config, outcome, codes=codes, final={}, lingering=lingering,
                      findings=findings, viewer=viewer, note=note, say=say)


def fault_plan_checked(scenario: Scenario, config: SuperviseConfig) -> tuple[Fault, ...]:
    """The run's faults (the scenario's and ``config.faults``), checked before connecting; they
    need the fault plan of the launcher that placed the fleet, or in a compose fleet
    the host's executor announced in the handoff directory
    (:mod:`tlfleet.coordinator.faults.handoff`)."""
    from tlfleet.coordinator.faults.plan import run_faults

    faults = run_faults(scenario, config.faults, config.duration)
    if faults and config.fault_handoff is not None:  # a compose fleet: the host injects them
        from tlfleet.coordinator.faults.handoff import check_compose_fault, wait_for_executor

        for fault in faults:
            check_compose_fault(fault)
        wait_for_executor(config.fault_handoff, config.supervisor.ready_timeout)
        return faults
    if faults and config.fault_plan is None:
        raise SuperviseError("faults need a fault plan (--fault-plan, written by `tlfleet run "
                             "--hosts N --fault …`): supervise alone does not know the fleet's "
                             "processes and links (in compose: --fault-handoff DIR)")
    if faults:
        from tlfleet.coordinator.faults.on_hosts import HostsActuator

        actuator = HostsActuator.from_file(config.fault_plan)
        for fault in faults:
            actuator.check(fault)
    return faults


def hosts_schedule(faults: tuple[Fault, ...], config: SuperviseConfig, session: Supervision,
                   say: Say) -> Any:
    from tlfleet.coordinator.faults.schedule import FaultScheduler

    if config.fault_handoff is not None:
        from tlfleet.coordinator.faults.handoff import ComposeActuator

        actuator: Any = ComposeActuator(config.fault_handoff, session.supervisor)
    else:
        from tlfleet.coordinator.faults.on_hosts import HostsActuator

        assert config.fault_plan is not None
        actuator = HostsActuator.from_file(config.fault_plan, session.supervisor)
        # the plan's pids (a restart updates them): a process whose token is gone while its
        # pid runs is unreachable, not dead
        for name in actuator.pids:
            if name == "sim" or name.startswith("agent-"):
                session.supervisor.probes[name] = \
                    lambda name=name: group_alive(actuator.pids[name])  # zombies are gone
    return FaultScheduler(faults, actuator, session.prepared.recorder.on_event, say)
