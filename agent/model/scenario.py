"""Typed model of a scenario file (architecture.md §5, scenarios.md).

Every value is immutable; lengths are in metres, angles in radians, times in seconds, rates in Hz.
The loader (``tlfleet.agent.scenario.loader``) is the only place that builds these from TOML and it
validates everything, so code that receives a ``Scenario`` can trust it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from tlfleet.agent.model.faults import Fault

RobotKind = Literal["unicycle", "omni"]


@dataclass(frozen=True)
class RectObstacle:
    """Axis-aligned rectangular static obstacle [m]."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float
    name: str = ""

    def contains(self, x: float, y: float) -> bool:
        return self.xmin <= x <= self.xmax and self.ymin <= y <= self.ymax


@dataclass(frozen=True)
class DiscObstacle:
    """Circular static obstacle: centre [m] and radius [m]."""

    center: tuple[float, float]
    radius: float
    name: str = ""

    def contains(self, x: float, y: float) -> bool:
        return math.hypot(x - self.center[0], y - self.center[1]) <= self.radius


Obstacle = RectObstacle | DiscObstacle


@dataclass(frozen=True)
class Arena:
    """The rectangular workspace [xmin, xmax] × [ymin, ymax] [m], walled on its border."""

    xmin: float = -3.5
    xmax: float = 3.5
    ymin: float = -3.5
    ymax: float = 3.5
    obstacles: tuple[Obstacle, ...] = ()

    @property
    def width(self) -> float:
        return self.xmax - self.xmin

    @property
    def height(self) -> float:
        return self.ymax - self.ymin

    def contains(self, x: float, y: float) -> bool:
        return self.xmin <= x <= self.xmax and self.ymin <= y <= self.ymax


@dataclass(frozen=True)
class Region:
    """A region of interest for LTL robots: a disc (centre [m], radius [m]).

    :attr:`labels` are the atomic propositions that hold while a robot is inside: those declared
    (the scenario file's ``labels``), or, when none are, just the region's own name. A generic
    proposition may label several regions (ltl-planning.md §3).
    """

    name: str
    center: tuple[float, float]  # [m]
    radius: float = 0.25  # [m]
    declared_labels: frozenset[str] = frozenset()  # none: the region's own name

    @property
    def labels(self) -> frozenset[str]:
        return self.declared_labels or frozenset({self.name})

    def contains(self, x: float, y: float) -> bool:
        return math.hypot(x - self.center[0], y - self.center[1]) <= self.radius


@dataclass(frozen=True)
class UnicycleLimits:
    """Velocity and acceleration limits of a unicycle (Kobuki defaults, ltl-planning.md §6)."""

    max_v: float = 0.3  # [m/s]
    max_omega: float = 1.0  # [rad/s]
    acc_v: float = 1.0  # [m/s²]
    acc_omega: float = 2.0  # [rad/s²]


@dataclass(frozen=True)
class OmniLimits:
    """Saturation of an omnidirectional robot (stl-funnel.md §10.1, scenarios.md)."""

    max_lin: float = 0.2  # [m/s], bound on ‖(vx, vy)‖
    max_ang: float = 6.28  # [rad/s], bound on |ω|
    acc_lin: float = 2.0  # [m/s²], low-level velocity tracking (simulator)
    acc_ang: float = 20.0  # [rad/s²]


@dataclass(frozen=True)
class Robot:
    """One robot of the fleet.

    Exactly one of ``ltl`` (an LTL formula in Spot syntax) and ``stl`` (a non-empty sequence of
    STL sub-task strings, executed in order: stl-funnel.md §9) is set.
    ``phase_start_times`` forces the activation times of sub-tasks 2..m (stl-funnel.md §9 item 4).

    The texts are what the file says (reports and events quote them). The model holds text only:
    the cores turn it into formula trees (:func:`tlfleet.agent.ltl.task.robot_formula`,
    :func:`tlfleet.agent.stl.parser.robot_subtasks`), parsed once per process and text.
    """

    id: int
    kind: RobotKind
    pose: tuple[float, float, float]  # (x [m], y [m], θ [rad])
    radius: float = 0.2  # [m]
    ltl: str | None = None
    stl: tuple[str, ...] = ()
    phase_start_times: tuple[float, ...] | None = None
    rho_opt: tuple[float | None, ...] = ()  # per sub-task override of ρ_opt (stl-funnel.md §3)
    unicycle: UnicycleLimits = field(default_factory=UnicycleLimits)
    omni: OmniLimits = field(default_factory=OmniLimits)

    @property
    def is_ltl(self) -> bool:
        return self.ltl is not None

    @property
    def is_stl(self) -> bool:
        return bool(self.stl)


