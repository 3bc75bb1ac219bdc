"""One whole run of a fleet: validate, launch, supervise, record, summarise (issue 5 §4).

:func:`run_fleet` is what ``tlfleet run`` does, importable for tests and benchmarks: launch
(steps 3–4, :mod:`coordinator.launcher`) + the supervise-and-record code that ``tlfleet
supervise`` runs alone (steps 2, 5, 7, 8: :mod:`coordinator.supervise`):

1. load the scenario (``ScenarioError`` before any process starts);
2. create the run directory (:mod:`coordinator.recorder`), pick a free loopback port;
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

Whatever happens in 3–5 (error, Ctrl-C), step 6 runs: no child is left behind.
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
from agent.scenario import Scenario
from bus.transport import Transport, TransportConfig, check_config, open_transport
from coordinator.launcher import (
    Child,
    Launcher,
    LaunchError,
    free_port,
    tlfleet_command,
    wait_for_port,
)
from coordinator.supervise import (
    CLEAN_ENDS,
    Supervision,
    end_info,
    prepare_run,
    start_viewer,
    write_outputs,
    write_report,
    write_rrd,
)
from coordinator.supervisor import Outcome, SupervisorConfig

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


def default_child_argv(role: str, config: RunConfig, scenario: Scenario, robot: int | None,
                       endpoint: str) -> list[str]:
    """argv of the router / sim / agent processes (their CLI shapes are in architecture.md §1)."""
    path = str(Path(config.scenario_path).resolve())
    shared = ("--zenoh-config", str(config.zenoh_config)) if config.zenoh_config else ()
    if role == "router":
        return tlfleet_command("router", "--fleet", scenario.fleet, "--listen", endpoint,
                               *shared)
    if role == "sim":
        argv = ["sim", path, f"--{config.mode}", "--duration",
                repr(float(config.duration or scenario.duration))]
        if config.seed is not None:
            argv += ["--seed", str(config.seed)]
        if config.tick_timeout is not None:
            argv += ["--tick-timeout", repr(float(config.tick_timeout))]
        return tlfleet_command(*argv, *config.sim_args, "--connect", endpoint, *shared)
    return tlfleet_command("agent", path, "--robot", str(robot), *config.agent_args,
                           "--connect", endpoint, *shared)


def _open_client(endpoint: str, router: Child, timeout: float,
                 zenoh_config: Path | None = None) -> Transport:
    deadline = time.monotonic() + timeout
    while True:
        try:
            return open_transport(TransportConfig(mode="client", connect=(endpoint,),
                                                  zenoh_config=zenoh_config))
        except TlfleetError:
            raise  # a bad --zenoh-config: retrying cannot help
        except Exception as exc:  # zenoh raises ZError, not a stable type
            if router.returncode is not None or time.monotonic() > deadline:
                raise LaunchError(f"cannot open a client session to the router at {endpoint}: "
                                  f"{exc}\n{router.log_tail()}") from exc
            time.sleep(0.05)


def _router_clean(code: int | None) -> bool:
    return code in (0, -signal.SIGTERM, 128 + signal.SIGTERM)


# the shared supervise-and-record path (coordinator.supervise), under their historical names
_start_viewer = start_viewer
_write_report = write_report
_write_rrd = write_rrd


def run_fleet(config: RunConfig, stop: threading.Event | None = None,
              progress: Callable[[float, float], None] | None = None,
              report: Callable[[str], None] | None = None) -> RunResult:
    """Run the fleet of ``config`` to the end; see the module docstring."""
    say = report or (lambda text: logger.warning("%s", text))
    if config.zenoh_config is not None:  # a bad file fails here, before anything is written
        check_config(TransportConfig(mode="client", zenoh_config=config.zenoh_config))
    endpoint = f"tcp/{HOST}:{free_port(HOST)}"
    prepared = prepare_run(config.scenario_path, config.out, mode=config.mode,
                           duration=config.duration, seed=config.seed, endpoint=endpoint)
    scenario, run_dir, recorder, info = (prepared.scenario, prepared.run_dir, prepared.recorder,
                                         prepared.info)
    argv_of = config.child_argv or default_child_argv
    launcher = Launcher(run_dir / "logs")
    transport: Transport | None = None
    session: Supervision | None = None
    outcome = Outcome("error", 0.0)
    codes: dict[str, int | None] = {}
    wall_start = time.monotonic()
    viewer = _start_viewer(scenario, config, say) if config.viewer else None
    try:
        router = launcher.start("router", argv_of("router", config, scenario, None, endpoint))
        wait_for_port(HOST, int(endpoint.rsplit(":", 1)[1]), config.router_timeout, router)
        transport = _open_client(endpoint, router, config.router_timeout, config.zenoh_config)
        session = Supervision(transport, prepared, config=config.supervisor,
                              children={"router": router}, report=report,
                              on_message=None if viewer is None else viewer.on_message)
        children = session.supervisor.children
        children["sim"] = launcher.start("sim", argv_of("sim", config, scenario, None, endpoint))
        for robot in sorted(scenario.robots, key=lambda r: r.id):
            name = f"agent-{robot.id}"
            children[name] = launcher.start(
                name, argv_of("agent", config, scenario, robot.id, endpoint))
        outcome, codes = session.run(stop, progress)
        wall_start = session.wall_start
    except BaseException:
        if viewer is not None:
            viewer.close()
        raise
    finally:
        if session is not None:
            session.close()
        if transport is not None:
            transport.close()
        final = launcher.stop_all(config.kill_grace)
        info["pids"] = {child.name: child.pid for child in launcher.children}  # = their pgids
        recorder.close()
        info.update(exit_codes=final, exit_codes_after_stop=codes)
        end_info(prepared, outcome, wall_start)
        recorder.write_run_info(info)
    clean = (outcome.reason in CLEAN_ENDS and not outcome.deaths
             and all(code == 0 for code in codes.values())
             and _router_clean(final.get("router")))
    info["clean"] = clean
    recorder.write_run_info(info)
    outputs = write_outputs(prepared, config, say)
    return RunResult(run_dir, outcome, final, clean, outputs.summary_text, outputs.summary, info,
                     outputs.report, outputs.rrd, viewer)
