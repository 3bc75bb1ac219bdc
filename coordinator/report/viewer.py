"""The fleet in rerun (architecture.md §1, §6; stack-notes.md §4): the only module importing rerun.

Importing rerun costs ≈ 0.9 s, so callers import this module lazily, when they log.

:class:`FleetLog` turns the run's typed messages into rerun entities on an explicit
``rr.RecordingStream`` (no global recording), on the timeline ``sim_time`` (a duration [s]).
``rr.set_time`` is thread-local: every method must run on the logging thread. Entities::

    /world                 static flip y → −y (rerun's 2D views draw y downwards)
    /world/arena           static border (LineStrips2D)
    /world/obstacles/rects, /world/obstacles/discs       static (Boxes2D, Ellipses2D)
    /world/obstacles/names static names at the obstacles' centres (Points2D labels)
    /world/regions         static discs (Ellipses2D)
    /world/regions/names   static region names at the discs' centres (Points2D labels)
    /world/robots          every robot: disc of its radius, colour, label "3 STL" (Points2D)
    /world/headings        heading arrows (Arrows2D)
    /world/trails          one segment per robot every ``trail_period`` of sim time (LineStrips2D),
                           accumulated by the blueprint's visible time range (−∞, cursor]
    /world/plans/r<id>     LTL plan: prefix and suffix paths through region centres (LineStrips2D)
    /world/plans/r<id>/target   the current target region: a ring on its disc, and the label
                           "1 → a2" beside it (not on the region's own name)
    /world/goals           static STL goal points of the sub-tasks (× + "goal 3 [57, 58] s")
    /rho/r<id>/{rho,rho_max,lower,r}   STL funnel and robustness (Scalars; NaN = idle, not logged)
    /rho/r<id>/critical    ρ at each critical event (SeriesPoints)
    /rho/r<id>/repairs     r̄ after each repair (SeriesPoints)
    /rho/r<id>/recoveries  r after each robustness recovery (SeriesPoints)
    /events/<source>       every event as a line of text (TextLog); source "agent/4" → "r4"

:func:`replay_run` logs a finished run directory (``scenario.toml``, ``trajectory.csv``,
``status.csv``, ``events.jsonl``) through the same :class:`FleetLog`; :class:`LiveView` feeds it
from the coordinator's recorder tap, decimated, and never lets a failure reach the run.
"""

from __future__ import annotations

import json
import logging
import math
import socket
import time
import urllib.parse
import uuid
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from tlfleet.agent.model import DiscObstacle, RectObstacle, Scenario
from tlfleet.bus.protocol.messages import Event, LtlStatus, MocapFrame, StlStatus
from tlfleet.coordinator.record.rundir import RunFileError, RunFiles, read_run

logger = logging.getLogger(__name__)

APPLICATION_ID = "tlfleet"
TIMELINE = "sim_time"
HOST = "127.0.0.1"

# tab10: distinguishable, and the same robot keeps its colour in every view
PALETTE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
           (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))
REGION_COLOR = (90, 160, 255)
OBSTACLE_COLOR = (120, 120, 120)
ARENA_COLOR = (60, 60, 60)
STL_SERIES = (("rho", "ρ", (31, 119, 180)), ("rho_max", "ρ_max", (44, 160, 44)),
              ("lower", "lower bound", (214, 39, 40)), ("r", "r̄", (255, 127, 14)))
COLOR_NAMES = {(31, 119, 180): "blue", (44, 160, 44): "green", (214, 39, 40): "red",
               (255, 127, 14): "orange"}
GOAL_COLOR = (20, 20, 20)
EVENT_LEVELS = {"process_died": "ERROR", "critical_event": "WARN", "stuck": "WARN",
                "contact": "WARN", "deadline_miss": "WARN", "fault": "ERROR",
                "repair": "INFO", "agent_stats": "DEBUG", "sim_stats": "DEBUG"}
EVENT_TEXT_LIMIT = 240  # [characters] of the event's data shown in the text log


def robot_color(robot_id: int) -> tuple[int, int, int]:
    return PALETTE[(robot_id - 1) % len(PALETTE)]


