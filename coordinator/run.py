"""One whole run of a fleet: validate, launch, supervise, record, summarise.

:func:`run_fleet` is what ``tlfleet run`` does, importable for tests and benchmarks. It is the
launcher around :mod:`tlfleet.coordinator.supervise`, the code ``tlfleet supervise`` runs alone
(steps 2, 3 and 5–8 below are that module's):

1. load the scenario (``ScenarioError`` before any process starts);
2. create the run directory (:mod:`tlfleet.coordinator.record.recorder`), pick a free loopback
   port; with ``secure`` (a key directory of ``tlfleet keys``) the keys are checked first, every
   link is
   ``tls/`` with mutual authentication, every child gets ``--secure`` and ``run.json`` records
   ``secure`` and the certificates' fingerprints (:mod:`tlfleet.bus.zenoh.security`);
3. start the router, wait until it listens, open the coordinator's own session (a client of the
   router; a peer in a lockstep run over peer links, :func:`peer_links`), declare
   ``alive/coordinator/0`` and subscribe the recorder;
4. start the simulator, then one agent per robot (each its own process group,
   :mod:`tlfleet.coordinator.launch.processes`);
5. wait for every liveliness token, send ``Control(start)``, supervise until the end of the
   mission (:mod:`tlfleet.coordinator.live.supervisor`), send ``Control(stop)``;
6. close the session, stop every process group (SIGTERM, then SIGKILL), close the files and write
   ``summary.txt`` with the verdict (:mod:`tlfleet.coordinator.report.summary`,
   :mod:`tlfleet.coordinator.report.outputs`);
7. write ``report.md``, ``report.json`` and the PNG figures
   (:func:`tlfleet.coordinator.report.run_report.write_report`, the code path of ``tlfleet
   report``); a failure here is reported and never fails the run;
8. write ``run.rrd`` by replaying the recorded files
   (:func:`tlfleet.coordinator.report.viewer.replay_run`, the code path of ``tlfleet replay``).
   Logging after the run keeps rerun off the CPU the agents share while they run; a failure here is
   reported and never fails the run.

With ``viewer`` set, a :class:`tlfleet.coordinator.report.viewer.LiveView` also serves the fleet
live while it runs (gRPC + web viewer on 127.0.0.1, URL reported), fed by the recorder tap on the
loop thread at a decimated rate; it is returned in :attr:`RunResult.viewer` still serving (the
caller closes it). rerun (0.9 s to import) is imported only for 8 and the live view; matplotlib only
for 7.

Whatever happens in 3–5 (error, Ctrl-C), step 6 runs: no child is left behind. Step 6
is exception-safe and bounded in time (:mod:`tlfleet.coordinator.launch.cleanup`); the recorder tap
drops implausible frames and flags events whose claimed identity does not hold
(:mod:`tlfleet.coordinator.record.trust`); silent (frozen/partitioned) agents are noticed
(:mod:`tlfleet.coordinator.live.health`); the run's verdict — clean, degraded, failed or
interrupted, with its exit code (:mod:`tlfleet.coordinator.live.verdict`) — goes into ``run.json``
and ``summary.txt``.
"""

from __future__ import annotations

import logging
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from tlfleet.agent.model import Scenario
from tlfleet.agent.model.faults import Fault
from tlfleet.bus.transport import Transport, TransportConfig
from tlfleet.bus.zenoh.transport import check_config
from tlfleet.coordinator.faults.plan import run_faults
from tlfleet.coordinator.faults.schedule import FaultScheduler, ProcessActuator
from tlfleet.coordinator.launch.cleanup import Cleanup
from tlfleet.coordinator.launch.netns_hosts import RECONNECT
from tlfleet.coordinator.launch.plan import PlanConfig, ProcessSpec, plan_fleet
from tlfleet.coordinator.launch.processes import (
    Child,
    Launcher,
    LaunchError,
    fifo_permitted,
    free_port,
    share_with_children,
    tlfleet_command,
    wait_for_port,
)
from tlfleet.coordinator.live.supervisor import Outcome, SupervisorConfig
from tlfleet.coordinator.report.outputs import start_viewer
from tlfleet.coordinator.supervise import (
    RunResult,
    SuperviseError,
    Supervision,
    client_config,
    end_info,
    finish_run,
    load_checked,
    open_client,
    prepare_run,
)

