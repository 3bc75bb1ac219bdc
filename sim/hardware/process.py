"""The hardware bridge process: ``tlfleet hw SCENARIO --lab LAB.toml`` (docs/hardware.md).

It takes the simulator's place in a fleet. The loop is the realtime simulator's own
(:class:`tlfleet.sim.process.SimProcess`), so it publishes exactly what that publishes — the
frames on ``mocap``, ``mocap_every/<d>/<φ>`` and ``mocap_at/<s>`` at the scenario's frame
offsets, ``clock``, the events, ``sim_stats`` and ``sim_done``, the ``sim/backfill`` queryable,
the ``alive/sim/0`` token — and agents and coordinator are unchanged. Its world is
:class:`tlfleet.sim.hardware.world.HardwareWorld`: each frame carries every robot's newest
motion-capture pose (sample and hold), which the loop takes from ROS 2 just before it reads the
poses (:meth:`tlfleet.sim.hardware.ros_link.RosLink.poll`).

Commands go out as they come, not at the loop's next tick: on the transport's thread a command
is decoded and passes the simulator's checks (its key, :class:`FleetBounds`, the robot's
command shape, its age against ``--max-command-age`` / 5 control periods, as in the simulator)
before the safety rules (:mod:`tlfleet.sim.hardware.safety`) let it through to the robot's
``Twist``/``TwistStamped`` (body frame for omni robots); the loop then does the simulator's
bookkeeping (latency, deadlines, malformed counts) from the same sample.

Ending: at the end of the mission, at ``Control(stop)``, SIGINT or SIGTERM every robot gets
``stop_repeats`` zero commands, the bridge waits (at most ``stop_ack_timeout``) until the robots
have acknowledged them, and only then shuts rclpy down. Realtime only: the real world does not
wait for a lockstep tick.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from tlfleet.agent.model import Scenario
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.scenario.lab import Lab, check_lab, load_lab
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import ProtocolError, decode
from tlfleet.bus.protocol.messages import Command, MocapFrame
from tlfleet.bus.signals import install_signal_handlers
from tlfleet.bus.transport import Transport, TransportConfig
from tlfleet.bus.zenoh.transport import open_transport
from tlfleet.sim.frame_ring import BACKFILL_SECONDS
from tlfleet.sim.hardware.world import HardwareWorld
from tlfleet.sim.process import LINGER, SWITCH_INTERVAL, SimConfig, SimProcess

logger = logging.getLogger(__name__)


class HardwareError(TlfleetError):
    """The lab's hardware is not there as the lab file says (a body without poses, ...)."""


@dataclass(frozen=True)
class BridgeProcessConfig:
    """What ``tlfleet hw`` gives :func:`main`."""

    scenario: Path
    lab: Path
    duration: float | None = None  # [s] None: the scenario's
    transport: TransportConfig = field(default_factory=TransportConfig)
    max_command_age: float | None = None  # [s] None: 5 control periods
    backfill_seconds: float = BACKFILL_SECONDS
    wait_mocap: float = 10.0  # [s] wall: every rigid body must have sent a pose by then