@dataclass(frozen=True)
class LtlParams:
    """Parameters of the LTL planner (ltl-planning.md §5) and the LTL control loop."""

    suffix_weight: float = 10.0  # β in cost = prefix + β·suffix (P_MAS_TG default)
    control_rate: float = 5.0  # [Hz]
    # LTL agents at phase offsets within the control period (Scenario.control_phase):
    # no two of them step on the same mocap tick while there are at most d of them
    stagger: bool = True


@dataclass(frozen=True)
class StlParams:
    """Parameters of the STL agents (stl-funnel.md §10.1 and §15); scenario-wide."""

    eta: float = 10.0  # LSE sharpness η
    n_stage1: int = 2  # K = N_i, stage-1 repairs before stage 2/3
    delta: float = 0.02  # δ, r decrement / stage-3 margin
    zeta_l: float = 0.2  # ζ_l, lower margin after a stage-1/2 repair
    r1: float = 0.6  # [m] R1, full-repulsion radius
    r_sense: float = 0.7  # [m] R, collision-avoidance sensing radius
    beta: float = 2.0  # β_i, collision weight in eq. (6)
    control_rate: float = 100.0  # [Hz]
    # F-task termination (stl-funnel.md §6.1 step 5 and §8; docs/stl-saturation.md §6). The
    # defaults meet feasible tasks: no hold, and an F sub-task is done at the first instant of its
    # window where ρ reaches the level its first funnel aimed at (r_frac·ρ_max > 0), or where it
    # has been met already and the next sub-task needs the robot (look-ahead). The authors' code:
    # hold_f_above_r = true, complete_f_on_satisfaction = true, complete_f_at_goal = false (done at
    # the first r < ρ < ρ_max, below 0 once repairs lowered r). The paper's Algorithm 2: the first
    # two false (the funnel controller runs through the whole window).
    hold_f_above_r: bool = False
    complete_f_on_satisfaction: bool = True
    complete_f_at_goal: bool = True
    lookahead: bool = True  # F sub-tasks met early enough for the next one (stl-saturation.md §6)
    # Saturation-aware funnels (docs/stl-saturation.md §3-§4): the lower boundary climbs at most
    # at saturation_share × the rate the speed limit allows; false: the authors' exponential
    # funnel whatever the limit.
    saturation_aware: bool = True
    saturation_share: float = 0.9
    # ρ_opt of a sub-task without rho_opt: the supremum over the arena (bodies, walls, obstacles
    # and coupled pairs kept apart; stl-saturation.md §5); false: the literal bound (§3).
    rho_opt_from_arena: bool = True
    # Robots coupled by a literal avoid each other with radii from their bodies:
    # R1 = r_i + r_j + coupled_r1_margin, R = r_i + r_j + coupled_r_margin [m] (stl-saturation.md
    # §7); false: R1 and R above for every pair (paper eq. (6)).
    coupled_radii: bool = True
    coupled_r1_margin: float = 0.03  # [m]
    coupled_r_margin: float = 0.08  # [m]
    # Walls and static obstacles in eq. (6) (stl-saturation.md §8): full repulsion below
    # r + wall_r1_margin from a surface, none beyond r + wall_r_margin [m]; route_around: a
    # sub-task whose goal is out of sight follows a grid-planner route around the obstacles.
    wall_avoidance: bool = True
    wall_r1_margin: float = 0.03  # [m]
    wall_r_margin: float = 0.10  # [m]
    route_around: bool = True
    # Robustness recovery (tlfleet.agent.stl.recovery, docs/coupling.md §2; beyond the paper, §V):
    # raise r again once the robustness has room. False reproduces Algorithm 2 as published.
    recovery: bool = True


