"""The run directory: the one module that reads and writes its files (docs/run-directory.md).

Layout under ``runs/<scenario>-<YYYYmmdd-HHMMSS>/`` (or ``--out``)::

    scenario.toml    copy of the scenario file
    run.json         how the run was started and how it ended
    trajectory.csv   t,x1,y1,th1,x2,y2,th2,… (robot ids ascending), one row per mocap frame
    status.csv       one row per LtlStatus / StlStatus (columns per robot kind: STATUS_COLUMNS)
    events.jsonl     one JSON object per Event: {"t", "source", "kind", "data"}
    summary.txt, summary.json, report.md, report.json, *.png, run.rrd   written at the end
    logs/<name>.log  each child's stdout and stderr (written by the launcher)

Readers return frozen records and typed messages (``Event``, ``LtlStatus``, ``StlStatus``,
``tlfleet.agent.stl.monitor.Trajectory``); :func:`read_run` is the single entry point that reads
each file of a directory once, for every consumer of one command (summary, report, figures, rerun
replay). It is *lenient* by default — a line that does not convert back is skipped and listed in
``RunFiles.problems`` (a torn last line is what a crash leaves) — or *strict*, raising
:class:`RunFileError` naming the file and line. Writers produce exactly what the readers read. JSON
appears only at the edge (:func:`write_json`): in memory, an empty robustness window is ±inf and a
value not evaluated is None; on disk ±inf becomes ``"inf"``/``"-inf"``.
"""

from __future__ import annotations

import contextlib
import csv
import fcntl
import json
import logging
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from tlfleet.agent.model import Scenario
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.stl.monitor import Trajectory, read_trajectory_csv
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol.events import data_problem
from tlfleet.bus.protocol.messages import Event, LtlStatus, StlStatus

logger = logging.getLogger(__name__)

SCENARIO, RUN_INFO, TRAJECTORY, STATUS, EVENTS = (
    "scenario.toml", "run.json", "trajectory.csv", "status.csv", "events.jsonl")
SUMMARY_TEXT, SUMMARY_JSON, REPORT_MD, REPORT_JSON, RRD = (
    "summary.txt", "summary.json", "report.md", "report.json", "run.rrd")

# status.csv: the common columns, then each kind's own (blank in the other kind's rows)
COMMON_STATUS_COLUMNS = ("t", "robot", "kind")
STL_STATUS_COLUMNS = ("subtask", "rho", "rho_max", "lower", "r", "stage", "ce", "c", "follow",
                      "events")
LTL_STATUS_COLUMNS = ("target", "mode", "rounds", "visits", "prefix", "suffix", "buchi_states")
STATUS_COLUMNS = COMMON_STATUS_COLUMNS + STL_STATUS_COLUMNS + LTL_STATUS_COLUMNS

Status = LtlStatus | StlStatus


class RunFileError(TlfleetError, ValueError):
    """A file of a run directory that cannot be read back: names the file, the line and why."""

    def __init__(self, file: str | Path, line: int, reason: str):
        self.file, self.line, self.reason = Path(file), line, reason
        super().__init__(f"{file}{f':{line}' if line else ''}: {reason}")


class RunDirectoryError(TlfleetError, ValueError):
    """A run directory that cannot be reported on: names the directory or file and why."""

    def __init__(self, path: Path, reason: str):
        self.path, self.reason = path, reason
        super().__init__(f"{path}: {reason}")


