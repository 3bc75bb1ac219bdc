"""One launch plan for every way a fleet is started (architecture.md §1, "One launch plan").

A fleet is the same processes wherever it runs: a router, the simulator, one agent per robot and,
when the coordinator is a process of its own, ``tlfleet supervise``. :func:`plan_fleet` says what
each of them runs — pure: a loaded scenario and a :class:`PlanConfig` in, a tuple of
:class:`ProcessSpec` out, nothing started and nothing written. The three launchers are placements
of that one plan:

* ``tlfleet run`` (:mod:`tlfleet.coordinator.run`): every process a child on this machine, linked
  to one loopback router (zenoh peers in an unsecured run);
* ``tlfleet run --hosts N`` (:mod:`tlfleet.coordinator.run_hosts`): the processes in network
  namespaces, each linked to its host's router (or a peer mesh for partitions), ``supervise`` on
  host 0;
* ``tlfleet compose`` (:mod:`tlfleet.coordinator.compose`): one compose service per process.

A placement only fills in where a process links to (:meth:`ProcessSpec.placed`: endpoints, mode,
the key directory as the process sees it) and how it is wrapped (``ip netns exec``, a container).
The transport flags every process shares are written by one serializer, :meth:`Links.argv`, the
inverse of :func:`tlfleet.cli.transport_flags.add_transport_arguments` (a test parses one with the
other). ``secure`` is one type everywhere: the key directory (``Path``) or ``None``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from tlfleet.agent.model import Scenario

#: ``Links.runtime`` values: zenoh's pools (``None``, the processes' default) or its minimal
#: runtime (``tlfleet.bus.transport.MINIMAL_RUNTIME``)
RUNTIMES = (None, "minimal")
#: ``ProcessSpec.sched`` values (``tlfleet.cli.process_flags``); ``None``: as started
SCHEDS = (None, "default", "batch", "fifo")
ROLES = ("router", "sim", "agent", "coordinator")


@dataclass(frozen=True)
class Links:
    """The transport flags of one process (``tlfleet.cli.transport_flags``).

    ``mode`` None keeps the command's default (a router is a router, everyone else a client);
    ``secure`` is the key directory of ``tlfleet keys`` *as the process sees it* (inside a
    container: its mount point); ``lease_ms`` [ms]."""

    mode: str | None = None
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    secure: Path | None = None
    lease_ms: int | None = None
    zenoh_config: Path | None = None
    runtime: str | None = None

    def __post_init__(self) -> None:
        if self.mode not in (None, "client", "peer", "router"):
            raise ValueError(f"Links.mode {self.mode!r}: expected client, peer or router")
        if self.runtime not in RUNTIMES:
            raise ValueError(f"Links.runtime {self.runtime!r}: expected None or 'minimal'")
        if self.lease_ms is not None and self.lease_ms <= 0:
            raise ValueError(f"Links.lease_ms {self.lease_ms!r}: must be positive")

    def argv(self) -> tuple[str, ...]:
        """The flags, in one fixed order: mode, endpoints, keys, lease, zenoh file, runtime."""
        out: list[str] = []
        if self.mode is not None:
            out += ["--mode", self.mode]
        for endpoint in self.connect:
            out += ["--connect", endpoint]
        for endpoint in self.listen:
            out += ["--listen", endpoint]
        if self.secure is not None:
            out += ["--secure", str(self.secure)]
        if self.lease_ms is not None:
            out += ["--lease-ms", str(self.lease_ms)]
        if self.zenoh_config is not None:
            out += ["--zenoh-config", str(self.zenoh_config)]
        if self.runtime is not None:
            out += ["--zenoh-runtime", self.runtime]
        return tuple(out)


@dataclass(frozen=True)
class ProcessSpec:
    """One process of a fleet: ``tlfleet <args> <links> [--sched S] <tail>``.

    ``name`` is what the launcher and the supervisor call it (``router``, ``sim``, ``agent-3``,
    ``coordinator``); ``args`` the subcommand and its own flags; ``tail`` flags that follow the
    transport flags (``supervise``'s outputs)."""

    name: str
    role: str
    args: tuple[str, ...]
    links: Links = field(default_factory=Links)
    robot: int | None = None
    sched: str | None = None
    tail: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f"ProcessSpec.role {self.role!r}: expected one of {ROLES}")
        if self.sched not in SCHEDS:
            raise ValueError(f"ProcessSpec.sched {self.sched!r}: expected one of {SCHEDS[1:]}")

    def argv(self) -> tuple[str, ...]:
        """The arguments of ``tlfleet`` (prefix them with the command that runs it)."""
        sched = ("--sched", self.sched) if self.sched not in (None, "default") else ()
        return (*self.args, *self.links.argv(), *sched, *self.tail)

    def placed(self, **links: object) -> ProcessSpec:
        """This process with some of its :class:`Links` fields replaced (a placement)."""
        return replace(self, links=replace(self.links, **links))


