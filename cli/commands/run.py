"""``tlfleet run SCENARIO [--lockstep|--realtime] [--out DIR] [--duration S] [--seed N] [--viewer]``
(and ``--quiet``, ``--no-report``, ``--no-figures``, ``--no-rrd``, ``--secure DIR``).

Validates the scenario (an invalid file exits 1 before any process starts), launches router → sim
→ agents, supervises and records the run (:mod:`tlfleet.coordinator.run`), shows a progress bar in
sim time on stderr when it is a terminal. At the end the run directory gets ``summary.txt``,
``report.md``/``report.json`` with the PNG figures (:mod:`tlfleet.coordinator.report.run_report`)
and ``run.rrd`` (rerun); the command prints the report table, the paths of the report, figures and
``run.rrd``, and the run directory last. ``--viewer`` also serves the run live to a web viewer on
127.0.0.1 (its URL is printed on stderr) and keeps serving after the run until Ctrl-C.

Exit codes (the run's verdict, :mod:`tlfleet.coordinator.live.verdict`, printed last as ``outcome:
…``): 0 clean; 1 invalid scenario or launch failure; 3 failed (a process died, the router was lost,
a process did not stop cleanly, or the run ended early); 4 degraded (it ran to the end, but with
missed deadlines, watchdog stops, stale commands, malformed input, flagged events, silent or
recovered agents: listed); 130 interrupted (a message says so). The line before it is the task
tally (:mod:`tlfleet.coordinator.report.task_tally`); with ``--require-tasks``, 5 instead of 0 or 4
when a task was not met.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.signals import stop_on_signals, wait_for_signal
from tlfleet.cli.arg_types import fault_spec, positive_float, scenario_file
from tlfleet.cli.conventions import add_json_argument, add_out_argument
from tlfleet.cli.run_flags import add_mode_arguments, add_output_arguments
from tlfleet.cli.transport_flags import (
    add_lease_argument,
    add_secure_argument,
    add_zenoh_config_argument,
)
from tlfleet.coordinator.live.supervisor import SupervisorConfig
from tlfleet.coordinator.run import SCHED_CHOICES, RunConfig, RunResult, run_fleet

if TYPE_CHECKING:
    from tlfleet.agent.model import Scenario
    from tlfleet.coordinator.report.viewer import LiveView

NAME = "run"
HELP = "launch, supervise and record a whole fleet"
BAR_WIDTH = 30
EXAMPLES = (
    ("tlfleet run scenario1",
     "run the bundled Scenario 1 in lockstep; report and figures at the end"),
    ("tlfleet run my.toml --realtime -o runs/try1 --duration 30",
     "30 s of my.toml on wall-clock time, recorded in runs/try1"),
    ("tlfleet run scenario2 --json -q", "no progress bar; the result as JSON on stdout"),
    ("tlfleet run my.toml --hardware lab.toml",
     "real robots on ROS 2 (docs/hardware.md): `tlfleet hw` in the simulator's place, realtime"),
)
EXIT_CODES = {
    0: "clean: the run reached its end and every check passed",
    1: "invalid scenario or a launch failure (nothing ran)",
    3: "failed: a process died, the router was lost, a process did not stop cleanly, or the run "
       "ended early",
    4: "degraded: it ran to the end, with missed deadlines, watchdog stops, stale commands, "
       "malformed input or flagged events (listed)",
    5: "with --require-tasks: the fleet ran (clean or degraded) but a task was not met (the "
       "'tasks:' line names each)",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=scenario_file,
                        help="scenario TOML file or a bundled scenario's name")
    add_mode_arguments(parser)
    add_out_argument(parser, "run directory (default runs/<scenario>-<YYYYmmdd-HHMMSS>)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="sim time to run [s] (default: the scenario's duration)")
    parser.add_argument("--seed", type=int, default=None, help="simulator seed")
    parser.add_argument("--tick-timeout", type=float, default=None, metavar="S",
                        help="lockstep: wall time the sim waits for a due command [s]")
    parser.add_argument("--max-speed", type=positive_float, default=None, metavar="FACTOR",
                        help="lockstep: sim time runs at most FACTOR × wall-clock time (1: watch "
                             "the run live; default: as fast as the agents answer; the trajectory "
                             "is the same either way)")
    parser.add_argument("--ready-timeout", type=float, default=60.0, metavar="S",
                        help="wall time for every process to come up [s] (default 60)")
    parser.add_argument("--wall-timeout", type=float, default=None, metavar="S",
                        help="wall-clock safety limit of the run [s] (default 3·duration + 60)")
    add_lease_argument(parser, "every process's")
    parser.add_argument("--viewer", action="store_true",
                        help="serve the run live to a web viewer (URL on stderr); after the run, "
                             "keep serving until Ctrl-C")
    parser.add_argument("--grpc-port", type=int, default=0, metavar="PORT",
                        help="--viewer: gRPC port on 127.0.0.1 (default: a free one)")
    parser.add_argument("--web-port", type=int, default=0, metavar="PORT",
                        help="--viewer: web viewer port (default: a free one)")
    add_secure_argument(parser, "and the router's access control; without it the links are "
                                "plain TCP on 127.0.0.1")
    add_output_arguments(parser)
    add_json_argument(parser, "print the result (verdict, run directory, report) as JSON on "
                              "stdout instead of the report table")
    add_zenoh_config_argument(parser)
    parser.add_argument("--fault", dest="faults", type=fault_spec, action="append", default=[],
                        metavar="SPEC",
                        help="inject a fault (repeatable): cut:TARGET@T+D, partition:A,B@T+D, "
                             "freeze:TARGET@T+D, kill:TARGET@T, restart:TARGET@T; TARGET robot<N>, "
                             "sim, router or host<i>; T sim time [s], D wall time [s]; link cuts "
                             "run on namespace hosts (root) — README \"Faults\"")
    parser.add_argument("--hosts", type=int, default=0, metavar="N",
                        help="run across N network-namespace hosts, one zenoh router each, "
                             "routers connected (root only); secured by default with keys "
                             "made for the run (or --secure DIR)")
    parser.add_argument("--via-router", dest="direct_links", action="store_false",
                        help="send frames and commands through the router too (by default an "
                             "unsecured run links the sim and the agents as zenoh peers; "
                             "architecture.md §1)")
    parser.add_argument("--sched", choices=SCHED_CHOICES, default="auto",
                        help="OS scheduling of the router, sim and agents: 'fifo' (Linux "
                             "SCHED_FIFO priority 1) where this user may (root or "
                             "RLIMIT_RTPRIO), else 'batch' (SCHED_BATCH, no preemption on "
                             "wake-up) in lockstep and the OS default in realtime (auto, the "
                             "default); or one of them for both; --hosts runs keep their own")
    parser.add_argument("--insecure", action="store_true",
                        help="with --hosts: plain TCP links, no authentication, no access control")
    parser.add_argument("--mcap", action="store_true",
                        help="also write run.mcap at the end: the run in ROS 2 messages for "
                             "Foxglove and ros2 bag (tlfleet export-mcap; the tlfleet[ros2] extra)")
    parser.add_argument("--hardware", type=Path, default=None, metavar="LAB.toml",
                        help="real robots on ROS 2: start `tlfleet hw --lab LAB.toml` in the "
                             "simulator's place (realtime only; docs/hardware.md)")
    parser.set_defaults(mode=None)  # lockstep, or realtime with --hardware
    add_require_tasks_argument(parser)


def add_require_tasks_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--require-tasks", action="store_true",
                        help="exit 5 when the fleet ran (clean or degraded) but a task was not "
                             "met: the tally's line 'tasks: N of M met; …' names them")


class ProgressBar:
    """``\r[#####     ] 45.0/90.0 s  14.2x  ETA 0:03`` on a terminal: sim time, the speed (sim
    seconds per wall second, over the last :data:`RATE_WINDOW` seconds of wall time) and the wall
    time left at that speed. Redrawn at most every 0.1 s of sim time or 0.5 s of wall time."""

    RATE_WINDOW = 3.0  # [s] wall: long enough to smooth a tick's jitter, short to follow a change

    def __init__(self, stream: TextIO, width: int = BAR_WIDTH,
                 clock: Callable[[], float] = time.monotonic):
        self.stream = stream
        self.width = width
        self.clock = clock
        self._last = -1.0
        self._last_wall = -math.inf
        self._samples: deque[tuple[float, float]] = deque()  # (wall [s], sim time [s])
        self.drawn = False

    def rate(self) -> float | None:
        """Sim seconds per wall second over the window; None until there are two samples."""
        if len(self._samples) < 2:
            return None
        (w0, t0), (w1, t1) = self._samples[0], self._samples[-1]
        return (t1 - t0) / (w1 - w0) if w1 > w0 else None

    def __call__(self, t: float, duration: float) -> None:
        now = self.clock()
        if self.drawn and abs(t - self._last) < 0.1 and now - self._last_wall < 0.5:
            return
        self._samples.append((now, t))
        while len(self._samples) > 2 and now - self._samples[1][0] >= self.RATE_WINDOW:
            self._samples.popleft()
        self._last, self._last_wall = t, now
        self.stream.write("\r" + self.line(t, duration) + "\x1b[K")
        self.stream.flush()
        self.drawn = True

    def line(self, t: float, duration: float) -> str:
        filled = int(self.width * min(max(t / duration, 0.0), 1.0)) if duration > 0 else 0
        text = f"[{'#' * filled}{' ' * (self.width - filled)}] {t:.1f}/{duration:.1f} s"
        rate = self.rate()
        if rate is not None and rate > 0:
            left = max(duration - t, 0.0) / rate
            text += f"  {rate:.1f}x  ETA {int(left // 60)}:{int(left % 60):02d}"
        return text

    def end(self) -> None:
        if self.drawn:
            self.stream.write("\n")
            self.stream.flush()


def _linger(viewer: LiveView, interrupted: bool) -> None:
    """Keep the live viewer serving the finished run until Ctrl-C / SIGTERM (not after an
    interrupted run: that Ctrl-C already meant "stop")."""
    if interrupted:
        viewer.close()
        return
    with stop_on_signals() as stop:
        try:
            print(f"tlfleet run: viewer still serving at {viewer.url} until Ctrl-C",
                  file=sys.stderr, flush=True)
            wait_for_signal(stop)
        finally:
            viewer.close()


def result_json(result: RunResult) -> dict:
    """``--json``: what :func:`print_outputs` prints, as data: the verdict, the run directory, the
    files written and the report (as ``report.json`` holds it), or the summary (as
    ``summary.json``) without a report."""
    from tlfleet.coordinator.record.rundir import json_ready
    from tlfleet.coordinator.record.typed_json import to_json

    record = result.report if result.report is not None else result.summary
    return {
        "verdict": result.verdict.to_json(),
        "tasks": None if result.tasks is None else result.tasks.to_json(),
        "end": {"reason": result.outcome.reason, "t_end": result.outcome.t_end},
        "run_dir": str(result.run_dir),
        "report": str(result.run_dir / "report.json") if result.report is not None else None,
        "figures": ([str(p) for p in result.report.figure_paths] if result.report is not None
                    else []),
        "rrd": None if result.rrd is None else str(result.rrd),
        "exit_codes": result.exit_codes,
        "data": None if record is None else json_ready(to_json(record)),
    }


def _write_mcap(run_dir: Path, report) -> None:
    """``--mcap``: run.mcap beside the report; a failure is reported, never fails the run."""
    try:
        from tlfleet.coordinator.report.mcap_export import export_mcap

        report(f"wrote {export_mcap(run_dir)}")
    except (ImportError, TlfleetError, OSError) as exc:
        report(f"run.mcap not written: {exc}")


def print_outputs(result: RunResult, as_json: bool = False) -> None:
    """The report table (the summary if no report was written), the files a person opens next and
    the run directory, then the last two lines: the task tally (``tasks: 5 of 7 met; …``) and the
    verdict (``outcome: …``); with ``as_json`` one JSON document (:func:`result_json`) instead."""
    if as_json:
        print(json.dumps(result_json(result), indent=2, default=str), flush=True)
        return
    if result.report is not None:
        from tlfleet.coordinator.report.render import render_table

        print(render_table(result.report))
        print(f"report:  {result.run_dir / 'report.md'}  (and report.json)")
        for path in result.report.figure_paths:
            print(f"figure:  {path}")
    else:
        print(result.summary_text)
        print(f"summary: {result.run_dir / 'summary.txt'}")
    if result.rrd is not None:
        print(f"rerun:   {result.rrd}  (open with `rerun {result.rrd}`, or headless: "
              f"`tlfleet replay {result.run_dir} --viewer` prints a web viewer's URL)")
    print(f"run directory: {result.run_dir}")
    if result.tasks is not None:
        print(result.tasks.line)
    print(result.verdict.line, flush=True)


def run_hosts(args: argparse.Namespace, scenario: Scenario) -> int:
    """``--hosts N``: launch on N namespace hosts, then ``tlfleet supervise`` on host 0 (it
    prints the report and the run directory); ``scenario``: the file, loaded and checked."""
    from tlfleet.coordinator.run_hosts import run_on_hosts

    extra = ["--quiet"] if args.quiet else []
    for flag, value in (("--duration", args.duration), ("--seed", args.seed),
                        ("--wait", args.ready_timeout), ("--wall-timeout", args.wall_timeout)):
        if value is not None:
            extra += [flag, repr(value)]
    extra += [] if args.report else ["--no-report"]
    extra += [] if args.figures else ["--no-figures"]
    extra += [] if args.rrd else ["--no-rrd"]
    extra += ["--require-tasks"] if args.require_tasks else []
    sim = [] if args.seed is None else ["--seed", str(args.seed)]
    sim += [] if args.duration is None else ["--duration", repr(args.duration)]
    sim += [] if args.tick_timeout is None else ["--tick-timeout", repr(args.tick_timeout)]
    sim += [] if args.max_speed is None else ["--max-speed", repr(args.max_speed)]
    with stop_on_signals() as stop:  # SIGINT / SIGTERM: interrupted, every host cleaned up
        result = run_on_hosts(Path(args.scenario), args.hosts, out=args.out, mode=args.mode,
                              secure=args.secure, insecure=args.insecure,
                              supervise_args=extra, sim_args=sim, lease_ms=args.lease_ms,
                              faults=tuple(args.faults), stop=stop, scenario=scenario)
    return result.returncode


def run(args: argparse.Namespace) -> int:
    if args.hardware is not None:
        if args.mode == "lockstep":
            print("tlfleet run: --hardware runs in realtime only: real robots do not wait for a "
                  "lockstep tick (drop --lockstep)", file=sys.stderr)
            return 2
        if args.hosts or args.faults:
            print("tlfleet run: --hardware cannot be combined with --hosts or --fault (they act "
                  "on the simulator's processes and links)", file=sys.stderr)
            return 2
    args.mode = args.mode or ("realtime" if args.hardware is not None else "lockstep")
    from tlfleet.coordinator.supervise import load_checked

    # the one load of the file in this process: checked here (exit 1 before anything starts),
    # then passed down to the fault plan, the launcher (local or on namespace hosts) and the
    # report
    scenario = load_checked(Path(args.scenario), args.secure)
    if not args.hosts:
        from tlfleet.coordinator.faults.plan import hosts_for

        args.hosts = hosts_for(scenario, args.faults, args.duration)
        if args.hosts:
            print(f"tlfleet run: link faults: running on {args.hosts} namespace host(s) "
                  "(tlfleet.coordinator.launch.netns_hosts)", file=sys.stderr, flush=True)
    if args.hosts:
        return run_hosts(args, scenario)
    duration = args.duration
    wall_timeout = args.wall_timeout
    if wall_timeout is None:
        sim_time = duration or scenario.duration
        paced = sim_time / args.max_speed if args.max_speed else 0.0  # [s] wall, at least
        wall_timeout = 3.0 * sim_time + paced + 60.0
    config = RunConfig(
        scenario_path=Path(args.scenario), mode=args.mode, out=args.out, duration=duration,
        seed=args.seed, tick_timeout=args.tick_timeout,
        supervisor=SupervisorConfig(ready_timeout=args.ready_timeout, wall_timeout=wall_timeout),
        report=args.report, figures=args.figures, figure_format=args.figure_format,
        rrd=args.rrd, viewer=args.viewer,
        grpc_port=args.grpc_port, web_port=args.web_port, secure=args.secure,
        lease_ms=args.lease_ms, zenoh_config=args.zenoh_config, faults=tuple(args.faults),
        direct_links=args.direct_links, sched=args.sched, hardware=args.hardware,
        sim_args=() if args.max_speed is None else ("--max-speed", repr(args.max_speed)))
    bar = ProgressBar(sys.stderr) if not args.quiet and sys.stderr.isatty() else None

    def report(text: str) -> None:
        if bar is not None and bar.drawn:
            sys.stderr.write("\n")
            bar.drawn = False
        print(f"tlfleet run: {text}", file=sys.stderr, flush=True)

    if args.secure is None:
        report("links are plain TCP on 127.0.0.1, unauthenticated (use --secure DIR from "
               "`tlfleet keys` for mutual TLS and access control)")
    with stop_on_signals() as stop:
        try:
            result = run_fleet(config, stop=stop, progress=bar, report=report,
                               scenario=scenario)
        finally:
            if bar is not None:
                bar.end()
    if args.mcap:
        _write_mcap(result.run_dir, report)
    print_outputs(result, as_json=args.json)
    verdict = result.verdict
    if result.viewer is not None:
        _linger(result.viewer, interrupted=verdict.label == "interrupted")
    if verdict.label == "interrupted":
        print(f"tlfleet run: the run was interrupted at t = {result.outcome.t_end:.2f} s; the "
              f"run directory holds what was recorded until then", file=sys.stderr, flush=True)
    elif verdict.label != "clean":
        print(f"tlfleet run: {verdict.label} (end: {result.outcome.reason}, exit codes: "
              f"{result.exit_codes})", file=sys.stderr)
    return result.exit_code(args.require_tasks)
