"""One whole run of a fleet: validate, launch, supervise, record, summarise (issue 5 §4).

:func:`run_fleet` is what ``tlfleet run`` does, importable for tests and benchmarks:

1. load the scenario (``ScenarioError`` before any process starts);
2. create the run directory (:mod:`coordinator.recorder`), pick a free loopback port; with
   ``secure`` (a key directory of ``tlfleet keys``) the keys are checked first, every link is
   ``tls/`` with mutual authentication, every child gets ``--secure`` and ``run.json`` records
   ``secure`` and the certificates' fingerprints (:mod:`bus.security`);
3. start the router, wait until it listens, open the coordinator's own client session, declare
   ``alive/coordinator/0`` and subscribe the recorder;
4. start the simulator, then one agent per robot (each its own process group,
   :mod:`coordinator.launcher`);
5. wait for every liveliness token, send ``Control(start)``, supervise until the end of the
   mission (:mod:`coordinator.supervisor`), send ``Control(stop)``;
6. close the session, stop every process group (SIGTERM, then SIGKILL), close the files and write
   ``summary.txt`` (:mod:`coordinator.summary`);
7. write ``report.md``, ``report.json`` and the PNG figures
   (:func:`coordinator.report.write_report`, the code path of ``tlfleet report``); a failure
   here is reported and never fails the run;
8. write ``run.rrd`` by replaying the recorded files (:func:`coordinator.visual.replay_run`, the
   code path of ``tlfleet replay``). Logging after the run keeps rerun off the CPU the agents
   share while they run; a failure here is reported and never fails the run.

With ``viewer`` set, a :class:`coordinator.visual.LiveView` also serves the fleet live while it
runs (gRPC + web viewer on 127.0.0.1, URL reported), fed by the recorder tap on the loop thread
at a decimated rate; it is returned in :attr:`RunResult.viewer` still serving (the caller closes
it). rerun (0.9 s to import) is imported only for 8 and the live view; matplotlib only for 7.

Whatever happens in 3–5 (error, Ctrl-C), step 6 runs: no child is left behind. Issue 11: step 6
is exception-safe and bounded in time (:mod:`coordinator.cleanup`); the recorder tap drops
implausible frames and flags events whose claimed identity does not hold
(:mod:`coordinator.trust`); silent (frozen/partitioned) agents are noticed
(:mod:`coordinator.health`); the run's verdict — clean, degraded, failed or interrupted, with its
exit code (:mod:`coordinator.outcome`) — goes into ``run.json`` and ``summary.txt``.
"""

from __future__ import annotations

import logging
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agent.errors import TlfleetError
from agent.protocol import keys
from agent.protocol.bounds import FleetBounds
from agent.protocol.plausibility import max_jump_ticks
from agent.scenario import Scenario, load_scenario
from bus.security import fingerprints, secure_transport
from bus.transport import TransportConfig, check_config, open_transport
from bus.zenoh_transport import ZenohTransport
from coordinator import rundir
from coordinator.cleanup import Cleanup
from coordinator.health import Health
from coordinator.launcher import (
    Child,
    Launcher,
    LaunchError,
    free_port,
    tlfleet_command,
    wait_for_port,
)
from coordinator.outcome import Verdict, classify, mission_event_kinds
from coordinator.recorder import Recorder, RecorderTap
from coordinator.rundir import RunFiles, default_run_dir
from coordinator.summary import write_summary
from coordinator.supervisor import Outcome, Supervisor, SupervisorConfig

logger = logging.getLogger(__name__)

HOST = "127.0.0.1"
ChildArgv = Callable[[str, "RunConfig", Scenario, int | None, str], list[str]]


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
    figures: bool = True  # ... and the PNG figures
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
    #                                   every process of the run (bus.zenoh_config)


@dataclass
class RunResult:
    run_dir: Path
    outcome: Outcome
    exit_codes: dict[str, int | None]
    clean: bool
    summary_text: str = ""
    summary: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    report: Any = None  # coordinator.report.Report, when written
    rrd: Path | None = None  # run.rrd, when written
    viewer: Any = None  # coordinator.visual.LiveView, still serving (close() it)
    verdict: Verdict = field(default_factory=lambda: Verdict("failed", ("no verdict",)))


