"""The coordinator without the launcher: supervise and record a fleet (issue 12 §1).

``tlfleet supervise`` is this module, joining a fleet whose router, simulator and agents were
started elsewhere (by hand, on other machines, as compose services). ``tlfleet run``
(:mod:`coordinator.runner`) still has its own launch-and-supervise path, which carries the
hardening of issue 11 (guarded clean-up, health, verdicts) and the keys of ``--secure``; folding
the two into one is left open:

1. :func:`prepare_run` — load the scenario (``ScenarioError`` first), create the run directory,
   copy the scenario, write the first ``run.json``;
2. :class:`Supervision` — over an open client session: declare ``alive/coordinator/0``, subscribe
   the recorder tap, wait for the liveliness token of every process the scenario needs (saying
   which ones are still missing, every ``waiting_period``), send ``Control(start)``, supervise
   until the end of the mission and send ``Control(stop)`` (:mod:`coordinator.supervisor`);
3. :func:`write_outputs` — ``summary.txt``, ``report.md``/``report.json`` with the figures and
   ``run.rrd``; a failure of the report or of ``run.rrd`` is reported and never fails the run.

:func:`supervise_fleet` strings the three together for a fleet reached at an endpoint. A client
session to an endpoint with no router fails within ``connect_timeout`` (default 1 s) with a
:class:`SuperviseError` that names the endpoint.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from agent.errors import TlfleetError
from agent.protocol import keys
from agent.scenario import Scenario, load_scenario
from bus.transport import Transport, TransportConfig, open_transport
from bus.zenoh_config import clean_reason
from coordinator.recorder import Recorder, RecorderTap
from coordinator.rundir import RunFiles, default_run_dir, read_run
from coordinator.summary import write_summary
from coordinator.supervisor import ChildLike, Outcome, Supervisor, SupervisorConfig

logger = logging.getLogger(__name__)

Say = Callable[[str], None]
CLEAN_ENDS = ("sim_done", "duration")


class SuperviseError(TlfleetError, RuntimeError):
    """The coordinator cannot join the fleet (no router at the endpoint, …)."""


class OutputSettings(Protocol):
    """What :func:`write_outputs` and the live viewer read from a run's configuration (both
    :class:`coordinator.runner.RunConfig` and :class:`SuperviseConfig` have these fields)."""

    report: bool
    figures: bool
    rrd: bool
    rrd_every: int
    grpc_port: int
    web_port: int


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
    report: bool = True
    figures: bool = True
    rrd: bool = True
    rrd_every: int = 5
    viewer: bool = False
    grpc_port: int = 0
    web_port: int = 0


@dataclass
class PreparedRun:
    scenario: Scenario
    run_dir: Path
    recorder: Recorder
    info: dict[str, Any]
    duration: float  # [s] sim time


def prepare_run(scenario_path: Path, out: Path | None, *, mode: str, duration: float | None,
                seed: int | None, endpoint: str, out_prefix: str = "") -> PreparedRun:
    """Steps 1: the loaded scenario and a fresh run directory with ``scenario.toml`` and the first
    ``run.json`` (``ScenarioError`` before anything is written)."""
    scenario = load_scenario(scenario_path)
    total = float(duration or scenario.duration)
    run_dir = Path(out) if out else default_run_dir(out_prefix + scenario.name)
    recorder = Recorder(run_dir, [r.id for r in scenario.robots])
    recorder.copy_scenario(Path(scenario_path))
    info: dict[str, Any] = {
        "scenario": scenario.name, "scenario_path": str(scenario_path),
        "mode": mode, "duration": total,
        "seed": scenario.sim.seed if seed is None else seed,
        "endpoint": endpoint, "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    recorder.write_run_info(info)
    return PreparedRun(scenario, run_dir, recorder, info, total)


class Supervision:
    """Step 2 over an open transport: the coordinator's token, the recorder tap, the supervisor.

    ``children`` are the processes this coordinator started itself (none for ``supervise``);
    more can be added to :attr:`supervisor` ``.children`` before :meth:`run`.
    """

    def __init__(self, transport: Transport, prepared: PreparedRun, *,
                 config: SupervisorConfig, children: Mapping[str, ChildLike] | None = None,
                 report: Say | None = None, on_message: Callable[..., Any] | None = None):
        self.prepared = prepared
        scenario = prepared.scenario
        self._token = transport.declare_alive(keys.alive(scenario.fleet, "coordinator", 0))
        self.tap = RecorderTap(transport, scenario.fleet, prepared.recorder,
                               on_message=on_message)
        self.supervisor = Supervisor(transport, scenario, self.tap, dict(children or {}),
                                     duration=prepared.duration, config=config, report=report)
        self.wall_start = time.monotonic()

    def run(self, stop: threading.Event | None = None,
            progress: Callable[[float, float], None] | None = None,
            waiting: Callable[[list[str]], None] | None = None) -> tuple[Outcome, dict]:
        """Wait for the fleet, start, supervise to the end, stop → (outcome, exit codes of the
        children after ``Control(stop)``). ``info`` of the prepared run gets ``ready_time`` and
        ``wall_time``."""
        info, supervisor = self.prepared.info, self.supervisor
        info["ready_time"] = supervisor.wait_ready(stop, waiting=waiting)
        supervisor.start()
        self.wall_start = time.monotonic()
        try:
            outcome = supervisor.supervise(stop, progress)
        except KeyboardInterrupt:
            outcome = Outcome("interrupted", supervisor.sim_time, list(supervisor.deaths.values()))
        info["wall_time"] = time.monotonic() - self.wall_start
        return outcome, supervisor.finish()

    def close(self) -> None:
        """Drain and close the tap (its malformed counts go to ``info``), close the supervisor."""
        self.tap.drain()
        self.tap.close()
        self.prepared.info["malformed_received"] = dict(self.tap.malformed)
        self.supervisor.close()
        self._token.close()


def end_info(prepared: PreparedRun, outcome: Outcome, wall_start: float) -> None:
    """The closing fields of ``run.json`` common to ``run`` and ``supervise``."""
    info = prepared.info
    info.update(reason=outcome.reason, t_end=outcome.t_end,
                frames=prepared.recorder.frames_written)
    info.setdefault("wall_time", time.monotonic() - wall_start)
    if info["wall_time"] > 0:
        info["speedup"] = outcome.t_end / info["wall_time"]


def start_viewer(scenario: Scenario, config: OutputSettings, say: Say) -> Any:
    """A serving LiveView, or None (reported) when it cannot start: the run goes on without."""
    try:
        from coordinator.launcher import free_port
        from coordinator.visual import HOST as VIEW_HOST
        from coordinator.visual import LiveView

        view = LiveView.serve(scenario, grpc_port=config.grpc_port or free_port(VIEW_HOST),
                              web_port=config.web_port or free_port(VIEW_HOST))
    except Exception as exc:  # rerun missing, port taken…: never a reason to fail the run
        say(f"no live viewer ({type(exc).__name__}: {exc})")
        return None
    say(f"viewer: {view.url}")
    return view


def write_report(files: RunFiles, summary: dict[str, Any], figures: bool,
                 say: Say) -> tuple[Any, str]:
    """report.md/json (+ figures); failures are reported, never raised → (Report, error)."""
    try:
        from coordinator.report import write_report as write

        return write(files, figures=figures, summary=summary), ""
    except Exception as exc:
        say(f"report not written ({type(exc).__name__}: {exc})")
        return None, f"{type(exc).__name__}: {exc}"


def write_rrd(files: RunFiles, every: int, say: Say) -> dict[str, Any]:
    """``run.rrd`` from the recorded files; failures are reported, never raised."""
    try:
        from coordinator.visual import replay_run

        result = replay_run(files, every=every)
    except Exception as exc:
        say(f"run.rrd not written ({type(exc).__name__}: {exc})")
        return {"error": f"{type(exc).__name__}: {exc}"}
    return {"path": str(result.path), "seconds": round(result.seconds, 3),
            "frames": result.frames}


@dataclass
class Outputs:
    summary_text: str
    summary: dict[str, Any]
    report: Any  # coordinator.report.Report, when written
    rrd: Path | None


def write_outputs(prepared: PreparedRun, config: OutputSettings, say: Say) -> Outputs:
    """Step 3, after the recorder is closed and ``run.json`` holds the end of the run: the run
    directory is read once (:func:`coordinator.rundir.read_run`) for the summary, the report and
    ``run.rrd``."""
    run_dir, recorder, info = prepared.run_dir, prepared.recorder, prepared.info
    files = read_run(run_dir, scenario=prepared.scenario)
    text, data = write_summary(files)
    report_result = None
    if config.report:
        report_result, error = write_report(files, data, config.figures, say)
        info["report"] = {"error": error} if error else {
            "path": str(run_dir / "report.md"),
            "figures": [str(path) for path in report_result.figures]}
        recorder.write_run_info(info)
    rrd_path: Path | None = None
    if config.rrd:
        info["rrd"] = write_rrd(files, config.rrd_every, say)
        rrd_path = Path(info["rrd"]["path"]) if "path" in info["rrd"] else None
        recorder.write_run_info(info)
    return Outputs(text, data, report_result, rrd_path)


def open_client(connect: tuple[str, ...], timeout: float,
                extra: Mapping[str, Any] | None = None,
                zenoh_config: Path | None = None) -> Transport:
    """A client session to the fleet's router; :class:`SuperviseError` naming the endpoints when
    none answers within ``timeout`` [s] (a zenoh client fails at once when no router listens;
    this retries until the deadline, for a router that is still starting)."""
    config = TransportConfig(mode="client", connect=tuple(connect), extra=dict(extra or {}),
                             zenoh_config=zenoh_config)
    deadline = time.monotonic() + timeout
    while True:
        try:
            return open_transport(config)
        except TlfleetError:
            raise  # a bad --zenoh-config: retrying cannot help
        except Exception as exc:  # zenoh raises ZError, not a stable type
            if time.monotonic() > deadline:
                raise SuperviseError(
                    f"no zenoh router answers at {', '.join(connect)} (tried for {timeout:g} s: "
                    f"{clean_reason(str(exc))}); start one with `tlfleet router --listen "
                    f"ENDPOINT` or give the right --connect") from exc
            time.sleep(0.1)


@dataclass
class SuperviseResult:
    run_dir: Path
    outcome: Outcome
    clean: bool
    left: dict[str, bool]  # process -> its token was gone within stop_grace after Control(stop)
    summary_text: str = ""
    summary: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    report: Any = None
    rrd: Path | None = None
    viewer: Any = None


def _wait_gone(supervisor: Supervisor, grace: float) -> dict[str, bool]:
    """After ``Control(stop)``: wait up to ``grace`` [s] for every process token to disappear."""
    deadline = time.monotonic() + grace
    names = list(supervisor.tokens.values())
    while time.monotonic() < deadline:
        supervisor.check()
        if not any(name in supervisor.alive for name in names):
            break
        time.sleep(0.02)
    return {name: name not in supervisor.alive for name in names}


def supervise_fleet(config: SuperviseConfig, stop: threading.Event | None = None,
                    progress: Callable[[float, float], None] | None = None,
                    report: Say | None = None,
                    waiting: Callable[[list[str]], None] | None = None) -> SuperviseResult:
    """``tlfleet supervise``: join the fleet at ``config.connect``, record one run to its end."""
    say = report or (lambda text: logger.warning("%s", text))
    load_scenario(config.scenario_path)  # ScenarioError before connecting or writing anything
    transport = open_client(config.connect, config.connect_timeout,
                            zenoh_config=config.zenoh_config)
    try:
        prepared = prepare_run(config.scenario_path, config.out, mode=config.mode,
                               duration=config.duration, seed=config.seed,
                               endpoint=", ".join(config.connect))
    except BaseException:
        transport.close()
        raise
    prepared.info["coordinator"] = "supervise"
    outcome = Outcome("error", 0.0)
    left: dict[str, bool] = {}
    viewer = start_viewer(prepared.scenario, config, say) if config.viewer else None
    session: Supervision | None = None
    wall_start = time.monotonic()
    try:
        session = Supervision(transport, prepared, config=config.supervisor, report=report,
                              on_message=None if viewer is None else viewer.on_message)
        outcome, _ = session.run(stop, progress, waiting)
        wall_start = session.wall_start
        left = _wait_gone(session.supervisor, config.supervisor.stop_grace)
    except BaseException:
        if viewer is not None:
            viewer.close()
        raise
    finally:
        if session is not None:
            session.close()
        transport.close()
        prepared.recorder.close()
        end_info(prepared, outcome, wall_start)
        prepared.info["left_after_stop"] = left
        prepared.recorder.write_run_info(prepared.info)
    clean = outcome.reason in CLEAN_ENDS and not outcome.deaths and all(left.values())
    prepared.info["clean"] = clean
    prepared.recorder.write_run_info(prepared.info)
    outputs = write_outputs(prepared, config, say)
    return SuperviseResult(prepared.run_dir, outcome, clean, left, outputs.summary_text,
                           outputs.summary, prepared.info, outputs.report, outputs.rrd, viewer)