__all__ = ["SCHED_CHOICES", "HardwareRunError", "RunConfig", "RunResult", "check_hardware",
           "child_sched", "default_child_argv", "fleet_plan", "peer_links", "run_fleet"]

logger = logging.getLogger(__name__)

HOST = "127.0.0.1"
ChildArgv = Callable[[ProcessSpec], list[str]]


@dataclass(frozen=True)
class RunConfig:
    """Everything ``tlfleet run`` needs; ``None`` means "the scenario's value"."""

    scenario_path: Path
    mode: str = "lockstep"  # "lockstep" | "realtime"
    out: Path | None = None
    duration: float | None = None  # [s] sim time
    seed: int | None = None
    tick_timeout: float | None = None  # [s] wall, lockstep wait for a due command
    supervisor: SupervisorConfig = field(default_factory=SupervisorConfig)
    router_timeout: float = 15.0  # [s] wall, for the router to listen
    kill_grace: float = 3.0  # [s] wall, SIGTERM → SIGKILL
    sim_args: tuple[str, ...] = ()  # extra flags for `tlfleet sim`
    agent_args: tuple[str, ...] = ()  # extra flags for every `tlfleet agent`
    child_argv: ChildArgv | None = None  # replaces default_child_argv (tests: stand-ins)
    report: bool = True  # write report.md/json after the run
    figures: bool = True  # ... and the figures
    figure_format: str = "png"  # png | pdf | svg (tlfleet.coordinator.report.figures.FORMATS)
    rrd: bool = True  # write run.rrd after the run
    rrd_every: int = 5  # log every n-th trajectory row to run.rrd
    viewer: bool = False  # serve the run live to a web viewer
    grpc_port: int = 0  # viewer ports on 127.0.0.1 (0: free ones)
    web_port: int = 0
    secure: Path | None = None  # key directory (`tlfleet keys`): mutual TLS + the router's ACL
    lease_ms: int | None = None  # [ms] zenoh link lease of every session (None: zenoh's 10 s)
    silence: float = 2.0  # [s] wall: an agent without status this long is silent (health)
    close_timeout: float = 5.0  # [s] wall: closing the coordinator's session, at most
    zenoh_config: Path | None = None  # JSON5 file merged under tlfleet's own settings, for
    #                                   every process of the run (tlfleet.bus.zenoh.config)
    faults: tuple[Fault, ...] = ()  # --fault specs, after the scenario's [[faults]]
    direct_links: bool = True  # unsecured: sim and agents linked as zenoh peers
    #                            (peer_links; False: every sample through the router)
    sched: str = "auto"  # OS scheduling of the router, sim and agents (child_sched)
    hardware: Path | None = None  # a lab file: `tlfleet hw` drives real robots in the
    #                               simulator's place (realtime only, docs/hardware.md)


class HardwareRunError(LaunchError):
    """A ``--hardware`` run asked for something the real world cannot do."""


def check_hardware(config: RunConfig, scenario: Scenario) -> None:
    """A ``--hardware`` run: realtime only, no injected faults, and a lab file that drives
    exactly the scenario's robots (``ScenarioError`` naming the lab file otherwise)."""
    if config.hardware is None:
        return
    if config.mode != "realtime":
        raise HardwareRunError("--hardware runs in realtime only: real robots do not wait for "
                               "a lockstep tick (drop --lockstep)")
    if config.faults or scenario.faults:
        raise HardwareRunError("--hardware: injected faults ([[faults]], --fault) act on the "
                               "simulator's processes and links, not on real robots")
    from tlfleet.agent.scenario.lab import check_lab, load_lab

    check_lab(load_lab(config.hardware), scenario)


#: what a sim or agent process listens on when it is a peer (peer_links): a free loopback port
PEER_LISTEN = f"tcp/{HOST}:0"


