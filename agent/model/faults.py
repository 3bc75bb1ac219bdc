"""Fault specifications: what ``tlfleet run --fault SPEC`` and a scenario's ``[[faults]]`` mean
(fault-injection notes §5, §6.1).

A fault is one of

* ``cut:TARGET@T+D`` — every link of process TARGET silently dropped at sim time T [s] for D [s]
  of wall time, then restored (namespace hosts: an nft drop of the process's router port, or a
  host's bridge port down);
* ``partition:A,B@T+D`` — only the traffic between A and B dropped;
* ``freeze:TARGET@T+D`` — SIGSTOP of TARGET's process group, SIGCONT D [s] of wall time later;
* ``kill:TARGET@T`` — SIGKILL;
* ``restart:TARGET@T`` — SIGKILL, then the same argv started again.

TARGET is ``robot<N>`` (or ``agent-<N>``: robot N's agent), ``sim``, ``router`` or ``host<i>``
(namespace host i; cuts and partitions only). Parsing is pure and total: anything else is a
:class:`FaultSpecError` that names the part that is wrong (kind, target, time, duration) before
anything starts. :func:`check_fault` then checks a parsed fault against a scenario's robots and
the run's duration.

In a scenario file the same fault is a table, either ``spec = "cut:robot3@20+3"`` or its parts::

    [[faults]]
    kind = "cut"          # cut | partition | freeze | kill | restart
    target = "robot3"     # partition: targets = ["robot3", "robot4"]
    at = 20.0             # [s] sim time
    duration = 3.0        # [s] wall time (cut, partition, freeze)
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

from tlfleet.bus.errors import TlfleetError

KINDS = ("cut", "partition", "freeze", "kill", "restart")
TIMED = frozenset({"cut", "partition", "freeze"})  # these need +D
NETWORK = frozenset({"cut", "partition"})  # these need namespace hosts
MAX_DURATION = 3600.0  # [s] wall: a longer fault is a typo

_ROBOT = re.compile(r"(?:robot|agent-?)(\d+)\Z")
_HOST = re.compile(r"host-?(\d+)\Z")
_NUMBER = re.compile(r"[0-9]+(?:\.[0-9]*)?\Z|\.[0-9]+\Z")


class FaultSpecError(TlfleetError, ValueError):
    """A fault that cannot be scheduled; ``part`` is the part that is wrong."""

    def __init__(self, spec: str, part: str, reason: str):
        self.spec = spec
        self.part = part
        self.reason = reason
        super().__init__(f"fault {spec!r}: {part}: {reason}")


@dataclass(frozen=True)
class Fault:
    """One scheduled fault; ``targets`` are process names (``agent-3``, ``sim``, ``router``)
    or host names (``host-1``)."""

    kind: str
    targets: tuple[str, ...]
    at: float  # [s] sim time
    duration: float | None = None  # [s] wall time (None for kill / restart)
    text: str = ""  # the spec as written (or as rebuilt from a [[faults]] table)

    @property
    def target(self) -> str:
        return self.targets[0]

    @property
    def needs_hosts(self) -> bool:
        """True for faults that only namespace hosts can inject (link cuts, partitions)."""
        return self.kind in NETWORK

    @property
    def spec(self) -> str:
        """The canonical spec text (``cut:agent-3@20+3``)."""
        end = "" if self.duration is None else f"+{self.duration:g}"
        return f"{self.kind}:{','.join(self.targets)}@{self.at:g}{end}"

    def as_dict(self) -> dict[str, object]:
        return {"kind": self.kind, "targets": list(self.targets), "at": self.at,
                "duration": self.duration, "spec": self.text or self.spec}


def parse_kind(spec: str, text: str) -> str:
    if text not in KINDS:
        raise FaultSpecError(spec, "kind", f"{text!r} is not a fault kind: expected one of "
                                           f"{', '.join(KINDS)}")
    return text


def parse_target(spec: str, text: str, kind: str) -> str:
    """``robot3`` / ``agent-3`` → ``agent-3``; ``sim``; ``router``; ``host1`` → ``host-1``."""
    text = text.strip()
    if text in ("sim", "router"):
        return text
    robot = _ROBOT.match(text)
    if robot:
        return f"agent-{int(robot.group(1))}"
    host = _HOST.match(text)
    if host:
        if kind not in NETWORK:
            raise FaultSpecError(spec, "target", f"{text!r}: a host can only be cut or "
                                                 f"partitioned, not {kind}")
        return f"host-{int(host.group(1))}"
    raise FaultSpecError(spec, "target", f"{text!r} is not a target: expected robot<N>, "
                                         "agent-<N>, sim, router or host<i>")


def parse_targets(spec: str, text: str, kind: str) -> tuple[str, ...]:
    parts = [p for p in text.split(",")] if text else []
    if not parts or any(not p.strip() for p in parts):
        raise FaultSpecError(spec, "target", "missing (expected e.g. robot3 before the @)")
    if kind == "partition":
        if len(parts) != 2:
            raise FaultSpecError(spec, "target", f"a partition needs two targets A,B, got "
                                                 f"{len(parts)}")
    elif len(parts) != 1:
        raise FaultSpecError(spec, "target", f"{kind} takes one target, got {len(parts)} "
                                             "(only a partition takes A,B)")
    targets = tuple(parse_target(spec, p, kind) for p in parts)
    if len(set(targets)) != len(targets):
        raise FaultSpecError(spec, "target", f"{targets[0]} cannot be partitioned from itself")
    return targets


def check_time(spec: str, value: float) -> float:
    if not math.isfinite(value) or value < 0:
        raise FaultSpecError(spec, "time", f"{value!r} s: expected a sim time ≥ 0 s")
    return float(value)


def check_duration(spec: str, kind: str, value: float | None) -> float | None:
    if kind not in TIMED:
        if value is not None:
            raise FaultSpecError(spec, "duration", f"{kind} takes no +D (it does not end by "
                                                   "itself)")
        return None
    if value is None:
        raise FaultSpecError(spec, "duration", f"{kind} needs +D, the wall time it lasts [s] "
                                               f"(e.g. {kind}:robot3@20+3)")
    if not math.isfinite(value) or value <= 0:
        raise FaultSpecError(spec, "duration", f"{value!r} s: expected a wall time > 0 s")
    if value > MAX_DURATION:
        raise FaultSpecError(spec, "duration", f"{value:g} s: at most {MAX_DURATION:g} s")
    return float(value)


def _number(spec: str, part: str, text: str, what: str) -> float:
    if not _NUMBER.match(text):
        raise FaultSpecError(spec, part, f"{text!r} is not a number of seconds ({what})")
    return float(text)


def parse_fault(spec: str) -> Fault:
    """``KIND:TARGET@T[+D]`` → :class:`Fault`; :class:`FaultSpecError` naming the bad part."""
    text = spec.strip()
    if ":" not in text:
        raise FaultSpecError(spec, "kind", "missing: expected KIND:TARGET@T[+D], e.g. "
                                           "cut:robot3@20+3")
    kind_text, rest = text.split(":", 1)
    kind = parse_kind(spec, kind_text.strip())
    if "@" not in rest:
        raise FaultSpecError(spec, "time", "missing: expected @T after the target (sim time "
                                           "[s])")
    target_text, when = rest.split("@", 1)
    targets = parse_targets(spec, target_text.strip(), kind)
    at_text, plus, duration_text = when.partition("+")
    at = check_time(spec, _number(spec, "time", at_text.strip(), "the sim time T of @T"))
    duration = None
    if plus:
        duration = _number(spec, "duration", duration_text.strip(), "the wall time D of +D")
    return Fault(kind, targets, at, check_duration(spec, kind, duration), spec)


def check_fault(fault: Fault, robot_ids: Iterable[int], duration: float) -> None:
    """The fault against a run: its robots exist and it starts before the end (``duration``
    [s] sim time)."""
    ids = sorted(robot_ids)
    spec = fault.text or fault.spec
    for target in fault.targets:
        if target.startswith("agent-") and int(target[6:]) not in ids:
            raise FaultSpecError(spec, "target", f"{target}: the scenario has no robot "
                                                 f"{target[6:]} (robots: "
                                                 f"{', '.join(map(str, ids))})")
    if fault.at >= duration:
        raise FaultSpecError(spec, "time", f"@{fault.at:g} s is not before the end of the run "
                                           f"({duration:g} s)")