def robot_label(scenario: Scenario, robot_id: int) -> str:
    """``"1 LTL"`` / ``"3 STL"``."""
    return f"{robot_id} {'LTL' if scenario.robot(robot_id).is_ltl else 'STL'}"


def event_entity(source: str) -> str:
    """``events/r4`` for ``agent/4``, ``events/sim`` for ``sim``."""
    kind, _, rest = source.partition("/")
    if kind == "agent" and rest.isdigit():
        return f"events/r{rest}"
    cleaned = "".join(c if c.isalnum() or c in "_-" else "_" for c in source) or "unknown"
    return f"events/{cleaned}"


def blueprint(scenario: Scenario) -> rrb.Blueprint:
    """A 2D view of /world beside one time-series view of /rho/r<id> per STL robot and the
    event log; the trails keep their whole history up to the time cursor."""
    arena = scenario.arena
    margin = 0.25  # [m]
    history = rrb.VisibleTimeRanges([rrb.VisibleTimeRange(
        TIMELINE, start=rrb.TimeRangeBoundary.infinite(),
        end=rrb.TimeRangeBoundary.cursor_relative())])
    world = rrb.Spatial2DView(
        name="fleet", origin="/", contents="/world/**",
        # the view sees /world through its y flip: y ∈ [−ymax, −ymin]
        visual_bounds=rrb.VisualBounds2D(x_range=[arena.xmin - margin, arena.xmax + margin],
                                         y_range=[-arena.ymax - margin, -arena.ymin + margin]),
        overrides={"world/trails": history})
    # one time range [0, duration] for every ρ panel, so that their time axes line up; the
    # legends would cover a third of a small panel: the colours are named in the title instead
    shared = rrb.VisibleTimeRange(TIMELINE, start=rrb.TimeRangeBoundary.absolute(seconds=0.0),
                                  end=rrb.TimeRangeBoundary.absolute(seconds=scenario.duration))
    key = " · ".join(f"{title} {COLOR_NAMES[color]}" for _name, title, color in STL_SERIES)
    series = [rrb.TimeSeriesView(name=f"robot {robot.id}: {key}", origin=f"/rho/r{robot.id}",
                                 plot_legend=rrb.PlotLegend(visible=False), time_ranges=shared)
              for robot in sorted(scenario.robots, key=lambda r: r.id) if robot.is_stl]
    log = rrb.TextLogView(name="events", origin="/events")
    if len(series) > 4:
        right = rrb.Vertical(rrb.Tabs(*series), log, row_shares=[3, 1])
    else:
        right = rrb.Vertical(*series, log, row_shares=[2] * len(series) + [1])
    return rrb.Blueprint(rrb.Horizontal(world, right, column_shares=[3, 2]),
                         rrb.TimePanel(timeline=TIMELINE), collapse_panels=False)


def new_recording() -> rr.RecordingStream:
    """A fresh recording (its own id), not the global one."""
    return rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4())


def web_viewer_url(web_port: int, grpc_uri: str) -> str:
    return f"http://{HOST}:{web_port}/?url={urllib.parse.quote(grpc_uri, safe='')}"


def serve(recording: rr.RecordingStream, scenario: Scenario, grpc_port: int, web_port: int,
          *, save: Path | None = None) -> str:
    """Serve ``recording`` over gRPC on ``127.0.0.1:grpc_port`` and the web viewer on
    ``web_port`` (and write it to ``save`` too); returns the viewer's URL (it connects to the
    gRPC server). Call before logging: only data logged after it reaches the sinks.

    The gRPC server keeps everything logged in memory for late viewers and stops when the
    recording is disconnected. The web viewer's HTTP server lives until the process exits.
    """
    # rerun only logs a gRPC bind failure, from its server thread: find out here instead
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((HOST, grpc_port))
        except OSError as exc:
            raise OSError(f"gRPC port {HOST}:{grpc_port} is not free: {exc.strerror}") from None
    sink = rr.GrpcServerSink(bind_ip=HOST, port=grpc_port)
    sinks: list[Any] = [sink] if save is None else [sink, rr.FileSink(save)]
    recording.set_sinks(*sinks, default_blueprint=blueprint(scenario))
    uri = sink.uri
    rr.serve_web_viewer(web_port=web_port, open_browser=False, connect_to=uri)
    return web_viewer_url(web_port, uri)