def peer_links(config: RunConfig) -> bool:
    """Whether the sim, the agents and the coordinator of this run are zenoh **peers**
    (architecture.md §1): without ``--secure``, without ``--zenoh-config`` and without
    ``--via-router``, in lockstep and in realtime (``run_fleet`` also turns them off for a run
    with faults). Each then listens on a free loopback port, connects to the router and learns
    the others' locators from it (zenoh's gossip), so frames and commands go sim ↔ agent
    directly instead of through the router (one hop and two wake-ups less per sample), and so
    do the frames, statuses and events the coordinator records and its control
    (:func:`_open_client`). The sim and the agents also run zenoh's minimal runtime
    (``--zenoh-runtime minimal``, :data:`tlfleet.bus.transport.MINIMAL_RUNTIME`: one worker thread
    that receives and sends too; less CPU per sample); the router and the coordinator keep zenoh's
    pools. Realtime Scenario 1 (6 interleaved pairs, docs/performance.md): latency p50
    2.3 → 1.8 ms, the STL robots' p99 on quiet ticks 4.0 → 3.4 ms. A secured run keeps every
    link on the router, where the access-control policy is enforced
    (:mod:`tlfleet.coordinator.security.policy`); a user's zenoh file keeps the topology it
    describes."""
    return config.direct_links and config.secure is None and config.zenoh_config is None


#: ``RunConfig.sched`` values (``tlfleet run --sched``)
SCHED_CHOICES = ("auto", "default", "batch", "fifo")


def child_sched(config: RunConfig) -> str:
    """``--sched`` of the router, the sim and the agents (:mod:`tlfleet.cli.process_flags`):
    ``auto`` is ``fifo`` where this user may ask for it (Linux ``SCHED_FIFO`` priority 1: a process
    runs as soon as it wakes), in either mode: Scenario 1 in lockstep ≈ 1.4× faster; in realtime its
    latency p99 0.81–0.91 against 1.14–1.56 ms and a 30-robot fleet's missed deadlines 0.23–0.40
    against 0.54–8.2 % (docs/performance.md). Without that right, ``batch`` in
    lockstep (``SCHED_BATCH``: no process is preempted when another wakes up; ≈ 4–8 % faster) and
    ``default`` in realtime, where batch made the latency tail worse."""
    if config.sched not in SCHED_CHOICES:
        raise ValueError(f"RunConfig.sched {config.sched!r}: expected one of "
                         f"{', '.join(SCHED_CHOICES)}")
    if config.sched == "auto":
        if fifo_permitted():
            return "fifo"
        return "batch" if config.mode == "lockstep" else "default"
    return config.sched


def fleet_plan(config: RunConfig, scenario: Scenario,
               endpoint: str) -> tuple[ProcessSpec, ...]:
    """The run's processes (:func:`tlfleet.coordinator.launch.plan.plan_fleet`) placed on this
    machine: the router listens on ``endpoint``, the sim and the agents connect to it and, over
    peer links (:func:`peer_links`), also listen on a free loopback port as zenoh peers with
    zenoh's minimal runtime."""
    sched = child_sched(config)
    plan = plan_fleet(scenario, PlanConfig(
        scenario_ref=str(Path(config.scenario_path).resolve()), mode=config.mode,
        duration=float(config.duration or scenario.duration), seed=config.seed,
        tick_timeout=config.tick_timeout, sim_args=config.sim_args,
        agent_args=config.agent_args,
        secure=None if config.secure is None else Path(config.secure).resolve(),
        lease_ms=config.lease_ms or None, zenoh_config=config.zenoh_config,
        sched=None if sched == "default" else sched))
    if config.hardware is not None:  # `tlfleet hw` in the simulator's place
        hw = ("hw", str(Path(config.scenario_path).resolve()), "--lab",
              str(Path(config.hardware).resolve()), "--duration",
              repr(float(config.duration or scenario.duration)))
        plan = tuple(replace(spec, args=hw) if spec.role == "sim" else spec for spec in plan)
    peers = peer_links(config)
    placed = []
    for spec in plan:
        if spec.role == "router":
            placed.append(spec.placed(listen=(endpoint,)))
        elif peers:
            placed.append(spec.placed(connect=(endpoint,), mode="peer", listen=(PEER_LISTEN,),
                                      runtime="minimal"))
        else:
            placed.append(spec.placed(connect=(endpoint,)))
    return tuple(placed)