def default_child_argv(role: str, config: RunConfig, scenario: Scenario, robot: int | None,
                       endpoint: str) -> list[str]:
    """argv of the router / sim / agent processes (their CLI shapes are in architecture.md §1)."""
    path = str(Path(config.scenario_path).resolve())
    secure = ("--secure", str(Path(config.secure).resolve())) if config.secure else ()
    lease = ("--lease-ms", str(config.lease_ms)) if config.lease_ms else ()
    lease += ("--zenoh-config", str(config.zenoh_config)) if config.zenoh_config else ()
    if role == "router":
        return tlfleet_command("router", "--fleet", scenario.fleet, "--listen", endpoint,
                               *secure, *lease)
    if role == "sim":
        argv = ["sim", path, f"--{config.mode}", "--duration",
                repr(float(config.duration or scenario.duration))]
        if config.seed is not None:
            argv += ["--seed", str(config.seed)]
        if config.tick_timeout is not None:
            argv += ["--tick-timeout", repr(float(config.tick_timeout))]
        return tlfleet_command(*argv, *config.sim_args, "--connect", endpoint, *secure, *lease)
    return tlfleet_command("agent", path, "--robot", str(robot), *config.agent_args,
                           "--connect", endpoint, *secure, *lease)


def _open_client(endpoint: str, router: Child, timeout: float,
                 secure: Path | None = None, lease_ms: int | None = None,
                 zenoh_config: Path | None = None) -> ZenohTransport:
    deadline = time.monotonic() + timeout
    client = TransportConfig(mode="client", connect=(endpoint,), lease_ms=lease_ms,
                             zenoh_config=zenoh_config)
    if secure is not None:
        client = secure_transport(client, secure, "coordinator")
    while True:
        try:
            return open_transport(client)
        except TlfleetError:
            raise  # a bad --zenoh-config: retrying cannot help
        except Exception as exc:  # zenoh raises ZError, not a stable type
            if router.returncode is not None or time.monotonic() > deadline:
                raise LaunchError(f"cannot open a client session to the router at {endpoint}: "
                                  f"{exc}\n{router.log_tail()}") from exc
            time.sleep(0.05)


def _router_clean(code: int | None) -> bool:
    return code in (0, -signal.SIGTERM, 128 + signal.SIGTERM)


def _start_viewer(scenario: Scenario, config: RunConfig,
                  say: Callable[[str], None]) -> Any:
    """A serving LiveView, or None (reported) when it cannot start: the run goes on without."""
    try:
        from coordinator.visual import HOST as VIEW_HOST
        from coordinator.visual import LiveView

        view = LiveView.serve(scenario, grpc_port=config.grpc_port or free_port(VIEW_HOST),
                        web_port=config.web_port or free_port(VIEW_HOST))
    except Exception as exc:  # rerun missing, port taken…: never a reason to fail the run
        say(f"no live viewer ({type(exc).__name__}: {exc})")
        return None
    say(f"viewer: {view.url}")
    return view


def _write_report(files: rundir.RunFiles, summary: dict[str, Any], figures: bool,
                  say: Callable[[str], None]) -> tuple[Any, str]:
    """Step 7: report.md/json (+ figures); failures are reported, never raised → (Report, error)."""
    try:
        from coordinator.report import write_report

        return write_report(files, figures=figures, summary=summary), ""
    except Exception as exc:
        say(f"report not written ({type(exc).__name__}: {exc})")
        return None, f"{type(exc).__name__}: {exc}"


def _write_rrd(run: rundir.RunFiles | Path, every: int,
               say: Callable[[str], None]) -> dict[str, Any]:
    """Step 8: ``run.rrd`` from the recorded files; failures are reported, never raised."""
    try:
        from coordinator.visual import replay_run

        result = replay_run(run, every=every)
    except Exception as exc:
        say(f"run.rrd not written ({type(exc).__name__}: {exc})")
        return {"error": f"{type(exc).__name__}: {exc}"}
    return {"path": str(result.path), "seconds": round(result.seconds, 3),
            "frames": result.frames}