def default_run_dir(scenario_name: str, root: Path = Path("runs"),
                    now: datetime | None = None) -> Path:
    """``runs/<scenario>-<YYYYmmdd-HHMMSS>`` (UTC); a suffix ``-2``, ``-3``… if it exists.

    Always a direct child of ``root``: a name that would leave it (a path separator,
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


# --------------------------------------------------------------------------------- claiming

LOCK = "run.lock"  # held by the run writing the directory, removed when it is done
#: environment variable naming a run directory the parent process claimed for this one (the
#: namespace-host launcher claims it and writes logs/ before its ``tlfleet supervise`` starts)
CLAIMED_ENV = "TLFLEET_RUN_DIR_CLAIMED"


class RunDirLock:
    """A run directory claimed by this run (:func:`claim_run_dir`): its ``run.lock`` is held
    (``flock``) until :meth:`release`, or until this process ends."""

    def __init__(self, path: Path, fd: int | None):
        self.path = path
        self._fd = fd

    def release(self) -> None:
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        with contextlib.suppress(OSError):
            (self.path / LOCK).unlink()
        os.close(fd)


def _refuse_a_run(path: Path) -> None:
    entries = sorted(e.name for e in path.iterdir() if e.name != LOCK)
    if entries:
        shown = ", ".join(entries[:3]) + (" …" if len(entries) > 3 else "")
        raise RunDirectoryError(path, f"holds {len(entries)} file(s) already ({shown}): a run "
                                      "directory is never overwritten; give a new --out or "
                                      "remove it")


def claim_run_dir(path: Path, environ: Mapping[str, str] | None = None) -> RunDirLock:
    """Create run directory ``path`` (with its parents) for one run and lock it, or raise
    :class:`RunDirectoryError` in one line: a file in its place, a directory that cannot be
    created or written, one that holds anything already (a run directory is never overwritten:
    a stale report would sit beside the new files), one another run is writing into."""
    path = Path(path)
    environ = os.environ if environ is None else environ
    claimed = environ.get(CLAIMED_ENV)
    if claimed and Path(claimed).resolve() == path.resolve() and (path / LOCK).exists():
        return RunDirLock(path, None)  # the parent holds it for us
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise RunDirectoryError(path, "exists and is not a directory: give --out a directory "
                                      "for the run") from None
    except OSError as exc:
        raise RunDirectoryError(path, f"cannot create the run directory: {exc.strerror}") from None
    if not path.is_dir():
        raise RunDirectoryError(path, "exists and is not a directory: give --out a directory "
                                      "for the run")
    _refuse_a_run(path)  # before anything is written into it
    try:
        fd = os.open(path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise RunDirectoryError(path, f"cannot write into it: {exc.strerror}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        holder = os.read(fd, 32).decode(errors="replace").strip()
        os.close(fd)
        raise RunDirectoryError(path, "another run is writing into it"
                                      + (f" (pid {holder})" if holder else "")) from None
    try:
        _refuse_a_run(path)  # again: a run may have started between the look and the lock
    except RunDirectoryError:
        os.close(fd)
        raise
    os.ftruncate(fd, 0)
    os.write(fd, str(os.getpid()).encode())
    return RunDirLock(path, fd)


# --------------------------------------------------------------------------------- JSON edge


def json_ready(value: Any) -> Any:
    """``value`` with ±inf as ``"inf"``/``"-inf"`` and NaN as None, tuples as lists, numpy
    scalars as numbers: what :func:`write_json` puts on disk."""
    if isinstance(value, float):
        if math.isnan(value):
            return None
        return value if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, str):
        return json_ready(value.item())
    return value


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as indented UTF-8 JSON (see :func:`json_ready`); other objects as str."""
    text = json.dumps(json_ready(data), indent=2, ensure_ascii=False, default=str,
                      allow_nan=False)
    path.write_text(text + "\n", encoding="utf-8")