@dataclass(frozen=True)
class NavParams:
    """Navigation of the LTL robots beyond the paper (docs/coupling.md).

    ``coupling_aware``: an LTL robot that STL tasks depend on limits its (v, ω) to what those
    robots can track (``tlfleet.agent.nav.coupling_limits``); false reproduces the purely reactive
    navigation of the paper. ``coupling_share``: the share κ of a dependant's input the leader may
    use up (the same constant for every scenario).
    """

    coupling_aware: bool = True
    coupling_share: float = 0.9

    def __post_init__(self) -> None:
        if not 0.0 < self.coupling_share <= 1.0:
            raise ValueError(f"navigation.coupling_share must be in (0, 1], got "
                             f"{self.coupling_share}")


@dataclass(frozen=True)
class SimParams:
    """Simulator settings (architecture.md §3)."""

    physics_rate: float = 1000.0  # [Hz] pymunk steps
    mocap_rate: float = 100.0  # [Hz] pose frames (and the lockstep tick)
    disturbance: float = 0.0  # [m/s] bound on ‖w_i‖, additive velocity disturbance
    mocap_noise: float = 0.0  # [m] standard deviation of position noise (heading: same in rad)
    seed: int = 0
    watchdog: float = 0.5  # [s] a robot with no fresh command for this long is stopped
    # Realtime only: each robot's frames are sampled at its own offset within the mocap period
    # (Scenario.frame_offset), so the agents compute one after another instead of all at once
    # at the tick (architecture.md §3). Lockstep samples every frame at the tick.
    spread_frames: bool = True
    # Realtime, spread frames: the distinct frame instants a mocap period has at most. A fleet
    # with more slots than this shares them, ⌈m / frame_slots⌉ robots an instant
    # (Scenario.frame_offset): every instant wakes the simulator and costs it a publication.
    # Five instants against ten: the simulator 5-13 points of a core less; a 20-robot fleet
    # 5-23 points less; at 30 robots, saturated, the missed deadlines split with the hour
    # (docs/performance.md). Scenario 1 (4 slots) is unaffected.
    frame_slots: int = 5


