"""Pure closed-loop harness: STL agents on single-integrator omnidirectional robots.

Each robot integrates ẋ_i = u_i + w_i with zero-order hold and explicit Euler at the control
rate (Δt = 0.01 s, stl-funnel.md §1): x_i(t+Δt) = x_i(t) + Δt·(u_i + w_i), where u_i = (v_x, v_y, ω)
is the agent's world-frame command and w_i an optional bounded planar disturbance,
‖w_i‖ ≤ ``disturbance`` [m/s], drawn uniformly in the disc from a caller-supplied
``numpy.random.Generator``.

Samples are taken at t_k = k/rate, k = 0 … round(duration·rate); every agent steps at each sample
in a fixed order (ascending ids). Messages are delivered with ``latency_steps`` ∈ {0, 1}:
1 (default, ≈ the ROS setting of §7.5) delivers at the next step; 0 delivers at once, so agents
later in the order read them in the same step and earlier ones at the next step. Exogenous robots
(e.g. LTL robots) follow a scripted pose function of time, or stand still.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from tlfleet.agent.policy.stl import AgentState, LogRecord, StepInput, StlAgent
from tlfleet.agent.stl.control_law import ControlParams
from tlfleet.agent.stl.funnel import FunnelParams
from tlfleet.agent.stl.messages import Message
from tlfleet.agent.stl.monitor import Trajectory
from tlfleet.agent.stl.repair import ProtocolParams


def authors_design(**params) -> dict:
    """``AgentConfig`` keyword arguments of the authors' design, which the regression vectors of
    stl-funnel.md §11 and the paper's narratives were computed with: exponential funnels (§5,
    §7.3), the hold rule and F done at r < ρ < ρ_max (§6.1 step 5, §8), no look-ahead.
    ``params`` override them (e.g. ``control=ControlParams(hold_F_when_above_r=False)``)."""
    base = {"funnel": FunnelParams(saturation_aware=False),
            "control": ControlParams(hold_F_when_above_r=True),
            "protocol": ProtocolParams(f_done_at_goal=False), "lookahead": False}
    return {**base, **params}


@dataclass(frozen=True)
class ScriptedRobot:
    """An exogenous robot: ``pose_at(t) -> (x, y, θ)``, or a fixed ``pose`` (``pose_at`` None)."""

    robot_id: int
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    pose_at: Callable[[float], Sequence[float]] | None = None

    def at(self, t: float) -> np.ndarray:
        return np.asarray(self.pose if self.pose_at is None else self.pose_at(t), dtype=float)


@dataclass
class ClosedLoopResult:
    """Trajectory of every robot, per-agent logs, final states and every message sent."""

    trajectory: Trajectory
    logs: dict[int, list[LogRecord]]
    states: dict[int, AgentState]
    messages: list[tuple[float, Message]] = field(default_factory=list)

    def events(self, robot_id: int) -> list[tuple[float, int]]:
        """(t, stage) of every repair of ``robot_id``."""
        return [(rec.t, rec.repair) for rec in self.logs[robot_id] if rec.repair]


def run_closed_loop(
    agents: Sequence[StlAgent],
    initial_poses: Mapping[int, Sequence[float]],
    duration: float,
    *,
    start: float = 0.0,
    exogenous: Sequence[ScriptedRobot] = (),
    rate: float = 100.0,
    latency_steps: int = 1,
    disturbance: float = 0.0,
    rng: np.random.Generator | None = None,
    states: Mapping[int, AgentState] | None = None,
) -> ClosedLoopResult:
    """Run the agents together from ``start`` to ``start + duration`` [s] (both included).

    ``initial_poses[i]``: (x, y, θ) of every agent; ``disturbance`` > 0 needs ``rng``.
    """
    if latency_steps not in (0, 1):
        raise ValueError(f"latency_steps must be 0 or 1, got {latency_steps}")
    if disturbance > 0 and rng is None:
        raise ValueError("a disturbance needs a numpy.random.Generator (rng)")
    order = sorted(agents, key=lambda a: a.robot_id)
    ids = [a.robot_id for a in order]
    exo_ids = [r.robot_id for r in exogenous]
    all_ids = sorted(ids + exo_ids)
    k0 = round(start * rate)
    n = round(duration * rate)
    dt = 1.0 / rate
    times = (k0 + np.arange(n + 1)) / rate
    traj = {j: np.empty((n + 1, 3)) for j in all_ids}
    pose = {j: np.asarray(initial_poses[j], dtype=float).copy() for j in ids}
    agent_states = {a.robot_id: (states or {}).get(a.robot_id, a.initial_state()) for a in order}
    logs: dict[int, list[LogRecord]] = {j: [] for j in ids}
    inbox: dict[int, list[Message]] = {j: [] for j in ids}
    sent: list[tuple[float, Message]] = []
    for step in range(n + 1):
        t = (k0 + step) / rate
        for robot in exogenous:
            pose[robot.robot_id] = robot.at(t)
        for j in all_ids:
            traj[j][step] = pose[j]
        next_inbox: dict[int, list[Message]] = {j: [] for j in ids}
        commands = {}
        for agent in order:
            j = agent.robot_id
            delivered, inbox[j] = inbox[j], []
            agent_states[j], output = agent.step(agent_states[j], StepInput(t, pose, delivered))
            commands[j] = output.u
            logs[j].append(output.log)
            for msg in output.messages:
                sent.append((t, msg))
                target = inbox if latency_steps == 0 else next_inbox
                if msg.receiver in target:
                    target[msg.receiver].append(msg)
        if latency_steps == 1:
            inbox = next_inbox
        if step == n:
            break
        for j in ids:
            u = commands[j]
            new = pose[j] + dt * np.asarray(u)
            if disturbance > 0:
                radius = disturbance * np.sqrt(rng.uniform())
                angle = rng.uniform(0.0, 2.0 * np.pi)
                new[0] += dt * radius * np.cos(angle)
                new[1] += dt * radius * np.sin(angle)
            pose[j] = new
    return ClosedLoopResult(Trajectory(times, traj), logs, agent_states, sent)
