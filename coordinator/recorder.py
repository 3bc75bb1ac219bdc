"""The run directory of architecture.md §6, written as the run goes.

Layout under ``runs/<scenario>-<YYYYmmdd-HHMMSS>/`` (or ``--out``)::

    scenario.toml    copy of the scenario file
    run.json         how the run was started (mode, seed, duration, argv) and how it ended
    trajectory.csv   t,x1,y1,th1,x2,y2,th2,… (robot ids ascending), one row per mocap frame
                     after Control(start); readable by agent.stl.monitor.read_trajectory_csv
    status.csv       one row per LtlStatus / StlStatus
    events.jsonl     one JSON object per Event: {"t", "source", "kind", "data"}
    logs/<name>.log  each child's stdout and stderr (written by the launcher)
    summary.txt      the plain-text summary (coordinator.summary), at the end
    run.rrd          the rerun recording (coordinator.visual), at the end

Everything is appended and flushed at least every ``flush_period`` (1 s), so a crash loses at most
the last second. :class:`Recorder` is a plain consumer of decoded messages (no transport);
:class:`RecorderTap` wires it to a transport with callbacks that only queue bytes
(stack-notes.md §0) and decodes in the coordinator's loop. :func:`read_statuses` and
:func:`read_events` turn ``status.csv`` and ``events.jsonl`` back into typed messages (replay).
"""

from __future__ import annotations

import csv
import json
import logging
import math
import queue
import shutil
import time
from collections import Counter
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

from agent.errors import TlfleetError
from agent.protocol import keys
from agent.protocol.bounds import FleetBounds
from agent.protocol.codec import ProtocolError, decode, peek_kind
from agent.protocol.messages import Event, LtlStatus, MocapFrame, StlStatus
from agent.protocol.plausibility import FrameGate, Verdict
from bus.transport import Closeable, Transport

logger = logging.getLogger(__name__)

STATUS_COLUMNS = ("t", "robot", "kind", "subtask", "rho", "rho_max", "lower", "r", "stage", "ce",
                  "c", "follow", "events", "target", "mode", "rounds", "visits", "prefix",
                  "suffix", "buchi_states")


COORDINATOR_SOURCE = "coordinator"  # Event.source of the events the coordinator makes


class RunFileError(TlfleetError, ValueError):
    """A run-directory file that cannot be read back: names the file, the 1-based line (0: the
    whole file) and what is wrong."""

    def __init__(self, file: str | Path, line: int, reason: str):
        self.file, self.line, self.reason = str(file), line, reason
        super().__init__(f"{file}:{line}: {reason}" if line else f"{file}: {reason}")


def default_run_dir(scenario_name: str, root: Path = Path("runs"),
                    now: datetime | None = None) -> Path:
    """``runs/<scenario>-<YYYYmmdd-HHMMSS>`` (UTC); a suffix ``-2``, ``-3``… if it exists.

    Always a direct child of ``root`` (issue 11): a name that would leave it (a path separator,
    ``..``) is refused even if the loader let it through.
    """
    stamp = (now or datetime.now(UTC)).strftime("%Y%m%d-%H%M%S")
    base = root / f"{scenario_name}-{stamp}"
    if ("/" in scenario_name or "\\" in scenario_name or ".." in scenario_name
            or "\0" in scenario_name or base.parent != root):
        raise RunFileError(base, 0, f"scenario name {scenario_name[:40]!r} would put the run "
                                    f"directory outside {root}")
    path, n = base, 1
    while path.exists():
        n += 1
        path = base.with_name(f"{base.name}-{n}")
    return path


def _json_default(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    return str(value)


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (tuple, list)):
        return json.dumps(value, default=_json_default, separators=(",", ":"))
    return "" if value is None else str(value)