def read_json(path: Path, default: Any = None) -> Any:
    """A JSON file written by :func:`write_json`; ``default`` when missing or not JSON (or
    nested beyond Python's recursion limit)."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError):
        return default


# --------------------------------------------------------------------------------- events


#: ``Event.data`` mark of an event the recorder received after the simulator's ``sim_done``
#: (:class:`tlfleet.coordinator.record.recorder.RecorderTap`): said once the mission had ended, so
#: :func:`tlfleet.coordinator.live.verdict.mission_event_kinds` and the summary leave it out
AFTER_SIM_DONE = "after_sim_done"


def event_line(event: Event) -> str:
    """One ``events.jsonl`` line (with its newline)."""
    record = {"t": event.t, "source": event.source, "kind": event.kind, "data": event.data}
    return json.dumps(record, default=json_default, allow_nan=True) + "\n"


def json_default(value: Any) -> Any:
    """How ``events.jsonl`` and ``run.json`` write what JSON has no type for."""
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, set | frozenset | tuple):
        return list(value)
    return str(value)


def _event_from_line(line: str) -> Event:
    try:
        record = json.loads(line)
    except RecursionError:
        raise ValueError("JSON nested too deeply") from None
    if not isinstance(record, dict):
        raise ValueError("not a JSON object")
    t, source, kind = record.get("t"), record.get("source"), record.get("kind")
    data = record.get("data", {})
    if isinstance(t, bool) or not isinstance(t, int | float):
        raise ValueError(f"'t' must be a number, found {t!r}")
    if not isinstance(source, str) or not isinstance(kind, str):
        raise ValueError(f"'source' and 'kind' must be strings, found {source!r}, {kind!r}")
    if not isinstance(data, dict):
        raise ValueError(f"'data' must be an object, found {type(data).__name__}")
    problem = data_problem(kind, data)  # the types its readers rely on
    if problem is not None:
        raise ValueError(problem)
    return Event(t=float(t), source=source, kind=kind, data=data)


# --------------------------------------------------------------------------------- statuses


def status_cells(status: Status) -> list[str]:
    """One ``status.csv`` row in :data:`STATUS_COLUMNS` order. Lists are space-separated tokens
    (``prefix`` "a11 a12", ``buchi_states`` "0 2", ``events`` "1 0 3"), visits ``name:count``
    tokens ("a11:2 a12:1"); numbers in full precision (``repr``); NaN as an empty cell."""
    row: dict[str, str] = {"t": _num(status.t), "robot": str(status.robot)}
    if isinstance(status, StlStatus):
        row.update(kind="stl", subtask=str(status.subtask), rho=_num(status.rho),
                   rho_max=_num(status.rho_max), lower=_num(status.lower), r=_num(status.r),
                   stage=str(status.stage), ce=str(status.ce), c=str(status.c),
                   follow=str(status.follow), events=" ".join(str(n) for n in status.events))
    else:
        row.update(kind="ltl", target=status.target or "", mode=status.mode,
                   rounds=str(status.rounds),
                   visits=" ".join(f"{name}:{count}" for name, count in status.visits),
                   prefix=" ".join(status.prefix), suffix=" ".join(status.suffix),
                   buchi_states=" ".join(str(q) for q in status.buchi_states))
    return [row.get(col, "") for col in STATUS_COLUMNS]


def _num(value: float) -> str:
    value = float(value)
    return "" if math.isnan(value) else repr(value)


def _tokens(cell: str) -> list[str]:
    """A list cell: space-separated tokens, or the JSON list of run directories written before
    the token format (``["a11", "a12"]``, ``[["a11", 2]]``)."""
    cell = cell.strip()
    if cell.startswith("["):
        value = json.loads(cell)
        if not isinstance(value, list):
            raise ValueError(f"expected a list, found {cell!r}")
        return [":".join(str(x) for x in v) if isinstance(v, list) else str(v) for v in value]
    return cell.split()


def status_from_row(row: dict[str, str]) -> Status:
    """The one parser of ``status.csv`` cells: a row (column → cell) back to its message."""
    def number(col: str) -> float:
        return math.nan if row[col] == "" else float(row[col])

    def integer(col: str, default: int = 0) -> int:
        return default if row[col] == "" else int(row[col])

    t, robot = float(row["t"]), int(row["robot"])
    if row["kind"] == "stl":
        events = tuple(int(v) for v in _tokens(row["events"])) or (0, 0, 0)
        if len(events) != 3:
            raise ValueError(f"events must list 3 counts, found {row['events']!r}")
        return StlStatus(robot=robot, t=t, subtask=integer("subtask"), rho=number("rho"),
                         rho_max=number("rho_max"), lower=number("lower"), r=number("r"),
                         stage=integer("stage"), ce=integer("ce"), c=integer("c"),
                         follow=integer("follow", -1), events=events)  # type: ignore[arg-type]
    if row["kind"] == "ltl":
        visits = []
        for token in _tokens(row["visits"]):
            name, sep, count = token.rpartition(":")
            if not sep:
                raise ValueError(f"visits must be name:count tokens, found {token!r}")
            visits.append((name, int(count)))
        return LtlStatus(robot=robot, t=t, prefix=tuple(_tokens(row["prefix"])),
                         suffix=tuple(_tokens(row["suffix"])), target=row["target"] or None,
                         buchi_states=tuple(int(v) for v in _tokens(row["buchi_states"])),
                         visits=tuple(visits), rounds=integer("rounds"), mode=row["mode"])
    raise ValueError(f"kind must be 'ltl' or 'stl', found {row['kind']!r}")


# --------------------------------------------------------------------------------- reading


@dataclass(frozen=True)
class Problem:
    """A line of a run file that did not convert back (skipped by a lenient read)."""

    file: str  # file name in the run directory
    line: int  # 1-based (0: the whole file)
    reason: str
    torn: bool = False  # the last line, cut short by a crash (no newline)


def _lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8").splitlines(keepends=True)
    except FileNotFoundError:
        raise RunFileError(path, 0, "missing") from None
    except IsADirectoryError:
        raise RunFileError(path, 0, "is a directory, not a file") from None
    except OSError as exc:
        raise RunFileError(path, 0, f"cannot read: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise RunFileError(path, 0, f"not UTF-8 text: {exc.reason}") from None


def _torn(lines: list[str], index: int) -> bool:
    """The last line without a newline: a write cut short by a crash."""
    return index == len(lines) - 1 and not lines[index].endswith("\n")


def read_events(path: str | Path, *, strict: bool = True,
                problems: list[Problem] | None = None) -> list[Event]:
    """The events of ``events.jsonl`` in file order. A line that is not a JSON object with a
    number ``t``, strings ``source`` and ``kind`` and an object ``data`` raises
    :class:`RunFileError` when ``strict`` (a torn last line is always skipped, with a warning),
    and is otherwise skipped and appended to ``problems``."""
    path = Path(path)
    lines = _lines(path)
    events: list[Event] = []
    for index, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            events.append(_event_from_line(line))
        except ValueError as exc:  # json.JSONDecodeError is a ValueError
            _skip_or_raise(path, index, str(exc), strict, _torn(lines, index), problems)
    return events


def read_statuses(path: str | Path, *, strict: bool = True,
                  problems: list[Problem] | None = None) -> list[Status]:
    """The rows of ``status.csv`` as status messages (see :func:`read_events` for ``strict``)."""
    path = Path(path)
    lines = _lines(path)
    if not lines:
        raise RunFileError(path, 1, f"empty: expected the header {','.join(STATUS_COLUMNS)}")
    try:
        header = next(csv.reader([lines[0]]))
    except csv.Error as exc:
        raise RunFileError(path, 1, f"not CSV: {exc}") from None
    missing = [col for col in STATUS_COLUMNS if col not in header]
    if missing and strict:
        raise RunFileError(path, 1, f"header lacks the column(s) {', '.join(missing)}")
    blank = dict.fromkeys(missing, "")  # lenient: an absent column reads as blank cells
    statuses: list[Status] = []
    for index in range(1, len(lines)):
        if not lines[index].strip():
            continue
        try:
            cells = next(csv.reader([lines[index]]))
            if len(cells) != len(header):
                raise ValueError(f"expected {len(header)} values, found {len(cells)}")
            statuses.append(status_from_row({**blank, **dict(zip(header, cells, strict=True))}))
        except (ValueError, TypeError, csv.Error) as exc:
            _skip_or_raise(path, index, str(exc), strict, _torn(lines, index), problems)
    return statuses


def _skip_or_raise(path: Path, index: int, reason: str, strict: bool, torn: bool,
                   problems: list[Problem] | None) -> None:
    if strict and not torn:
        raise RunFileError(path, index + 1, reason)
    # said at INFO: the caller reports ``problems`` (the report lists them, ``tlfleet report``
    # sums them up in one line)
    logger.info("%s:%d: %s%s: skipped", path, index + 1, "torn last line: " if torn else "",
                reason)
    if problems is not None:
        problems.append(Problem(path.name, index + 1, reason, torn))


@dataclass(frozen=True)
class RunFiles:
    """Every file of a run directory a report needs, each read once (:func:`read_run`)."""

    run_dir: Path
    scenario: Scenario
    info: dict[str, Any]  # run.json ({} when missing or unreadable)
    events: tuple[Event, ...]
    statuses: tuple[Status, ...]
    trajectory: Trajectory | None  # None when it cannot be read
    trajectory_error: str  # why not ("" when read)
    problems: tuple[Problem, ...] = ()  # lines skipped by a lenient read

    @property
    def skipped_event_lines(self) -> list[int]:
        return [p.line for p in self.problems if p.file == EVENTS]


def read_run(run_dir: str | Path, *, strict: bool = False,
             scenario: Scenario | None = None) -> RunFiles:
    """Read the run directory once. ``scenario.toml`` is required (unless the caller passes the
    loaded ``scenario``); a missing or unreadable trajectory is recorded in ``trajectory_error``;
    missing status/event files read as empty unless ``strict``."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise RunDirectoryError(run_dir, "not a run directory (does not exist or is not a folder)")
    if scenario is None:
        if not (run_dir / SCENARIO).is_file():
            raise RunDirectoryError(run_dir / SCENARIO, "missing: a run directory holds the "
                                                        "scenario.toml copy written by "
                                                        "`tlfleet run`")
        scenario = load_scenario(run_dir / SCENARIO)
    problems: list[Problem] = []
    info = read_json(run_dir / RUN_INFO, None)
    if info is None and (run_dir / RUN_INFO).exists():
        problems.append(Problem(RUN_INFO, 0, "not JSON (or nested too deeply): ignored"))
    info = checked_info(info if info is not None else {}, problems)
    events = _optional(run_dir / EVENTS, strict, problems, read_events)
    statuses = _optional(run_dir / STATUS, strict, problems, read_statuses)
    trajectory: Trajectory | None = None
    trajectory_error = ""
    try:
        trajectory = read_trajectory_csv(run_dir / TRAJECTORY)
    except TlfleetError as exc:
        if strict:
            raise
        trajectory_error = str(exc)
    return RunFiles(run_dir, scenario, info, tuple(events),
                    tuple(statuses), trajectory, trajectory_error, tuple(problems))


