"""The faults of one run: the scenario's ``[[faults]]`` and the ``--fault`` specs, checked
before anything starts.

:func:`run_faults` merges both lists and checks each against the run (its robots exist, it starts
before the end of the run: :func:`tlfleet.agent.model.faults.check_fault`), so a bad spec exits 1
before any file or process exists. :func:`need_hosts` says whether a run must go to namespace
hosts (link cuts and partitions: only there does every process have a link of its own that can
be dropped, :mod:`tlfleet.coordinator.launch.netns_hosts`) and, when it cannot, why
(:class:`FaultError`).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterable
from pathlib import Path

from tlfleet.agent.model import Scenario
from tlfleet.agent.model.faults import Fault, check_fault, parse_fault
from tlfleet.agent.scenario import load_scenario
from tlfleet.coordinator.faults.schedule import FaultError

__all__ = ["FaultError", "hosts_for", "need_hosts", "parse_specs", "run_faults"]


def parse_specs(specs: Iterable[str]) -> tuple[Fault, ...]:
    """``--fault`` texts → faults (:class:`~tlfleet.agent.model.faults.FaultSpecError` on the first
    bad one, naming its wrong part)."""
    return tuple(parse_fault(spec) for spec in specs)


def run_faults(scenario: Scenario, extra: Iterable[Fault] = (),
               duration: float | None = None) -> tuple[Fault, ...]:
    """The scenario's faults, then ``extra`` (``--fault``), each checked against the run."""
    faults = (*scenario.faults, *extra)
    total = float(duration or scenario.duration)
    for fault in faults:
        check_fault(fault, scenario.robot_ids, total)
    return faults


def need_hosts(faults: Iterable[Fault]) -> bool:
    """True when some fault drops links: the run must go to namespace hosts.
    :class:`FaultError` naming the fault when this machine cannot provide them."""
    network = [f for f in faults if f.needs_hosts]
    if not network:
        return False
    first = network[0].text or network[0].spec
    if os.geteuid() != 0:
        raise FaultError(f"fault {first}: dropping a link needs network namespaces, and those "
                         "need root (run as root, or use freeze/kill/restart faults, which do "
                         "not)")
    for tool, package in (("ip", "iproute2"), ("nft", "nftables")):
        if shutil.which(tool) is None:
            raise FaultError(f"fault {first}: dropping a link needs `{tool}` (Debian package "
                             f"{package})")
    return True


def hosts_for(scenario_path: Path | Scenario, extra: Iterable[Fault] = (),
              duration: float | None = None) -> int:
    """How many namespace hosts a run with these faults needs: 0 when none drops a link, else
    one more than the highest ``host<i>`` named (at least 1: on one host every process still
    has a router port of its own); with a partition, the peer layout's count (a host per
    process, :func:`tlfleet.coordinator.launch.netns_hosts.place_peers`). Scenario and fault errors,
    and :class:`FaultError` when this machine has no namespaces, come first."""
    scenario = (scenario_path if isinstance(scenario_path, Scenario)
                else load_scenario(scenario_path))  # the caller's, loaded once
    faults = run_faults(scenario, extra, duration)
    if not need_hosts(faults):
        return 0
    if any(f.kind == "partition" for f in faults):
        from tlfleet.coordinator.launch.netns_hosts import place_peers

        return place_peers(scenario).hosts
    hosts = [int(t[5:]) for f in faults for t in f.targets if t.startswith("host-")]
    return max(hosts, default=0) + 1