class Recorder:
    """Writes ``trajectory.csv``, ``status.csv`` and ``events.jsonl`` of one run.

    ``robot_ids`` fixes the trajectory columns (ascending). Frames are written only after
    :meth:`start` (the mission start), with strictly increasing ``seq``; the newest frame is held
    back until a newer one arrives (the sim's last pre-start frame and tick 0 both carry seq 0,
    the later one wins), then written — so the file's times increase strictly.
    """

    def __init__(self, run_dir: Path, robot_ids: Sequence[int], *,
                 flush_period: float = 1.0, clock: Callable[[], float] = time.monotonic):
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.robot_ids = tuple(sorted(robot_ids))
        self.flush_period = flush_period  # [s] wall
        self._clock = clock
        self._last_flush = clock()
        self._started = False
        self._pending: MocapFrame | None = None
        self._last_written_seq = -1
        self.frames_written = 0
        self.frames_skipped = 0
        self.last_t = 0.0  # [s] sim time of the newest frame seen after start
        self.statuses = 0
        self.events = 0
        self.event_kinds: Counter[str] = Counter()
        self._traj: IO[str] = open(self.run_dir / "trajectory.csv", "w", newline="",  # noqa: SIM115
                                   encoding="utf-8")
        self._traj_csv = csv.writer(self._traj)
        self._traj_csv.writerow(["t"] + [f"{c}{r}" for r in self.robot_ids
                                         for c in ("x", "y", "th")])
        self._status: IO[str] = open(self.run_dir / "status.csv", "w", newline="",  # noqa: SIM115
                                     encoding="utf-8")
        self._status_csv = csv.writer(self._status)
        self._status_csv.writerow(STATUS_COLUMNS)
        self._events: IO[str] = open(self.run_dir / "events.jsonl", "w",  # noqa: SIM115
                                     encoding="utf-8")
        self.flush()

    # ----------------------------------------------------------------- files beside the stream

    def copy_scenario(self, source: Path) -> None:
        shutil.copyfile(source, self.run_dir / "scenario.toml")

    def write_run_info(self, info: dict[str, Any]) -> None:
        """(Re)write ``run.json`` with ``info`` (small, rewritten whole)."""
        path = self.run_dir / "run.json"
        path.write_text(json.dumps(info, indent=2, default=_json_default) + "\n",
                        encoding="utf-8")

    # ----------------------------------------------------------------- stream

    def start(self) -> None:
        """Mission start: frames from now on are trajectory rows."""
        self._started = True

    def on_mocap(self, frame: MocapFrame) -> None:
        if not self._started:
            return
        if self._pending is not None and frame.seq < self._pending.seq:
            self.frames_skipped += 1  # out of order (realtime) or a late pre-start frame
            return
        if self._pending is not None and frame.seq > self._pending.seq:
            self._write_frame(self._pending)
        self._pending = frame
        self.last_t = max(self.last_t, frame.t)
        self._maybe_flush()

    def _write_frame(self, frame: MocapFrame) -> None:
        if frame.seq <= self._last_written_seq:
            self.frames_skipped += 1
            return
        poses = {int(row[0]): row[1:4] for row in frame.poses}
        try:
            values = [float(v) for r in self.robot_ids for v in poses[r]]
        except KeyError as exc:
            logger.warning("mocap frame seq %d lacks robot %s: not recorded", frame.seq, exc)
            self.frames_skipped += 1
            return
        if not all(math.isfinite(v) for v in values) or not math.isfinite(frame.t):
            logger.warning("mocap frame seq %d has a non-finite value: not recorded", frame.seq)
            self.frames_skipped += 1
            return
        self._traj_csv.writerow([repr(float(frame.t))] + [repr(v) for v in values])
        self._last_written_seq = frame.seq
        self.frames_written += 1

    def on_status(self, status: LtlStatus | StlStatus) -> None:
        row: dict[str, Any] = {"t": status.t, "robot": status.robot}
        if isinstance(status, StlStatus):
            row.update(kind="stl", subtask=status.subtask, rho=status.rho,
                       rho_max=status.rho_max, lower=status.lower, r=status.r,
                       stage=status.stage, ce=status.ce, c=status.c, follow=status.follow,
                       events=status.events)
        else:
            row.update(kind="ltl", target=status.target, mode=status.mode, rounds=status.rounds,
                       visits=[list(v) for v in status.visits], prefix=status.prefix,
                       suffix=status.suffix, buchi_states=status.buchi_states)
        self._status_csv.writerow([_cell(row.get(col)) for col in STATUS_COLUMNS])
        self.statuses += 1
        self._maybe_flush()

    def on_event(self, event: Event) -> None:
        record = {"t": event.t, "source": event.source, "kind": event.kind, "data": event.data}
        self._events.write(json.dumps(record, default=_json_default, allow_nan=True) + "\n")
        self.events += 1
        self.event_kinds[event.kind] += 1
        if event.kind in ("process_died", "sim_done"):
            self._events.flush()  # rare and important: on disk at once
        self._maybe_flush()

    # ----------------------------------------------------------------- files

    def _maybe_flush(self) -> None:
        if self._clock() - self._last_flush >= self.flush_period:
            self.flush()

    def flush(self) -> None:
        for handle in (self._traj, self._status, self._events):
            handle.flush()
        self._last_flush = self._clock()

    def close(self) -> None:
        """Write the held-back frame and close every file (idempotent)."""
        if self._traj.closed:
            return
        if self._pending is not None:
            self._write_frame(self._pending)
            self._pending = None
        for handle in (self._traj, self._status, self._events):
            handle.close()


