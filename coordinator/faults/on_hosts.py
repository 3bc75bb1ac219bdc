"""Faults on namespace hosts: link cuts (fault-injection notes §5.3, §5.5).

``tlfleet run --fault cut:…`` goes to namespace hosts
(:func:`tlfleet.coordinator.run_hosts.run_on_hosts`), where every process reaches the fleet through
a router port of its own. The launcher writes a **fault plan** (``logs/fault-plan.json``: the
namespaces' prefix, count and subnet, the placement and the children's pids) and ``tlfleet
supervise`` — on host 0, as root — injects the faults with a :class:`HostsActuator` built from it:

* ``cut:agent-3`` / ``cut:sim`` — an nft table in the process's host drops its router port both
  ways (a silent partition, :meth:`tlfleet.coordinator.launch.netns_hosts.NetnsHosts.cut_process`);
  ``cut:host1`` — host 1's bridge port down (carrier loss), every process on it cut;
* while a process is cut (and for ``CUT_GRACE`` seconds after the restore, but not after the
  mission's end), the loss of its liveliness token is a ``link_lost`` of the supervisor, not a
  death, and its return a ``link_restored``
  (:class:`tlfleet.coordinator.live.supervisor.Supervisor`);
* ``partition:A,B`` — only in the peer layout
  (:func:`tlfleet.coordinator.launch.netns_hosts.place_peers`, which
  :func:`tlfleet.coordinator.run_hosts.run_on_hosts` chooses for a run with a partition): an nft
  bridge rule drops what the bridge forwards between A's and B's hosts, so their direct peer link is
  gone while both keep their links to the router and to every other peer (a router does not relay
  between peers); in the router layout the hosts' routers form a mesh and would route around a
  dropped pair (§5.5). In the peer layout a cut is always the host's carrier loss;
* ``freeze:`` and ``kill:`` signal the child's process group by the pid in the plan (the same
  pid namespace); ``restart:`` (agents only) kills the group, waits until it is gone and starts
  the plan's argv for it again (its own ``ip netns exec`` prefix included, its log appended),
  as a child of ``tlfleet supervise``; the new pid goes to ``logs/restarted.json``, so the
  launcher stops it with the others (:func:`stop_restarted`), and the agent gets
  ``Control(start)`` again once its token is back.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import time
from pathlib import Path
from typing import Any

from tlfleet.agent.model.faults import Fault
from tlfleet.coordinator.faults.schedule import (
    FaultError,
    StartAgain,
    check_restartable,
    kill_group,
)
from tlfleet.coordinator.launch.netns_hosts import NetnsHosts, Placement
from tlfleet.coordinator.launch.processes import Launcher, group_alive

PLAN_NAME = "fault-plan.json"
RESTARTED_NAME = "restarted.json"  # {process: pid} of the processes the actuator started again
CUT_GRACE = 1.0  # [s] wall after a restore during which a lost token is still a link loss
#                  (a lease that expires just as the link comes back); not after sim_done


def write_plan(path: Path, net: NetnsHosts, placement: Placement, pids: dict[str, int],
               argv: dict[str, list[str]] | None = None) -> Path:
    """The fault plan: namespaces, placement, the children's pids and (for ``restart:``) their
    argv; the log directory is the plan's own."""
    path.write_text(json.dumps({"prefix": net.prefix, "count": net.count, "subnet": net.subnet,
                                "placement": placement.as_dict(), "pids": pids,
                                "argv": argv or {}}, indent=2))
    return path


def stop_restarted(log_dir: Path, grace: float) -> dict[str, int | None]:
    """Stop what the actuator started again (``logs/restarted.json``): SIGTERM, then SIGKILL
    after ``grace`` [s]; returns {process: pid} of what was still running."""
    path = Path(log_dir) / RESTARTED_NAME
    if not path.is_file():
        return {}
    try:
        restarted = {str(k): int(v) for k, v in json.loads(path.read_text()).items()}
    except (ValueError, AttributeError, TypeError):
        return {}
    running = {name: pid for name, pid in restarted.items() if group_alive(pid)}
    for pid in running.values():
        with contextlib.suppress(ProcessLookupError):
            os.killpg(pid, signal.SIGTERM)
    deadline = time.monotonic() + grace
    while any(group_alive(pid) for pid in running.values()) and time.monotonic() < deadline:
        time.sleep(0.02)
    for pid in running.values():
        with contextlib.suppress(ProcessLookupError):
            os.killpg(pid, signal.SIGKILL)
    return dict(running)


def check_hosts_fault(fault: Fault, placement: Placement | None = None) -> None:
    """Reject, before the run, what namespace hosts cannot do (see the module docstring)."""
    spec = fault.text or fault.spec
    check_restartable(fault)
    if fault.kind == "partition" and placement is not None and placement.layout != "peers":
        raise FaultError(f"fault {spec}: a partition needs the peer layout (every process a peer "
                         "on a host of its own, which `tlfleet run` chooses for a run with a "
                         "partition): with a router per host the routers route around a dropped "
                         "pair")
    if "router" in fault.targets:
        raise FaultError(f"fault {spec}: on namespace hosts every host has its router; cut the "
                         "host (host<i>) instead")
    if placement is None:
        return
    for target in fault.targets:
        if target.startswith("host-"):
            host = int(target[5:])
            if host >= placement.hosts:
                raise FaultError(f"fault {spec}: there is no {target} (hosts 0 to "
                                 f"{placement.hosts - 1})")
        elif target not in placement.host_of:
            raise FaultError(f"fault {spec}: no process {target} in this fleet")