@dataclass(frozen=True)
class Scenario:
    """One fully specified run (architecture.md §5)."""

    name: str
    fleet: str
    duration: float  # [s]
    arena: Arena
    regions: tuple[Region, ...]
    robots: tuple[Robot, ...]
    ltl: LtlParams = field(default_factory=LtlParams)
    stl: StlParams = field(default_factory=StlParams)
    sim: SimParams = field(default_factory=SimParams)
    navigation: NavParams = field(default_factory=NavParams)
    description: str = ""
    source: Path | None = None
    faults: tuple[Fault, ...] = ()  # [[faults]] (tlfleet.agent.model.faults)

    def robot(self, robot_id: int) -> Robot:
        """The robot with this id; ``KeyError`` naming the known ids otherwise."""
        for robot in self.robots:
            if robot.id == robot_id:
                return robot
        known = ", ".join(str(r.id) for r in self.robots)
        raise KeyError(f"scenario {self.name!r} has no robot {robot_id} (robots: {known})")

    def region(self, name: str) -> Region:
        for region in self.regions:
            if region.name == name:
                return region
        raise KeyError(f"scenario {self.name!r} has no region {name!r}")

    def control_rate(self, robot_id: int) -> float:
        """f_r [Hz]: the LTL loop rate for an LTL robot, the STL loop rate otherwise."""
        return self.ltl.control_rate if self.robot(robot_id).is_ltl else self.stl.control_rate

    def control_divider(self, robot_id: int) -> int:
        """d_r = max(1, round(mocap_rate / f_r)): mocap ticks per control period of the robot
        (architecture.md §3). The one place this is computed: the simulator's due rule and the
        agent's loop both use it."""
        return max(1, round(self.sim.mocap_rate / self.control_rate(robot_id)))

    def control_phase(self, robot_id: int) -> int:
        """φ_r ∈ [0, d_r): robot r is due at the mocap ticks k with (k − φ_r) mod d_r = 0
        (architecture.md §3). 0 for STL robots; for LTL robots with ``ltl.stagger`` (the
        default), the n LTL robots in id order spread evenly over the period, φ = ⌊rank·d/n⌋
        (Scenario 1's two at 5 Hz: ticks 0 and 10 of every 20), so their navigation steps never
        share a tick while n ≤ d; without it, 0. Computed here only, like the
        divider: the simulator's due rule, the frame keys and the agent's loop all use it."""
        robot = self.robot(robot_id)
        divider = self.control_divider(robot_id)
        if not robot.is_ltl or not self.ltl.stagger or divider < 2:
            return 0
        ltl = sorted(r.id for r in self.robots if r.is_ltl)
        return ltl.index(robot_id) * divider // len(ltl)

    @property
    def substeps_per_tick(self) -> int:
        """Physics steps per mocap period (the simulator's ``World.substeps`` of one period)."""
        return max(1, round(self.sim.physics_rate / self.sim.mocap_rate))

    def frame_offset(self, robot_id: int) -> int:
        """s_r ∈ [0, S), S = :attr:`substeps_per_tick`: in realtime with ``sim.spread_frames``
        (the default) robot r's frames are sampled s_r physics steps after their tick and
        published then (architecture.md §3). The period has m evenly spaced slots,
        s = ⌊j·S/m⌋: one per robot due every tick (id order, slots 0 …) and, when the fleet has
        robots with divider ≥ 2 (LTL robots, whose ticks ``control_phase`` already spreads), one
        more, the last, which they share. Scenario 1 (S = 10): STL robots 3, 4, 5 at 0, 2 and 5
        ms of each 10, LTL robots 1 and 2 at 7. A fleet with m > K = ``sim.frame_slots`` shares
        K slots, slot j in ⌊j·K/m⌋ (consecutive ids together, the LTL robots in the last):
        s = ⌊⌊j·K/m⌋·S/K⌋ — a generated 30-robot fleet (K = 5) at 0, 2, 4, 6 and 8 ms, six
        robots each. 0 without ``spread_frames`` or with S = 1.
        Lockstep ignores it: its frames are all the tick's. Computed here only: the simulator's
        schedule, the frame keys and the agent's loop all use it."""
        steps = self.substeps_per_tick
        if not self.sim.spread_frames or steps < 2:
            return 0
        every = sorted(r.id for r in self.robots if self.control_divider(r.id) == 1)
        slots = len(every) + (len(every) < len(self.robots))
        slot = every.index(robot_id) if self.control_divider(robot_id) == 1 else slots - 1
        if slots > self.sim.frame_slots:
            slot, slots = slot * self.sim.frame_slots // slots, self.sim.frame_slots
        return slot * steps // slots

    def every_tick_offsets(self) -> tuple[int, ...]:
        """The distinct frame offsets s ≥ 1 of the robots due every tick, ascending: the
        ``mocap_at/<s>`` keys of the fleet (:meth:`frame_offset`)."""
        return tuple(sorted({self.frame_offset(r.id) for r in self.robots
                             if self.control_divider(r.id) == 1} - {0}))

    def speed_limits(self) -> dict[int, tuple[float, float]]:
        """Robot id → (max linear [m/s], max angular [rad/s]): the plausibility bounds of
        commands (tlfleet.bus.protocol.bounds.FleetBounds)."""
        return {r.id: (r.omni.max_lin, r.omni.max_ang) if r.kind == "omni"
                else (r.unicycle.max_v, r.unicycle.max_omega) for r in self.robots}

    @property
    def robot_ids(self) -> tuple[int, ...]:
        return tuple(sorted(r.id for r in self.robots))

    @property
    def propositions(self) -> frozenset[str]:
        """Every atomic proposition some region carries."""
        return frozenset().union(*(r.labels for r in self.regions)) if self.regions else frozenset()