@dataclass(frozen=True)
class PlanConfig:
    """What varies between runs of one scenario, independent of where the processes run.

    ``scenario_ref``: the scenario file as the processes name it (an absolute path, or a
    container's mount point). ``secure``: the key directory as the processes see it. ``None``
    values are left to the processes' defaults (the scenario's)."""

    scenario_ref: str
    mode: str = "lockstep"  # "lockstep" | "realtime"
    duration: float | None = None  # [s] sim time
    seed: int | None = None
    tick_timeout: float | None = None  # [s] wall, lockstep
    max_speed: float | None = None  # lockstep: sim time ≤ max_speed × wall time
    sim_args: tuple[str, ...] = ()  # more flags of `tlfleet sim`
    agent_args: tuple[str, ...] = ()  # more flags of every `tlfleet agent`
    heartbeat: bool = False  # decimated agents also watch the sim's clock (runs with faults)
    secure: Path | None = None
    lease_ms: int | None = None  # [ms]
    zenoh_config: Path | None = None
    sched: str | None = None  # OS scheduling of router, sim and agents
    supervise: tuple[str, ...] | None = None  # None: no coordinator process; else its flags
    supervise_tail: tuple[str, ...] = ()  # supervise's flags after the transport flags

    def __post_init__(self) -> None:
        if self.mode not in ("lockstep", "realtime"):
            raise ValueError(f"PlanConfig.mode {self.mode!r}: expected lockstep or realtime")


def _number(value: float) -> str:
    """A float flag's text: exact (``repr``), without a useless ``.0`` for whole numbers."""
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e15 else repr(value)


def plan_fleet(scenario: Scenario, config: PlanConfig) -> tuple[ProcessSpec, ...]:
    """The processes of ``scenario``'s fleet: the router, the simulator, one agent per robot
    (ids ascending) and, with ``config.supervise``, the coordinator. Each carries the flags
    every placement shares; endpoints are the placement's (:meth:`ProcessSpec.placed`)."""
    links = Links(secure=config.secure, lease_ms=config.lease_ms,
                  zenoh_config=config.zenoh_config)
    ref = config.scenario_ref
    sim = ["sim", ref, f"--{config.mode}"]
    for flag, value in (("--duration", config.duration), ("--tick-timeout", config.tick_timeout),
                        ("--max-speed", config.max_speed)):
        if value is not None:
            sim += [flag, _number(value)]
    if config.seed is not None:
        sim += ["--seed", str(config.seed)]
    specs = [
        ProcessSpec("router", "router", ("router", "--fleet", scenario.fleet), links,
                    sched=config.sched),
        ProcessSpec("sim", "sim", (*sim, *config.sim_args), links, sched=config.sched),
    ]
    beat = ("--heartbeat",) if config.heartbeat else ()
    for robot in sorted(scenario.robot_ids):
        specs.append(ProcessSpec(
            f"agent-{robot}", "agent",
            ("agent", ref, "--robot", str(robot), *config.agent_args, *beat), links,
            robot=robot, sched=config.sched))
    if config.supervise is not None:
        length = ("--duration", _number(config.duration)) if config.duration is not None else ()
        specs.append(ProcessSpec(
            "coordinator", "coordinator",
            ("supervise", ref, f"--{config.mode}", *config.supervise),
            links,
            tail=(*config.supervise_tail, *length)))
    return tuple(specs)


def by_name(plan: tuple[ProcessSpec, ...]) -> dict[str, ProcessSpec]:
    return {spec.name: spec for spec in plan}