class HostsActuator:
    """Injects faults into a fleet on namespace hosts (see the module docstring)."""

    def __init__(self, plan: dict[str, Any], supervisor: Any = None):
        self.placement = Placement.from_dict(plan["placement"])
        self.net = NetnsHosts(int(plan["count"]), prefix=str(plan["prefix"]),
                              subnet=int(plan["subnet"]))  # created empty: never deleted here
        self.pids: dict[str, int] = {k: int(v) for k, v in plan["pids"].items()}
        self.argv: dict[str, list[str]] = {k: list(v) for k, v in plan.get("argv", {}).items()}
        self.log_dir = Path(plan["log_dir"]) if plan.get("log_dir") else None
        self.supervisor = supervisor
        self.start_again = StartAgain(supervisor)
        self.kill_wait = 5.0  # [s] wall, for a killed group to be gone
        self._launcher: Launcher | None = None  # started on the first restart

    @classmethod
    def from_file(cls, path: Path, supervisor: Any = None) -> HostsActuator:
        return cls({"log_dir": str(Path(path).parent), **json.loads(Path(path).read_text())},
                   supervisor)

    def check(self, fault: Fault) -> None:
        check_hosts_fault(fault, self.placement)
        spec = fault.text or fault.spec
        if fault.kind in ("freeze", "kill", "restart") and fault.target not in self.pids:
            raise FaultError(f"fault {spec}: no pid of {fault.target} in the fault plan")
        if fault.kind == "restart" and (fault.target not in self.argv or self.log_dir is None):
            raise FaultError(f"fault {spec}: no command line of {fault.target} in the fault "
                             "plan")

    def poll(self) -> None:
        self.start_again.poll()

    def _cut_names(self, target: str) -> list[str]:
        if target.startswith("host-"):
            return [p for p in self.placement.on(int(target[5:])) if p != "coordinator"]
        return [target]

    def _mark(self, target: str, until: float) -> None:
        if self.supervisor is not None:
            for name in self._cut_names(target):
                self.supervisor.cut[name] = until

    def _host(self, target: str) -> int:
        """The host of a cut (``host-<i>``, or in the peer layout the process's own host)."""
        if target.startswith("host-"):
            return int(target[5:])
        return self.placement.host_of[target]

    def _host_cut(self, target: str) -> bool:
        return target.startswith("host-") or self.placement.layout == "peers"

    def start(self, fault: Fault) -> dict[str, Any]:
        target = fault.target
        if fault.kind == "partition":
            a, b = (self._host(t) for t in fault.targets)
            self.net.partition(a, b)
            return {"how": f"bridge drops between p{a} and p{b} (nft)"}
        if fault.kind == "cut":
            self._mark(target, math.inf)
            if self._host_cut(target):
                host = self._host(target)
                self.net.cut_host(host)
                return {"how": f"bridge port p{host} down", "processes":
                        self._cut_names(f"host-{host}")}
            host, port = self.placement.link(target)
            self.net.cut_process(self.placement, target)
            return {"how": f"nft drop of port {port} in {self.net.name(host)}"}
        pid = self.pids[target]
        if fault.kind == "restart":
            return self._restart(target, fault)
        if fault.kind == "freeze":  # a frozen process misses its keep-alives: a link loss
            self._mark(target, math.inf)
        os.killpg(pid, signal.SIGSTOP if fault.kind == "freeze" else signal.SIGKILL)
        if fault.kind == "kill":
            self._killed(target, fault)
        return {"pid": pid}

    def _killed(self, name: str, fault: Fault) -> None:
        """The supervisor learns the death from us: it follows this process by the plan's pid,
        which a restart replaces before the old token's loss is seen."""
        if self.supervisor is not None and hasattr(self.supervisor, "process_killed"):
            self.supervisor.process_killed(name, f"killed by fault {fault.text or fault.spec}")

    def _restart(self, name: str, fault: Fault) -> dict[str, Any]:
        pid = self.pids[name]
        kill_group(pid, self.kill_wait)
        self._killed(name, fault)
        assert self.log_dir is not None  # check() made sure
        if self._launcher is None:
            self._launcher = Launcher(self.log_dir)
        child = self._launcher.start(name, self.argv[name])
        self.pids[name] = child.pid
        restarted = self.log_dir / RESTARTED_NAME
        known = json.loads(restarted.read_text()) if restarted.is_file() else {}
        restarted.write_text(json.dumps({**known, name: child.pid}) + "\n")
        self.start_again.add(name)
        return {"pid": pid, "new_pid": child.pid}

    def end(self, fault: Fault) -> dict[str, Any]:
        target = fault.target
        if fault.kind == "partition":
            self.net.heal(*(self._host(t) for t in fault.targets))
        elif fault.kind == "cut":
            if self._host_cut(target):
                self.net.restore_host(self._host(target))
            else:
                self.net.restore_process(self.placement, target)
            self._mark(target, time.monotonic() + CUT_GRACE)
        elif fault.kind == "freeze":
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.pids[target], signal.SIGCONT)
            self._mark(target, time.monotonic() + CUT_GRACE)
        return {}
