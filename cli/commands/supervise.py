"""``tlfleet supervise SCENARIO --connect ENDPOINT [--out DIR] [--lockstep|--realtime] [--wait S]``:
the coordinator without the launcher (:mod:`tlfleet.coordinator.supervise`).

It joins a fleet whose router, simulator and agents were started elsewhere (by hand, on other
machines, as compose services), prints every second which processes it still waits for (their
liveliness tokens), sends ``start``, records the run directory exactly as ``tlfleet run`` does,
shows the progress bar, writes the report and at the end sends ``stop``. Exit codes as
``tlfleet run``: 0 clean, 1 invalid scenario / no router at the endpoint / a process missing
after ``--wait`` seconds, 3 the run finished but not cleanly, 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tlfleet.bus.signals import stop_on_signals
from tlfleet.cli.arg_types import fault_spec, scenario_file
from tlfleet.cli.commands.run import ProgressBar, add_require_tasks_argument, print_outputs
from tlfleet.cli.conventions import add_json_argument
from tlfleet.cli.run_flags import add_mode_arguments, add_output_arguments
from tlfleet.cli.transport_flags import add_transport_arguments
from tlfleet.coordinator.live.supervisor import SupervisorConfig
from tlfleet.coordinator.supervise import SuperviseConfig, supervise_fleet

NAME = "supervise"
HELP = "join a running fleet: wait for it, start, supervise and record the run"
EXAMPLES = (
    ("tlfleet supervise scenario1.toml --connect tcp/127.0.0.1:7447 -o runs/s1",
     "join the fleet of Scenario 1 started elsewhere, run and record it in runs/s1"),
)
EXIT_CODES = {
    0: "clean: the run reached its end and every check passed",
    1: "invalid scenario, no router at --connect, or a process missing after --wait",
    3: "failed: a process died, the router was lost, a process did not stop cleanly, or the run "
       "ended early",
    4: "degraded: it ran to the end, with missed deadlines, watchdog stops, stale commands, "
       "malformed input or flagged events (listed)",
    5: "with --require-tasks: the fleet ran (clean or degraded) but a task was not met (the "
       "'tasks:' line names each)",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=scenario_file,
                        help="scenario TOML file or a bundled scenario's name (the one the fleet "
                             "was started with)")
    add_mode_arguments(parser, "the simulator runs in lockstep (default; recorded in run.json)",
                       "the simulator runs on wall-clock time")
    parser.add_argument("-o", "--out", type=Path, default=None,
                        help="run directory (default runs/<scenario>-<YYYYmmdd-HHMMSS>)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="sim time after which the run ends [s] (default: the scenario's)")
    parser.add_argument("--seed", type=int, default=None,
                        help="the simulator's seed, for run.json (default: the scenario's)")
    parser.add_argument("--wait", type=float, default=60.0, metavar="S",
                        help="wall time to wait for every process of the scenario [s] "
                             "(default 60)")
    parser.add_argument("--connect-timeout", type=float, default=1.0, metavar="S",
                        help="wall time for a router to answer at --connect [s] (default 1)")
    parser.add_argument("--wall-timeout", type=float, default=None, metavar="S",
                        help="wall-clock safety limit of the run [s] (default 3·duration + 60)")
    add_output_arguments(parser)
    add_json_argument(parser, "print the result (verdict, run directory, report) as JSON on "
                              "stdout instead of the report table")
    add_transport_arguments(parser, connect_default="tcp/127.0.0.1:7447", client_only=True)
    parser.add_argument("--fault", dest="faults", type=fault_spec, action="append", default=[],
                        metavar="SPEC", help="inject a fault (as `tlfleet run --fault`); needs "
                                             "--fault-plan or --fault-handoff")
    parser.add_argument("--fault-plan", type=Path, default=None, metavar="FILE",
                        help="the fleet's namespaces, placement and pids (written by `tlfleet "
                             "run --hosts N --fault …`)")
    parser.add_argument("--fault-handoff", type=Path, default=None, metavar="DIR",
                        help="a compose fleet: hand each fault to the host's executor through "
                             "DIR (`tlfleet compose-faults`, started by docker/compose-run.sh)")
    add_require_tasks_argument(parser)


def run(args: argparse.Namespace) -> int:
    from tlfleet.coordinator.supervise import (  # exit 1 before connecting
        COORDINATOR_KEYS,
        load_checked,
    )

    # the one load of the file; with --secure only the CA and the coordinator's pair needed
    scenario = load_checked(Path(args.scenario), args.secure, COORDINATOR_KEYS)
    duration = args.duration or scenario.duration
    wall_timeout = args.wall_timeout if args.wall_timeout is not None else 3.0 * duration + 60.0
    connect = tuple(args.connect) or ("tcp/127.0.0.1:7447",)
    config = SuperviseConfig(
        scenario_path=Path(args.scenario), connect=connect, mode=args.mode, out=args.out,
        duration=args.duration, seed=args.seed, connect_timeout=args.connect_timeout,
        supervisor=SupervisorConfig(ready_timeout=args.wait, wall_timeout=wall_timeout),
        zenoh_config=args.zenoh_config, secure=args.secure, lease_ms=args.lease_ms,
        report=args.report, figures=args.figures, figure_format=args.figure_format,
        rrd=args.rrd, faults=tuple(args.faults),
        fault_plan=args.fault_plan, fault_handoff=args.fault_handoff)
    bar = ProgressBar(sys.stderr) if not args.quiet and sys.stderr.isatty() else None

    def say(text: str) -> None:
        if bar is not None and bar.drawn:
            sys.stderr.write("\n")
            bar.drawn = False
        print(f"tlfleet supervise: {text}", file=sys.stderr, flush=True)

    def waiting(missing: list[str]) -> None:
        if not args.quiet:
            say(f"waiting for {len(missing)} process(es) on {', '.join(connect)}: "
                f"{', '.join(missing)}")

    with stop_on_signals() as stop:
        try:
            result = supervise_fleet(config, stop=stop, progress=bar, report=say, scenario=scenario,
                                     waiting=waiting)
        finally:
            if bar is not None:
                bar.end()
    print_outputs(result, as_json=args.json)
    verdict = result.verdict
    if verdict.label == "interrupted":
        say(f"the run was interrupted at t = {result.outcome.t_end:.2f} s; the run directory "
            f"holds what was recorded until then")
    elif verdict.label != "clean":
        say(f"{verdict.label} (end: {result.outcome.reason})")
    return result.exit_code(args.require_tasks)
