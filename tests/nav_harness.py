"""Closed-loop unicycle harness for tests and benchmarks (pure numpy; no physics engine).

Several unicycles ``ẋ = v cos θ + w_x``, ``ẏ = v sin θ + w_y``, ``θ̇ = ω`` (paper eq. (1) for
the TurtleBots, with an additive bounded disturbance ``‖w‖ ≤ w̄`` [m/s]) are integrated with
explicit Euler at ``integration_dt`` (100 Hz by default). Controllers are sampled every
``control_period`` (5 Hz, ltl-planning.md §6) and their command is held in between (zero-order
hold). The actual velocities track the commands to first order with time constant ``tau`` [s]
and the robot's acceleration limits: ``v̇ = clip((v_cmd − v)/tau, −a_v, a_v)``, same for ω.

Contacts are checked at every integration step: robot–robot when ``‖p_i − p_j‖ < r_i + r_j``,
robot–wall when the arena clearance of ``p_i`` (walls and static obstacles) is ``< r_i``. A
contact is recorded once when it begins.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from tlfleet.agent.model.scenario import Arena, UnicycleLimits
from tlfleet.agent.nav.events import NavEvent
from tlfleet.agent.nav.executor import Executor, ExecutorInputs, ExecutorOutputs, ExecutorState
from tlfleet.agent.nav.grid import arena_clearance

# A controller maps (time [s], own index, poses (N, 3)) to a command (v [m/s], ω [rad/s]).
Controller = Callable[[float, int, np.ndarray], tuple[float, float]]


@dataclass(frozen=True)
class HarnessConfig:
    control_period: float = 0.2  # [s] controller sampling (5 Hz)
    integration_dt: float = 0.01  # [s] integration step (100 Hz)
    tau: float = 0.05  # [s] first-order velocity tracking time constant
    disturbance: float = 0.0  # [m/s] bound on the additive world-frame velocity disturbance

    def __post_init__(self) -> None:
        ratio = self.control_period / self.integration_dt
        if self.integration_dt <= 0 or abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(
                f"control_period {self.control_period} must be a positive multiple of "
                f"integration_dt {self.integration_dt}"
            )


@dataclass(frozen=True)
class SimRobot:
    """A simulated unicycle: initial pose (x [m], y [m], θ [rad]), radius [m] and limits."""

    pose: tuple[float, float, float]
    radius: float = 0.2
    limits: UnicycleLimits = field(default_factory=UnicycleLimits)


@dataclass(frozen=True)
class Contact:
    """A contact that began at time ``t`` [s]: ``kind`` is "robot" (indices ``a`` < ``b``) or
    "wall" (robot ``a``, ``b`` = -1)."""

    t: float
    kind: str
    a: int
    b: int


@dataclass(frozen=True, eq=False)
class HarnessResult:
    """Recorded run, sampled at control instants.

    ``times`` (C+1,) [s]; ``poses`` (C+1, N, 3); ``velocities`` (C+1, N, 2) actual (v, ω);
    ``commands`` (C, N, 2) commanded (v, ω) held during [times[c], times[c+1]).
    ``min_robot_gap`` [m] is the smallest ``‖p_i − p_j‖ − r_i − r_j`` seen at any integration
    step (inf for one robot), ``min_wall_gap`` [m] the smallest ``clearance − r_i``.
    """

    times: np.ndarray
    poses: np.ndarray
    velocities: np.ndarray
    commands: np.ndarray
    contacts: tuple[Contact, ...]
    min_robot_gap: float
    min_wall_gap: float

    @property
    def duration(self) -> float:
        """Simulated time covered [s]."""
        return float(self.times[-1] - self.times[0])


def _uniform_disc(rng: np.random.Generator, n: int, bound: float) -> np.ndarray:
    """n samples (n, 2) uniform in the disc of radius ``bound``."""
    r = bound * np.sqrt(rng.random(n))
    a = rng.random(n) * 2.0 * math.pi
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def simulate(
    robots: Sequence[SimRobot],
    controllers: Sequence[Controller],
    duration: float,
    arena: Arena,
    config: HarnessConfig | None = None,
    rng: np.random.Generator | None = None,
    stop: Callable[[float, np.ndarray], bool] | None = None,
    t0: float = 0.0,
) -> HarnessResult:
    """Run the closed loop for ``duration`` [s] (or until ``stop(t, poses)`` is True).

    The clock starts at ``t0`` [s] (to continue an earlier run with the same controllers).

    ``controllers[i]`` drives ``robots[i]``. A disturbance (``config.disturbance > 0``) needs
    ``rng``; it is redrawn every integration step.
    """
    config = config or HarnessConfig()
    if len(robots) != len(controllers):
        raise ValueError(f"{len(robots)} robots but {len(controllers)} controllers")
    if config.disturbance > 0 and rng is None:
        raise ValueError("a disturbance needs a numpy Generator (rng)")
    n = len(robots)
    pose = np.array([r.pose for r in robots], dtype=float).reshape(n, 3)
    radius = np.array([r.radius for r in robots], dtype=float)
    acc = np.array([[r.limits.acc_v, r.limits.acc_omega] for r in robots], dtype=float)
    vel = np.zeros((n, 2))
    substeps = round(config.control_period / config.integration_dt)
    dt = config.integration_dt
    n_ctrl = math.floor(duration / config.control_period + 1e-9)
    pair_i, pair_j = np.triu_indices(n, k=1)
    touching_pairs = np.zeros(len(pair_i), dtype=bool)
    touching_walls = np.zeros(n, dtype=bool)
    contacts: list[Contact] = []
    min_robot_gap = math.inf
    min_wall_gap = math.inf
    times = [t0]
    poses = [pose.copy()]
    vels = [vel.copy()]
    commands = []
    t = 0.0
    for c in range(n_ctrl):
        t = t0 + c * config.control_period
        if stop is not None and stop(t, pose.copy()):
            break
        cmd = np.array([controllers[i](t, i, pose.copy()) for i in range(n)], dtype=float)
        cmd = cmd.reshape(n, 2)
        commands.append(cmd)
        for k in range(substeps):
            rate = np.clip((cmd - vel) / config.tau, -acc, acc)
            vel = vel + rate * dt
            heading = pose[:, 2]
            dx = vel[:, 0] * np.cos(heading)
            dy = vel[:, 0] * np.sin(heading)
            if config.disturbance > 0:
                w = _uniform_disc(rng, n, config.disturbance)
                dx = dx + w[:, 0]
                dy = dy + w[:, 1]
            pose = pose + dt * np.stack([dx, dy, vel[:, 1]], axis=1)
            pose[:, 2] = (pose[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
            now = t + (k + 1) * dt
            wall_gap = arena_clearance(arena, pose[:, :2]) - radius
            min_wall_gap = min(min_wall_gap, float(np.min(wall_gap)))
            on_wall = wall_gap < 0.0
            for i in np.flatnonzero(on_wall & ~touching_walls):
                contacts.append(Contact(now, "wall", int(i), -1))
            touching_walls = on_wall
            if len(pair_i):
                gap = (
                    np.linalg.norm(pose[pair_i, :2] - pose[pair_j, :2], axis=1)
                    - radius[pair_i]
                    - radius[pair_j]
                )
                min_robot_gap = min(min_robot_gap, float(np.min(gap)))
                touching = gap < 0.0
                for p in np.flatnonzero(touching & ~touching_pairs):
                    contacts.append(Contact(now, "robot", int(pair_i[p]), int(pair_j[p])))
                touching_pairs = touching
        times.append(t0 + (c + 1) * config.control_period)
        poses.append(pose.copy())
        vels.append(vel.copy())
    return HarnessResult(
        times=np.array(times),
        poses=np.array(poses),
        velocities=np.array(vels),
        commands=np.array(commands).reshape(-1, n, 2),
        contacts=tuple(contacts),
        min_robot_gap=min_robot_gap,
        min_wall_gap=min_wall_gap,
    )


class ExecutorController:
    """Adapter that runs a plan executor as a harness controller (tests, benchmarks).

    Holds the executor state between ticks and records every output; ``ids[i]`` is the robot id
    of harness index ``i`` (used to build the ``(id, x, y, θ)`` pose frame of the others).
    Setting ``pending_plan`` hands a new plan to the executor on the next tick. ``refresh``:
    run the step's deferred global re-plan right after it, as the agent runtime does once the
    command is sent (``Executor.refresh``; without it the next step runs it, same result).
    """

    def __init__(self, executor: Executor, state: ExecutorState, ids: Sequence[int], *,
                 refresh: bool = False):
        self.executor = executor
        self.state = state
        self.ids = tuple(ids)
        self.refresh = refresh
        self.outputs: list[ExecutorOutputs] = []
        self.events: list[NavEvent] = []
        self.pending_plan: tuple[tuple[str, ...], tuple[str, ...]] | None = None

    def __call__(self, t: float, index: int, poses: np.ndarray) -> tuple[float, float]:
        ids = np.asarray(self.ids, dtype=float)[:, None]
        frame = np.hstack([ids, poses])
        others = np.delete(frame, index, axis=0)
        inputs = ExecutorInputs(
            t=t, pose=tuple(poses[index]), others=others, new_plan=self.pending_plan
        )
        self.pending_plan = None
        self.state, out = self.executor.step(self.state, inputs)
        if self.refresh:
            self.state = self.executor.refresh(self.state)
        self.outputs.append(out)
        self.events.extend(out.events)
        return out.v, out.omega
