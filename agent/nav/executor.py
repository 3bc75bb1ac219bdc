"""Plan executor: drives a unicycle along its LTL plan, one pure step per control tick.

docs/ltl-navigation.md and paper §III-A. The plan is the projection on regions of the optimal
prefix–suffix run (paper Algorithm 1): targets ``τ = prefix · suffix^ω``, with the planner's
conventions (``tlfleet.agent.ltl.planner``): ``prefix[0]`` (``suffix[0]`` when the prefix is
empty) is where the robot is, possibly the virtual ``"start"`` state, and a name equal to the
previous one means "stay". Each step (5 Hz):

1. **The run's word** (docs/ltl-navigation.md §1). The regions whose disc the centre entered
   since the last step (the segment between the two poses meets the disc; re-entry only after
   leaving by ``region_hysteresis``): an entry into the target is a visit (``RegionVisited``)
   and the plan advances (stays pass at once, without a new visit); an entry into the word's last
   letter is a stutter; any other entry is a letter the plan did not schedule
   (``RegionEntered``: the plan does not advance, the agent decides). A suffix that loops on one
   region ends the motion (``PlanFinished``): the robot drives on to that region's centre and
   holds there.
2. **Global path** (``grid_planner.plan_path``, preferring ``path_clearance`` from obstacles)
   from the pose to the target centre, on the keep-out grid of the transition (the word's last
   letter → the target: every other region is an obstacle, docs/ltl-navigation.md §2) with the
   other robots within ``local_range`` stamped in as inflated discs — the paper's local cost map
   — re-planned every ``replan_period`` and whenever the target changes. Robots ahead are stamped
   a second time shifted to our left, so paths keep right. The periodic re-plans (and the
   re-plan around blocking robots of step 5) are *deferred* (``deferred_replan``): the step that
   finds one due keeps following the current path and records a :class:`PathRequest` (its pose
   and the robots to stamp); the runtime runs it with :meth:`Executor.refresh` after the command
   is on its way, and the path is followed from the next step on — move_base's global planner,
   which runs beside the controller at 1 Hz, has the same one-period lag. A step that finds a
   request still pending runs it first, so the trajectory is the same whether or not the caller
   refreshes between steps. A new target (a region reached, a new plan) has no path to follow
   yet and is planned at once.
3. **Right of way** (``traffic``, docs/ltl-navigation.md §6): in a narrow passage or at a
   crossing, the robot without the right of way yields (mode ``yield``, ``Yielding`` events),
   in a passage from a refuge beside its path.
4. **DWA** (``dwa.dwa_control``) follows the path on the same keep-out grid, with the other
   robots as discs moving at the velocity estimated from two consecutive pose frames.
5. **Stuck detection and recovery** (docs/ltl-navigation.md §5). Progress is a decrease of the
   remaining path length by at least ``progress_epsilon``. With none for ``blocked_after`` the
   global path is re-planned with the nearby robots stamped at full size (a robot that blocks
   the way is passed around); with none for ``stuck_timeout`` the executor emits ``Stuck``,
   rotates in place (``rotate_time``), backs off (``back_off_time``, only if the space behind is
   free), waits (``wait_time``), and drives on to the same target (``Recovered``) while a path to
   it exists with the robots stamped at full size, at most ``max_recoveries`` times; otherwise it
   emits ``ReplanRequest`` with the edge (last letter → target). The runtime may answer with a
   new plan (``ExecutorInputs.new_plan``); its first state, when it is the word's last letter,
   counts as reached.

Progress: visits per region (entries of the word), ``rounds`` (GF progress: visits of the least
visited suffix region), ``cycles`` (complete passes through the suffix), the target and the mode
(frozen once the agent has declared the task lost, :meth:`Executor.lose`). Every command respects
the unicycle's velocity and acceleration limits relative to the previous command (the dynamic
window of one controller period).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

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
    Recovered,
    RegionEntered,
    RegionVisited,
    ReplanRequest,
    Stuck,
    Yielding,
)
from tlfleet.agent.nav.grid import (
    DEFAULT_MARGIN,
    DEFAULT_RESOLUTION,
    OccupancyGrid,
    grid_from_arena,
)
from tlfleet.agent.nav.grid_planner import plan_path
from tlfleet.agent.nav.keep_out import RegionPaths
from tlfleet.agent.nav.polyline import point_along_vertices, remaining_vertices, vertices_length
from tlfleet.agent.nav.traffic import (
    Traffic,
    TrafficConfig,
    crossing_conflict,
    narrow_conflict,
    narrow_intervals,
    passing_width,
    refuge,
)

log = logging.getLogger(__name__)

NAVIGATE, ROTATE, BACK_OFF, WAIT, HOLD = "navigate", "rotate", "back_off", "wait", "hold"
YIELD, LOST = "yield", "lost"
RECOVERING = (ROTATE, BACK_OFF, WAIT)
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
    wait_time: float = 2.0  # [s] recovery: stand still (a robot in the way may move on)
    max_recoveries: int = 3  # recoveries on the way to one target before the edge is given up
    blocked_edge_penalty: float = 10.0  # [m] added to a blocked edge's weight on replanning
    deferred_replan: bool = True  # periodic / blocked re-plans run after the command (step 2)
    path_clearance: float = 0.3  # [m] clearance the global path prefers beyond the inflation
    # (grid_planner's clearance preference; 0: the shortest path, grazing inflated obstacles)
    region_hysteresis: float = 0.05  # [m] leave a region by this much before re-entering counts
    traffic: TrafficConfig = field(default_factory=TrafficConfig)  # head-on / crossing rule

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
    from the ``pose`` (3,) [m, rad] to the centre ``goal`` (2,) [m] of region ``target``, with
    the other robots ``others`` stamped as discs (``Executor._stamps``, at full size when
    ``blocked``: step 4), on the keep-out grid of the transition between the ``allowed``
    regions. The stamps are computed when the request runs, from these inputs, so a deferred
    request costs the step nothing."""

    t: float
    target: str
    allowed: tuple[str | None, str]
    pose: np.ndarray
    goal: np.ndarray
    others: MovingDiscs
    blocked: bool

    @property
    def start(self) -> np.ndarray:
        return self.pose[:2]