def write_outputs(run_dir: Path, scenario: Scenario, config: RunConfig, info: dict[str, Any],
                  write_info: Callable[[dict[str, Any]], None], note: Callable[[str], None],
                  say: Callable[[str], None],
                  judge: Callable[[RunFiles, dict[str, Any]], Verdict] | None = None,
                  ) -> tuple[str, dict[str, Any], Any, Path | None, Verdict | None]:
    """Steps 6–8 after the fleet stopped: the run directory is read once
    (:func:`rundir.read_run`) and the summary (computed once), the run's verdict (``judge``),
    the report with its figures and ``run.rrd`` are all made from those files → (summary text,
    summary data, report, rrd path, verdict). ``info`` (run.json) gains the verdict and the
    report's and the recording's paths or errors."""
    files = rundir.read_run(run_dir, scenario=scenario)
    text, data = write_summary(files)
    verdict = None
    if judge is not None:
        verdict = judge(files, data)
        info["outcome"] = verdict.to_json()
        write_info(info)
        text = f"{text}\n{verdict.line}"
        with open(run_dir / rundir.SUMMARY_TEXT, "a", encoding="utf-8") as summary_file:
            summary_file.write(verdict.line + "\n")
    report_result = None
    if config.report:
        report_result, error = _write_report(files, data, config.figures, say)
        info["report"] = {"error": error} if error else {
            "path": str(run_dir / rundir.REPORT_MD),
            "figures": [str(path) for path in report_result.figures]}
        write_info(info)
    rrd_path: Path | None = None
    if config.rrd:
        note(f"writing {run_dir / rundir.RRD} (rerun) …")
        info["rrd"] = _write_rrd(files, config.rrd_every, say)
        rrd_path = Path(info["rrd"]["path"]) if "path" in info["rrd"] else None
        write_info(info)
    return text, data, report_result, rrd_path, verdict


def _tap_checks(scenario: Scenario, duration: float) -> dict[str, Any]:
    """The recorder tap's plausibility checks for this run (issue 11)."""
    a = scenario.arena
    dividers = [scenario.control_divider(r) for r in scenario.robot_ids]
    return {"bounds": FleetBounds((a.xmin, a.xmax, a.ymin, a.ymax), duration,
                                  scenario.sim.mocap_rate, scenario.speed_limits()),
            "max_jump": max_jump_ticks(scenario.sim.mocap_rate, dividers),
            "robot_ids": scenario.robot_ids}


def _verdict(files: RunFiles, info: dict[str, Any], outcome: Outcome, data: dict[str, Any],
             router_clean: bool, codes: dict[str, int | None],
             findings: list[str]) -> Verdict:
    events = [{"t": e.t, "kind": e.kind} for e in files.events]  # read once (lenient)
    return classify(reason=outcome.reason, deaths=[d.process for d in outcome.deaths],
                    exit_codes=codes, router_clean=router_clean, mode=str(info.get("mode")),
                    deadlines=data.get("deadlines") or {},
                    event_kinds=mission_event_kinds(events, outcome.t_end),
                    findings=findings + [f"clean-up: {e}" for e in info.get("cleanup_errors", [])])