def default_child_argv(spec: ProcessSpec) -> list[str]:
    """argv of a planned process: ``python -P -m tlfleet.cli`` and its arguments."""
    return tlfleet_command(*spec.argv())


def _open_client(endpoint: str, router: Child, config: RunConfig) -> Transport:
    """The coordinator's session to the router it started; :class:`LaunchError` with the
    router's log when the router dies or does not answer within ``router_timeout``. In a
    peer-link run (:func:`peer_links`) it is a peer too, listening on a free loopback port: the
    frames, statuses and events it records come straight from the sim and the agents instead of
    through the router (the router no longer forwards 100 frames per sim second)."""
    client = client_config((endpoint,), secure=config.secure, lease_ms=config.lease_ms,
                           zenoh_config=config.zenoh_config)
    if peer_links(config):
        client = replace(client, mode="peer", listen=(PEER_LISTEN,))
    try:
        return open_client(client, config.router_timeout,
                           given_up=lambda: router.returncode is not None)
    except SuperviseError as exc:
        raise LaunchError(f"cannot open a client session to the router at {endpoint}: "
                          f"{exc.__cause__}\n{router.log_tail()}") from exc


def _router_clean(code: int | None) -> bool:
    return code in (0, -signal.SIGTERM, 128 + signal.SIGTERM)


#: [s] wall between two supervision steps in lockstep (the recorder drains its channels at each)
LOCKSTEP_POLL_PERIOD = 0.01


def supervisor_config(config: RunConfig) -> SupervisorConfig:
    """The supervision's settings: in lockstep the recorder is drained every
    :data:`LOCKSTEP_POLL_PERIOD` at most. The fleet runs 8-17x faster than real time there, so the
    default 50 ms between drains was 0.4-0.85 s of sim time the record trailed the simulator by
    (bench/recorder_lag_bench.py); 10 ms keeps it to a few tenths at most, for 100 wake-ups a
    second of a process that decodes every frame anyway."""
    if config.mode != "lockstep":
        return config.supervisor
    return replace(config.supervisor,
                   poll_period=min(config.supervisor.poll_period, LOCKSTEP_POLL_PERIOD))


def _checked_before_launch(config: RunConfig, scenario: Scenario) -> tuple[Fault, ...]:
    """What ``config`` asks of ``scenario`` that could fail, checked before anything is
    written or started (``ValueError``, ``FaultSpecError``, ``FaultError``, a lab file or zenoh
    config that does not fit); → the run's faults."""
    child_sched(config)  # ValueError for a bad RunConfig.sched
    check_hardware(config, scenario)
    faults = run_faults(scenario, config.faults, config.duration)
    ProcessActuator.check_all(faults)  # link cuts need namespace hosts (launch.netns_hosts)
    if config.zenoh_config is not None:
        check_config(TransportConfig(mode="client", zenoh_config=config.zenoh_config))
    return faults


def _config_for_faults(config: RunConfig, faults: tuple[Fault, ...], run_dir: Path
                       ) -> RunConfig:
    """``config`` as a run with ``faults`` needs it: router links only (the topology the fault
    plans and their measurements were made for); after a router restart every client (the
    coordinator's too) back within a retry period of the new router, instead of zenoh's
    back-off of up to 4 s (fault-injection notes §5.3), through ``<run>/logs/client.json5``."""
    if config.zenoh_config is None and any(f.kind == "restart" and f.target == "router"
                                           for f in faults):
        conf = run_dir / "logs" / "client.json5"
        conf.parent.mkdir(parents=True, exist_ok=True)
        conf.write_text(f"{{ {RECONNECT} }}\n")
        config = replace(config, zenoh_config=conf)
    if faults:
        config = replace(config, direct_links=False)
    return config