class FleetLog:
    """Logs one fleet to ``recording`` (see the module docstring for the entities).

    Call :meth:`log_static` once, then :meth:`frame`, :meth:`ltl_status`, :meth:`stl_status` and
    :meth:`event` in (roughly) increasing sim time, all on one thread. Frames, trail segments and
    STL series are buffered: :meth:`flush` sends them (one ``send_columns`` per entity instead of
    one ``log`` per row: rows built one by one cost several times the CPU), at the end and, live,
    every so often.
    """

    def __init__(self, scenario: Scenario, recording: rr.RecordingStream, *,
                 trail_period: float = 0.1):
        self.scenario = scenario
        self.rec = recording
        self.trail_period = trail_period  # [s] sim time between two trail points
        self._series: dict[str, tuple[list[float], list[float]]] = {}  # entity -> (t, value)
        self._frame_t: list[float] = []  # buffered frames: times [s], poses (n, 3) each
        self._frame_xyth: list[np.ndarray] = []
        self._trail_times: list[float] = []  # buffered trail segments: times, (n, 2, 2) each
        self._trail_segments: list[np.ndarray] = []
        self.ids = scenario.robot_ids
        self._radii = np.array([scenario.robot(i).radius for i in self.ids], dtype=np.float32)
        self._colors = np.array([robot_color(i) for i in self.ids], dtype=np.uint8)
        self._labels = [robot_label(scenario, i) for i in self.ids]
        self._trail_last: np.ndarray | None = None  # (n, 2) [m]
        self._trail_t = -math.inf
        self._poses: dict[int, tuple[float, float, float]] = {
            r.id: r.pose for r in scenario.robots}
        self._plans: dict[int, tuple[tuple[str, ...], tuple[str, ...]]] = {}
        self._targets: dict[int, str | None] = {}
        self.t_first = math.inf  # [s] sim time range logged
        self.t_last = -math.inf
        self.frames = 0  # frames logged

    def _at(self, t: float) -> None:
        self.rec.set_time(TIMELINE, duration=t)
        self.t_first = min(self.t_first, t)
        self.t_last = max(self.t_last, t)

    # ----------------------------------------------------------------- static scene

    def log_static(self) -> None:
        rec, scenario, arena = self.rec, self.scenario, self.scenario.arena
        rec.log("world", rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
        corners = [(arena.xmin, arena.ymin), (arena.xmax, arena.ymin), (arena.xmax, arena.ymax),
                   (arena.xmin, arena.ymax), (arena.xmin, arena.ymin)]
        rec.log("world/arena", rr.LineStrips2D([corners], colors=ARENA_COLOR, radii=0.02),
                static=True)
        rects = [o for o in arena.obstacles if isinstance(o, RectObstacle)]
        discs = [o for o in arena.obstacles if isinstance(o, DiscObstacle)]
        if rects:
            rec.log("world/obstacles/rects", rr.Boxes2D(
                mins=[(o.xmin, o.ymin) for o in rects],
                sizes=[(o.xmax - o.xmin, o.ymax - o.ymin) for o in rects],
                colors=OBSTACLE_COLOR), static=True)
        if discs:
            rec.log("world/obstacles/discs", rr.Ellipses2D(
                centers=[o.center for o in discs], half_sizes=[(o.radius, o.radius) for o in discs],
                colors=OBSTACLE_COLOR), static=True)
        if scenario.regions:
            rec.log("world/regions", rr.Ellipses2D(
                centers=[r.center for r in scenario.regions],
                half_sizes=[(r.radius, r.radius) for r in scenario.regions],
                colors=REGION_COLOR), static=True)
        # Names as labelled points at the shapes' centres: rerun draws the labels of Boxes2D and
        # Ellipses2D without the /world y flip (a region's name stood at its mirror image), while
        # the points, like the robots' labels, go through it.
        names = [(o.name, ((o.xmin + o.xmax) / 2, (o.ymin + o.ymax) / 2)) for o in rects if o.name]
        names += [(o.name, o.center) for o in discs if o.name]
        if names:
            rec.log("world/obstacles/names", rr.Points2D(
                [c for _, c in names], labels=[n for n, _ in names], radii=0.0,
                colors=OBSTACLE_COLOR, show_labels=True), static=True)
        if scenario.regions:
            rec.log("world/regions/names", rr.Points2D(
                [r.center for r in scenario.regions], labels=[r.name for r in scenario.regions],
                radii=0.0, colors=REGION_COLOR, show_labels=True), static=True)
        goals = stl_goals(scenario)
        if goals:
            rec.log("world/goals", rr.Points2D(
                [(x, y) for _rid, x, y, _tol, _label in goals],
                radii=[tol for _rid, _x, _y, tol, _label in goals], colors=GOAL_COLOR,
                labels=[label for *_rest, label in goals], show_labels=True), static=True)
        # styling is static, positions temporal (static data of a component hides temporal data)
        rec.log("world/robots", rr.Points2D.from_fields(
            radii=self._radii, colors=self._colors, labels=self._labels, show_labels=True),
            static=True)
        rec.log("world/headings", rr.Arrows2D.from_fields(colors=self._colors, radii=0.015),
                static=True)
        rec.log("world/trails", rr.LineStrips2D.from_fields(colors=self._colors, radii=0.01),
                static=True)
        for robot in scenario.robots:
            if not robot.is_stl:
                continue
            for name, title, color in STL_SERIES:
                rec.log(f"rho/r{robot.id}/{name}",
                        rr.SeriesLines(names=title, colors=color, widths=1.5), static=True)
            rec.log(f"rho/r{robot.id}/critical",
                    rr.SeriesPoints(names="critical event (ρ)", colors=(214, 39, 40),
                                    markers="cross", marker_sizes=4.0), static=True)
            rec.log(f"rho/r{robot.id}/repairs",
                    rr.SeriesPoints(names="repair (new r̄)", colors=(255, 127, 14),
                                    markers="diamond", marker_sizes=4.0), static=True)
            rec.log(f"rho/r{robot.id}/recoveries",
                    rr.SeriesPoints(names="recovery (raised r)", colors=(44, 160, 44),
                                    markers="up", marker_sizes=4.0), static=True)

    # ----------------------------------------------------------------- per message

    def frame(self, t: float, poses: Iterable[Sequence[float]]) -> None:
        """Every robot's pose ``(id, x [m], y [m], θ [rad])`` at sim time ``t`` [s]."""
        for row in poses:
            self._poses[int(row[0])] = (float(row[1]), float(row[2]), float(row[3]))
        xyth = np.array([self._poses[i] for i in self.ids], dtype=np.float64)  # (n, 3)
        self._at(t)
        self._frame_t.append(t)
        self._frame_xyth.append(xyth)
        if self._trail_last is None or t - self._trail_t >= self.trail_period - 1e-9:
            xy = xyth[:, :2]
            start = xy if self._trail_last is None else self._trail_last
            self._trail_times.append(t)
            self._trail_segments.append(np.stack((start, xy), axis=1))  # (n, 2, 2)
            self._trail_last = xy
            self._trail_t = t
        self.frames += 1

    def _send_frames(self) -> None:
        n = len(self.ids)
        if self._frame_t:
            xyth = np.concatenate(self._frame_xyth)  # (k·n, 3)
            xy = xyth[:, :2]
            heading = np.column_stack((np.cos(xyth[:, 2]), np.sin(xyth[:, 2])))
            length = np.tile(1.6 * self._radii, len(self._frame_t))[:, None]  # [m]
            times = [rr.TimeColumn(TIMELINE, duration=self._frame_t)]
            lengths = [n] * len(self._frame_t)
            self.rec.send_columns("world/robots", indexes=times,
                                  columns=rr.Points2D.columns(positions=xy).partition(lengths))
            self.rec.send_columns("world/headings", indexes=times, columns=rr.Arrows2D.columns(
                origins=xy, vectors=heading * length).partition(lengths))
            self._frame_t, self._frame_xyth = [], []
        if self._trail_times:
            segments = np.concatenate(self._trail_segments)  # (k·n, 2, 2)
            self.rec.send_columns(
                "world/trails", indexes=[rr.TimeColumn(TIMELINE, duration=self._trail_times)],
                columns=rr.LineStrips2D.columns(strips=list(segments)).partition(
                    [n] * len(self._trail_times)))
            self._trail_times, self._trail_segments = [], []

    def _point(self, robot_id: int, name: str) -> tuple[float, float] | None:
        """Centre of region ``name``; ``start`` (not a region) is the robot's start position."""
        for region in self.scenario.regions:
            if region.name == name:
                return region.center
        if name == "start":
            pose = self.scenario.robot(robot_id).pose
            return pose[0], pose[1]
        return None

    def ltl_status(self, status: LtlStatus) -> None:
        """The plan (logged when it changes) and the current target (when it changes)."""
        plan = (tuple(status.prefix), tuple(status.suffix))
        color = robot_color(status.robot)
        if self._plans.get(status.robot) != plan:
            self._plans[status.robot] = plan
            self._at(status.t)
            strips, labels = [], []
            for part, names in (("prefix", plan[0]), ("suffix", plan[1])):
                points = [p for p in (self._point(status.robot, n) for n in names) if p]
                if len(points) >= 2:
                    strips.append(points)
                    labels.append(f"{status.robot} {part}")
            self.rec.log(f"world/plans/r{status.robot}", rr.LineStrips2D(
                strips, colors=color, radii=[0.02, 0.01][:len(strips)], labels=labels))
        if self._targets.get(status.robot, "") != status.target:
            self._targets[status.robot] = status.target
            self._at(status.t)
            centre = self._point(status.robot, status.target) if status.target else None
            if centre is None:
                self.rec.log(f"world/plans/r{status.robot}/target", rr.Clear(recursive=True))
            else:
                # a ring on the region, and the label beside it, below the region's own name
                # (at its centre): "1 → a11" and "a11" overlapped as "1 a1a11"
                ring = [(centre[0] + 0.18 * math.cos(a), centre[1] + 0.18 * math.sin(a))
                        for a in np.linspace(0.0, 2 * math.pi, 25)]
                self.rec.log(f"world/plans/r{status.robot}/target",
                             rr.LineStrips2D([ring], colors=color, radii=0.015))
                offset = 0.45 + 0.2 * (status.robot % 3)  # [m] robots apart
                self.rec.log(f"world/plans/r{status.robot}/target/label", rr.Points2D(
                    [(centre[0], centre[1] - offset)], radii=0.0, colors=color,
                    labels=[f"{status.robot} → {status.target}"], show_labels=True))

    def stl_status(self, status: StlStatus) -> None:
        """ρ, ρ_max, the lower funnel bound and r̄ (NaN values, i.e. idle, are not logged)."""
        self._at(status.t)
        for name, _title, _color in STL_SERIES:
            value = getattr(status, name)
            if math.isfinite(value):
                times, values = self._series.setdefault(f"rho/r{status.robot}/{name}", ([], []))
                times.append(status.t)
                values.append(value)

    @property
    def pending(self) -> int:
        """Rows buffered, not sent yet."""
        return (len(self._frame_t) + len(self._trail_times)
                + sum(len(times) for times, _values in self._series.values()))

    def flush(self) -> None:
        """Send the buffered frames, trail segments and STL series."""
        self._send_frames()
        for entity, (times, values) in self._series.items():
            if times:
                self.rec.send_columns(entity, indexes=[rr.TimeColumn(TIMELINE, duration=times)],
                                      columns=rr.Scalars.columns(scalars=values))
                times.clear()
                values.clear()

    def event(self, event: Event) -> None:
        """A line of text per event; critical events, repairs and robustness recoveries also mark
        the ρ plot."""
        self._at(event.t)
        data = json.dumps(event.data, separators=(",", ":"), default=str, allow_nan=True)
        if len(data) > EVENT_TEXT_LIMIT:
            data = data[:EVENT_TEXT_LIMIT] + "…"
        self.rec.log(event_entity(event.source), rr.TextLog(
            f"{event.kind} {data}", level=EVENT_LEVELS.get(event.kind, "INFO")))
        kind, _, rest = event.source.partition("/")
        if kind != "agent" or not rest.isdigit():
            return
        value = event.data.get("rho") if event.kind == "critical_event" else (
            event.data.get("r") if event.kind in ("repair", "recovery") else None)
        if isinstance(value, (int, float)) and math.isfinite(value):
            entity = {"critical_event": "critical", "repair": "repairs"}.get(event.kind,
                                                                              "recoveries")
            self.rec.log(f"rho/r{rest}/{entity}", rr.Scalars(float(value)))


# --------------------------------------------------------------------------------- replay


@dataclass(frozen=True)
class ReplayResult:
    path: Path | None  # the .rrd written (None: logged to a given recording only)
    frames: int  # trajectory rows logged
    statuses: int
    events: int
    t_first: float  # [s] sim time range of the trajectory
    t_last: float
    seconds: float  # [s] wall time spent


def load_run(run: RunFiles | str | Path) -> RunFiles:
    """A finished run directory's files, read strictly
    (:func:`tlfleet.coordinator.record.rundir.read_run`), or already read once by the caller and
    checked here: a missing or unreadable file, or a line that does not convert back, raises
    :class:`~tlfleet.bus.errors.TlfleetError` naming it."""
    if not isinstance(run, RunFiles) and not (Path(run) / "scenario.toml").is_file():
        raise RunFileError(Path(run) / "scenario.toml", 0, "missing")
    files = run if isinstance(run, RunFiles) else read_run(run, strict=True)
    problems = [p for p in files.problems if not p.torn]  # a torn last line is a crash's mark
    if problems:
        raise RunFileError(files.run_dir / problems[0].file, problems[0].line, problems[0].reason)
    if files.trajectory is None:
        raise RunFileError(files.run_dir / "trajectory.csv", 0, files.trajectory_error)
    traj, scenario = files.trajectory, files.scenario
    if set(traj.robot_ids) != set(scenario.robot_ids):
        raise RunFileError(files.run_dir / "trajectory.csv", 1,
                           f"robot columns {list(traj.robot_ids)} do not match the scenario's "
                           f"robots {list(scenario.robot_ids)}")
    return files


def log_run(data: RunFiles, recording: rr.RecordingStream, *, every: int = 5) -> FleetLog:
    """Log ``data`` to ``recording`` (whose sinks are set): every ``every``-th trajectory row and
    always the first and last (so the ``sim_time`` range is the trajectory's), every status and
    event, in time order."""
    if every < 1:
        raise ValueError(f"every must be ≥ 1, found {every}")
    log = FleetLog(data.scenario, recording)
    log.log_static()
    traj = data.trajectory
    n = len(traj.t)
    rows = sorted(set(range(0, n, every)) | {n - 1})
    ids = traj.robot_ids
    # one stream in time order; at equal times frames first, then statuses, then events
    items: list[tuple[float, int, int, Any]] = [(float(traj.t[k]), 0, k, None) for k in rows]
    items += [(s.t, 1, k, s) for k, s in enumerate(data.statuses)]
    items += [(e.t, 2, k, e) for k, e in enumerate(data.events)]
    items.sort(key=lambda item: item[:3])
    for t, what, k, message in items:
        if what == 0:
            log.frame(t, [(i, *traj.states[i][k]) for i in ids])
        elif isinstance(message, StlStatus):
            log.stl_status(message)
        elif isinstance(message, LtlStatus):
            log.ltl_status(message)
        else:
            log.event(message)
    log.flush()
    return log


def replay_run(run: RunFiles | str | Path, out: str | Path | None = None, *,
               every: int = 5) -> ReplayResult:
    """Log the finished run (its directory, or its files read once) to ``out`` (default
    ``run_dir/run.rrd``).

    Inputs are read (and errors raised) before the file is opened, so a bad run directory never
    clobbers an existing recording.
    """
    started = time.monotonic()
    data = load_run(run)
    path = Path(out) if out is not None else data.run_dir / "run.rrd"
    rec = new_recording()
    rec.save(path, default_blueprint=blueprint(data.scenario))
    try:
        log = log_run(data, rec, every=every)
    finally:
        rec.disconnect()  # flush, write the footer, close the file
    traj = data.trajectory
    return ReplayResult(path, log.frames, len(data.statuses), len(data.events),
                        float(traj.t[0]), float(traj.t[-1]), time.monotonic() - started)


# --------------------------------------------------------------------------------- live


class LiveView:
    """Live logging while the fleet runs, fed by ``RecorderTap(on_message=view.on_message)`` on
    the coordinator's loop thread; :meth:`serve` makes one that serves a web viewer.

    Frames are logged at most every ``frame_period`` of sim time, and the buffered rows are sent
    every ``flush_period`` of wall time (the run must not slow down: the coordinator shares the
    CPU with the agents); every status and event is logged. The first failure
    is logged as a warning and switches the view off: it never reaches the run.
    """

    def __init__(self, log: FleetLog, *, url: str = "", frame_period: float = 0.05,
                 flush_period: float = 0.2, clock: Callable[[], float] = time.monotonic):
        self.log = log
        self.url = url
        self.frame_period = frame_period  # [s] sim time between two frames logged
        # [s] wall time between two sends of the buffered rows: each send_columns costs ≈ 0.3 ms
        # whatever its size, so the cadence is the wall clock's, not the (6× faster) sim time's
        self.flush_period = flush_period
        self._clock = clock
        self._last_flush = clock()
        self.failed: str | None = None
        self._last_frame_t = -math.inf

    @classmethod
    def serve(cls, scenario: Scenario, *, grpc_port: int, web_port: int,
              frame_period: float = 0.05, flush_period: float = 0.2) -> LiveView:
        recording = new_recording()
        url = serve(recording, scenario, grpc_port, web_port)
        log = FleetLog(scenario, recording)  # flushed by the view, on the wall clock
        log.log_static()
        return cls(log, url=url, frame_period=frame_period, flush_period=flush_period)

    def on_message(self, what: str, message: Any) -> None:
        if self.failed is not None:
            return
        try:
            if isinstance(message, MocapFrame):
                if message.t - self._last_frame_t < self.frame_period - 1e-9:
                    return
                self._last_frame_t = message.t
                self.log.frame(message.t, message.poses)
            elif isinstance(message, StlStatus):
                self.log.stl_status(message)
            elif isinstance(message, LtlStatus):
                self.log.ltl_status(message)
            elif isinstance(message, Event):
                self.log.event(message)
            now = self._clock()
            if now - self._last_flush >= self.flush_period:
                self._last_flush = now
                self.log.flush()
        except Exception as exc:  # a viewer must never take the run down
            self.failed = f"{type(exc).__name__}: {exc}"
            logger.warning("live viewer: logging failed, no more live data (%s)", self.failed)

    def close(self) -> None:
        """Flush and disconnect: stops the gRPC server (the web viewer's HTTP server lives until
        the process exits)."""
        try:
            if self.failed is None:
                self.log.flush()
            self.log.rec.disconnect()
        except Exception as exc:
            logger.warning("live viewer: closing failed: %s", exc)


def stl_goals(scenario: Scenario) -> list[tuple[int, float, float, float, str]]:
    """The STL goal points of every sub-task (``run_report.subtask_goals``) with a label naming
    the robot and the window: ``(robot, x [m], y [m], tolerance [m], "goal 3 [57, 58] s")``."""
    from tlfleet.coordinator.report.run_report import subtask_goals

    return [(rid, x, y, tol, f"goal {rid} [{a:g}, {b:g}] s")
            for _robot, a, b, (rid, x, y, tol) in subtask_goals(scenario)]
