"""STL agents on the simulator's physics, in one process: lockstep without processes or transport.

Each 100 Hz tick: the poses of the pymunk world (``tlfleet.sim.world.World``: velocity tracking
with acceleration limits, walls, obstacles, contacts, the scenario's disturbance) are the frame
of time t_k; every STL agent steps on it in id order; its command holds over [t_k, t_{k+1})
(``World.set_command``, then ``World.step``), as in a lockstep run. Stage-2 messages are
delivered at the next tick. No LTL robots (they would need their navigation). For benchmarks
that run many short tasks (``bench/stl_maps_bench.py``), where a fleet of processes per task
would cost minutes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.policy.stl import AgentState, StepInput, build_agents
from tlfleet.sim.world import World


@dataclass
class WorldRun:
    t: np.ndarray  # (N,) [s]
    states: dict[int, np.ndarray]  # robot -> (N, 3) x, y, θ
    outcomes: dict[int, tuple]  # robot -> its SubTaskOutcomes
    repairs: int = 0
    contacts: list = field(default_factory=list)  # the world's contact records


def run_in_world(scenario: Scenario, duration: float | None = None, seed: int | None = None
                 ) -> WorldRun:
    """Run the scenario's STL robots for ``duration`` [s] (default: the scenario's) on the world
    seeded with ``seed`` (default: the scenario's)."""
    if any(r.is_ltl for r in scenario.robots):
        raise ValueError("run_in_world runs STL robots only")
    rate = scenario.sim.mocap_rate
    dt = 1.0 / rate
    steps = round((duration if duration is not None else scenario.duration) * rate)
    world = World.from_scenario(scenario, np.random.default_rng(
        scenario.sim.seed if seed is None else seed))
    agents = build_agents(scenario, warn=False)
    order = sorted(agents)
    states: dict[int, AgentState] = {i: agents[i].initial_state() for i in order}
    inbox: dict[int, list] = {i: [] for i in order}
    t_all = np.empty(steps + 1)
    traj = {i: np.empty((steps + 1, 3)) for i in world.ids}
    repairs = 0
    contacts = []
    for k in range(steps + 1):
        t = k * dt
        poses = {i: (x, y, th) for i, x, y, th in world.poses()}
        t_all[k] = t
        for i, pose in poses.items():
            traj[i][k] = pose
        nxt: dict[int, list] = {i: [] for i in order}
        for i in order:
            states[i], out = agents[i].step(states[i], StepInput(t, poses, inbox[i], tuples=True))
            repairs += bool(out.log.repair)
            for msg in out.messages:
                if msg.receiver in nxt:
                    nxt[msg.receiver].append(msg)
            world.set_command(i, out.u, t)
        inbox = nxt
        if k == steps:
            break
        world.step(dt)
        contacts.extend(world.drain_contacts())
    return WorldRun(t_all, traj, {i: states[i].outcomes for i in order}, repairs, contacts)
