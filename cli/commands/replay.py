"""``tlfleet replay RUN_DIR [--out FILE.rrd] [--every N] [--viewer]``: re-log a run to rerun.

Reads ``scenario.toml``, ``trajectory.csv``, ``status.csv`` and ``events.jsonl`` of the run
directory (architecture.md §6) and logs them with :mod:`tlfleet.coordinator.report.viewer` to
``--out`` (default
``RUN_DIR/run.rrd``): every N-th trajectory row (and the last), every status and event. With
``--viewer`` the recording is also served (gRPC + web viewer on 127.0.0.1) and the command prints
the viewer's URL and keeps serving until Ctrl-C.

Exit codes: 0 written (with ``--viewer``: served until Ctrl-C or SIGTERM, the normal end);
1 a missing or unreadable input (the one-line message names the file; nothing is written).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tlfleet.bus.errors import TlfleetError

NAME = "replay"
HELP = "re-log a finished run to rerun (run.rrd, --viewer)"
EXAMPLES = (
    ("tlfleet replay runs/scenario1-20250101-120000",
     "write the run's run.rrd again (open it with `rerun`)"),
    ("tlfleet replay runs/scenario1-20250101-120000 --viewer",
     "serve the run to a web viewer; its URL is printed (works over ssh with a port forward)"),
)
EXIT_CODES = {0: "written (with --viewer: served until Ctrl-C or SIGTERM, the normal end)",
              1: "a missing or unreadable input (the message names the file)"}


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be ≥ 1, found {value}")
    return value


def _port(text: str) -> int:
    value = int(text)
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"not a port: {value}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", type=Path, help="run directory written by `tlfleet run`")
    parser.add_argument("-o", "--out", type=Path, default=None, metavar="FILE.rrd",
                        help="recording to write (default RUN_DIR/run.rrd)")
    parser.add_argument("--every", type=_positive, default=5, metavar="N",
                        help="log every N-th trajectory row (default 5: 20 Hz at 100 Hz mocap)")
    parser.add_argument("--viewer", action="store_true",
                        help="also serve the recording to a web viewer until Ctrl-C")
    parser.add_argument("--grpc-port", type=_port, default=0, metavar="PORT",
                        help="--viewer: gRPC port on 127.0.0.1 (default: a free one)")
    parser.add_argument("--web-port", type=_port, default=0, metavar="PORT",
                        help="--viewer: web viewer port (default: a free one)")


def run(args: argparse.Namespace) -> int:
    run_dir: Path = args.run_dir
    if not run_dir.is_dir():
        raise TlfleetError(f"{run_dir}: not a run directory")
    from tlfleet.bus.signals import stop_on_signals, wait_for_signal
    from tlfleet.coordinator.launch.processes import free_port
    from tlfleet.coordinator.report import viewer  # rerun: 0.9 s, paid only here

    if not args.viewer:
        result = viewer.replay_run(run_dir, args.out, every=args.every)
        print(f"{result.path}: {result.frames} frames, {result.statuses} statuses, "
              f"{result.events} events, sim time {result.t_first:g}–{result.t_last:g} s")
        return 0

    data = viewer.load_run(run_dir)  # errors before anything is served or written
    recording = viewer.new_recording()
    out = args.out if args.out is not None else run_dir / "run.rrd"
    with stop_on_signals() as stop:
        try:
            try:
                url = viewer.serve(recording, data.scenario,
                                   args.grpc_port or free_port(viewer.HOST),
                                   args.web_port or free_port(viewer.HOST), save=out)
            except (OSError, RuntimeError) as exc:  # a port taken
                raise TlfleetError(f"cannot serve the viewer: {exc}") from None
            with recording:  # on exit: run.rrd finalised (footer), the gRPC server goes on
                log = viewer.log_run(data, recording, every=args.every)
            print(f"{out}: {log.frames} frames, {len(data.statuses)} statuses, "
                  f"{len(data.events)} events, sim time {log.t_first:g}–{log.t_last:g} s")
            print(f"viewer: {url}", flush=True)
            print("serving until Ctrl-C", file=sys.stderr, flush=True)
            wait_for_signal(stop)
        finally:
            recording.disconnect()
    return 0
