"""The OS scheduling flag of the fleet's processes (``tlfleet sim``, ``agent``, ``router``):
``--sched {default,batch,fifo}`` (measured in docs/performance.md).

``batch`` puts the process under Linux's ``SCHED_BATCH`` before it opens its session, so every
thread it starts (zenoh's included) inherits it. A batch task is never preempted by a task that
wakes up; it runs until it blocks or its time slice ends, and takes the same share of the CPU as
before. A lockstep tick is a chain of compute-then-wait — the simulator sends the frame to every
peer, each agent steps and answers, the simulator steps the physics — and preemption on
wake-up only interrupts the process whose output the others wait for: in Scenario 1 the frame's
put took 0.3–0.7 ms instead of 0.03 ms in 19–31 % of the ticks, until the simulator itself was
a batch task. Lowering a process to ``SCHED_BATCH`` needs no privilege.

``fifo`` puts it under ``SCHED_FIFO`` at :data:`FIFO_PRIORITY`, the lowest real-time
priority: it runs as soon as it wakes, before every ordinary process (the coordinator, a
compiler, another user's job), and no task of its own priority preempts it. The fleet's
processes block between their steps (a channel, a timed wait), so none holds a core for long,
and the kernel keeps 5 % of every second for ordinary tasks anyway (``sched_rt_runtime_us``).
Scenario 1 in lockstep: 13.6–14.5× real time against 8.7–9.4× under ``batch`` (5 of 5
interleaved pairs). It needs root, ``CAP_SYS_NICE`` or an ``RLIMIT_RTPRIO`` ≥ 1
(``tlfleet.coordinator.launch.processes.fifo_permitted``); without them the process says so and runs
under
``batch``.

``tlfleet run`` asks for ``fifo`` where it is permitted, in either mode (``RunConfig.sched``):
in realtime a tick's deadline is met when every agent is woken and runs within the period, and
under ``fifo`` Scenario 1's latency p99 was 0.81–0.91 against 1.14–1.56 ms and a 30-robot fleet
missed 0.23–0.40 against 0.54–8.2 % of its deadlines (interleaved pairs; an earlier series
had it worse in 2 of 4 pairs). Where it is not permitted a lockstep run uses ``batch``
and a realtime run ``default`` (batch made the realtime tail worse in 4 of 4 pairs).
Where the OS has no such policy the process says so and runs as it is.
"""

from __future__ import annotations

import argparse
import logging
import os

from tlfleet.bus.lifeline import ORPHAN_AFTER
from tlfleet.cli.arg_types import positive_float
from tlfleet.coordinator.launch.processes import FIFO_PRIORITY

logger = logging.getLogger(__name__)

#: ``--sched`` values
POLICIES = ("default", "batch", "fifo")


def add_process_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("process")
    group.add_argument("--sched", choices=POLICIES, default="default",
                       help="OS scheduling: as started (default), 'batch' (Linux "
                            "SCHED_BATCH: not preempted when another process wakes up) or "
                            "'fifo' (SCHED_FIFO priority 1: runs as soon as it wakes, before "
                            "ordinary processes; needs root or RLIMIT_RTPRIO, else batch); "
                            "`tlfleet run` uses fifo or batch in lockstep, where they are faster")


def add_orphan_argument(parser: argparse.ArgumentParser) -> None:
    """``--orphan-after S`` of the processes a coordinator supervises (the sim, the agents)."""
    parser.add_argument("--orphan-after", type=positive_float, default=ORPHAN_AFTER, metavar="S",
                        help="exit when the coordinator's liveliness token, once seen, has been "
                             f"gone this long [s wall] (default {ORPHAN_AFTER:g}): a run whose "
                             "coordinator died leaves nothing behind")


def apply_scheduling(policy: str) -> str | None:
    """Put this process under ``policy``: every thread it has (Linux sets the policy per thread;
    a library may have started some at import) and, by inheritance, every thread it starts from
    now on. Returns what did not go as asked (and, for a refused ``fifo``, that the process runs
    under ``batch`` instead), or None. ``default`` changes nothing."""
    if policy not in POLICIES:
        raise ValueError(f"scheduling policy {policy!r}: expected one of {', '.join(POLICIES)}")
    if policy == "default":
        return None
    if policy == "fifo":
        problem = _set_policy("SCHED_FIFO", FIFO_PRIORITY)
        if problem is None:
            return None
        fallback = _set_policy("SCHED_BATCH", 0)
        return (f"{problem} (needs root, CAP_SYS_NICE or an RLIMIT_RTPRIO >= {FIFO_PRIORITY}); "
                + ("running under SCHED_BATCH instead" if fallback is None
                   else f"and {fallback}; running with the OS default"))
    problem = _set_policy("SCHED_BATCH", 0)
    return None if problem is None else f"{problem}; running with the OS default"


def _set_policy(name: str, priority: int) -> str | None:
    """``os.<name>`` at ``priority`` on every thread of this process; why not, or None."""
    policy = getattr(os, name, None)
    if policy is None or not hasattr(os, "sched_setscheduler"):
        return f"this OS has no {name}"
    try:
        threads = [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:
        threads = [0]
    for tid in threads:
        try:
            os.sched_setscheduler(tid, policy, os.sched_param(priority))
        except ProcessLookupError:  # a thread that ended meanwhile
            continue
        except OSError as exc:
            return f"sched_setscheduler({name}) failed: {exc}"
    return None


def apply_process_flags(args: argparse.Namespace, source: str) -> None:
    """Apply ``--sched`` before the process opens its session (``source``: who logs it)."""
    problem = apply_scheduling(getattr(args, "sched", "default"))
    if problem is not None:
        logger.warning("%s: --sched %s not applied: %s", source, args.sched, problem)