#: the fields of ``run.json`` the summary and the report read, and the types they need
INFO_FIELDS: dict[str, tuple[type, ...]] = {
    "mode": (str,), "wall_time": (int, float), "duration": (int, float), "t_end": (int, float),
    "reason": (str,), "malformed_received": (dict,), "faults": (list,), "scenario": (str,),
}


def checked_info(info: Any, problems: list[Problem]) -> dict[str, Any]:
    """``run.json`` as read, without the fields whose type its readers cannot use (each one
    named in ``problems``): a damaged or hand-edited file reports what it can, never raises."""
    if not isinstance(info, dict):
        if info:
            problems.append(Problem(RUN_INFO, 0, "not a JSON object: ignored"))
        return {}
    out = dict(info)
    for name, types in INFO_FIELDS.items():
        value = out.get(name)
        if value is not None and (isinstance(value, bool) or not isinstance(value, types)):
            problems.append(Problem(RUN_INFO, 0, f"{name} has the wrong type "
                                                 f"({type(value).__name__}): ignored"))
            del out[name]
    counts = out.get("malformed_received")
    if counts is not None and not all(isinstance(n, int) and not isinstance(n, bool)
                                      for n in counts.values()):
        problems.append(Problem(RUN_INFO, 0, "malformed_received holds a count that is not an "
                                             "integer: ignored"))
        del out["malformed_received"]
    return out


