"""What every agent process does around its loop (style.md §6; stack-notes.md §0, §1.7, §2.3).

``run_agent`` opens the transport from the shared flags, builds the agent (planning included)
*before* declaring ``alive/agent/<id>`` (the token means "ready to answer frames"), runs the loop
until ``Control(stop)``, SIGINT or SIGTERM, and closes everything in ``finally``. It sets
``sys.setswitchinterval(0.0005)`` so transport callbacks are not held ~5 ms behind the GIL by the
agent's CPU-bound step. On a clean stop it publishes ``Event(kind="agent_stats")`` (frames, steps,
step times, collaboration and malformed counters).
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.runtime.config import AgentConfig
from tlfleet.agent.runtime.inbox import MalformedCounter
from tlfleet.agent.runtime.loop import AgentLoop, Core, LoopConfig
from tlfleet.agent.runtime.peers import CollabLink
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.lifeline import CoordinatorWatch
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.bounds import MAX_TIME, FleetBounds
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Event
from tlfleet.bus.protocol.plausibility import max_jump_ticks
from tlfleet.bus.signals import install_signal_handlers
from tlfleet.bus.transport import Transport
from tlfleet.bus.zenoh.transport import open_transport

logger = logging.getLogger(__name__)

Built = tuple[Core, Any, tuple[Event, ...], CollabLink | None]
Builder = Callable[[Transport, MalformedCounter, Callable[[Event], None]], Built | None]

SWITCH_INTERVAL = 0.0005  # [s] stack-notes.md §2.3
LINGER = 0.1  # [s] wall between the last publication and closing the session


def plausibility(scenario: Scenario) -> dict[str, Any]:
    """The loop's frame checks for ``scenario``: the arena box and robots, and the
    sequence gate. The run's duration may be overridden on the simulator's command line, which
    the agent does not see, so times are only bounded by the codec's MAX_TIME here."""
    if not isinstance(scenario, Scenario):  # a test double: no plausibility checks
        return {}
    a = scenario.arena
    bounds = FleetBounds((a.xmin, a.xmax, a.ymin, a.ymax), MAX_TIME, scenario.sim.mocap_rate,
                         scenario.speed_limits())
    dividers = [scenario.control_divider(r) for r in scenario.robot_ids]
    return {"bounds": bounds, "max_jump": max_jump_ticks(scenario.sim.mocap_rate, dividers)}


def frame_subscription(scenario: Scenario, robot: int) -> dict[str, Any]:
    """The loop reads only the frames it can be due for, at its frame offset
    (``keys.robot_frames``): the simulator of a real scenario publishes them. Test
    doubles keep reading every frame on ``mocap``."""
    if not isinstance(scenario, Scenario):
        return {}
    return {"decimated": True, "mocap_rate": scenario.sim.mocap_rate,
            "offset": scenario.frame_offset(robot)}


def run_agent(config: AgentConfig, scenario: Scenario, build: Builder, *,
              transport: Transport | None = None, stop: threading.Event | None = None) -> int:
    """Run one agent process; 0 on a clean stop, 1 on a fault: ``build`` raising a
    :class:`~tlfleet.bus.errors.TlfleetError` (e.g. an unsatisfiable LTL task) or returning None, or
    the loop failing; each is reported as ``Event(kind="fault", data={"error": ...})``.

    ``transport`` and ``stop`` are for tests (a fake transport, a stop event they control);
    by default the zenoh session is opened from ``config.transport`` and SIGINT/SIGTERM set
    ``stop``.
    """
    sys.setswitchinterval(SWITCH_INTERVAL)
    if stop is None:
        stop = threading.Event()
        install_signal_handlers(stop)
    own_transport = transport is None
    if transport is None:
        transport = open_transport(config.transport)
    source = f"agent/{config.robot}"
    divider = scenario.control_divider(config.robot)
    loop: AgentLoop | None = None
    watch = CoordinatorWatch(transport, keys.alive(scenario.fleet, "coordinator", 0), stop,
                             config.orphan_after, source)
    try:
        malformed = MalformedCounter(source)
        event_key = keys.event(scenario.fleet, "agent", config.robot)

        def publish(event: Event) -> None:
            transport.publish(event_key, encode(event))

        try:
            built = build(transport, malformed, publish)
        except TlfleetError as exc:  # e.g. UnsatisfiableTask: report it, exit 1
            logger.error("%s: %s", source, exc)
            publish(Event(0.0, source, "fault", {"error": str(exc)}))
            return 1
        if built is None:
            return 1
        core, state, events, link = built
        loop_config = LoopConfig(scenario.fleet, config.robot, divider, config.stale_after,
                                 **plausibility(scenario),
                                 **frame_subscription(scenario, config.robot),
                                 heartbeat=config.heartbeat,
                                 phase=scenario.control_phase(config.robot))
        loop = AgentLoop(transport, loop_config, core, state, link=link, malformed=malformed)
        loop.open()
        loop.ready()
        for event in events:
            loop.publish_startup_event(event)
        logger.info("%s ready (fleet %s, divider %d, phase %d)", source, scenario.fleet, divider,
                    loop_config.phase)
        logger.info("agent %d: waiting for start from a coordinator on %s and mocap frames "
                    "from the simulator on %s", config.robot, keys.control(scenario.fleet),
                    keys.mocap(scenario.fleet))
        try:
            code = loop.run(stop)
        except Exception as exc:  # a bug in a core: report it, then exit non-zero
            logger.exception("%s: fault", source)
            loop.publish_event(Event(loop.last_t, source, "fault",
                                     {"error": f"{type(exc).__name__}: {exc}"}))
            return 1
        stats = loop.summary()
        loop.publish_event(Event(loop.last_t, source, "agent_stats", stats))
        logger.info("%s stopped: %s", source, stats)
        return code
    finally:
        watch.close()
        if loop is not None:
            loop.close()
        if own_transport:
            time.sleep(LINGER)  # let zenoh deliver the last command / event before closing
            transport.close()