@dataclass(frozen=True, eq=False)
class ExecutorState:
    """Everything the executor remembers between ticks (immutable; ``step`` returns a new one)."""

    prefix: tuple[str, ...]
    suffix: tuple[str, ...]
    step: int = 0  # index of the current target in prefix · suffix^ω
    mode: str = NAVIGATE
    mode_since: float = 0.0  # [s]
    visits: tuple[tuple[str, int], ...] = ()
    last_region: str | None = None  # the run's word's last letter (None: start)
    inside: frozenset[str] = frozenset()  # regions the centre is in (with the hysteresis)
    prev_position: tuple[float, float] | None = None  # [m] at the last step
    recoveries: int = 0  # recoveries on the way to the current target
    yield_to: int | None = None  # the robot we give way to (mode YIELD)
    yielded: float = 0.0  # [s] spent yielding on the way to the current target
    refuge: tuple[float, float] | None = None  # [m] where a yield in a passage waits
    path_narrow: tuple[tuple[float, float], ...] = ()  # [m] arc lengths of the path's narrow
    # stretches (``traffic.narrow_intervals``), found when the path is planned
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
        if self.mode in (HOLD, LOST):
            return None
        return target_at(self.prefix, self.suffix, self.step)


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
    ruled: frozenset[int] = frozenset()  # other robots that apply the right-of-way rule
    # keep-out grids the caller already built over these regions and grid (the LTL planner
    # weighs its transitions with the same ones); None: built on first use
    shared_paths: RegionPaths | None = None
    # robots whose tasks couple them to this one (escorts, a formation): they move with it, so
    # the right-of-way rule leaves them to the local planner (never yield to a follower)
    followers: frozenset[int] = frozenset()

    @cached_property
    def paths(self) -> RegionPaths:
        """The keep-out paths between the regions: ``shared_paths``, or built from ``regions``
        and ``grid`` with the configured clearance preference."""
        if self.shared_paths is not None:
            return self.shared_paths
        return RegionPaths(tuple(self.regions), self.grid, self.config.path_clearance)

    @cached_property
    def _discs(self) -> tuple[tuple[str, float, float, float, float], ...]:
        """(name, x, y, radius, radius + hysteresis) [m] of every region, for the word's
        entries."""
        return tuple((r.name, float(r.center[0]), float(r.center[1]), float(r.radius),
                      float(r.radius) + self.config.region_hysteresis) for r in self.regions)

    @property
    def _passing_width(self) -> float:
        """The clearance below which the widest other robot cannot pass beside this one."""
        widest = max((r for _, r in self.other_radii), default=self.config.default_other_radius)
        return passing_width(self.config.robot_radius, widest, self.config.traffic)

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
        # the unicycles run this executor and apply the right-of-way rule; the STL robots do not
        ruled = frozenset(r.id for r in scenario.robots
                          if r.id != robot_id and r.kind == "unicycle")
        paths = RegionPaths(tuple(scenario.regions), grid, cfg.path_clearance)
        return Executor(scenario.regions, grid, cfg, radii, robot_id, ruled, paths)

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
        others, traffic = self._local_obstacles(s, frame, pose, t)
        s = evolve(s, control_cycles=s.control_cycles + 1, prev_others=frame, prev_time=t)
        if inputs.new_plan is not None:
            s = self._accept_plan(s, inputs.new_plan, t, events)
        s = self._word(s, pose, t, events)
        limits = inputs.limits
        if s.mode == LOST:
            command = self._ramp(s.command, (0.0, 0.0))
        elif s.mode == HOLD:
            s, command = self._settle(s, pose, others, limits)
        elif s.mode in RECOVERING:
            s, command = self._recover(s, pose, t, others, events, limits)
        else:
            s, command = self._navigate(s, pose, t, others, events, limits, traffic)
        s = evolve(s, command=command, prev_position=(float(pose[0]), float(pose[1])))
        for event in events:
            log.debug("t=%.2f %s", t, event)
        return s, ExecutorOutputs(
            v=command[0],
            omega=command[1],
            events=tuple(events),
            progress=self._progress(s),
            path=s.path if s.path is not None else np.zeros((0, 2)),
        )

    def lose(self, state: ExecutorState, t: float) -> ExecutorState:
        """The task is lost (the run's word left the Büchi automaton): stop and hold still."""
        return evolve(state, mode=LOST, mode_since=t, path=None, path_target=None, pending=None)

    def _accept_plan(self, s: ExecutorState, plan, t: float, events: list) -> ExecutorState:
        prefix, suffix = tuple(plan[0]), tuple(plan[1])
        self._check_plan(prefix, suffix)
        counts = dict(s.visits)
        for name in (*prefix, *suffix):
            if name != START_STATE:
                counts.setdefault(name, 0)
        events.append(PlanAccepted(t, prefix, suffix))
        # The plan's first state (prefix[0], or suffix[0] when the prefix is empty: the
        # planner's convention) is where the planner assumes the robot is: the word's last
        # letter when replanning from there, taken as reached without a new visit.
        first = prefix[0] if prefix else suffix[0]
        start_step = 1 if first in (s.last_region, START_STATE) else 0
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
            pending=None,
            best_remaining=math.inf,
            progress_time=t,
            recoveries=0,
            yield_to=None,
            yielded=0.0,
            cycle_start=t if start_step >= len(prefix) else None,
        )
        s = self._pass_stays(s, t, events)
        if self._finished(s):
            events.append(PlanFinished(t, s.last_region or first))
            s = evolve(s, mode=HOLD, mode_since=t)
        return s

    def _entries(self, s: ExecutorState, pose: np.ndarray) -> tuple[list[str], frozenset[str]]:
        """Regions the centre entered since the last step (docs/ltl-navigation.md §1: the disc
        is entered when the segment from the last position to this one meets it; left when the
        centre is ``region_hysteresis`` outside it), by name, and the regions it is in now."""
        px, py = float(pose[0]), float(pose[1])
        ax, ay = s.prev_position if s.prev_position is not None else (px, py)
        dx, dy = px - ax, py - ay
        seg2 = dx * dx + dy * dy
        entered, inside = [], set(s.inside)
        for name, cx, cy, radius, leave in self._discs:
            if name in inside:
                if math.hypot(px - cx, py - cy) > leave:
                    inside.discard(name)
                continue
            u = 0.0 if seg2 <= 0.0 else min(max(((cx - ax) * dx + (cy - ay) * dy) / seg2, 0.0),
                                            1.0)
            if math.hypot(ax + u * dx - cx, ay + u * dy - cy) <= radius:
                entered.append(name)
                inside.add(name)
        if not entered and len(inside) == len(s.inside):
            return entered, s.inside  # nothing changed (the common step)
        return sorted(entered), frozenset(inside)

    def _word(self, s: ExecutorState, pose: np.ndarray, t: float, events: list
              ) -> ExecutorState:
        """Track the run's word and advance the plan on its planned letters.

        An entry into the region the plan drives to (the target) is a visit: the plan advances
        (stays pass at once, without a new visit). An entry into the word's last letter again is
        a stutter (no letter). Any other entry is a letter the plan did not schedule:
        ``RegionEntered`` (the agent decides: replan or task lost); the plan does not advance.
        """
        entered, inside = self._entries(s, pose)
        if entered or inside != s.inside:
            s = evolve(s, inside=inside)
        if s.mode == LOST:  # the task is lost: no progress is counted any more
            return s
        if s.mode != HOLD and s.step == 0:  # the virtual start (later stays pass on arrival)
            s = self._pass_stays(s, t, events)
        for name in entered:
            if name == s.last_region:
                continue
            counts = dict(s.visits)
            counts[name] = counts.get(name, 0) + 1
            target = s.target
            if name == target:
                events.append(RegionVisited(t, name, counts[name]))
                s = evolve(
                    s,
                    mode=NAVIGATE if s.mode in (*RECOVERING, YIELD) else s.mode,
                    visits=tuple(counts.items()),
                    last_region=name,
                    best_remaining=math.inf,
                    progress_time=t,
                    path=None,
                    path_target=None,
                    pending=None,
                    recoveries=0,
                    yield_to=None,
                    yielded=0.0,
                )
                s = self._advance(s, t, events)
            else:
                events.append(RegionEntered(t, name, target, s.last_region, counts[name]))
                s = evolve(s, visits=tuple(counts.items()), last_region=name, path=None,
                           path_target=None, pending=None)
        return s

    def _advance(self, s: ExecutorState, t: float, events: list) -> ExecutorState:
        """One plan position on (the target was reached), then every stay after it."""
        s = self._step_on(s, t, events)
        if s.mode == HOLD:
            return s
        return self._pass_stays(s, t, events)

    def _pass_stays(self, s: ExecutorState, t: float, events: list) -> ExecutorState:
        """Pass the plan positions that need no motion: the virtual start at position 0, and
        names equal to the word's last letter right after it (a stay)."""
        for _ in range(len(s.prefix) + len(s.suffix) + 1):
            target = target_at(s.prefix, s.suffix, s.step)
            if target is None or s.mode == HOLD:
                break
            if s.step == 0 and target == START_STATE:
                s = self._step_on(s, t, events)
                continue
            previous = target_at(s.prefix, s.suffix, s.step - 1) if s.step > 0 else None
            if not (previous == target and s.last_region == target):
                break
            s = self._step_on(s, t, events)
        return s

    def _step_on(self, s: ExecutorState, t: float, events: list) -> ExecutorState:
        reached = target_at(s.prefix, s.suffix, s.step)
        s = evolve(s, step=s.step + 1)
        into_suffix = s.step - len(s.prefix)
        if s.suffix and into_suffix == 0:
            s = evolve(s, cycle_start=t)
        elif s.suffix and into_suffix > 0 and into_suffix % len(s.suffix) == 0:
            start = s.cycle_start if s.cycle_start is not None else t
            events.append(CycleCompleted(t, s.cycles, t - start))
            s = evolve(s, cycle_start=t)
        if self._finished(s):
            events.append(PlanFinished(t, reached or ""))
            return evolve(s, mode=HOLD, mode_since=t)
        return s

    def _finished(self, s: ExecutorState) -> bool:
        """No further motion: past a finite plan, or in a suffix that loops on one region."""
        if s.step < len(s.prefix):
            return False
        if not s.suffix:
            return True
        return len(set(s.suffix)) == 1 and s.last_region == s.suffix[0]

    def _local_obstacles(
        self, s: ExecutorState, frame: np.ndarray, pose: np.ndarray, t: float
    ) -> tuple[MovingDiscs, Traffic | None]:
        """Other robots of the pose frame (K, 4) within ``local_range`` as moving discs (the local
        cost map's layer); velocities from the previous frame, capped at ``max_other_speed``.
        Beside them, in the same pass, the robots the right-of-way rule considers (``traffic``):
        with a narrow stretch on the path every robot, else the moving ones within its
        ``crossing_range`` (a standing robot is no crossing), never a follower; None with the
        rule off.

        Plain floats over the few rows, with the array form's operations:
        ``‖·‖ = sqrt(x² + y²)``, ``u = Δp / Δt``, ``u·cap / ‖u‖``."""
        px, py = float(pose[0]), float(pose[1])
        local_range = self.config.local_range
        rule = self.config.traffic
        narrow = bool(s.path_narrow)
        reach = (math.inf if narrow else rule.crossing_range) if rule.enabled else -1.0
        previous = None
        if s.prev_others is not None and s.prev_time is not None and t > s.prev_time:
            dt = t - s.prev_time
            cap = self.config.max_other_speed
            previous = {int(row[0]): (row[1], row[2]) for row in s.prev_others.tolist()}
        radii_by_id = dict(self.other_radii)
        default = self.config.default_other_radius
        centers, velocities, radii, rows = [], [], [], []
        for row in frame.tolist():
            if row[0] == self.robot_id:
                continue
            dx, dy = row[1] - px, row[2] - py
            distance = math.sqrt(dx * dx + dy * dy)
            local = distance <= local_range
            if not (local or distance <= reach):
                continue
            rid = int(row[0])
            ux = uy = 0.0
            before = previous.get(rid) if previous is not None else None
            if before is not None:
                ux, uy = (row[1] - before[0]) / dt, (row[2] - before[1]) / dt
                speed = math.sqrt(ux * ux + uy * uy)
                if speed > cap:
                    ux, uy = ux * cap / max(speed, 1e-12), uy * cap / max(speed, 1e-12)
            radius = radii_by_id.get(rid, default)
            if local:
                centers.append((row[1], row[2]))
                velocities.append((ux, uy))
                radii.append(radius)
            if (distance <= reach and (narrow or ux * ux + uy * uy >= 4e-4)
                    and rid not in self.followers):
                rows.append((rid, row[1], row[2], ux, uy, radius, rid in self.ruled))
        traffic = Traffic(tuple(rows)) if rule.enabled else None
        if not centers:
            return MovingDiscs.empty(), traffic
        return (MovingDiscs(np.array(centers), np.array(velocities), np.array(radii)),
                traffic)

    def _ramp(self, current: tuple[float, float], goal: tuple[float, float]) -> tuple[float, float]:
        """The command closest to ``goal`` reachable from ``current`` in one period, saturated."""
        d = self.config.dwa
        v = _move_toward(current[0], goal[0], d.acc_lim_x * d.controller_period)
        w = _move_toward(current[1], goal[1], d.acc_lim_theta * d.controller_period)
        v = min(max(v, -d.max_vel_x), d.max_vel_x)
        w = min(max(w, -d.max_rot_vel), d.max_rot_vel)
        return v, w

    def _edge_grid(self, s: ExecutorState, target: str | None) -> OccupancyGrid:
        """The static grid with the keep-out zones of the transition from the word's last
        letter to ``target`` (docs/ltl-navigation.md §2)."""
        return self.paths.grid_for((s.last_region, target))

    def _recover(
        self, s: ExecutorState, pose: np.ndarray, t: float, others: MovingDiscs, events: list,
        limits: VelocityLimits | None = None,
    ) -> tuple[ExecutorState, tuple[float, float]]:
        """Recovery (Nav2's behaviours, docs/ltl-navigation.md §5): rotate in place, back off
        (if the space behind is free of walls, keep-out zones and robots), wait; then drive on
        to the same target, or ask for a replan when it is out of reach."""
        cfg = self.config
        grid = self._edge_grid(s, s.target)
        if s.mode == ROTATE and t - s.mode_since >= cfg.rotate_time:
            # The back-off travels at most back_off_speed · back_off_time; check 0.1 m beyond.
            reach = cfg.back_off_speed * cfg.back_off_time + 0.1
            behind = pose[:2] - reach * np.array([math.cos(pose[2]), math.sin(pose[2])])
            gaps = np.linalg.norm(others.centers - behind, axis=1) - others.radii
            back_free = bool(grid.clearance_at(behind) > cfg.robot_radius) and bool(
                np.all(gaps > cfg.robot_radius)
            )
            s = evolve(s, mode=BACK_OFF if back_free else WAIT, mode_since=t)
        if s.mode == BACK_OFF and t - s.mode_since >= cfg.back_off_time:
            s = evolve(s, mode=WAIT, mode_since=t)
        if s.mode == WAIT and t - s.mode_since >= cfg.wait_time:
            s = self._end_recovery(s, pose, t, others, events)
            return s, self._ramp(s.command, (0.0, 0.0))
        rot = cfg.dwa.max_rot_vel
        back = cfg.back_off_speed
        if limits:
            rot, back = min(rot, limits.omega_max), min(back, limits.v_max)
        if s.mode == ROTATE:
            return s, self._ramp(s.command, (0.0, rot))
        if s.mode == BACK_OFF:
            return s, self._ramp(s.command, (-back, 0.0))
        return s, self._ramp(s.command, (0.0, 0.0))

    def _end_recovery(
        self, s: ExecutorState, pose: np.ndarray, t: float, others: MovingDiscs, events: list
    ) -> ExecutorState:
        """After a recovery: the same target while a path to it exists with the robots nearby
        stamped at full size and fewer than ``max_recoveries`` recoveries were spent on it;
        else a ``ReplanRequest`` for the edge (last letter → target)."""
        target = s.target
        s = evolve(s, mode=NAVIGATE, mode_since=t, best_remaining=math.inf, progress_time=t,
                   path=None, path_target=None, pending=None)
        if target is None:
            return s
        attempt = s.recoveries + 1
        reachable = False
        if attempt < self.config.max_recoveries:
            grid = self._edge_grid(s, target)
            if len(others):
                centers, radii = self._stamps(pose, others, full=True,
                                              goal=self.region(target).center)
                grid = grid.with_disc_blocks(centers, radii)
            region = self.region(target)
            try:
                end = plan_path(grid, pose[:2], region.center).goal
                reachable = region.contains(*end)  # not a free cell beside a robot on it
            except NoPathError:
                reachable = False
        if reachable:
            events.append(Recovered(t, target, attempt))
            return evolve(s, recoveries=attempt)
        events.append(
            ReplanRequest(
                t,
                s.last_region,
                target,
                self.config.blocked_edge_penalty,
                (float(pose[0]), float(pose[1])),
            )
        )
        return evolve(s, recoveries=0)

    def _give_way(self, s: ExecutorState, pose: np.ndarray, t: float, traffic: Traffic | None,
                  grid: OccupancyGrid, events: list, vertices: list[list[float]],
                  ahead: list[list[float]]) -> tuple[int | None, bool]:
        """The robot to yield to this step (``traffic``), None to drive, and whether it is a
        passage's conflict (else a crossing's); emits ``Yielding`` when a yield begins or ends.
        A yield lasts at most ``traffic.max_wait``. ``vertices``: the path's; ``ahead``: its
        part ahead of the robot's projection (``remaining_vertices``)."""
        narrow = False
        rule = self.config.traffic
        spent = s.yielded + (t - s.mode_since if s.mode == YIELD else 0.0)
        if not rule.enabled or s.path is None or not traffic or spent >= rule.max_wait:
            other = None  # nobody that could conflict (``_local_obstacles``)
        else:
            px, py = float(pose[0]), float(pose[1])
            rid = self.robot_id if self.robot_id is not None else 0
            stretch = None
            if s.path_narrow:  # where the robot is along the path, and the next narrow part
                done = vertices_length(vertices) - vertices_length(ahead)
                for a, b in s.path_narrow:
                    if b > done:
                        stretch = (max(0.0, a - done), b - done)
                        break
                if stretch is not None and stretch[0] > rule.lookahead:
                    stretch = None
            lead = math.hypot(ahead[0][0] - px, ahead[0][1] - py)
            if lead > 1e-6:  # from the robot itself onto its path
                ahead = [[px, py], *ahead]
                if stretch is not None:
                    stretch = (stretch[0] + lead if stretch[0] > 0.0 else 0.0,
                               stretch[1] + lead)
            other = narrow_conflict(rid, (px, py), self.config.robot_radius, ahead, grid,
                                    traffic, rule, stretch)
            narrow = other is not None
            if other is None:
                carrot = point_along_vertices(ahead, self.config.dwa.carrot_distance)
                other = crossing_conflict(rid, (px, py), self.config.robot_radius, carrot,
                                          traffic, rule)
        if other is None and s.mode == YIELD and t - s.mode_since < rule.min_yield and (
                spent < rule.max_wait):
            other = s.yield_to  # hold the yield a moment: no begin/end flicker
            narrow = s.refuge is not None
        position = (float(pose[0]), float(pose[1]))
        if other is not None and s.mode != YIELD:
            events.append(Yielding(t, "begin", other, position))
        elif other is None and s.mode == YIELD:
            events.append(Yielding(t, "end", s.yield_to if s.yield_to is not None else -1,
                                   position))
        return other, narrow

    def _navigate(
        self, s: ExecutorState, pose: np.ndarray, t: float, others: MovingDiscs, events: list,
        limits: VelocityLimits | None = None, traffic: Traffic | None = None,
    ) -> tuple[ExecutorState, tuple[float, float]]:
        cfg = self.config
        target = s.target
        if target is None:  # past the end of a finite plan: nothing to drive to
            return evolve(s, mode=HOLD, mode_since=t), self._ramp(s.command, (0.0, 0.0))
        goal = self.region(target).center
        grid = self._edge_grid(s, target)
        blocked = t - s.progress_time >= cfg.blocked_after and len(others) > 0
        following = s.path is not None and s.path_target == target
        if (not following or t - s.path_time >= cfg.replan_period
                or (blocked and not s.blocked_plan)):
            request = PathRequest(t, target, (s.last_region, target), pose.copy(),
                                  np.asarray(goal, dtype=float), others, blocked)
            if following and cfg.deferred_replan:  # run after the command (module docstring)
                s = evolve(s, pending=request, path_time=t)
            else:
                s = self._take_note(self._run_request(s, request), events)
        if s.path is None or s.path_target != target:
            command = self._ramp(s.command, (0.0, 0.0))
            remaining = math.inf
        else:
            px, py = float(pose[0]), float(pose[1])
            vertices = s.path.tolist()
            ahead = remaining_vertices(px, py, vertices)
            yield_to, narrow = self._give_way(s, pose, t, traffic, grid, events, vertices, ahead)
            if yield_to is not None:
                return self._yield(s, pose, t, yield_to, narrow, grid, others, limits)
            if s.mode == YIELD:
                s = evolve(s, mode=NAVIGATE, mode_since=t, yield_to=None, refuge=None,
                           yielded=s.yielded + t - s.mode_since, path_time=-math.inf)
            result = dwa_control(
                pose, s.command, s.path, grid, cfg.robot_radius, others, cfg.dwa, limits
            )
            command = (result.v, result.omega)
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

    def _yield(self, s: ExecutorState, pose: np.ndarray, t: float, other: int, narrow: bool,
               grid: OccupancyGrid, others: MovingDiscs, limits: VelocityLimits | None
               ) -> tuple[ExecutorState, tuple[float, float]]:
        """Give way to robot ``other`` (``traffic``): at a crossing, stand; in a passage, step
        aside to a refuge first (chosen when the yield begins) and stand there. Waiting for the
        right of way is no stall: the progress clock stands still."""
        cfg = self.config
        if s.mode != YIELD:
            spot = None
            if narrow and s.path is not None:
                px, py = float(pose[0]), float(pose[1])
                ahead = remaining_vertices(px, py, s.path.tolist())
                radii = dict(self.other_radii)
                spot = refuge((px, py), [[px, py], *ahead], grid, cfg.robot_radius,
                              radii.get(other, cfg.default_other_radius), cfg.traffic)
            s = evolve(s, mode=YIELD, mode_since=t, yield_to=other, refuge=spot)
        else:
            s = evolve(s, yield_to=other)
        s = evolve(s, progress_time=t, best_remaining=math.inf)
        if s.refuge is not None:
            aside = np.array([pose[:2], s.refuge])
            if math.dist(pose[:2], s.refuge) > cfg.dwa.xy_goal_tolerance:
                result = dwa_control(pose, s.command, aside, grid, cfg.robot_radius, others,
                                     cfg.dwa, limits)
                return s, (result.v, result.omega)
        return s, self._ramp(s.command, (0.0, 0.0))

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
        grid = self.paths.grid_for(request.allowed)
        if len(request.others):
            centers, radii = self._stamps(request.pose, request.others, full=request.blocked,
                                          goal=request.goal)
            grid = grid.with_disc_blocks(centers, radii)
        try:
            path = plan_path(grid, request.start, request.goal,
                             prefer=self.config.path_clearance).waypoints
        except NoPathError as error:
            note = None
            if s.no_path_to != request.target:  # report once, keep trying every replan period
                note = NoPathFound(request.t, request.target, error.reason)
                log.info("no path to %s: %s", request.target, error.reason)
            return evolve(s, path_time=request.t, no_path_to=request.target, no_path_note=note)
        rule = self.config.traffic
        narrow = (narrow_intervals(path.tolist(), self.paths.grid_for(request.allowed),
                                   self._passing_width, rule.sample) if rule.enabled else ())
        return evolve(s, path=path, path_target=request.target, path_time=request.t,
                      no_path_to=None, blocked_plan=request.blocked, path_narrow=narrow)

    def _stamps(self, pose: np.ndarray, others: MovingDiscs, full: bool = False,
                goal: Sequence[float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Discs (centres (J, 2), radii (J,)) [m] that put the other robots into the global grid.

        Each robot is stamped with radius ``r + other_robot_margin``, shrunk where needed so that
        our own position stays outside its inflated disc (a robot that close, such as an STL robot
        escorting us, is left to the DWA). Each robot ahead gets a second disc shifted by
        ``keep_right_offset`` to our left, so the path passes it on our right (we keep right):
        two robots meeting head-on then pick opposite sides in the world instead of mirroring
        each other into a deadlock. ``full`` (after ``blocked_after`` without progress): every
        robot at its full radius ``r + other_robot_margin`` and no shift, so the path goes around
        the robots that block it (the planner snaps our start out of their discs). With a
        ``goal`` (the target's centre), every disc is also shrunk, down to the robot's own radius,
        so that the goal stays free: a robot standing beside a region leaves its centre
        reachable (else the path would end at the nearest free cell, maybe outside the region).
        """
        cfg = self.config
        centers = others.centers
        if full:
            radii = others.radii + cfg.other_robot_margin
            if goal is not None:
                radii = self._goal_room(centers, radii, others.radii, goal)
            return centers, radii
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
            own = np.concatenate([others.radii, others.radii[ahead]])
        else:
            own = others.radii
        if goal is not None:
            radii = self._goal_room(centers, radii, own, goal)
        keep = radii > 0.0
        return centers[keep], radii[keep]

    def _goal_room(self, centers: np.ndarray, radii: np.ndarray, own: np.ndarray,
                   goal: Sequence[float]) -> np.ndarray:
        """``radii`` shrunk so that ``goal`` lies outside every inflated disc, but not below the
        robots' own radii ``own`` (a robot standing on the goal keeps it blocked)."""
        room = (np.linalg.norm(centers - np.asarray(goal[:2], dtype=float), axis=1)
                - self.grid.inflation - self.grid.resolution)
        return np.where(radii > room, np.maximum(room, np.minimum(own, radii)), radii)

    def _settle(
        self, s: ExecutorState, pose: np.ndarray, others: MovingDiscs,
        limits: VelocityLimits | None = None,
    ) -> tuple[ExecutorState, tuple[float, float]]:
        """Holding: drive on to the final region's centre (as move_base does with its last goal)
        and stop within xy_goal_tolerance; no stuck detection."""
        if s.last_region is None:
            return s, self._ramp(s.command, (0.0, 0.0))
        goal = self.region(s.last_region).center
        grid = self._edge_grid(s, s.last_region)
        if s.path is None:
            try:
                path = plan_path(grid, pose[:2], goal,
                                 prefer=self.config.path_clearance).waypoints
            except NoPathError:
                return s, self._ramp(s.command, (0.0, 0.0))
            s = evolve(s, path=path, path_target=s.last_region)
        result = dwa_control(
            pose, s.command, s.path, grid, self.config.robot_radius, others, self.config.dwa,
            limits,
        )
        return s, (result.v, result.omega)

    def progress(self, s: ExecutorState) -> Progress:
        """The progress record of state ``s`` (the one each step reports)."""
        return self._progress(s)

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
