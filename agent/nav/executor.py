"""Plan executor: drives a unicycle along its LTL plan, one pure step per control tick.

ltl-planning.md §6 and paper §III-A. The plan is the projection on regions of the optimal
prefix–suffix run (ltl-planning.md §5): targets ``τ = prefix · suffix^ω``, with the planner's
conventions (``tlfleet.agent.ltl.planner``): ``prefix[0]`` may be the virtual ``"start"`` state, and
a name equal to the previous one means "stay". Each step (5 Hz):

1. **Visits.** The current target counts as visited when the robot is inside the region or within
   ``xy_goal_tolerance`` of its centre; the executor then advances (stays pass at once, without a
   new visit). A suffix that loops on one region ends the motion (``PlanFinished``): the robot
   drives on to that region's centre and holds there.
2. **Global path** (``grid_planner.plan_path``) from the pose to the target centre, on the
   static grid with the other robots within ``local_range`` stamped in as inflated discs — the
   paper's local cost map — re-planned every ``replan_period`` and whenever the target changes.
   Robots ahead are stamped a second time shifted to our left, so paths keep right. The
   periodic re-plans (and the re-plan around blocking robots of step 4) are *deferred*
   (``deferred_replan``): the step that finds one due keeps following the current
   path and records a :class:`PathRequest` (its pose and stamped robots); the runtime runs it
   with :meth:`Executor.refresh` after the command is on its way, and the path is followed from
   the next step on — move_base's global planner, which runs beside the controller at 1 Hz, has
   the same one-period lag. A step that finds a request still pending runs it first, so the
   trajectory is the same whether or not the caller refreshes between steps. A new target (a
   region reached, a new plan) has no path to follow yet and is planned at once.
3. **DWA** (``dwa.dwa_control``) follows the path, with the other robots as discs moving at the
   velocity estimated from two consecutive pose frames.
4. **Stuck detection.** Progress is a decrease of the remaining path length by at least
   ``progress_epsilon``. With none for ``blocked_after`` the global path is re-planned with the
   nearby robots stamped at full size (they become obstacles of the global plan, so a robot
   blocking the way is passed around); with none for ``stuck_timeout`` the executor emits
   ``Stuck``, rotates in
   place (``rotate_time``), backs off (``back_off_time``, only if the space behind is free), then
   emits ``ReplanRequest`` with the edge (last region → target) and resumes. The runtime may
   answer with a new plan (``ExecutorInputs.new_plan``); its ``prefix[0]``, when it is the last
   region visited, counts as reached.

Progress: visits per region, ``rounds`` (GF progress: visits of the least visited suffix
region), ``cycles`` (complete passes through the suffix), the target and the mode. Every command
respects the unicycle's velocity and acceleration limits relative to the previous command (the
dynamic window of one controller period).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from tlfleet.agent.evolve import evolve
from tlfleet.agent.model.scenario import Region, Scenario
from tlfleet.agent.nav.coupling_limits import VelocityLimits
from tlfleet.agent.nav.dwa import DwaConfig, MovingDiscs, dwa_control
from tlfleet.agent.nav.errors import InvalidPlanError, NoPathError
from tlfleet.agent.nav.events import (
    CycleCompleted,
    NavEvent,
    NoPathFound,
    PlanAccepted,
    PlanFinished,
    Progress,
    RegionVisited,
    ReplanRequest,
    Stuck,
)
from tlfleet.agent.nav.grid import (
    DEFAULT_MARGIN,
    DEFAULT_RESOLUTION,
    OccupancyGrid,
    grid_from_arena,
)
from tlfleet.agent.nav.grid_planner import plan_path
from tlfleet.agent.nav.polyline import remaining_vertices, vertices_length

log = logging.getLogger(__name__)

NAVIGATE, ROTATE, BACK_OFF, HOLD = "navigate", "rotate", "back_off", "hold"
START_STATE = "start"  # the LTL planner's virtual initial state (robot in no region)


@dataclass(frozen=True)
class ExecutorConfig:
    """Executor parameters (lengths [m], times [s], speeds [m/s])."""

    dwa: DwaConfig = field(default_factory=DwaConfig)
    robot_radius: float = 0.2  # [m]
    inflation_margin: float = DEFAULT_MARGIN  # [m] added to the radius in the global grid
    resolution: float = DEFAULT_RESOLUTION  # [m] grid cell
    default_other_radius: float = 0.2  # [m] radius of robots not listed in other_radii
    local_range: float = 2.5  # [m] other robots closer than this enter the local cost map
    replan_period: float = 1.0  # [s] global path refresh (move_base planner_frequency 1 Hz)
    other_robot_margin: float = 0.3  # [m] extra radius of other robots in the global path
    keep_right_offset: float = 0.3  # [m] lateral shift of robots ahead in the global path
    max_other_speed: float = 1.0  # [m/s] cap on velocities estimated from pose frames
    stuck_timeout: float = 10.0  # [s] no progress for this long → stuck
    blocked_after: float = 5.0  # [s] no progress for this long → re-plan around the robots
    # nearby at their full inflated size (no keep-clear shrink): a robot that blocks the way
    # (an escort between us and a wall) becomes an obstacle of the global path
    progress_epsilon: float = 0.1  # [m] path-length decrease that counts as progress
    rotate_time: float = 3.0  # [s] recovery: rotate in place at max_rot_vel
    back_off_time: float = 1.5  # [s] recovery: drive backwards
    back_off_speed: float = 0.1  # [m/s]
    blocked_edge_penalty: float = 10.0  # [m] added to a blocked edge's weight on replanning
    deferred_replan: bool = True  # periodic / blocked re-plans run after the command (step 2)

    def __post_init__(self) -> None:
        for name in ("robot_radius", "resolution", "replan_period", "stuck_timeout"):
            if getattr(self, name) <= 0:
                raise ValueError(f"ExecutorConfig.{name} must be positive")


@dataclass(frozen=True, eq=False)
class ExecutorInputs:
    """One tick's inputs: time [s], own pose (x, y, θ), the other robots of the pose frame as
    rows ``(id, x, y, θ)`` (K, 4), optionally a new plan ``(prefix, suffix)`` and the coupling
    limits of this tick (``tlfleet.agent.nav.coupling_limits``; they bound every command, recovery
    rotations included)."""

    t: float
    pose: tuple[float, float, float]
    others: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    new_plan: tuple[tuple[str, ...], tuple[str, ...]] | None = None
    limits: VelocityLimits | None = None


@dataclass(frozen=True, eq=False)
class ExecutorOutputs:
    """One tick's outputs: the command (v [m/s], ω [rad/s]), events, progress, and the global
    path being followed (W, 2) [m] (empty when none), for display."""

    v: float
    omega: float
    events: tuple[NavEvent, ...]
    progress: Progress
    path: np.ndarray


@dataclass(frozen=True, eq=False)
class PathRequest:
    """A global re-plan decided at sim time ``t`` [s] and run later (:meth:`Executor.refresh`):
    from ``start`` (2,) [m] to the centre ``goal`` (2,) [m] of region ``target``, with the other
    robots stamped as discs ``centers`` (J, 2) [m], ``radii`` (J,) [m]; ``blocked``: stamped at
    full size (step 4)."""

    t: float
    target: str
    start: np.ndarray
    goal: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    blocked: bool


@dataclass(frozen=True, eq=False)
class ExecutorState:
    """Everything the executor remembers between ticks (immutable; ``step`` returns a new one)."""

    prefix: tuple[str, ...]
    suffix: tuple[str, ...]
    step: int = 0  # index of the current target in prefix · suffix^ω
    mode: str = NAVIGATE
    mode_since: float = 0.0  # [s]
    visits: tuple[tuple[str, int], ...] = ()
    last_region: str | None = None
    command: tuple[float, float] = (0.0, 0.0)  # last (v, ω) sent
    control_cycles: int = 0
    path: np.ndarray | None = None
    path_target: str | None = None
    path_time: float = -math.inf  # [s]
    no_path_to: str | None = None  # target last reported unreachable (NoPathFound sent once)
    blocked_plan: bool = False  # the current path was planned around robots at full size
    best_remaining: float = math.inf  # [m]
    progress_time: float = 0.0  # [s]
    remaining: float = math.inf  # [m]
    stuck_count: int = 0
    cycle_start: float | None = None  # [s] when the current suffix pass began
    prev_others: np.ndarray | None = None  # (K, 4) previous frame's other robots
    prev_time: float | None = None  # [s]
    pending: PathRequest | None = None  # a deferred global re-plan, not run yet
    no_path_note: NoPathFound | None = None  # a deferred re-plan's failure, reported next step

    @property
    def cycles(self) -> int:
        """Completed passes through the suffix."""
        if not self.suffix:
            return 0
        return max(0, (self.step - len(self.prefix)) // len(self.suffix))

    @property
    def rounds(self) -> int:
        """GF progress: how many times every region of the suffix has been visited (the minimum
        of their visit counts)."""
        if not self.suffix:
            return 0
        counts = dict(self.visits)
        return min(counts.get(name, 0) for name in set(self.suffix))

    @property
    def target(self) -> str | None:
        return None if self.mode == HOLD else target_at(self.prefix, self.suffix, self.step)


def target_at(prefix: Sequence[str], suffix: Sequence[str], step: int) -> str | None:
    """The ``step``-th region of ``prefix · suffix^ω`` (None past the end of a finite plan)."""
    if step < len(prefix):
        return prefix[step]
    if not suffix:
        return None
    return suffix[(step - len(prefix)) % len(suffix)]


def _move_toward(current: float, goal: float, max_change: float) -> float:
    return current + min(max(goal - current, -max_change), max_change)


@dataclass(frozen=True, eq=False)
class Executor:
    """The executor's fixed context: regions, static grid and configuration.

    ``grid`` is the static arena inflated by ``robot_radius + inflation_margin``;
    ``other_radii`` maps robot ids to radii [m] for the local cost map; rows of the pose frame
    with the executor's own ``robot_id`` are ignored, so the runtime may pass the whole frame.
    """

    regions: tuple[Region, ...]
    grid: OccupancyGrid
    config: ExecutorConfig = field(default_factory=ExecutorConfig)
    other_radii: tuple[tuple[int, float], ...] = ()
    robot_id: int | None = None

    @staticmethod
    def from_scenario(
        scenario: Scenario, robot_id: int, config: ExecutorConfig | None = None
    ) -> Executor:
        """Executor for one unicycle of a scenario: its radius and limits set the grid and DWA."""
        robot = scenario.robot(robot_id)
        base = config or ExecutorConfig()
        limits = robot.unicycle
        dwa = replace(
            base.dwa,
            max_vel_x=limits.max_v,
            max_rot_vel=limits.max_omega,
            acc_lim_x=limits.acc_v,
            acc_lim_theta=limits.acc_omega,
            controller_period=1.0 / scenario.ltl.control_rate,
        )
        cfg = replace(base, robot_radius=robot.radius, dwa=dwa)
        grid = grid_from_arena(scenario.arena, robot.radius + cfg.inflation_margin, cfg.resolution)
        radii = tuple((r.id, r.radius) for r in scenario.robots if r.id != robot_id)
        return Executor(scenario.regions, grid, cfg, radii, robot_id)

    def region(self, name: str) -> Region:
        for region in self.regions:
            if region.name == name:
                return region
        known = ", ".join(r.name for r in self.regions)
        raise KeyError(f"no region {name!r} (regions: {known})")

    def _check_plan(self, prefix: Sequence[str], suffix: Sequence[str]) -> None:
        plan = (tuple(prefix), tuple(suffix))
        names = (
            [*prefix[1:], *suffix] if prefix and prefix[0] == START_STATE else [*prefix, *suffix]
        )
        if not names:
            raise InvalidPlanError(plan, "the plan has no region")
        known = {r.name for r in self.regions}
        unknown = [name for name in names if name not in known]
        if unknown:
            raise InvalidPlanError(plan, f"unknown regions {unknown} (known: {sorted(known)})")

    def initial_state(
        self, prefix: Sequence[str], suffix: Sequence[str], t0: float = 0.0
    ) -> ExecutorState:
        """State before the first step for the plan ``prefix · suffix^ω`` (region names)."""
        self._check_plan(prefix, suffix)
        names = tuple(n for n in dict.fromkeys((*prefix, *suffix)) if n != START_STATE)
        return ExecutorState(
            prefix=tuple(prefix),
            suffix=tuple(suffix),
            visits=tuple((n, 0) for n in names),
            mode_since=t0,
            progress_time=t0,
        )

    # ------------------------------------------------------------------ the step

    def step(
        self, state: ExecutorState, inputs: ExecutorInputs
    ) -> tuple[ExecutorState, ExecutorOutputs]:
        """One control tick: ``(state, inputs) -> (state, outputs)``; pure."""
        t = float(inputs.t)
        pose = np.asarray(inputs.pose, dtype=float)[:3]
        events: list[NavEvent] = []
        s = self._take_note(self.refresh(state), events)  # a re-plan not run after the command
        frame = np.asarray(inputs.others, dtype=float).reshape(-1, 4)
        others = self._local_obstacles(s, frame, pose, t)
        s = evolve(s, control_cycles=s.control_cycles + 1, prev_others=frame, prev_time=t)
        if inputs.new_plan is not None:
            s = self._accept_plan(s, inputs.new_plan, t, events)
        if s.mode != HOLD:
            s = self._visit(s, pose, t, events)
        limits = inputs.limits
        if s.mode == HOLD:
            s, command = self._settle(s, pose, others, limits)
        elif s.mode in (ROTATE, BACK_OFF):
            s, command = self._recover(s, pose, t, others, events, limits)
        else:
            s, command = self._navigate(s, pose, t, others, events, limits)
        s = evolve(s, command=command)
        for event in events:
            log.debug("t=%.2f %s", t, event)
        return s, ExecutorOutputs(
            v=command[0],
            omega=command[1],
            events=tuple(events),
            progress=self._progress(s),
            path=s.path if s.path is not None else np.zeros((0, 2)),
        )

    def _accept_plan(self, s: ExecutorState, plan, t: float, events: list) -> ExecutorState:
        prefix, suffix = tuple(plan[0]), tuple(plan[1])
        self._check_plan(prefix, suffix)
        counts = dict(s.visits)
        for name in (*prefix, *suffix):
            if name != START_STATE:
                counts.setdefault(name, 0)
        events.append(PlanAccepted(t, prefix, suffix))
        # prefix[0] is where the planner assumes the robot is: the last region it visited (when
        # replanning from there) is taken as reached, without counting a new visit.
        start_step = 1 if prefix and prefix[0] == s.last_region else 0
        s = evolve(
            s,
            prefix=prefix,
            suffix=suffix,
            step=start_step,
            mode=NAVIGATE,
            mode_since=t,
            visits=tuple(counts.items()),
            path=None,
            path_target=None,
            best_remaining=math.inf,
            progress_time=t,
            cycle_start=t if start_step == len(prefix) else None,
        )
        if self._finished(s):
            events.append(PlanFinished(t, s.last_region or prefix[-1]))
            s = evolve(s, mode=HOLD, mode_since=t)
        return s

    def _local_obstacles(
        self, s: ExecutorState, frame: np.ndarray, pose: np.ndarray, t: float
    ) -> MovingDiscs:
        """Other robots of the pose frame (K, 4) within ``local_range`` as moving discs (the local
        cost map's layer); velocities from the previous frame, capped at ``max_other_speed``.

        Plain floats over the few rows, with the array form's operations:
        ``‖·‖ = sqrt(x² + y²)``, ``u = Δp / Δt``, ``u·cap / ‖u‖``."""
        px, py = float(pose[0]), float(pose[1])
        local_range = self.config.local_range
        near = []
        for row in frame.tolist():
            if row[0] == self.robot_id:
                continue
            dx, dy = row[1] - px, row[2] - py
            if math.sqrt(dx * dx + dy * dy) <= local_range:
                near.append(row)
        if not near:
            return MovingDiscs.empty()
        velocities = [(0.0, 0.0)] * len(near)
        if s.prev_others is not None and s.prev_time is not None and t > s.prev_time:
            dt = t - s.prev_time
            cap = self.config.max_other_speed
            previous = {int(row[0]): (row[1], row[2]) for row in s.prev_others.tolist()}
            for k, row in enumerate(near):
                before = previous.get(int(row[0]))
                if before is not None:
                    ux, uy = (row[1] - before[0]) / dt, (row[2] - before[1]) / dt
                    speed = math.sqrt(ux * ux + uy * uy)
                    if speed > cap:
                        ux, uy = ux * cap / max(speed, 1e-12), uy * cap / max(speed, 1e-12)
                    velocities[k] = (ux, uy)
        radii_by_id = dict(self.other_radii)
        radii = [radii_by_id.get(int(row[0]), self.config.default_other_radius) for row in near]
        return MovingDiscs(np.array([(row[1], row[2]) for row in near]), np.array(velocities),
                           np.array(radii))

    def _visit(self, s: ExecutorState, pose: np.ndarray, t: float, events: list) -> ExecutorState:
        """Advance over every target the robot is currently in (bounded by the plan length).

        The planner's conventions (tlfleet.agent.ltl.planner): ``prefix[0]`` may be the virtual
        ``"start"`` state, passed at once; a name equal to the previous one means "stay", passed
        at once without counting a new visit.
        """
        tolerance = self.config.dwa.xy_goal_tolerance
        for _ in range(len(s.prefix) + len(s.suffix) + 1):
            target = target_at(s.prefix, s.suffix, s.step)
            if target is None:
                break
            previous = target_at(s.prefix, s.suffix, s.step - 1) if s.step > 0 else None
            if s.step == 0 and target == START_STATE:
                s = evolve(s, step=1)
                continue
            stay = previous == target and s.last_region == target
            if not stay:
                region = self.region(target)
                near = math.dist(region.center, pose[:2]) <= tolerance
                if not (region.contains(pose[0], pose[1]) or near):
                    break
                counts = dict(s.visits)
                counts[target] = counts.get(target, 0) + 1
                events.append(RegionVisited(t, target, counts[target]))
                s = evolve(
                    s,
                    mode=NAVIGATE if s.mode in (ROTATE, BACK_OFF) else s.mode,  # ends recovery
                    visits=tuple(counts.items()),
                    last_region=target,
                    best_remaining=math.inf,
                    progress_time=t,
                    path=None,
                    path_target=None,
                )
            s = evolve(s, step=s.step + 1)
            into_suffix = s.step - len(s.prefix)
            if s.suffix and into_suffix == 0:
                s = evolve(s, cycle_start=t)
            elif s.suffix and into_suffix > 0 and into_suffix % len(s.suffix) == 0:
                start = s.cycle_start if s.cycle_start is not None else t
                events.append(CycleCompleted(t, s.cycles, t - start))
                s = evolve(s, cycle_start=t)
            if self._finished(s):
                events.append(PlanFinished(t, target))
                return evolve(s, mode=HOLD, mode_since=t)
        return s

    def _finished(self, s: ExecutorState) -> bool:
        """No further motion: past a finite plan, or in a suffix that loops on one region."""
        if s.step < len(s.prefix):
            return False
        if not s.suffix:
            return True
        return len(set(s.suffix)) == 1 and s.last_region == s.suffix[0]

    def _ramp(self, current: tuple[float, float], goal: tuple[float, float]) -> tuple[float, float]:
        """The command closest to ``goal`` reachable from ``current`` in one period, saturated."""
        d = self.config.dwa
        v = _move_toward(current[0], goal[0], d.acc_lim_x * d.controller_period)
        w = _move_toward(current[1], goal[1], d.acc_lim_theta * d.controller_period)
        v = min(max(v, -d.max_vel_x), d.max_vel_x)
        w = min(max(w, -d.max_rot_vel), d.max_rot_vel)
        return v, w

    def _recover(
        self, s: ExecutorState, pose: np.ndarray, t: float, others: MovingDiscs, events: list,
        limits: VelocityLimits | None = None,
    ) -> tuple[ExecutorState, tuple[float, float]]:
        """Recovery: rotate in place, then back off (if the space behind is free of walls and
        robots), then ask for a replan and resume."""
        cfg = self.config
        if s.mode == ROTATE and t - s.mode_since >= cfg.rotate_time:
            # The back-off travels at most back_off_speed · back_off_time; check 0.1 m beyond.
            reach = cfg.back_off_speed * cfg.back_off_time + 0.1
            behind = pose[:2] - reach * np.array([math.cos(pose[2]), math.sin(pose[2])])
            gaps = np.linalg.norm(others.centers - behind, axis=1) - others.radii
            back_free = bool(self.grid.clearance_at(behind) > cfg.robot_radius) and bool(
                np.all(gaps > cfg.robot_radius)
            )
            s = evolve(s, mode=BACK_OFF if back_free else NAVIGATE, mode_since=t)
            if s.mode == NAVIGATE:
                return self._end_recovery(s, pose, t, events), self._ramp(s.command, (0.0, 0.0))
        if s.mode == BACK_OFF and t - s.mode_since >= cfg.back_off_time:
            s = self._end_recovery(s, pose, t, events)
            return s, self._ramp(s.command, (0.0, 0.0))
        rot = cfg.dwa.max_rot_vel
        back = cfg.back_off_speed
        if limits:
            rot, back = min(rot, limits.omega_max), min(back, limits.v_max)
        if s.mode == ROTATE:
            return s, self._ramp(s.command, (0.0, rot))
        return s, self._ramp(s.command, (-back, 0.0))

    def _end_recovery(
        self, s: ExecutorState, pose: np.ndarray, t: float, events: list
    ) -> ExecutorState:
        target = s.target
        if target is not None:
            events.append(
                ReplanRequest(
                    t,
                    s.last_region,
                    target,
                    self.config.blocked_edge_penalty,
                    (float(pose[0]), float(pose[1])),
                )
            )
        return evolve(
            s,
            mode=NAVIGATE,
            mode_since=t,
            best_remaining=math.inf,
            progress_time=t,
            path=None,
            path_target=None,
        )

    def _navigate(
        self, s: ExecutorState, pose: np.ndarray, t: float, others: MovingDiscs, events: list,
        limits: VelocityLimits | None = None,
    ) -> tuple[ExecutorState, tuple[float, float]]:
        cfg = self.config
        target = s.target
        if target is None:  # past the end of a finite plan: nothing to drive to
            return evolve(s, mode=HOLD, mode_since=t), self._ramp(s.command, (0.0, 0.0))
        goal = self.region(target).center
        blocked = t - s.progress_time >= cfg.blocked_after and len(others) > 0
        following = s.path is not None and s.path_target == target
        if (not following or t - s.path_time >= cfg.replan_period
                or (blocked and not s.blocked_plan)):
            centers, radii = (self._stamps(pose, others, full=blocked) if len(others)
                              else (np.zeros((0, 2)), np.zeros(0)))
            request = PathRequest(t, target, pose[:2].copy(), np.asarray(goal, dtype=float),
                                  centers, radii, blocked)
            if following and cfg.deferred_replan:  # run after the command (module docstring)
                s = evolve(s, pending=request, path_time=t)
            else:
                s = self._take_note(self._run_request(s, request), events)
        if s.path is None or s.path_target != target:
            command = self._ramp(s.command, (0.0, 0.0))
            remaining = math.inf
        else:
            result = dwa_control(
                pose, s.command, s.path, self.grid, cfg.robot_radius, others, cfg.dwa, limits
            )
            command = (result.v, result.omega)
            px, py = float(pose[0]), float(pose[1])
            ahead = remaining_vertices(px, py, s.path.tolist())
            dx, dy = ahead[0][0] - px, ahead[0][1] - py
            remaining = math.sqrt(dx * dx + dy * dy) + vertices_length(ahead)
        if remaining < s.best_remaining - cfg.progress_epsilon:
            s = evolve(s, remaining=remaining, best_remaining=remaining, progress_time=t)
        elif t - s.progress_time >= cfg.stuck_timeout:
            events.append(Stuck(t, target, s.progress_time, (float(pose[0]), float(pose[1]))))
            log.info("stuck on the way to %s since t=%.1f s: recovering", target, s.progress_time)
            s = evolve(s, remaining=remaining, mode=ROTATE, mode_since=t,
                        stuck_count=s.stuck_count + 1)
            command = self._ramp(s.command, (0.0, 0.0))
        else:
            s = evolve(s, remaining=remaining)
        return s, command

    def refresh(self, state: ExecutorState) -> ExecutorState:
        """Run the global re-plan the last step deferred (``state.pending``; the module
        docstring, step 2), if any; pure. The runtime calls it after publishing the command; a
        failure is reported as ``NoPathFound`` by the next step. Only a step sets ``pending``,
        for the path it follows, and the next step runs it first, so its target is current."""
        request = state.pending
        if request is None:
            return state
        return self._run_request(evolve(state, pending=None), request)

    @staticmethod
    def _take_note(s: ExecutorState, events: list) -> ExecutorState:
        """Move a re-plan's ``NoPathFound`` (``no_path_note``) into this step's events."""
        if s.no_path_note is None:
            return s
        events.append(s.no_path_note)
        return evolve(s, no_path_note=None)

    def _run_request(self, s: ExecutorState, request: PathRequest) -> ExecutorState:
        """Plan ``request`` on the static grid with its robots stamped; on success the path
        replaces the current one, else the current one is kept and the failure is noted once
        per target (``no_path_note``) and retried every ``replan_period``."""
        grid = self.grid
        if len(request.centers):
            grid = grid.with_disc_blocks(request.centers, request.radii)
        try:
            path = plan_path(grid, request.start, request.goal).waypoints
        except NoPathError as error:
            note = None
            if s.no_path_to != request.target:  # report once, keep trying every replan period
                note = NoPathFound(request.t, request.target, error.reason)
                log.info("no path to %s: %s", request.target, error.reason)
            return evolve(s, path_time=request.t, no_path_to=request.target, no_path_note=note)
        return evolve(s, path=path, path_target=request.target, path_time=request.t,
                       no_path_to=None, blocked_plan=request.blocked)

    def _stamps(self, pose: np.ndarray, others: MovingDiscs, full: bool = False
                ) -> tuple[np.ndarray, np.ndarray]:
        """Discs (centres (J, 2), radii (J,)) [m] that put the other robots into the global grid.

        Each robot is stamped with radius ``r + other_robot_margin``, shrunk where needed so that
        our own position stays outside its inflated disc (a robot that close, such as an STL robot
        escorting us, is left to the DWA). Each robot ahead gets a second disc shifted by
        ``keep_right_offset`` to our left, so the path passes it on our right (we keep right):
        two robots meeting head-on then pick opposite sides in the world instead of mirroring
        each other into a deadlock. ``full`` (after ``blocked_after`` without progress): every
        robot at its full radius ``r + other_robot_margin`` and no shift, so the path goes around
        the robots that block it (the planner snaps our start out of their discs).
        """
        cfg = self.config
        centers = others.centers
        if full:
            return centers, others.radii + cfg.other_robot_margin
        gap = (
            np.linalg.norm(centers - pose[:2], axis=1) - self.grid.inflation - self.grid.resolution
        )
        radii = np.minimum(others.radii + cfg.other_robot_margin, gap)
        heading = np.array([math.cos(pose[2]), math.sin(pose[2])])
        ahead = ((centers - pose[:2]) @ heading > 0.0) & (radii > 0.0)
        if cfg.keep_right_offset > 0.0 and np.any(ahead):
            left = np.array([-heading[1], heading[0]])
            shifted = centers[ahead] + cfg.keep_right_offset * left[None, :]
            shift_gap = (
                np.linalg.norm(shifted - pose[:2], axis=1)
                - self.grid.inflation
                - self.grid.resolution
            )
            centers = np.vstack([centers, shifted])
            radii = np.concatenate([radii, np.minimum(radii[ahead], shift_gap)])
        keep = radii > 0.0
        return centers[keep], radii[keep]

    def _settle(
        self, s: ExecutorState, pose: np.ndarray, others: MovingDiscs,
        limits: VelocityLimits | None = None,
    ) -> tuple[ExecutorState, tuple[float, float]]:
        """Holding: drive on to the final region's centre (as move_base does with its last goal)
        and stop within xy_goal_tolerance; no stuck detection."""
        if s.last_region is None:
            return s, self._ramp(s.command, (0.0, 0.0))
        goal = self.region(s.last_region).center
        if s.path is None:
            try:
                path = plan_path(self.grid, pose[:2], goal).waypoints
            except NoPathError:
                return s, self._ramp(s.command, (0.0, 0.0))
            s = evolve(s, path=path, path_target=s.last_region)
        result = dwa_control(
            pose, s.command, s.path, self.grid, self.config.robot_radius, others, self.config.dwa,
            limits,
        )
        return s, (result.v, result.omega)

    def _progress(self, s: ExecutorState) -> Progress:
        return Progress(
            target=s.target,
            step=s.step,
            visits=s.visits,
            cycles=s.cycles,
            rounds=s.rounds,
            control_cycles=s.control_cycles,
            mode=s.mode,
            stuck_count=s.stuck_count,
            distance_to_target=s.remaining,
        )