def run_fleet(config: RunConfig, stop: threading.Event | None = None,
              progress: Callable[[float, float], None] | None = None,
              report: Callable[[str], None] | None = None,
              scenario: Scenario | None = None) -> RunResult:
    """Run the fleet of ``config`` to the end; see the module docstring. ``scenario``: the file
    of ``config.scenario_path`` as the caller already loaded and checked it
    (:func:`~tlfleet.coordinator.supervise.load_checked`): ``tlfleet run`` reads and checks it
    once, and the report reuses it."""
    say = report or (lambda text: logger.warning("%s", text))
    note = report or (lambda text: logger.info("%s", text))
    if scenario is None:
        scenario = load_checked(config.scenario_path, config.secure)  # before anything else
    faults = _checked_before_launch(config, scenario)
    endpoint = f"{'tls' if config.secure else 'tcp'}/{HOST}:{free_port(HOST)}"
    prepared = prepare_run(scenario, config.scenario_path, config.out, mode=config.mode,
                           duration=config.duration, seed=config.seed, endpoint=endpoint,
                           secure=config.secure, lease_ms=config.lease_ms)
    info = prepared.info
    config = _config_for_faults(config, faults, prepared.run_dir)
    info["links"] = "peer" if peer_links(config) else "router"
    if config.hardware is not None:
        info["hardware"] = str(Path(config.hardware).resolve())
    argv_of = config.child_argv or default_child_argv
    launcher = Launcher(prepared.run_dir / "logs")
    transport: Transport | None = None
    session: Supervision | None = None
    outcome = Outcome("error", 0.0)
    codes: dict[str, int | None] = {}
    final: dict[str, int | None] = {}
    wall_start = time.monotonic()
    viewer = start_viewer(scenario, config, say) if config.viewer else None
    cleanup = Cleanup()
    schedule: FaultScheduler | None = None
    try:
        plan = {spec.name: spec for spec in fleet_plan(config, scenario, endpoint)}
        router = launcher.start("router", argv_of(plan.pop("router")))
        wait_for_port(HOST, int(endpoint.rsplit(":", 1)[1]), config.router_timeout, router)
        transport = _open_client(endpoint, router, config)
        session = Supervision(transport, prepared, config=supervisor_config(config),
                              silence=config.silence, children={"router": router},
                              report=report,
                              on_message=None if viewer is None else viewer.on_message)
        children = session.supervisor.children
        for name, spec in plan.items():  # the sim, then the agents (ids ascending)
            children[name] = launcher.start(name, argv_of(spec))
        if faults:
            actuator = ProcessActuator(launcher, children, supervisor=session.supervisor)
            schedule = FaultScheduler(faults, actuator, prepared.recorder.on_event, say)
            progress = schedule.progress(progress)
        with share_with_children(child_sched(config), above=config.mode == "lockstep"):
            outcome, codes = session.run(stop, progress)
        wall_start = session.wall_start
    except BaseException:
        if viewer is not None:
            Cleanup().step("viewer", viewer.close)
        if prepared.lock is not None:
            prepared.lock.release()
        raise
    finally:
        if schedule is not None:  # restore every fault before anything is stopped
            cleanup.step("end the faults", schedule.close)
            info["faults"] = schedule.log
        if session is not None:
            session.close(cleanup)
        if transport is not None:
            cleanup.step("close the session", transport.close, timeout=config.close_timeout)
        final = cleanup.step("stop the children", lambda: launcher.stop_all(config.kill_grace)) \
            or {c.name: c.returncode for c in launcher.children}
        info["pids"] = {child.name: child.pid for child in launcher.children}  # = their pgids
        cleanup.step("close the recorder", prepared.recorder.close)
        info.update(exit_codes=final, exit_codes_after_stop=codes)
        end_info(prepared, outcome, wall_start, cleanup)
        cleanup.step("write run.json", lambda: prepared.recorder.write_run_info(info))
    findings = session.findings() if session is not None else []
    findings += schedule.findings() if schedule is not None else []
    return finish_run(prepared, config, outcome, codes=codes, final=final,
                      router_clean=_router_clean(final.get("router")), findings=findings,
                      viewer=viewer, note=note, say=say)
