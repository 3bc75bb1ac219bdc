"""One STL agent as a pure, message-driven step function (stl-funnel.md §6–§9, §12; paper Alg. 2).

    state, out = agent.step(state, StepInput(t, poses, inbox))

``poses[j]`` is robot j's (x [m], y [m], θ [rad]) (numpy array or tuple) for every robot the agent
can see (LTL robots included, for collision avoidance); ``inbox`` the messages delivered to this
agent. ``out.u`` is the world-frame command (v_x [m/s], v_y [m/s], ω [rad/s]) of eq. (6),
``out.messages`` the outgoing messages (each carries its ``receiver``) and ``out.log`` one
:class:`LogRecord`. The state is a small frozen dataclass; the agent object only holds the
immutable configuration (compiled sub-tasks of every STL robot, parameters).

Order of operations in one step (§12):

1. inbox: peer status, collaboration request / update / release (§7.5);
2. sequencer: activate the next sub-task when due (§9), initialising its funnel (§5);
3. own robustness ρ^ψ and ∂ρ^ψ/∂x_i, running ρ^φ over the samples in [a, b];
4. completion (§8): F when a ≤ t ≤ b and r < ρ < ρ_max (or failed at t > b), G at t ≥ b;
5. control: follower → funnel of the requester, no detection (Alg. 2 line 5);
   own F with ρ > r → hold (u_nom = 0); otherwise ζ, critical event → stage (§7.4) →
   repair R1–R10 (§7.3) → ζ again; ε; u_nom (§6.1);
6. u = saturate(β·ū_col + ū_nom) over all robots within R (§6.2, eq. (6)); log.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from tlfleet.agent.control.collision import (
    CollisionParams,
    StaticAvoidance,
    collision_velocity,
    static_velocity,
)
from tlfleet.agent.control.mixing import mix
from tlfleet.agent.control.saturation import saturate
from tlfleet.agent.evolve import evolve
from tlfleet.agent.model.scenario import DiscObstacle, RectObstacle
from tlfleet.agent.policy.route import Route, RoutePlanner
from tlfleet.agent.scenario import stl_setup
from tlfleet.agent.scenario.stl_timing import PositionGrid, position_grid, reach_time, transfer_time
from tlfleet.agent.stl import recovery as rec
from tlfleet.agent.stl.control_law import ControlParams, nominal_velocity
from tlfleet.agent.stl.funnel import Funnel, FunnelParams, epsilon, received_funnel_problem
from tlfleet.agent.stl.messages import (
    CollabRelease,
    CollabRequest,
    CollabUpdate,
    Message,
    StatusAnnounce,
)
from tlfleet.agent.stl.repair import ProtocolParams, choose_stage, stage2_enabled
from tlfleet.agent.stl.sequencer import check_phase_start_times
from tlfleet.agent.stl.supremum import Workspace, maximize
from tlfleet.agent.stl.syntax import literals
from tlfleet.agent.stl.task import Task
from tlfleet.agent.stl.timing import (
    conjunct_rates,
    design_rate,
    minimal_time,
    smoothing_offset,
)

logger = logging.getLogger(__name__)

NO_REPAIR = 0


@dataclass(frozen=True)
class AgentConfig:
    """Immutable configuration of STL agent ``robot_id``.

    ``subtasks``: its own sequence (§9); ``library``: every STL robot's sub-tasks by (robot, index)
    (a follower adopts ψ_j from here); ``peers``: the STL robots that receive status announcements.
    """

    robot_id: int
    subtasks: tuple[Task, ...]
    library: Mapping[tuple[int, int], Task] = field(compare=False)
    peers: tuple[int, ...] = ()
    phase_start_times: tuple[float, ...] | None = None
    funnel: FunnelParams = field(default_factory=FunnelParams)
    control: ControlParams = field(default_factory=ControlParams)
    collision: CollisionParams = field(default_factory=CollisionParams)
    protocol: ProtocolParams = field(default_factory=ProtocolParams)
    recovery: rec.RecoveryParams = field(default_factory=rec.RecoveryParams)
    random_seed: int | None = None  # None: fixed fractions (§5); int: code-faithful U(0,1) draws
    # docs/stl-saturation.md §6: an F sub-task followed by another one must be met early enough
    # for the next one to stay feasible at the speed limit (its deadline), and is done there
    # once it has been satisfied
    lookahead: bool = True
    # where the robots can be (the goal state of a sub-task, its supremum: tlfleet.agent.stl.
    # supremum); None: the whole plane
    workspace: Workspace | None = field(default=None, compare=False)
    # docs/stl-saturation.md §7: robots coupled to this one by a literal, each with its own
    # (smaller) avoidance radii; every other robot gets ``collision``
    pair_collision: Mapping[int, CollisionParams] = field(default_factory=dict, compare=False)
    static: StaticAvoidance | None = None  # walls and obstacles in eq. (6) (§8); None: none
    # §8: routes around obstacles when a sub-task's goal is out of sight (None: never)
    router: RoutePlanner | None = field(default=None, compare=False)
    route_check_period: float = 0.5  # [s] how often an unrouted sub-task looks for a blocked goal


@dataclass(frozen=True, slots=True)
class SubTaskOutcome:
    """Result of one sub-task (§8): r̄ (final r), ρ^φ and the repairs per stage.

    ``rho_phi`` is min (G) / max (F) of the *smooth* ρ^ψ (what the agent controls) over the
    agent's own samples in [a, b]; reports use the standard semantics from the trajectory
    (``tlfleet.agent.stl.monitor``), which is ≥ this value.
    """

    index: int
    t_done: float  # [s]
    satisfied: bool  # ρ^φ > 0 (paper §II-B) for the smooth ρ^φ above: conservative, the
    # standard min/max robustness of the trajectory can be positive when this is not
    final_r: float
    rho_phi: float
    events: tuple[int, int, int]  # critical events handled by stage 1, 2, 3
    ended_by: Literal["satisfaction", "window_end"] = "window_end"  # §8: the completion rule
    # (F: first a ≤ t ≤ b with r < ρ < ρ_max; G: t ≥ b inside the funnel) or the window's end
    # robustness recoveries (tlfleet.agent.stl.recovery); r̄ is then the least r
    recoveries: int = 0
    # in force (final_r = min(final funnel's r, every r a recovery replaced))


@dataclass(frozen=True, slots=True)
class AgentState:
    """Per-agent mutable-by-replacement state (small on purpose)."""

    k: int = 0  # index of the current sub-task (len(subtasks) when all are done)
    active: bool = False  # sub-task k activated (funnel initialised)
    funnel: Funnel | None = None
    ce: int = 0  # critical-event counter (Alg. 2)
    c: int = 0  # 0 own task | i requesting collaboration | −1 done (paper encoding)
    stage: int = 0  # stage of the last repair on this sub-task (0 = none yet)
    events: tuple[int, int, int] = (0, 0, 0)
    follow: int | None = None  # requester being followed
    follow_subtask: int = -1
    follow_funnel: Funnel | None = None
    peers: Mapping[int, StatusAnnounce] = field(default_factory=dict)  # replaced, never mutated
    rho_phi: float = math.nan  # running min (G) / max (F) of ρ^ψ over samples in [a, b]
    t_done: float = -math.inf  # [s] completion time of sub-task k − 1
    outcomes: tuple[SubTaskOutcome, ...] = ()
    announced: tuple[int, int, bool] | None = None  # last (c, k, active) sent to peers
    t_announced: float = -math.inf  # [s] time of that announcement
    recovery: rec.RecoveryState | None = None  # robustness recovery of sub-task k
    # (requester, its sub-task) this agent released itself from because the requester was
    # unreachable, not on its CollabRelease: its next CollabUpdate means it still counts on us
    orphaned: tuple[int, int] | None = None
    r_goal: float = math.nan  # r_frac·ρ_max of sub-task k's first funnel: an F is met there
    leave_by: float = math.inf  # [s] sub-task k's look-ahead deadline (docs/stl-saturation.md §6)
    route: Route | None = None  # the route the funnel follows around obstacles (§8), if any
    route_checked: float = -math.inf  # [s] last look for a blocked goal


# A per-tick value, never changed once built; not frozen: a frozen __init__ costs 3-4x.
@dataclass(slots=True)
class StepInput:
    """``unreachable``: peers the runtime knows it cannot reach (liveliness token gone, or a
    message to them unanswered). [OUR CHOICE] The step forgets their status announcements, so
    they block stage 2 like a peer never heard of (§7.4); a follower whose requester is
    unreachable releases itself (as on ``CollabRelease``); a requester (c_i = i) whose helpers
    are all unreachable leaves stage 2 (c_i := 0), so its next critical event gets stage 3.
    Reachability is each agent's own view: a helper can find its requester unreachable (a reply
    late on a loaded machine) while the requester still finds the helper, stays in stage 2 and
    sends updates. [OUR CHOICE] A helper that released itself that way follows that requester
    again on its next ``CollabUpdate`` for the same sub-task (the update carries the funnel a
    request would), so the two agree again once the requester is reachable."""

    t: float  # [s] absolute mission time
    poses: Mapping[int, object]  # id -> (x, y, θ)
    inbox: Sequence[Message] = ()
    unreachable: frozenset[int] = frozenset()
    # True: ``poses`` is a dict of float tuples already (the runtime's decoded rows), so the step
    # uses it as it is instead of copying it (one loop over the fleet less per tick)
    tuples: bool = False


@dataclass(frozen=True, slots=True)
class LogRecord:
    """(t, ρ, ρ_max, ρ_max − γ(t), r, stage, ce, c_i, follow) of §8, plus the sub-task index and the
    stage of a repair done in this step (0 = none). NaN fields when the agent is idle."""

    t: float
    rho: float
    rho_max: float
    lower: float
    r: float
    stage: int
    ce: int
    c: int
    follow: int | None
    subtask: int
    repair: int = NO_REPAIR
    # a robustness recovery raised r in this step (tlfleet.agent.stl.recovery)
    recovered: bool = False


# A per-tick value, never changed once built; not frozen: a frozen __init__ costs 3-4x.
@dataclass(slots=True)
class StepOutput:
    u: tuple[float, float, float]  # world frame (v_x [m/s], v_y [m/s], ω [rad/s])
    messages: tuple[Message, ...]
    log: LogRecord


class StlAgent:
    """The step function of one STL agent bound to its immutable :class:`AgentConfig`."""

    __slots__ = ("_grid", "cfg")

    def __init__(self, config: AgentConfig):
        self.cfg = config
        self._grid: PositionGrid | None = None  # positions of the workspace, built once

    @property
    def robot_id(self) -> int:
        return self.cfg.robot_id

    def initial_state(self) -> AgentState:
        return AgentState()

    # ----------------------------------------------------------------- helpers

    def _activation_time(self, state: AgentState) -> float:
        if state.k == 0:
            return -math.inf
        forced = self.cfg.phase_start_times
        if forced is not None:
            return max(state.t_done, forced[state.k - 1])
        return state.t_done

    def _status(self, state: AgentState, t: float) -> list[Message]:
        """Status announcements: on every change of (c_i, sub-task, active), and again every
        ``status_period`` seconds so that a peer that missed one (lossy transport, late start)
        catches up."""
        key = (state.c, state.k, state.active)
        period = self.cfg.protocol.status_period
        if not self.cfg.peers or (key == state.announced
                                  and (period is None or t - state.t_announced < period)):
            return []
        tasks = self.cfg.subtasks
        all_done = state.k >= len(tasks)
        task = tasks[state.k] if state.active and not all_done else None
        return [StatusAnnounce(sender=self.cfg.robot_id, receiver=v, c=state.c, subtask=state.k,
                               kind=task.kind if task else None,
                               a=task.a if task else math.nan, b=task.b if task else math.nan,
                               all_done=all_done)
                for v in self.cfg.peers]

    def _rng(self, subtask: int, ce: int, t: float) -> np.random.Generator | None:
        """``None`` (deterministic fractions, the default) or, with ``random_seed``, a Generator
        seeded by (seed, robot, sub-task, event count, t [ms]) for the authors' U(0,1) draws
        (§13 item 2): reproducible, and the step stays a pure function of its inputs."""
        seed = self.cfg.random_seed
        if seed is None:
            return None
        return np.random.default_rng([seed, self.cfg.robot_id, subtask, ce, round(t * 1000)])

    def collab_problem(self, msg: Message) -> str | None:
        """Why this agent does not act on ``msg`` (its ``sender`` already authenticated by the
        runtime), or None (stl-funnel.md §7.5). A request, update or release must be for a
        sub-task of the sender in whose V this robot is (the only sub-tasks it can follow), a
        request or update with that sub-task's funnel (:func:`received_funnel_problem`); a
        status must come from another STL robot, for a finite window (it is only stored: the
        stage-2 rule reads those of V_i alone). Any
        other message is dropped, never acted on: a request for a sub-task the receiver takes
        no part in used to raise in ``Task.block`` and kill the agent."""
        i = self.cfg.robot_id
        if msg.receiver != i:
            return f"addressed to robot {msg.receiver}, this is robot {i}"
        if msg.sender == i:
            return "sent by this robot to itself"
        if isinstance(msg, StatusAnnounce):
            if (msg.sender, 0) not in self.cfg.library:
                return f"robot {msg.sender} is no STL robot of this fleet"
            if msg.kind is not None and not (math.isfinite(msg.a) and math.isfinite(msg.b)):
                return "status of a sub-task without a finite window"
            return None
        task = self.cfg.library.get((msg.sender, msg.subtask))
        if task is None:
            return f"robot {msg.sender} has no STL sub-task {msg.subtask}"
        if i not in task.v_ctrl:
            return f"robot {i} takes no part in robot {msg.sender}'s sub-task {msg.subtask}"
        if isinstance(msg, CollabRequest | CollabUpdate):
            return received_funnel_problem(msg.funnel, task.kind, task.a, task.b)
        return None

    def _read_inbox(self, state: AgentState, inbox: Sequence[Message],
                    unreachable: frozenset[int] = frozenset()):
        """Apply peer status and collaboration messages (§7.5, paper Alg. 2 lines 20–25; the
        rejoin of an orphaned requester, ``StepInput``).

        Returns (follow, follow_subtask, follow_funnel, peers, released, orphaned); ``peers`` is
        a new dict only if some status arrived.
        """
        i = self.cfg.robot_id
        follow, follow_subtask, follow_funnel = (state.follow, state.follow_subtask,
                                                 state.follow_funnel)
        peers = state.peers
        released = False
        orphaned = state.orphaned
        for msg in inbox:
            problem = self.collab_problem(msg)
            if problem is not None:  # the runtime refuses these; a direct caller may not
                logger.warning("robot %d: %s from %d ignored: %s", i, type(msg).__name__,
                               msg.sender, problem)
                continue
            if isinstance(msg, StatusAnnounce):
                if peers is state.peers:
                    peers = dict(peers)
                peers[msg.sender] = msg
            elif isinstance(msg, CollabRequest):
                if msg.sender == i or state.c == i:
                    # [OUR CHOICE] a requester (c_i = i) keeps steering its own funnel: following
                    # someone else would strand its own followers.
                    continue
                if (follow is None or follow == msg.sender
                        or not self.cfg.protocol.first_come_follow):
                    follow, follow_subtask, follow_funnel = msg.sender, msg.subtask, msg.funnel
            elif isinstance(msg, CollabUpdate):
                if msg.sender == follow and msg.subtask == follow_subtask:
                    follow_funnel = msg.funnel
                elif (follow is None and orphaned == (msg.sender, msg.subtask)
                      and msg.sender not in unreachable):
                    logger.info("robot %d: requester %d still collaborating, followed again",
                                i, msg.sender)
                    follow, follow_subtask, follow_funnel = msg.sender, msg.subtask, msg.funnel
            elif isinstance(msg, CollabRelease):
                if msg.sender == follow:
                    follow, follow_subtask, follow_funnel = None, -1, None
                    released = True
                elif orphaned is not None and msg.sender == orphaned[0]:
                    orphaned = None  # it does not count on us any more
        if follow is not None and follow != state.follow:
            orphaned = None  # following someone (again, or on a request): nobody is orphaned
        return follow, follow_subtask, follow_funnel, peers, released, orphaned

    def _rate(self, task: Task, tick: _Tick, funnel: Funnel | None) -> float | None:
        """v = κ·(the rate at which the robot can raise ρ^ψ towards the funnel's goal at its
        speed limit) [1/s] (tlfleet.agent.stl.timing.design_rate; docs/stl-saturation.md §1):
        towards r_frac·ρ_max of a new funnel (``funnel`` None), towards r of a repaired one.
        None when the funnels are not saturation-aware."""
        fp, cp = self.cfg.funnel, self.cfg.control
        if not fp.saturation_aware:
            return None
        if tick.route is not None:
            # along a route ρ̃ rises at the speed limit times ‖∂ρ̃/∂z_i‖ (route.py)
            b0 = task.block(self.cfg.robot_id)
            g = tick.grad_ctl
            return fp.saturation_share * cp.max_lin * math.hypot(g[b0], g[b0 + 1])
        rho = tick.rho_own
        if funnel is None:
            base = max(0.0, rho)
            level = fp.r_frac * (base + fp.rho_max_frac * (task.rho_opt - base))
        else:
            level = funnel.r
        rate = design_rate(task, task.stacked_state(tick.poses), self.cfg.robot_id, rho, level,
                           cp.max_lin, cp.max_ang, at_least=self._reach_time(task, tick, level))
        return fp.saturation_share * rate

    def _reach_time(self, task: Task, tick: _Tick, level: float) -> float:
        """The minimal-time bound [s] to the set where ψ's conjuncts hold at ``level`` (+ the
        smoothing offset) at once (tlfleet.agent.scenario.stl_timing); 0 without a workspace or
        where ρ^ψ is at the level already."""
        grid = self._position_grid()
        if grid is None or tick.rho_own >= level:
            return 0.0
        cp = self.cfg.control
        smooth = smoothing_offset(len(literals(task.psi)), task.eta)
        need = reach_time(task, self.cfg.robot_id, tick.poses, grid, level, cp.max_lin,
                          cp.max_ang, smooth)
        return need if math.isfinite(need) else 0.0

    def _route(self, state: AgentState, tick: _Tick, task: Task, activating: bool) -> None:
        """The route of the tick (docs/stl-saturation.md §8): planned at activation, looked for
        every ``route_check_period`` while there is none (a goal that moved, or a robot pushed,
        out of sight: the funnel is then re-initialised on ρ̃), advanced past reached waypoints;
        sets ``tick.rho_ctl``/``tick.grad_ctl`` to ρ̃ and its gradient."""
        cfg = self.cfg
        router, t, i = cfg.router, tick.t, cfg.robot_id
        route = None if activating else state.route
        pose = tick.poses[i]
        x, y = pose[0], pose[1]
        if route is not None:
            route = route.advanced(x, y, router.reach)
        elif activating or t - state.route_checked >= cfg.route_check_period:
            goal = self._goal_pose(task, tick.poses)
            route = router.plan((x, y), (goal[0], goal[1]))
            tick.changes["route_checked"] = t
            if route is not None and not activating:
                logger.info("robot %d: sub-task %d's goal out of sight at t=%.2f: route %s", i,
                            tick.k + 1, t, route.waypoints)
                tick.reinit = True
        if route is not state.route:
            tick.changes["route"] = route
        tick.route = route
        if route is None or tick.grad_own is None:
            return
        penalty, dx, dy = route.penalty(x, y)
        b0 = task.block(i)
        grad = list(tick.grad_own)
        grad[b0] += dx
        grad[b0 + 1] += dy
        tick.rho_ctl, tick.grad_ctl = tick.rho_own - penalty, grad

    def _leave_by(self, k: int, poses: Mapping[int, object], at_goal: bool = True) -> float:
        """Look-ahead deadline of sub-task k (docs/stl-saturation.md §6.2): an F sub-task
        followed by sub-task k+1 must be met by rel(k+1) − T/κ, with T the minimal-time bound
        to the goal level of ψ_(k+1), from the best point where ψ_k is at its goal level
        (``at_goal``: the funnel's deadline, over the workspace grid) or from where the robot
        is now (the others where they are now), and rel = a of a G, b of an F; inf for a G, the
        last sub-task, forced phase starts or without look-ahead."""
        cfg = self.cfg
        tasks = cfg.subtasks
        if (not cfg.lookahead or k + 1 >= len(tasks) or tasks[k].kind != "F"
                or cfg.phase_start_times is not None):
            return math.inf
        task, after = tasks[k], tasks[k + 1]
        i, cp, fp = cfg.robot_id, cfg.control, cfg.funnel
        if any(j not in poses for j in (*task.participants, *after.participants)):
            return math.inf
        level = fp.r_frac * fp.rho_max_frac * after.rho_opt
        smooth = smoothing_offset(len(literals(after.psi)), after.eta)
        if at_goal:
            grid = self._position_grid()
            if grid is None:
                return math.inf
            need = transfer_time(task, after, i, poses, grid, cp.max_lin,
                                 fp.r_frac * fp.rho_max_frac * task.rho_opt, level + smooth)
        else:  # every tick once met: the conjuncts' bound, no grid (docs §6.2)
            rates = conjunct_rates(after, after.stacked_state(poses), i, cp.max_lin,
                                   cp.max_ang)
            need = minimal_time(rates, level, smooth=smooth)
        if not math.isfinite(need):
            return math.inf
        due = after.a if after.kind == "G" else after.b
        return due - need / fp.saturation_share

    def _position_grid(self) -> PositionGrid | None:
        """The robot's positions over its workspace (tlfleet.agent.scenario.stl_timing), built
        once; None without a workspace."""
        workspace = self.cfg.workspace
        if workspace is None:
            return None
        if self._grid is None:
            # 0.1 m: the look-ahead's estimate loses ≤ 0.5 s at 0.2 m/s, and an activation step
            # costs a few ms instead of tens (the distance transform is cubic in the side)
            self._grid = position_grid(workspace.arena,
                                       workspace.clearance_of(self.cfg.robot_id), spacing=0.1)
        return self._grid

    def _goal_pose(self, task: Task, poses: Mapping[int, object]) -> tuple[float, float, float]:
        """The own pose that maximises ρ^ψ with the other participants where they are now
        (tlfleet.agent.stl.supremum.maximize from the current pose and the supremum's state)."""
        i = self.cfg.robot_id
        b0 = task.block(i)
        if task.goal and task.participants == (i,):
            # ψ of the own state alone: the supremum's state is its goal, wherever the robot is
            return tuple(task.goal[b0:b0 + 3])
        current = task.stacked_state(poses)
        starts = [current]
        if task.goal:
            hinted = list(current)
            hinted[b0:b0 + 3] = task.goal[b0:b0 + 3]
            starts.append(hinted)
        workspace = self.cfg.workspace
        if workspace is None:
            return tuple(current[b0:b0 + 3]) if not task.goal else tuple(task.goal[b0:b0 + 3])
        free = [j == i for j in task.participants]
        best = maximize(task.compiled.value_grad, task.participants, workspace, starts, free=free)
        return tuple(best.state[b0:b0 + 3])

    def _repair(self, task: Task, funnel: Funnel, rho: float, t: float, ce: int, c: int,
                peers: Mapping[int, StatusAnnounce],
                rate: float | None = None) -> tuple[Funnel, int, int, list[Message]]:
        """Critical event number ``ce`` of the owner: stage choice (§7.4), repair (§7.3, with the
        ramp of a saturation-aware funnel at ``rate``) and the stage-2 messages. Returns (new
        funnel, new c_i, stage, outgoing messages)."""
        cfg = self.cfg
        i = cfg.robot_id
        fp = cfg.funnel
        stage2_ok = ce > fp.n_stage1 and c != i and stage2_enabled(i, task, c, peers)
        stage = choose_stage(ce, fp.n_stage1, c, i, stage2_ok)
        rng = self._rng(task.index, ce, t)
        messages: list[Message] = []
        if stage == 1:
            funnel = funnel.repair(1, rho, t, fp, rng, rate=rate)
        elif stage == 2 and c != i:  # entry (Alg. 2 lines 10–12)
            if cfg.protocol.stage2_entry_repair:
                funnel = funnel.repair(2, rho, t, fp, rng, rate=rate)
            c = i
            messages = [CollabRequest(sender=i, receiver=v, subtask=task.index, funnel=funnel, c=i)
                        for v in task.v_ctrl if v != i]
        elif stage == 2:  # repeat while c_i = i (lines 13–15): stage-3 computation + update
            funnel = funnel.repair(3, rho, t, fp, rng, rate=rate)
            if cfg.protocol.stage2_repeat_broadcast:
                messages = [CollabUpdate(sender=i, receiver=v, subtask=task.index, funnel=funnel)
                            for v in task.v_ctrl if v != i]
        else:
            funnel = funnel.repair(3, rho, t, fp, rng, rate=rate)
        logger.debug("robot %d: critical event %d at t=%.2f, stage %d: %s", i, ce, t, stage,
                     funnel)
        return funnel, c, stage, messages

    def _recover(self, state: AgentState, tick: _Tick, rho: float, grad_own,
                 critical: bool) -> None:
        """Robustness recovery of the own sub-task (tlfleet.agent.stl.recovery; G, and F unless
        ``recovery.f_tasks`` is off): updates the tick's funnel (when a recovery raises r) and the
        recovery state in ``tick.changes``."""
        cfg, t, changes = self.cfg, tick.t, tick.changes
        params = cfg.recovery
        current = changes.get("recovery", state.recovery)
        if current is None:
            current = rec.RecoveryState.start(tick.funnel, cfg.funnel, params)
        if critical:
            changes["recovery"] = rec.on_critical(current, t, params)
            return
        rate = params.rate_share * rec.achievable_rate(grad_own, cfg.control.max_lin,
                                                       cfg.control.max_ang)
        new_state, new = rec.advance(current, tick.funnel, rho, t, rate, cfg.funnel, params)
        if new_state is not current:
            changes["recovery"] = new_state
        if new is None:
            return
        logger.debug("robot %d: recovery at t=%.2f: r %.4f -> %.4f", cfg.robot_id, t,
                     tick.funnel.r, new.r)
        changes["funnel"] = tick.funnel = new
        tick.recovered = True

    # ----------------------------------------------------------------- step

    def step(self, state: AgentState, inputs: StepInput) -> tuple[AgentState, StepOutput]:
        """One control step: the phases of the module docstring (stl-funnel.md §12), in order,
        on one scratch :class:`_Tick`; the new state is the old one with the phases' changes."""
        # tuples (as the runtime decodes them) pass as they are: hasattr fails slowly, once per
        # robot and tick
        tick = _Tick(t=inputs.t, poses=inputs.poses if inputs.tuples else {
            j: p if type(p) is tuple else p.tolist() if hasattr(p, "tolist") else p
            for j, p in inputs.poses.items()})
        self._read_messages(state, inputs, tick)  # 1.
        self._sequence(state, tick)  # 2.
        self._complete(state, tick)  # 3./4.
        self._control(state, tick)  # 5.
        u = self._avoid_and_mix(tick)  # 6.
        return self._finish(state, tick, u)

    def _read_messages(self, state: AgentState, inputs: StepInput, tick: _Tick) -> None:
        """Phase 1: peer status and collaboration messages (§7.5); unreachable peers forgotten,
        an unreachable requester released."""
        i = self.cfg.robot_id
        unreachable = inputs.unreachable
        follow, follow_subtask, follow_funnel, peers, reinit, orphaned = self._read_inbox(
            state, inputs.inbox, unreachable)
        if unreachable:
            if any(v in peers for v in unreachable):
                peers = {v: status for v, status in peers.items() if v not in unreachable}
            if follow is not None and follow in unreachable:
                logger.info("robot %d: requester %d unreachable, released", i, follow)
                orphaned = (follow, follow_subtask)
                follow, follow_subtask, follow_funnel, reinit = None, -1, None, True
        if follow != state.follow or follow_funnel is not state.follow_funnel:
            tick.changes.update(follow=follow, follow_subtask=follow_subtask,
                                follow_funnel=follow_funnel)
        if orphaned != state.orphaned:
            tick.changes["orphaned"] = orphaned
        if peers is not state.peers:
            tick.changes["peers"] = peers
        tick.follow, tick.follow_subtask, tick.follow_funnel = follow, follow_subtask, follow_funnel
        tick.peers, tick.reinit, tick.unreachable = peers, reinit, unreachable

    def _sequence(self, state: AgentState, tick: _Tick) -> None:
        """Phase 2: activate sub-task k when due (§9) with a new funnel (§5), or re-initialise
        it after a release; ρ^ψ and ∂ρ^ψ/∂x of the current sub-task; stage 2 left when every
        helper is unreachable."""
        cfg = self.cfg
        i, t, fp, changes = cfg.robot_id, tick.t, cfg.funnel, tick.changes
        tasks = cfg.subtasks
        tick.k, tick.active, tick.funnel = state.k, state.active, state.funnel
        task = tick.task = tasks[tick.k] if tick.k < len(tasks) else None
        ce_before = state.ce if tick.active else 0
        if task is not None and (tick.active or t >= self._activation_time(state)):
            tick.rho_own, tick.grad_own = task.compiled.value_grad(task.stacked_state(tick.poses))
            tick.rho_ctl, tick.grad_ctl = tick.rho_own, tick.grad_own
            if cfg.router is not None and tick.follow is None:
                self._route(state, tick, task, activating=not tick.active)
            if not tick.active:
                tick.active = True
                leave_by = self._leave_by(tick.k, tick.poses)
                rate = self._rate(task, tick, None)
                if rate and math.isfinite(leave_by):
                    # the next sub-task's need never dooms this one: the deadline is at least
                    # when this one can reach its goal level at the rate v
                    base = max(0.0, tick.rho_ctl)
                    level = fp.r_frac * (base + fp.rho_max_frac * (task.rho_opt - base))
                    leave_by = max(leave_by, t + (level - tick.rho_ctl + fp.ramp_margin) / rate)
                tick.funnel = Funnel.init(task.kind, task.a, task.b, task.rho_opt, tick.rho_ctl,
                                          t, fp, self._rng(tick.k, ce_before, t), rate=rate,
                                          deadline=None if math.isinf(leave_by) else leave_by)
                changes.update(active=True, funnel=tick.funnel, ce=0, c=0, stage=0,
                               events=(0, 0, 0), rho_phi=math.nan,
                               recovery=rec.RecoveryState.start(tick.funnel, fp, cfg.recovery),
                               r_goal=fp.r_frac * tick.funnel.rho_max, leave_by=leave_by)
                logger.debug("robot %d: sub-task %d active at t=%.2f: %s", i, tick.k + 1, t,
                             tick.funnel)
            elif tick.reinit:
                leave_by = state.leave_by
                tick.funnel = Funnel.init(task.kind, task.a, task.b, task.rho_opt, tick.rho_ctl,
                                          t, fp, self._rng(tick.k, ce_before, t),
                                          rate=self._rate(task, tick, None),
                                          deadline=None if math.isinf(leave_by) else leave_by)
                floor = state.recovery.r_floor if state.recovery is not None else math.inf
                changes.update(funnel=tick.funnel, stage=0, recovery=replace(
                    rec.RecoveryState.start(tick.funnel, fp, cfg.recovery),
                    r_floor=min(floor, state.funnel.r if state.funnel else math.inf)))
                if cfg.protocol.reset_ce_on_release:
                    changes["ce"] = 0
        tick.ce = changes.get("ce", state.ce)
        tick.c = changes.get("c", state.c)
        if (tick.unreachable and tick.c == i and task is not None
                and all(v in tick.unreachable for v in task.v_ctrl if v != i)):
            logger.info("robot %d: every helper unreachable, stage 2 left at t=%.2f", i, t)
            tick.c = 0
            changes["c"] = 0
        tick.stage = changes.get("stage", state.stage)
        tick.events = changes.get("events", state.events)

    def _complete(self, state: AgentState, tick: _Tick) -> None:
        """Phases 3/4: the running ρ^φ over the samples in [a, b], and completion (§8)."""
        cfg = self.cfg
        i, t, task, changes = cfg.robot_id, tick.t, tick.task, tick.changes
        if not (tick.active and task is not None):
            return
        rho_own, funnel = tick.rho_own, tick.funnel
        rho_phi = changes.get("rho_phi", state.rho_phi)
        if task.a <= t <= task.b:
            if math.isnan(rho_phi):
                rho_phi = rho_own
            elif task.kind == "G":
                rho_phi = min(rho_phi, rho_own)
            else:
                rho_phi = max(rho_phi, rho_own)
            changes["rho_phi"] = rho_phi
        rho_ctl = tick.rho_ctl  # ρ̃ on a route (≤ ρ^ψ), else ρ^ψ: what the funnel holds
        inside = funnel.r < rho_ctl < funnel.rho_max
        if task.kind == "F" and cfg.protocol.f_done_at_goal:
            # docs/stl-saturation.md §6.1: met once ρ^ψ reaches the level the first funnel
            # aimed at (r_frac·ρ_max > 0), not merely r, which repairs may take below 0
            inside = rho_ctl > funnel.r and rho_own >= changes.get("r_goal", state.r_goal)
        by_rule = False
        if tick.follow is None and inside and cfg.protocol.complete_on_satisfaction and (
                (task.kind == "F" and task.a <= t <= task.b)
                or (task.kind == "G" and t >= task.b)):
            tick.done = by_rule = True
        elif (tick.follow is None and task.kind == "F" and task.a <= t <= task.b
              and rho_phi > 0.0 and t >= self._leave_by(tick.k, tick.poses, at_goal=False)):
            # §6.2: met already, and the next sub-task needs the robot now
            tick.done = by_rule = True
        elif (task.kind == "G" and t >= task.b) or (task.kind == "F" and t > task.b):
            tick.done = True
            if (task.kind == "G" and tick.follow is None
                    and not -1.0 < funnel.zeta(rho_ctl, t) < 0.0):
                # [OUR CHOICE] a critical event on the last sample of a G window is still
                # repaired (stage 1 or 3: the window is over, nobody can help any more) so
                # that the recorded r̄ keeps ρ^φ ≥ r̄ (paper Alg. 2 line 28).
                tick.ce += 1
                stage = self._local_stage(tick.ce)
                funnel = tick.funnel = funnel.repair(stage, rho_ctl, t, cfg.funnel,
                                                     self._rng(tick.k, tick.ce, t))
                _count_repair(tick, stage, funnel=funnel)
        if tick.done:
            k = tick.k
            recovery = changes.get("recovery", state.recovery)
            floor = recovery.r_floor if recovery is not None else math.inf
            outcome = SubTaskOutcome(k, t, rho_phi > 0.0, min(funnel.r, floor), rho_phi,
                                     tick.events, "satisfaction" if by_rule else "window_end",
                                     recovery.count if recovery is not None else 0)
            if tick.c == i and (by_rule or cfg.protocol.release_on_window_end):
                tick.out.extend(CollabRelease(sender=i, receiver=v, subtask=k)
                                for v in task.v_ctrl if v != i)
            tick.c = -1
            changes.update(k=k + 1, active=False, c=-1, t_done=t,
                           outcomes=(*state.outcomes, outcome))
            logger.info("robot %d: sub-task %d done at t=%.2f (%s), r=%.4f, rho_phi=%.4f, "
                        "events=%s", i, k + 1, t, outcome.ended_by, funnel.r, rho_phi,
                        tick.events)

    def _control(self, state: AgentState, tick: _Tick) -> None:
        """Phase 5: u_nom (§6.1) — of the requester's funnel for a follower (detection only if
        ``followers_detect``), of the own funnel otherwise (critical event → stage → repair →
        ζ again; own F above r held), saturated."""
        cfg = self.cfg
        i, t, fp, cp = cfg.robot_id, tick.t, cfg.funnel, cfg.control
        if tick.follow is not None:
            ftask = cfg.library[(tick.follow, tick.follow_subtask)]
            rho, g = ftask.compiled.value_grad(ftask.stacked_state(tick.poses))
            tick.rho_log = rho
            tick.log_funnel = tick.follow_funnel
            z = tick.follow_funnel.zeta(rho, t)
            if cfg.protocol.followers_detect and not -1.0 < z < 0.0:
                tick.ce += 1
                stage = self._local_stage(tick.ce)
                tick.follow_funnel = tick.follow_funnel.repair(stage, rho, t, fp,
                                                               self._rng(tick.k, tick.ce, t))
                _count_repair(tick, stage, follow_funnel=tick.follow_funnel)
                tick.log_funnel = tick.follow_funnel
                z = tick.follow_funnel.zeta(rho, t)
            if g is not None:
                b0 = ftask.block(i)
                g = g[b0:b0 + 3]
            tick.u_nom = nominal_velocity(epsilon(z, fp.zeta_clip), g, cp.normalize_grad,
                                          cp.k_eps)
        elif tick.active and not tick.done:
            task, rho = tick.task, tick.rho_ctl
            tick.rho_log = rho
            grad_own = tick.grad_ctl
            if grad_own is not None:
                b0 = task.block(i)
                grad_own = grad_own[b0:b0 + 3]
            if task.kind == "F" and cp.hold_F_when_above_r and rho > tick.funnel.r:
                tick.u_nom = (0.0, 0.0, 0.0)
            else:
                z = tick.funnel.zeta(rho, t)
                if not -1.0 < z < 0.0:
                    tick.ce += 1
                    tick.funnel, tick.c, stage, messages = self._repair(
                        task, tick.funnel, rho, t, tick.ce, tick.c, tick.peers,
                        self._rate(task, tick, tick.funnel))
                    tick.out.extend(messages)
                    _count_repair(tick, stage, funnel=tick.funnel, c=tick.c)
                    z = tick.funnel.zeta(rho, t)
                if (cfg.recovery.enabled and tick.c == 0
                        and (task.kind == "G" or cfg.recovery.f_tasks)):
                    self._recover(state, tick, rho, grad_own, bool(tick.repaired))
                    if tick.recovered:
                        z = tick.funnel.zeta(rho, t)
                tick.u_nom = nominal_velocity(epsilon(z, fp.zeta_clip), grad_own,
                                              cp.normalize_grad, cp.k_eps)
            tick.log_funnel = tick.funnel
        elif tick.done:  # the completion step still logs the finished sub-task's ρ and funnel
            tick.rho_log = tick.rho_own
            tick.log_funnel = tick.funnel
        tick.u_nom = saturate(tick.u_nom, cp.max_lin, cp.max_ang, cp.saturation)

    def _avoid_and_mix(self, tick: _Tick) -> tuple[float, float, float]:
        """Phase 6: u = saturate(β·ū_col + ū_nom) over every robot within R (§6.2, eq. (6)), a
        coupled robot within its pair's radii, walls and obstacles within their radii
        (docs/stl-saturation.md §7, §8)."""
        cfg = self.cfg
        col, cp, i = cfg.collision, cfg.control, cfg.robot_id
        own_pose = tick.poses[i]
        own = (own_pose[0], own_pose[1])
        pairs = cfg.pair_collision
        # every pose, its own included: at distance 0 it contributes nothing
        if not pairs:
            u_col = collision_velocity(own, tick.poses.values(), col)
        else:
            vx, vy, _ = collision_velocity(
                own, [p for j, p in tick.poses.items() if j not in pairs], col)
            for j, params in pairs.items():
                pose = tick.poses.get(j)
                if pose is not None:
                    px, py, _ = collision_velocity(own, (pose,), params)
                    vx += px
                    vy += py
            u_col = (vx, vy, 0.0)
        if cfg.static is not None:
            sx, sy, _ = static_velocity(own, cfg.static)
            u_col = (u_col[0] + sx, u_col[1] + sy, 0.0)
        return mix(tick.u_nom, u_col, col.beta, cp.max_lin, cp.max_ang, cp.saturation)

    def _finish(self, state: AgentState, tick: _Tick,
                u: tuple[float, float, float]) -> tuple[AgentState, StepOutput]:
        """The new state, the status announcements due (§7.4) and the step's log record."""
        t = tick.t
        # evolve: dataclasses.replace at a third of its cost (tlfleet.agent.evolve)
        if tick.changes:
            state = evolve(state, **tick.changes)
        announce = self._status(state, t)
        if announce:
            tick.out.extend(announce)
            state = evolve(state, announced=(state.c, state.k, state.active), t_announced=t)
        if tick.log_funnel is not None:
            f = tick.log_funnel
            record = LogRecord(t, tick.rho_log, f.rho_max, f.lower(t), f.r, tick.stage, tick.ce,
                               tick.c, tick.follow, tick.k, tick.repaired, tick.recovered)
        else:
            record = LogRecord(t, tick.rho_log, math.nan, math.nan, math.nan, tick.stage,
                               tick.ce, tick.c, tick.follow,
                               tick.k if tick.k < len(self.cfg.subtasks) else -1, tick.repaired)
        return state, StepOutput(u, tuple(tick.out), record)

    def _local_stage(self, ce: int) -> int:
        """The stage of a critical event nobody can help with: 1 for the first K, then 3."""
        return 1 if ce <= self.cfg.funnel.n_stage1 else 3


@dataclass(slots=True)
class _Tick:
    """The scratch of one :meth:`StlAgent.step` (never escapes it): what the phases read and
    write in turn. ``changes`` collects the fields of the next :class:`AgentState`."""

    t: float  # [s] sim time of the frame
    poses: dict  # robot id → (x [m], y [m], θ [rad])
    changes: dict = field(default_factory=dict)
    out: list = field(default_factory=list)  # outgoing messages
    follow: int | None = None
    follow_subtask: int = -1
    follow_funnel: Funnel | None = None
    peers: Mapping[int, StatusAnnounce] = field(default_factory=dict)
    reinit: bool = False
    unreachable: frozenset[int] = frozenset()
    k: int = 0
    active: bool = False
    funnel: Funnel | None = None
    task: Task | None = None
    rho_own: float = math.nan  # ρ^ψ of the own sub-task
    grad_own: np.ndarray | None = None  # ∂ρ^ψ/∂(stacked state)
    rho_ctl: float = math.nan  # what the funnel holds: ρ̃ on a route (route.py), else ρ^ψ
    grad_ctl: object = None  # its gradient (stacked state)
    route: Route | None = None
    ce: int = 0
    c: int = 0
    stage: int = 0
    events: tuple[int, int, int] = (0, 0, 0)
    repaired: int = NO_REPAIR
    recovered: bool = False  # a robustness recovery raised r in this step
    done: bool = False
    u_nom: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rho_log: float = math.nan
    log_funnel: Funnel | None = None


def _count_repair(tick: _Tick, stage: int, **funnel_changes: object) -> None:
    """The bookkeeping of one repair, written once: the stage and its counter in ``events``,
    and the state's new ce, stage, events and repaired funnel (``funnel_changes``)."""
    tick.stage = tick.repaired = stage
    tick.events = tuple(n + (s == stage) for s, n in enumerate(tick.events, start=1))
    tick.changes.update(ce=tick.ce, stage=stage, events=tick.events, **funnel_changes)


# --------------------------------------------------------------------------- construction


def status_readers(robot_id: int, library: Mapping[tuple[int, int], Task]) -> tuple[int, ...]:
    """The STL robots that read robot ``robot_id``'s status announcements: the owners of the
    sub-tasks whose V (``Task.v_ctrl``) contains it, ids ascending.

    The stage-2 rule (stl-funnel.md §7.4, ``tlfleet.agent.stl.repair.stage2_enabled``) is the only
    reader of announcements, and robot i reads only those of V_i ∖ {i}; an announcement to any other
    robot would be stored and never read (with 30 robots announcing to all: 870 queries/s across
    the fleet that change no command).
    """
    return tuple(sorted({owner for (owner, _), task in library.items()
                         if owner != robot_id and robot_id in task.v_ctrl}))


def build_agents(scenario, *, funnel: FunnelParams | None = None,
                 control: ControlParams | None = None,
                 protocol: ProtocolParams | None = None,
                 robots: Sequence[int] | None = None,
                 warn: bool = True) -> dict[int, StlAgent]:
    """One :class:`StlAgent` per STL robot of a loaded ``tlfleet.agent.model.scenario.Scenario``.

    Parameters come from the scenario's ``[stl]`` table and each robot's limits unless given.
    ``robots`` restricts which STL agents are built; the library holds their own sub-tasks and
    every sub-task of a robot whose tasks name one of them (the stage-2 requests they may follow,
    the announcements they owe), and nothing else.
    Each agent announces its status to :func:`status_readers` only.
    """
    p = scenario.stl
    stl_ids = tuple(r.id for r in scenario.robots if r.is_stl)
    library: dict[tuple[int, int], Task] = {}
    # the agents' own tasks and those that name them (a requester's task, followed in stage 2):
    # another robot's task, however broken, is that robot's agent's to report
    needed = None if robots is None else stl_setup.naming(scenario, frozenset(robots))
    sequences = stl_setup.stl_sequences(scenario, warn=warn, only=needed)
    for seq in sequences.values():
        for task in seq:
            library[(task.owner, task.index)] = task
    workspace = stl_setup.scenario_workspace(scenario)
    fparams = funnel or FunnelParams(n_stage1=p.n_stage1, delta=p.delta, zeta_l=p.zeta_l,
                                     saturation_aware=p.saturation_aware,
                                     saturation_share=p.saturation_share)
    agents = {}
    for robot_id in robots if robots is not None else stl_ids:
        robot = scenario.robot(robot_id)
        seq = sequences[robot_id]
        cparams = control or ControlParams(max_lin=robot.omni.max_lin,
                                           max_ang=robot.omni.max_ang,
                                           hold_F_when_above_r=p.hold_f_above_r)
        config = AgentConfig(
            robot_id=robot_id,
            subtasks=seq,
            library=library,
            peers=status_readers(robot_id, library),
            phase_start_times=check_phase_start_times(robot_id, seq, robot.phase_start_times),
            funnel=fparams,
            control=cparams,
            collision=CollisionParams(r1=p.r1, r_sense=p.r_sense, beta=p.beta,
                                      max_lin=cparams.max_lin),
            protocol=protocol or ProtocolParams(
                complete_on_satisfaction=p.complete_f_on_satisfaction,
                f_done_at_goal=p.complete_f_at_goal),
            recovery=rec.RecoveryParams(enabled=p.recovery),
            lookahead=p.lookahead,
            workspace=workspace,
            pair_collision=_pair_collision(scenario, robot_id, cparams.max_lin),
            static=_static_avoidance(scenario, robot, cparams.max_lin),
            router=_router(scenario, robot),
        )
        agents[robot_id] = StlAgent(config)
    return agents


def _pair_collision(scenario, robot_id: int, max_lin: float) -> dict[int, CollisionParams]:
    """The robots coupled to ``robot_id`` and their avoidance radii (docs/stl-saturation.md §7;
    ``[stl] coupled_radii``)."""
    p = scenario.stl
    if not p.coupled_radii:
        return {}
    out = {}
    for a, b in sorted(stl_setup.coupled_pairs(scenario)):
        if robot_id in (a, b):
            other = b if a == robot_id else a
            r1, big_r = stl_setup.pair_radii(scenario, robot_id, other)
            out[other] = CollisionParams(r1=r1, r_sense=big_r, beta=p.beta, max_lin=max_lin)
    return out


def _static_avoidance(scenario, robot, max_lin: float) -> StaticAvoidance | None:
    """Walls and obstacles of the arena for eq. (6) (docs/stl-saturation.md §8; ``[stl]
    wall_avoidance``)."""
    if not scenario.stl.wall_avoidance:
        return None
    arena = scenario.arena
    rects = tuple((o.xmin, o.ymin, o.xmax, o.ymax) for o in arena.obstacles
                  if isinstance(o, RectObstacle))
    discs = tuple((o.center[0], o.center[1], o.radius) for o in arena.obstacles
                  if isinstance(o, DiscObstacle))
    r1, big_r = stl_setup.wall_radii(scenario, robot)
    return StaticAvoidance((arena.xmin, arena.xmax, arena.ymin, arena.ymax), rects, discs,
                           r1=r1, r_sense=big_r, max_lin=max_lin)


def _router(scenario, robot) -> RoutePlanner | None:
    """Routes around the arena's obstacles (docs/stl-saturation.md §8; ``[stl] route_around``),
    planned with the clearance of the wall term's outer radius (or its inner one through a
    narrower door)."""
    if not scenario.stl.route_around or not scenario.arena.obstacles:
        return None
    r1, big_r = stl_setup.wall_radii(scenario, robot)
    return RoutePlanner(scenario.arena, clearance=big_r + 0.02, tight=r1 + 0.01)


def single_agent(robot_id: int, subtasks: Sequence[Task], *,
                 library: Mapping[tuple[int, int], Task] | None = None,
                 peers: Sequence[int] = (), **params) -> StlAgent:
    """Convenience constructor for tests and small set-ups (``params``: AgentConfig fields)."""
    lib = dict(library or {})
    for task in subtasks:
        lib.setdefault((task.owner, task.index), task)
    phase = params.pop("phase_start_times", None)
    return StlAgent(AgentConfig(robot_id=robot_id, subtasks=tuple(subtasks), library=lib,
                                peers=tuple(peers),
                                phase_start_times=check_phase_start_times(robot_id, subtasks,
                                                                          phase),
                                **params))