def damage(files: RunFiles) -> str:
    """What of a run directory could not be read, in one line ("" when whole): every problem but
    a torn last line (what a crash leaves), and an unreadable trajectory."""
    found = [f"{p.file}{f':{p.line}' if p.line else ''} ({p.reason})" for p in files.problems
             if not p.torn]
    if files.trajectory_error:
        found.append(files.trajectory_error)
    if not found:
        return ""
    more = f" and {len(found) - 2} more" if len(found) > 2 else ""
    return f"{len(found)} damaged part(s): " + "; ".join(f[:160] for f in found[:2]) + more


def _optional(path: Path, strict: bool, problems: list[Problem], reader) -> list[Any]:
    if not strict and not path.exists():
        return []
    try:
        return reader(path, strict=strict, problems=problems)
    except RunFileError as exc:
        if strict:
            raise
        problems.append(Problem(path.name, exc.line, exc.reason))
        return []


# --------------------------------------------------------------------------------- writing


class StatusWriter:
    """Appends rows to ``status.csv`` (header :data:`STATUS_COLUMNS`)."""

    def __init__(self, path: Path):
        self.handle = open(path, "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._csv = csv.writer(self.handle)
        self._csv.writerow(STATUS_COLUMNS)

    def write(self, status: Status) -> None:
        self._csv.writerow(status_cells(status))


class TrajectoryWriter:
    """Appends rows to ``trajectory.csv``: ``t`` then (x, y, θ) per robot, ids ascending."""

    def __init__(self, path: Path, robot_ids: Sequence[int]):
        self.handle = open(path, "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._csv = csv.writer(self.handle)
        self._csv.writerow(["t"] + [f"{c}{r}" for r in robot_ids for c in ("x", "y", "th")])

    def write(self, t: float, values: Iterable[float]) -> None:
        self._csv.writerow([repr(float(t))] + [repr(v) for v in values])
