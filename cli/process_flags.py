"""The OS scheduling flag of the fleet's processes (``tlfleet sim``, ``agent``, ``router``):
``--sched {default,batch}`` (issue 17, docs/performance.md round 9).

``batch`` puts the process under Linux's ``SCHED_BATCH`` before it opens its session, so every
thread it starts (zenoh's included) inherits it. A batch task is never preempted by a task that
wakes up; it runs until it blocks or its time slice ends, and takes the same share of the CPU as
before. A lockstep tick is a chain of compute-then-wait — the simulator sends the frame to every
peer, each agent steps and answers, the simulator steps the physics — and preemption on
wake-up only interrupts the process whose output the others wait for: in Scenario 1 the frame's
put took 0.3–0.7 ms instead of 0.03 ms in 19–31 % of the ticks, until the simulator itself was
a batch task. ``tlfleet run`` asks for it in lockstep (``RunConfig.sched``). In realtime it made
the latency tail worse (4 of 4 interleaved pairs), so a realtime run keeps ``default``.
Lowering a process to ``SCHED_BATCH`` needs no privilege; where the OS has no such policy the
process says so and runs as it is.
"""

from __future__ import annotations

import argparse
import logging
import os

logger = logging.getLogger(__name__)

#: ``--sched`` values
POLICIES = ("default", "batch")


def add_process_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("process")
    group.add_argument("--sched", choices=POLICIES, default="default",
                       help="OS scheduling: as started (default), or 'batch' (Linux "
                            "SCHED_BATCH: not preempted when another process wakes up; "
                            "`tlfleet run` uses it in lockstep, where it is faster)")


def apply_scheduling(policy: str) -> str | None:
    """Put this process under ``policy``: every thread it has (Linux sets the policy per thread;
    a library may have started some at import) and, by inheritance, every thread it starts from
    now on. Returns why it could not, or None. ``default`` changes nothing."""
    if policy not in POLICIES:
        raise ValueError(f"scheduling policy {policy!r}: expected one of {', '.join(POLICIES)}")
    if policy == "default":
        return None
    batch = getattr(os, "SCHED_BATCH", None)
    if batch is None or not hasattr(os, "sched_setscheduler"):
        return "this OS has no SCHED_BATCH"
    try:
        threads = [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:
        threads = [0]
    for tid in threads:
        try:
            os.sched_setscheduler(tid, batch, os.sched_param(0))
        except ProcessLookupError:  # a thread that ended meanwhile
            continue
        except OSError as exc:
            return f"sched_setscheduler(SCHED_BATCH) failed: {exc}"
    return None


def apply_process_flags(args: argparse.Namespace, source: str) -> None:
    """Apply ``--sched`` before the process opens its session (``source``: who logs it)."""
    problem = apply_scheduling(getattr(args, "sched", "default"))
    if problem is not None:
        logger.warning("%s: --sched %s not applied: %s; running with the OS default", source,
                       args.sched, problem)