def run_fleet(config: RunConfig, stop: threading.Event | None = None,
              progress: Callable[[float, float], None] | None = None,
              report: Callable[[str], None] | None = None) -> RunResult:
    """Run the fleet of ``config`` to the end; see the module docstring."""
    scenario = load_scenario(config.scenario_path)
    if config.secure is not None:  # checked before the run directory exists
        from coordinator.acl import identities
        from coordinator.keys import check_keys  # cryptography: imported for secured runs only

        check_keys(scenario, config.secure)
    say = report or (lambda text: logger.warning("%s", text))
    if config.zenoh_config is not None:  # a bad file fails here, before anything is written
        check_config(TransportConfig(mode="client", zenoh_config=config.zenoh_config))
    duration = float(config.duration or scenario.duration)
    run_dir = Path(config.out) if config.out else default_run_dir(scenario.name)
    recorder = Recorder(run_dir, [r.id for r in scenario.robots])
    recorder.copy_scenario(Path(config.scenario_path))
    endpoint = f"{'tls' if config.secure else 'tcp'}/{HOST}:{free_port(HOST)}"
    info: dict[str, Any] = {
        "scenario": scenario.name, "scenario_path": str(config.scenario_path),
        "mode": config.mode, "duration": duration,
        "seed": scenario.sim.seed if config.seed is None else config.seed,
        "endpoint": endpoint, "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "secure": config.secure is not None,
    }
    if config.secure is not None:
        info["keys"] = str(Path(config.secure).resolve())
        info["fingerprints"] = fingerprints(config.secure, identities(scenario))
    if config.lease_ms:
        info["lease_ms"] = config.lease_ms
    recorder.write_run_info(info)
    argv_of = config.child_argv or default_child_argv
    launcher = Launcher(run_dir / "logs")
    transport: ZenohTransport | None = None
    tap: RecorderTap | None = None
    supervisor: Supervisor | None = None
    outcome = Outcome("error", 0.0)
    codes: dict[str, int | None] = {}
    final: dict[str, int | None] = {}
    wall_start = time.monotonic()
    viewer = _start_viewer(scenario, config, say) if config.viewer else None
    health = Health(scenario.robot_ids, recorder.on_event, say, silence=config.silence)

    def on_message(what: str, message: Any) -> None:
        health.on_message(what, message)
        if viewer is not None:
            viewer.on_message(what, message)

    def step(t: float, d: float) -> None:
        health.poll()
        if progress is not None:
            progress(t, d)

    try:
        router = launcher.start("router", argv_of("router", config, scenario, None, endpoint))
        wait_for_port(HOST, int(endpoint.rsplit(":", 1)[1]), config.router_timeout, router)
        transport = _open_client(endpoint, router, config.router_timeout, config.secure,
                                 config.lease_ms, config.zenoh_config)
        transport.declare_alive(keys.alive(scenario.fleet, "coordinator", 0))
        tap = RecorderTap(transport, scenario.fleet, recorder, on_message=on_message,
                          **_tap_checks(scenario, duration))
        supervisor = Supervisor(transport, scenario, tap, {"router": router}, duration=duration,
                                config=config.supervisor, report=report)
        supervisor.children["sim"] = launcher.start(
            "sim", argv_of("sim", config, scenario, None, endpoint))
        for robot in sorted(scenario.robots, key=lambda r: r.id):
            name = f"agent-{robot.id}"
            supervisor.children[name] = launcher.start(
                name, argv_of("agent", config, scenario, robot.id, endpoint))
        info["ready_time"] = supervisor.wait_ready(stop)
        supervisor.start()
        health.start()
        wall_start = time.monotonic()
        try:
            outcome = supervisor.supervise(stop, step)
        except KeyboardInterrupt:
            outcome = Outcome("interrupted", supervisor.sim_time, list(supervisor.deaths.values()))
        info["wall_time"] = time.monotonic() - wall_start
        codes = supervisor.finish()
    except BaseException:
        if viewer is not None:
            Cleanup().step("viewer", viewer.close)
        raise
    finally:
        cleanup = Cleanup()
        if tap is not None:
            cleanup.step("drain the recorder tap", tap.drain)
            cleanup.step("close the recorder tap", tap.close)
            info["malformed_received"] = dict(tap.malformed)
            info["malformed_received_by_source"] = {
                f"{what} from {source}": n for (what, source), n in tap.malformed_by_source.items()}
            info["flagged_events"] = tap.flagged
        if supervisor is not None:
            cleanup.step("close the supervisor", supervisor.close)
            info["recovered"] = [d.process for d in supervisor.recovered]
        if transport is not None:
            cleanup.step("close the session", transport.close, timeout=config.close_timeout)
        final = cleanup.step("stop the children", lambda: launcher.stop_all(config.kill_grace)) \
            or {c.name: c.returncode for c in launcher.children}
        info["pids"] = {child.name: child.pid for child in launcher.children}  # = their pgids
        cleanup.step("close the recorder", recorder.close)
        info.update(reason=outcome.reason, t_end=outcome.t_end, exit_codes=final,
                    exit_codes_after_stop=codes, frames=recorder.frames_written)
        info.setdefault("wall_time", time.monotonic() - wall_start)
        if info["wall_time"] > 0:
            info["speedup"] = outcome.t_end / info["wall_time"]
        if cleanup.errors:
            info["cleanup_errors"] = cleanup.errors
        cleanup.step("write run.json", lambda: recorder.write_run_info(info))
    router_clean = _router_clean(final.get("router"))
    clean = (outcome.reason in ("sim_done", "duration") and not outcome.deaths
             and all(code == 0 for code in codes.values()) and router_clean)
    info["clean"] = clean
    recorder.write_run_info(info)
    note = report or (lambda text: logger.info("%s", text))
    note(f"writing summary.json{', report.md/json' if config.report else ''}"
         f"{' and figures' if config.report and config.figures else ''} in {run_dir} …")
    text, data, report_result, rrd_path, verdict = write_outputs(
        run_dir, scenario, config, info, recorder.write_run_info, note, say,
        judge=lambda files, summary: _verdict(files, info, outcome, summary, router_clean, codes,
                                              health.findings()))
    return RunResult(run_dir, outcome, final, clean, text, data, info, report_result, rrd_path,
                     viewer, verdict)
