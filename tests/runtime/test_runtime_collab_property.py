"""No well-formed collaboration message kills an STL agent: every combination of (sender,
receiver, sub-task, kind), each with funnels that fit the sub-task and funnels that do not, sent
over the fake bus to every STL agent of the paper's Scenarios 1–3 — accepted by the agent's
``CollabLink`` or refused (counted), then stepped through its ``StlCore`` twice (the step that
reads the inbox and one that acts on it): nothing raises.

A request is followed only when its sub-task involves both the sender (named by the key it
arrives on) and the receiver; the test checks that too, against the library's sub-tasks."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from pathlib import Path

import pytest
from tlfleet.agent.policy.stl import build_agents
from tlfleet.agent.runtime.collab import funnel_to_wire
from tlfleet.agent.runtime.inbox import MalformedCounter
from tlfleet.agent.runtime.loop import TickInput
from tlfleet.agent.runtime.peers import CollabLink
from tlfleet.agent.runtime.stl_agent import StlCore
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.stl.funnel import Funnel
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import CollabMessage, CollabReply, MocapFrame

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
KINDS = ("request", "update", "release", "status")


def funnels(task) -> list[Funnel]:
    """A funnel that fits ``task`` (its kind and window, the invariants of §5), one for another
    window, and degenerate ones the codec lets through (γ_∞ = 0, NaN, l < 0)."""
    fit = Funnel.init(task.kind, task.a, task.b, rho_opt=1.0, rho0=0.2, t_r=task.a - 1.0)
    return [fit, replace(fit, a=task.a + 1.0, b=task.b + 5.0), replace(fit, gamma_inf=0.0),
            replace(fit, r=math.nan, rho_max=math.nan), replace(fit, l=-3.0, gamma0=-1.0),
            replace(fit, ramp=1e6, t_knee=fit.t_r - 5.0), replace(fit, ramp=-1.0)]


def poses_at(scenario) -> tuple[tuple[int, float, float, float], ...]:
    return tuple((r.id, *r.pose) for r in sorted(scenario.robots, key=lambda r: r.id))


@pytest.mark.parametrize("name", ["scenario1", "scenario2", "scenario3"])
def test_every_well_formed_collaboration_message_leaves_every_agent_alive(name):
    scenario = load_scenario(SCENARIOS / f"{name}.toml")
    agents = build_agents(scenario, warn=False)
    library = next(iter(agents.values())).cfg.library
    ids = sorted(scenario.robot_ids)
    senders = [*ids, max(ids) + 1, 0]  # and two ids of no robot
    subtasks = range(-1, 1 + max(index for _, index in library) + 1)
    sample_task = next(iter(library.values()))
    times = sorted({0.0, *(t.a + 0.5 for t in library.values())})
    sent = followed = refused = 0
    for receiver, agent in agents.items():
        net = FakeNetwork()
        link = CollabLink(net.transport(f"robot{receiver}"), scenario.fleet, receiver,
                          agent.cfg.peers, MalformedCounter(f"agent/{receiver}"),
                          check=agent.collab_problem)
        link.open()
        core = StlCore(agent)
        for sender, subtask, kind in itertools.product(senders, subtasks, KINDS):
            task = library.get((sender, subtask), sample_task)
            for funnel in funnels(task) if kind in ("request", "update") else [None]:
                for t in times:
                    msg = CollabMessage(kind, sender, receiver, t, subtask,
                                        None if funnel is None else funnel_to_wire(funnel),
                                        c=sender, task_kind=task.kind, a=task.a, b=task.b)
                    replies = net.transport("peer").query(
                        keys.collab_from(scenario.fleet, receiver, sender), encode(msg), 1.0)
                    (reply,) = [decode(CollabReply, r) for r in replies]
                    sent += 1
                    owned = library.get((sender, subtask))
                    fits = owned is not None and receiver in owned.v_ctrl \
                        and sender != receiver
                    if kind == "request" and reply.accepted:
                        # followed only if the sub-task involves both, with a funnel for it
                        assert fits and funnel == funnels(owned)[0], (sender, subtask, funnel)
                        followed += 1
                    refused += not reply.accepted
                    frame = MocapFrame(t, round(t * 100), poses_at(scenario))
                    state = core.initial_state()
                    for step in range(2):  # the step that reads the inbox, one that acts on it
                        inbox = link.inbox.take_before(math.inf)
                        state, out = core.step(state, TickInput(
                            replace(frame, t=t + 0.01 * step), inbox))
                        assert all(math.isfinite(u) for u in out.u), (msg, out.u)
        link.close()
    combinations = len(agents) * len(senders) * len(subtasks) * len(times) * (2 * 7 + 2)
    assert sent == combinations and refused > 0, (sent, combinations, refused)
    coupled = any(len(task.v_ctrl) > 1 for task in library.values())
    assert (followed > 0) == coupled  # a scenario with coupled sub-tasks has requests to follow