class RecorderTap:
    """Subscribes a :class:`Recorder` to a fleet's mocap, status and event keys.

    Transport callbacks only queue ``(key, payload)``; :meth:`drain` (called from the coordinator's
    loop) decodes and records. Undecodable payloads are counted per key kind in ``malformed`` and
    per (kind, claimed source) in ``malformed_by_source``, logged at most once a second per kind,
    never raised. With ``bounds``/``max_jump`` (issue 11), implausible frames (outside the run,
    the arena, or a sequence jump not confirmed by the next frame: ``FrameGate``) count as
    malformed and are not recorded, so a spoofed frame neither ends the run (t = 10⁹) nor makes the
    recorder drop real rows (a high seq). With ``robot_ids``, events and statuses whose claimed
    identity does not hold (:mod:`coordinator.trust`) are recorded as ``flagged_event`` instead.
    """

    LOG_PERIOD = 1.0  # [s] wall between two log lines of one kind

    def __init__(self, transport: Transport, fleet: str, recorder: Recorder,
                 on_message: Callable[[str, Any], None] | None = None, *,
                 bounds: FleetBounds | None = None, max_jump: int | None = None,
                 robot_ids: Sequence[int] | None = None):
        self.recorder = recorder
        self.fleet = fleet
        self.bounds = bounds
        self.gate = FrameGate(max_jump) if max_jump else None
        self.robot_ids = frozenset(robot_ids) if robot_ids is not None else None
        self.flagged = 0
        self.malformed_by_source: Counter[tuple[str, str]] = Counter()
        self._logged: dict[str, float] = {}
        self.malformed: Counter[str] = Counter()
        self.latest_frame: MocapFrame | None = None
        self._on_message = on_message
        self._queue: queue.SimpleQueue[tuple[str, str, bytes]] = queue.SimpleQueue()
        self._handles: list[Closeable] = []
        for what, key in (("mocap", keys.mocap(fleet)), ("status", keys.all_statuses(fleet)),
                          ("event", keys.event(fleet))):
            self._handles.append(transport.subscribe(key, self._enqueue(what)))

    def _enqueue(self, what: str) -> Callable[[str, bytes], None]:
        put = self._queue.put

        def callback(key: str, payload: bytes) -> None:
            put((what, key, payload))

        return callback

    def drain(self, limit: int | None = None) -> int:
        """Decode and record what has arrived (at most ``limit`` samples); returns the count."""
        n = 0
        while limit is None or n < limit:
            try:
                what, key, payload = self._queue.get_nowait()
            except queue.Empty:
                break
            n += 1
            self._handle(what, key, payload)
        return n

    def _handle(self, what: str, key: str, payload: bytes) -> None:
        try:
            if what == "mocap":
                frame = decode(MocapFrame, payload)
                self._check_frame(frame)
                self.latest_frame = frame
                self.recorder.on_mocap(frame)
                message: Any = frame
            elif what == "status":
                cls = StlStatus if peek_kind(payload) == "StlStatus" else LtlStatus
                message = decode(cls, payload)
                if self.robot_ids is not None:
                    from coordinator.trust import status_problem

                    problem = status_problem(keys.robot_of(key), message)
                    if problem is None and message.robot not in self.robot_ids:
                        problem = f"status of robot {message.robot}, not in this fleet"
                    if problem:
                        raise ProtocolError(f"{type(message).__name__}: implausible: {problem}")
                self.recorder.on_status(message)
            else:
                message = decode(Event, payload)
                if message.source == COORDINATOR_SOURCE:  # ours are recorded when made
                    return
                if self._flag(message):
                    return
                self.recorder.on_event(message)
        except ProtocolError as exc:
            self._count(what, key, payload, exc)
            return
        if self._on_message is not None:
            self._on_message(what, message)

    def _check_frame(self, frame: MocapFrame) -> None:
        problem = self.bounds.frame_problem(frame) if self.bounds is not None else None
        if problem is None and self.gate is not None and self.gate.offer(frame.seq) is \
                Verdict.HELD:
            problem = f"seq {frame.seq} jumps from {self.gate.last}: held until confirmed"
        if problem is not None:
            raise ProtocolError(f"MocapFrame: implausible: {problem}")

    def _flag(self, event: Event) -> bool:
        """Record an event whose claimed identity does not hold as ``flagged_event``."""
        if self.robot_ids is None:
            return False
        from coordinator.trust import FLAGGED, event_problem

        problem = event_problem(event, self.robot_ids)
        if problem is None:
            return False
        self.flagged += 1
        if self._may_log("flagged"):
            logger.warning("flagged event %r from %r: %s (%d so far)", event.kind[:40],
                           event.source[:40], problem, self.flagged)
        self.recorder.on_event(Event(
            t=event.t, source=COORDINATOR_SOURCE, kind=FLAGGED,
            data={"claimed_source": event.source[:80], "claimed_kind": event.kind[:80],
                  "reason": problem}))
        return True

    def _count(self, what: str, key: str, payload: bytes, exc: Exception) -> None:
        if what == "status":
            source = f"agent/{keys.robot_of(key)}"
        elif what == "event":
            source = "?"
        else:
            source = "sim"
        self.malformed[what] += 1
        self.malformed_by_source[(what, source)] += 1
        if self._may_log(what):
            logger.warning("malformed payload on %s (%d of this kind so far): %s", key,
                           self.malformed[what], exc)

    def _may_log(self, what: str) -> bool:
        now = time.monotonic()
        if now - self._logged.get(what, -float("inf")) < self.LOG_PERIOD:
            return False
        self._logged[what] = now
        return True

    def close(self) -> None:
        for handle in self._handles:
            handle.close()
        self._handles.clear()


