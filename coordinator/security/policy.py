"""The access-control policy of a scenario's fleet: who may put, subscribe, serve,
query and declare what, as :class:`tlfleet.bus.zenoh.security.Grant` s over the fleet's keys
(``tlfleet.bus.protocol.keys``, architecture.md §2). Pure: a loaded scenario in, grants out.

=============  ==========================================================================
identity       grants (every key under ``tlfleet/<fleet>/``)
=============  ==========================================================================
``robot<i>``   publish ``robot/i/cmd``, ``robot/i/status``, ``event/agent/i``;
               token ``alive/agent/i``; serve ``robot/i/collab/*`` (STL robots);
               query ``robot/j/collab/i`` for every robot j it is coupled with (below: the
               key names the sender, which robot j checks against the message);
               subscribe ``mocap`` (divider d ≥ 2: ``mocap_every/d/φ`` instead; frame offset
               s ≥ 1: ``mocap_at/s``), ``clock``, ``control``; watch ``alive/**``
``sim``        publish ``mocap``, ``mocap_every/d/φ`` (each schedule, d ≥ 2, of the fleet),
               ``mocap_at/s`` (each every-tick robot's offset s ≥ 1), ``clock``,
               ``event/sim/0``;
               subscribe ``robot/*/cmd``, ``control``; serve ``sim/backfill``;
               token ``alive/sim/0``; watch ``alive/**``
``coordinator`` publish ``control``, ``event/coordinator/0``; subscribe ``**``; query
               ``sim/backfill``;
               token ``alive/coordinator/0``; watch ``alive/**``
``router``     nothing through its links (its own session is local to it); in a router mesh
               (``mesh=True``: ``tlfleet run --hosts N``, ``tlfleet keys --mesh``) everything
               under the fleet's prefix in both directions, because the routers forward each
               other's clients' traffic, already checked by the router the client is linked
               to — there the router's key is the fleet's most trusted one
=============  ==========================================================================

Robot i is *coupled* with j when stage-2 collaboration can send a message from i to j
(stl-funnel.md §7): j is STL-controlled in one of i's sub-tasks (``Task.v_ctrl``: requests,
updates, releases) or i is in the V of one of j's sub-tasks (status announcements,
``tlfleet.agent.policy.stl.status_readers``). LTL robots and robots with no coupling query nothing.
Everything else is denied by the router (``default_permission: "deny"``).

Every identity that publishes may *discover* the subscriptions under ``tlfleet/<fleet>/**``
(zenoh's write-side filtering needs the declarations, :mod:`tlfleet.bus.zenoh.security`); that shows
who subscribes what, never a sample. Beyond the issue's list, the sim subscribes ``control`` (it
stops on ``Control(stop)``) and the coordinator publishes ``event`` (supervision events), as the
code does today; watching ``alive/**`` (liveliness) is read-only presence.
"""

from __future__ import annotations

from tlfleet.agent.model import Scenario
from tlfleet.agent.policy.stl import build_agents
from tlfleet.bus.protocol import keys
from tlfleet.bus.zenoh.security import Grant, identity


def coupled_robots(scenario: Scenario) -> dict[int, tuple[int, ...]]:
    """For each STL robot, the robots whose ``collab`` queryable it may query (ids ascending)."""
    agents = build_agents(scenario, warn=False)
    out = {}
    for robot_id, agent in agents.items():
        targets = set(agent.cfg.peers)
        for task in agent.cfg.subtasks:
            targets.update(task.v_ctrl)
        targets.discard(robot_id)
        out[robot_id] = tuple(sorted(targets))
    return out


def fleet_grants(scenario: Scenario, *, mesh: bool = False) -> tuple[Grant, ...]:
    """The grants of every process of ``scenario``: sim, coordinator, one per robot; with
    ``mesh`` (several routers linked to each other) also the routers'."""
    fleet = scenario.fleet
    everyone_alive = (keys.all_alive(fleet),)
    everything = (f"{keys.prefix(fleet)}/**",)
    coupled = coupled_robots(scenario)
    schedule = {r.id: (scenario.control_divider(r.id), scenario.control_phase(r.id))
                for r in scenario.robots}
    every = tuple(keys.mocap_every(fleet, d, p)
                  for d, p in keys.frame_schedules(schedule.values()))
    every += tuple(keys.mocap_at(fleet, s) for s in scenario.every_tick_offsets())
    grants = [Grant("router", publish=everything, discover=everything, subscribe=everything,
                    serve=everything, query=everything, token=everything, watch=everything)
              ] if mesh else []
    grants += [
        Grant("sim", publish=(keys.mocap(fleet), *every, keys.clock(fleet),
                              keys.event(fleet, "sim", 0)),
              discover=everything,
              subscribe=(keys.all_cmds(fleet), keys.control(fleet)),
              serve=(keys.sim_backfill(fleet),),
              token=(keys.alive(fleet, "sim", 0),), watch=everyone_alive),
        Grant("coordinator", publish=(keys.control(fleet), keys.event(fleet, "coordinator", 0)),
              discover=everything, subscribe=everything, query=(keys.sim_backfill(fleet),),
              token=(keys.alive(fleet, "coordinator", 0),), watch=everyone_alive),
    ]
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        i = robot.id
        d, p = schedule[i]
        frames = keys.robot_frames(fleet, d, p, scenario.frame_offset(i))
        grants.append(Grant(
            identity("agent", i),
            publish=(keys.cmd(fleet, i), keys.status(fleet, i), keys.event(fleet, "agent", i)),
            discover=everything,
            subscribe=(frames, keys.clock(fleet), keys.control(fleet)),
            serve=(keys.collab_all(fleet, i),) if robot.is_stl else (),
            query=tuple(keys.collab_from(fleet, j, i) for j in coupled.get(i, ())),
            find=tuple(keys.collab_all(fleet, j) for j in coupled.get(i, ())),
            token=(keys.alive(fleet, "agent", i),), watch=everyone_alive))
    return tuple(grants)


def identities(scenario: Scenario) -> tuple[str, ...]:
    """Every process identity of a fleet, the router first: the certificates ``tlfleet keys``
    writes."""
    return ("router", "sim", "coordinator",
            *(identity("agent", r.id) for r in sorted(scenario.robots, key=lambda r: r.id)))