class BridgeProcess(SimProcess):
    """The realtime simulator's loop on real robots (see the module docstring)."""

    world: HardwareWorld

    def __init__(self, transport: Transport, scenario: Scenario, config: SimConfig,
                 world: HardwareWorld, stop: threading.Event | None = None):
        if config.mode != "realtime":
            raise HardwareError("the hardware bridge runs in realtime only: the real world "
                                "does not wait for a lockstep tick")
        super().__init__(transport, scenario, config, stop, world=world)
        self._forward_lock = threading.Lock()
        self._tick_clock: tuple[float, float | None] = (0.0, None)  # (t_k [s], wall [s])
        self.forwarded = 0
        self.held_back = 0

    # ----------------------------------------------------------------- commands, at once

    def _command_sample(self, key: str, payload: bytes) -> None:
        arrival = self._now()
        with self._forward_lock:  # one sample at a time: CommandAge counts
            command = self._forward(key, payload, arrival)
        # the loop's bookkeeping from the same sample: a command that failed a check is decoded
        # and checked there again, to be counted as the simulator counts it
        self._inbox.put(("checked", key, command, arrival) if command is not None
                        else ("cmd", key, payload, arrival))

    def _forward(self, key: str, payload: bytes, arrival: float) -> Command | None:
        """The simulator's checks on one command, then the safety rules and the robot's topic.
        Returns the command when it passed the checks (sent or not), else None."""
        try:
            command = decode(Command, payload)
        except ProtocolError:
            return None
        robot = self._cmd_robot.get(key)
        if robot is None or robot != command.robot or self.bounds.command_problem(command):
            return None
        try:
            u = self.world.check_command(robot, command.u)
        except ValueError:
            return None
        t0 = self.world.t0
        if t0 is None:  # before the start: the safety rules count it and send nothing
            self.world.command(robot, u, clipped=True)
            return command
        # [s] sim time now on the frames' clock: the newest tick's time plus the wall time
        # since it went out (after an overrun the loop's schedule restarts, and sim time lags
        # wall time since the start; the agents stamp their commands with frame times)
        tick_t, tick_wall = self._tick_clock
        t = tick_t + max(0.0, arrival - tick_wall) if tick_wall is not None else arrival - t0
        fresh, started = self.ages.fresh([command], t)
        for stale in started:
            logger.warning("robot %d: command for t = %.3f s is %.3f s old at t = %.3f s: "
                           "not sent", stale.robot, stale.t, t - stale.t, t)
            self._event_at(t, "stale_command", robot=stale.robot, command_t=stale.t,
                           age=t - stale.t)
        if fresh:
            if self.world.command(robot, u, clipped=True):
                self.forwarded += 1
            else:
                self.held_back += 1
        return command

    def _apply(self, commands: list[Command], t: float) -> None:
        """The loop's apply step: the commands went out when they came (:meth:`_forward`)."""

    # ----------------------------------------------------------------- phases

    def _wait_for_start(self) -> bool:
        """Publish the live poses as the initial frame every ``preview_period`` until
        ``Control(start)`` (the robots may be placed by hand meanwhile)."""
        logger.warning("hw: waiting for start from a coordinator on %s (tlfleet run --hardware "
                       "or tlfleet supervise)", keys.control(self.fleet))
        next_publish = self._now()
        while not self.stopping:
            if self._now() >= next_publish:
                self._frame0 = self.world.mocap_poses()
                self._publish_frame(MocapFrame(0.0, 0, self._frame0, ()))
                next_publish += self.config.preview_period
            self._pump(max(0.0, min(next_publish - self._now(), self.config.poll)))
            if self.started:
                self._frame0 = self.world.mocap_poses()
                return True
        return False

    def _publish_tick(self, k: int, due: tuple[int, ...]) -> None:
        published = self._now()
        super()._publish_tick(k, due)
        self._tick_clock = (self.clock.time(k), published)

    def _run_realtime(self) -> None:
        self.world.start()
        super()._run_realtime()

    def _finish(self) -> None:
        super()._finish()
        self.stop_robots("the end of the mission")

    def _report_step(self) -> None:
        super()._report_step()
        for event in self.world.drain_events():
            self._event(event.kind, **event.data)

    def stop_robots(self, why: str) -> None:
        """Zero to every robot (``stop_repeats`` times); nothing is sent afterwards."""
        if self.world.safety.ended:
            return
        logger.info("%s: zero to every robot", why)
        self.world.stop_all(self.world.lab.stop_repeats)

    def summary(self) -> dict[str, object]:
        out = super().summary()
        out["hardware"] = {"forwarded": self.forwarded, "held_back": self.held_back,
                           "sent": self.world.sent, "sent_by_reason": self.world.sends_by_reason,
                           "dropped": dict(self.world.safety.dropped),
                           "halted": None if self.world.safety.halted is None
                           else self.world.safety.halted.kind}
        return out


def wait_for_bodies(world: HardwareWorld, lab: Lab, timeout: float,
                    stop: threading.Event) -> None:
    """Wait until every robot's rigid body has sent a pose; :class:`HardwareError` naming the
    silent topics after ``timeout`` [s] wall."""
    deadline = time.monotonic() + timeout
    while not stop.is_set():
        missing = world.missing_poses()
        if not missing:
            return
        if time.monotonic() >= deadline:
            topics = ", ".join(f"robot {r}: {lab.robot(r).mocap_topic}" for r in missing)
            raise HardwareError(f"no pose within {timeout:g} s from {topics} (ROS domain "
                                f"{lab.domain_id}, discovery {lab.discovery_range}); "
                                f"`tlfleet hw --check` lists what the ROS graph shows")
        stop.wait(0.05)


def main(config: BridgeProcessConfig) -> int:
    """``tlfleet hw``: load and check scenario and lab, join ROS and zenoh, run, stop the robots,
    then close ROS and the session."""
    scenario = load_scenario(config.scenario)
    lab = load_lab(config.lab)
    check_lab(lab, scenario)
    sim_config = SimConfig.for_scenario(scenario, mode="realtime", duration=config.duration,
                                        max_command_age=config.max_command_age,
                                        backfill_seconds=config.backfill_seconds)
    from tlfleet.sim.hardware.ros_link import RosLink  # rclpy: the tlfleet[ros2] extra

    sys.setswitchinterval(SWITCH_INTERVAL)
    stop = threading.Event()
    install_signal_handlers(stop)  # before rclpy: its handlers are off (SignalHandlerOptions.NO)
    world = HardwareWorld(scenario, lab)
    link = RosLink(lab, world.on_pose)
    world.link, world.poll = link, link.poll
    process: BridgeProcess | None = None
    transport: Transport | None = None
    try:
        wait_for_bodies(world, lab, config.wait_mocap, stop)
        if stop.is_set():
            return 0
        transport = open_transport(config.transport)
        process = BridgeProcess(transport, scenario, sim_config, world, stop)
        code = process.run()
        process.stop_robots("stopping")  # first: the linger below is for zenoh, not the robots
        time.sleep(LINGER)
        return code
    finally:
        if process is not None:
            process.stop_robots("stopping")
        else:
            world.stop_all(lab.stop_repeats)
        acked = link.wait_acked(lab.stop_ack_timeout)
        counts = link.subscriber_counts()
        if not acked:
            logger.warning("not every robot acknowledged the zero command within %g s "
                           "(subscribers per robot: %s)", lab.stop_ack_timeout, counts)
        link.close()
        if transport is not None:
            transport.close()