# --------------------------------------------------------------------------------- reading back

def _read_lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8").splitlines(keepends=True)
    except FileNotFoundError:
        raise RunFileError(path, 0, "missing") from None
    except OSError as exc:
        raise RunFileError(path, 0, f"cannot read: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise RunFileError(path, 0, f"not UTF-8 text: {exc.reason}") from None


def _torn(lines: list[str], index: int) -> bool:
    """The last line without a newline: a write cut short by a crash, skipped when unreadable."""
    return index == len(lines) - 1 and not lines[index].endswith("\n")


def read_events(path: str | Path) -> list[Event]:
    """The events of ``events.jsonl`` as :class:`Event` messages, in file order.

    A line that is not a JSON object with a number ``t``, strings ``source`` and ``kind`` and an
    object ``data`` raises :class:`RunFileError`, except a torn last line (logged and skipped).
    """
    path = Path(path)
    lines = _read_lines(path)
    events: list[Event] = []
    for index, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
            if not isinstance(record, dict):
                raise ValueError("not a JSON object")
            t, source, kind = record.get("t"), record.get("source"), record.get("kind")
            data = record.get("data", {})
            if isinstance(t, bool) or not isinstance(t, (int, float)):
                raise ValueError(f"'t' must be a number, found {t!r}")
            if not isinstance(source, str) or not isinstance(kind, str):
                raise ValueError(f"'source' and 'kind' must be strings, found {source!r}, {kind!r}")
            if not isinstance(data, dict):
                raise ValueError(f"'data' must be an object, found {type(data).__name__}")
        except ValueError as exc:  # json.JSONDecodeError is a ValueError
            if _torn(lines, index):
                logger.warning("%s:%d: torn last line skipped", path, index + 1)
                continue
            raise RunFileError(path, index + 1, str(exc)) from None
        events.append(Event(t=float(t), source=source, kind=kind, data=data))
    return events


def _status_from_row(row: dict[str, str]) -> LtlStatus | StlStatus:
    def number(col: str) -> float:
        cell = row[col]
        return math.nan if cell == "" else float(cell)

    def integer(col: str, default: int = 0) -> int:
        return default if row[col] == "" else int(row[col])

    def json_list(col: str) -> list[Any]:
        value = json.loads(row[col]) if row[col] else []
        if not isinstance(value, list):
            raise ValueError(f"{col} must be a JSON list, found {row[col]!r}")
        return value

    t, robot = float(row["t"]), int(row["robot"])
    if row["kind"] == "stl":
        events = tuple(int(v) for v in json_list("events")) or (0, 0, 0)
        if len(events) != 3:
            raise ValueError(f"events must list 3 counts, found {row['events']!r}")
        return StlStatus(robot=robot, t=t, subtask=integer("subtask"), rho=number("rho"),
                         rho_max=number("rho_max"), lower=number("lower"), r=number("r"),
                         stage=integer("stage"), ce=integer("ce"), c=integer("c"),
                         follow=integer("follow", -1), events=events)  # type: ignore[arg-type]
    if row["kind"] == "ltl":
        visits = tuple((str(name), int(count)) for name, count in json_list("visits"))
        return LtlStatus(robot=robot, t=t, prefix=tuple(str(v) for v in json_list("prefix")),
                         suffix=tuple(str(v) for v in json_list("suffix")),
                         target=row["target"] or None,
                         buchi_states=tuple(int(v) for v in json_list("buchi_states")),
                         visits=visits, rounds=integer("rounds"), mode=row["mode"])
    raise ValueError(f"kind must be 'ltl' or 'stl', found {row['kind']!r}")


def read_statuses(path: str | Path) -> list[LtlStatus | StlStatus]:
    """The rows of ``status.csv`` (header :data:`STATUS_COLUMNS`) as status messages.

    A row that does not convert back raises :class:`RunFileError` naming the line, except a torn
    last row (logged and skipped).
    """
    path = Path(path)
    lines = _read_lines(path)
    if not lines:
        raise RunFileError(path, 1, f"empty: expected the header {','.join(STATUS_COLUMNS)}")
    header = next(csv.reader([lines[0]]))
    missing = [col for col in STATUS_COLUMNS if col not in header]
    if missing:
        raise RunFileError(path, 1, f"header lacks the column(s) {', '.join(missing)}")
    statuses: list[LtlStatus | StlStatus] = []
    for index in range(1, len(lines)):
        if not lines[index].strip():
            continue
        try:
            cells = next(csv.reader([lines[index]]))
            if len(cells) != len(header):
                raise ValueError(f"expected {len(header)} values, found {len(cells)}")
            statuses.append(_status_from_row(dict(zip(header, cells, strict=True))))
        except (ValueError, TypeError) as exc:
            if _torn(lines, index):
                logger.warning("%s:%d: torn last row skipped", path, index + 1)
                continue
            raise RunFileError(path, index + 1, str(exc)) from None
    return statuses
