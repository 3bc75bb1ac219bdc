"""What the STL agents and ``tlfleet check`` derive from a scenario, computed in one place so that
both agree: the workspace of the robots' centres, the coupled pairs and their avoidance radii, and
every STL robot's sub-tasks with ρ_opt resolved (docs/stl-saturation.md §5, §7).

* **Coupled pairs.** Two robots are coupled when both positions enter one literal of some STL
  sub-task (``dist(p2, p3) <= 0.5``, a formation slot ``dist(p3 - p1, [..]) <= 0.1``): the task
  may ask them to be near each other. With ``[stl] coupled_radii`` (the default) such a pair avoids
  each other with radii from their bodies, R1_ij = r_i + r_j + ``coupled_r1_margin`` and
  R_ij = r_i + r_j + ``coupled_r_margin``, instead of the scenario's R1 and R (paper eq. (6) keeps
  R1 = 0.6 m between 0.2 m bodies, which makes a 0.5 m rendezvous impossible).
* **Workspace.** Robot j's centre stays ``r_j + wall_r_margin`` from walls and obstacles (the
  static avoidance's outer radius) with ``[stl] wall_avoidance``, r_j without; a coupled pair stays
  R_ij apart (r_i + r_j without coupled radii). ρ_opt is the supremum of ρ^ψ over this workspace
  (``tlfleet.agent.stl.supremum``) unless the file gives ``rho_opt``, or ``[stl]
  rho_opt_from_arena = false`` asks for the literal bound of stl-funnel.md §3.
"""

from __future__ import annotations

import functools
from itertools import combinations

from tlfleet.agent.model.scenario import Robot, Scenario
from tlfleet.agent.stl.parser import robot_subtasks
from tlfleet.agent.stl.sequencer import build_sequence
from tlfleet.agent.stl.supremum import Workspace
from tlfleet.agent.stl.syntax import Position, StateVar, literals, robots_of
from tlfleet.agent.stl.task import Task


def positions_of(node) -> frozenset[int]:
    """Robots whose position (p_j, x_j or y_j, not θ_j alone) enters an expression or literal."""
    found: set[int] = set()

    def walk(n) -> None:
        if isinstance(n, Position) or (isinstance(n, StateVar) and n.component in ("x", "y")):
            found.add(n.robot)
            return
        for child in getattr(n, "__dataclass_fields__", {}):
            value = getattr(n, child)
            if isinstance(value, tuple):
                for item in value:
                    if hasattr(item, "__dataclass_fields__"):
                        walk(item)
            elif hasattr(value, "__dataclass_fields__"):
                walk(value)

    walk(node)
    return frozenset(found)


def naming(scenario: Scenario, robots: frozenset[int]) -> frozenset[int]:
    """The STL robots whose sub-tasks an agent of ``robots`` needs: those robots themselves and
    every STL robot with a sub-task that names one of them (a requester it may follow in stage 2,
    a leader's coupling limits)."""
    return frozenset(r.id for r in scenario.robots if r.is_stl and (r.id in robots or any(
        robots & robots_of(phi.body) for phi in robot_subtasks(r))))


def coupled_pairs(scenario: Scenario) -> frozenset[tuple[int, int]]:
    """Pairs (i, j), i < j, whose positions enter one literal of some STL sub-task."""
    pairs: set[tuple[int, int]] = set()
    for robot in scenario.robots:
        if not robot.is_stl:
            continue
        for phi in robot_subtasks(robot):
            for literal in literals(phi.body):
                pairs.update(combinations(sorted(positions_of(literal)), 2))
    return frozenset(pairs)


def pair_radii(scenario: Scenario, i: int, j: int) -> tuple[float, float]:
    """(R1_ij, R_ij) [m] of a coupled pair (module docstring)."""
    p = scenario.stl
    bodies = scenario.robot(i).radius + scenario.robot(j).radius
    return bodies + p.coupled_r1_margin, bodies + p.coupled_r_margin


def wall_radii(scenario: Scenario, robot: Robot) -> tuple[float, float]:
    """(R1, R) [m] of the static avoidance of ``robot``: distances from its centre to a wall's or
    an obstacle's surface (tlfleet.agent.control.collision.static_velocity)."""
    p = scenario.stl
    return robot.radius + p.wall_r1_margin, robot.radius + p.wall_r_margin


@functools.lru_cache(maxsize=32)
def scenario_workspace(scenario: Scenario) -> Workspace:
    """The workspace of the robots' centres (module docstring)."""
    p = scenario.stl
    clearance = tuple((r.id, wall_radii(scenario, r)[1] if p.wall_avoidance else r.radius)
                      for r in scenario.robots)
    separation = tuple(
        (i, j, pair_radii(scenario, i, j)[1] if p.coupled_radii
         else scenario.robot(i).radius + scenario.robot(j).radius)
        for i, j in sorted(coupled_pairs(scenario)))
    return Workspace(scenario.arena, clearance, separation)


def start_poses(scenario: Scenario) -> tuple[tuple[int, tuple[float, float, float]], ...]:
    return tuple((r.id, tuple(float(v) for v in r.pose)) for r in scenario.robots)


@functools.lru_cache(maxsize=32)
def stl_sequences(scenario: Scenario, warn: bool = False,
                  only: frozenset[int] | None = None) -> dict[int, tuple[Task, ...]]:
    """Every STL robot's sub-tasks (stl-funnel.md §9), ρ_opt resolved as the module docstring
    says; the agents (``build_agents``), the LTL robots' coupling model and ``tlfleet check`` all
    build them here. ``only``: just these robots' (an agent builds its own and those coupled to
    it, so that another robot's broken task is that robot's agent's to report)."""
    p = scenario.stl
    stl_ids = tuple(r.id for r in scenario.robots if r.is_stl)
    workspace = scenario_workspace(scenario) if p.rho_opt_from_arena else None
    poses = start_poses(scenario)
    return {robot.id: build_sequence(robot.id, robot_subtasks(robot),
                                     robot_ids=scenario.robot_ids, stl_ids=stl_ids,
                                     rho_opt=robot.rho_opt, eta=p.eta, warn=warn,
                                     workspace=workspace, poses=poses)
            for robot in scenario.robots if robot.is_stl and (only is None or robot.id in only)}

