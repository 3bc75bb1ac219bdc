"""``tlfleet run --hosts N`` and runs with link faults: a fleet launched on namespace hosts and
supervised there (the hosts and the placement are :mod:`tlfleet.coordinator.launch.netns_hosts`).

:func:`run_on_hosts` is launch + supervise: the routers, the simulator and the agents start in
their namespaces (:class:`tlfleet.coordinator.launch.processes.Launcher`, logs in ``<run>/logs``),
then
``tlfleet supervise`` runs on host 0 (:mod:`tlfleet.coordinator.supervise`, the code of ``tlfleet
run``) and writes the run directory. Everything it started is stopped and every namespace deleted,
also on error and on interruption: when ``stop`` is set (``tlfleet run`` sets it on SIGINT and
SIGTERM), supervise is interrupted (SIGINT: it ends the run as *interrupted* and writes the run
directory up to that point) and everything else is stopped after it. Needs root (``ip netns``);
nft only for process cuts.

Secured by default: every link is ``tls/`` with mutual authentication and every
router enforces the fleet's access-control policy. Without ``keys``, a fresh key directory for
this run (a CA, one certificate per process, the routers' names being the hosts' addresses, the
mesh policy of :func:`tlfleet.coordinator.security.policy.fleet_grants`) is written to a private
temporary directory and deleted with the namespaces; ``run.json`` records the fingerprints.
``insecure`` keeps plain TCP.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from tlfleet.agent.model import Scenario
from tlfleet.agent.model.faults import Fault
from tlfleet.bus.lifeline import child_environment as tie_to_this_process
from tlfleet.coordinator.launch.netns_hosts import (
    PEER_PORT,
    RECONNECT,
    ROUTER_PORT,
    HostsError,
    NetnsHosts,
    Placement,
    certificate_name,
    place,
    place_peers,
    require_root,
    wait_listening,
)
from tlfleet.coordinator.launch.plan import PlanConfig, ProcessSpec, by_name, plan_fleet
from tlfleet.coordinator.launch.processes import Launcher, tlfleet_command
from tlfleet.coordinator.record.rundir import CLAIMED_ENV, claim_run_dir, default_run_dir
from tlfleet.coordinator.supervise import load_checked

#: [s] wall an interrupted ``tlfleet supervise`` gets to stop the fleet and write the run
#: directory (its clean-up steps are bounded: tlfleet.coordinator.launch.cleanup) before it is
#: killed
SUPERVISE_GRACE = 30.0


def supervise_until_done(argv: Sequence[str], capture: bool, stop: threading.Event | None,
                         grace: float = SUPERVISE_GRACE, poll: float = 0.2,
                         run_dir: Path | None = None) -> subprocess.CompletedProcess:
    """Run ``tlfleet supervise`` (``argv``) to its end. When ``stop`` is set, interrupt it once
    with SIGINT, as Ctrl-C would (it ends the mission, records the verdict *interrupted* and
    writes its files), and kill it if it is still running ``grace`` [s] later. It runs in a
    session of its own, so a terminal's Ctrl-C reaches it only through this (once)."""
    pipe = subprocess.PIPE if capture else None
    env = tie_to_this_process(dict(os.environ))
    if run_dir is not None:  # claimed by this launcher, which wrote logs/ into it first
        env[CLAIMED_ENV] = str(Path(run_dir).resolve())
    process = subprocess.Popen(list(argv), stdout=pipe, stderr=pipe, text=True,
                               start_new_session=True, env=env)
    interrupted_at: float | None = None
    out = err = None
    try:
        while True:
            try:
                out, err = process.communicate(timeout=poll)  # retried: no output is lost
                break
            except subprocess.TimeoutExpired:
                pass
            if stop is not None and stop.is_set() and interrupted_at is None:
                process.send_signal(signal.SIGINT)
                interrupted_at = time.monotonic()
            elif interrupted_at is not None and time.monotonic() - interrupted_at > grace:
                process.kill()
    finally:
        if process.poll() is None:  # an exception here (not a stop): nothing may outlive us
            process.kill()
            process.wait()
    return subprocess.CompletedProcess(list(argv), process.returncode, out, err)


@dataclass
class HostsRun:
    run_dir: Path
    returncode: int  # tlfleet supervise's exit code
    placement: Placement
    exit_codes: dict[str, int | None]
    stdout: str = ""
    stderr: str = ""
    keys: Path | None = None  # the key directory made for the run (deleted at its end)


def run_on_hosts(scenario_path: Path, hosts: int, *, out: Path | None = None,
                 mode: str = "lockstep", supervise_args: Sequence[str] = (),
                 sim_args: Sequence[str] = (), agent_args: Sequence[str] = (),
                 capture: bool = False,
                 router_timeout: float = 15.0, kill_grace: float = 3.0,
                 prefix: str | None = None, secure: Path | None = None,
                 insecure: bool = False, lease_ms: int | None = None,
                 faults: Sequence[Fault] = (),
                 stop: threading.Event | None = None,
                 scenario: Scenario | None = None) -> HostsRun:
    """``tlfleet run SCENARIO --hosts N`` (see the module docstring). With ``faults``
    the supervisor on host 0 injects them from a fault plan
    (:mod:`tlfleet.coordinator.faults.on_hosts`) and every client reconnects fast (``RECONNECT``);
    ``lease_ms`` goes to every process. A partition fault puts the fleet in the peer layout
    (:func:`place_peers`; ``hosts`` is then the layout's own count). ``scenario``: the file of
    ``scenario_path`` as the caller already loaded and checked it
    (:func:`~tlfleet.coordinator.supervise.load_checked`; ``tlfleet run`` reads it once)."""
    require_root()
    if secure is not None and insecure:
        raise HostsError("--secure DIR and --insecure exclude each other")
    if scenario is None:  # ScenarioError, launch and key problems before anything starts
        scenario = load_checked(scenario_path, secure)
    all_faults, placement = _fault_placement(scenario, hosts, faults, secure)
    hosts = placement.hosts
    injecting = bool(all_faults)
    peers = bool(placement.peers)
    run_dir = Path(out) if out else default_run_dir(scenario.name)
    net = NetnsHosts(hosts, **({"prefix": prefix} if prefix else {}))
    launcher = Launcher(run_dir / "logs")
    done: subprocess.CompletedProcess | None = None
    codes: dict[str, int | None] = {}
    lock = claim_run_dir(run_dir)  # never overwrite a run; its supervise inherits the claim
    router_conf, client_conf = _zenoh_configs(run_dir, injecting, peers)
    links = _Links(net, placement, "tcp" if insecure else "tls")
    own_keys = None if insecure or secure is not None else Path(
        tempfile.mkdtemp(prefix="tlfleet-keys-"))  # 0700: private to this user
    with net:
        try:
            if own_keys is not None:
                _write_own_keys(scenario, own_keys, links)
            keydir = own_keys or secure
            # with faults, agents that read only every d-th frame watch the sim's clock key
            # too, so they notice a lost simulator within --stale-after like the others
            fleet = by_name(plan_fleet(scenario, PlanConfig(
                scenario_ref=str(Path(scenario_path).resolve()), mode=mode,
                sim_args=tuple(sim_args), agent_args=tuple(agent_args), heartbeat=injecting,
                secure=None if keydir is None else Path(keydir).resolve(), lease_ms=lease_ms,
                zenoh_config=client_conf, supervise=("--out", str(run_dir)))))
            _start_routers(links, launcher, fleet.pop("router"), router_conf, router_timeout)
            coordinator = fleet.pop("coordinator")
            for name, spec in fleet.items():  # the sim, then the agents (ids ascending)
                launcher.start(name, [*net.exec_prefix(placement.host_of[name]),
                                      *tlfleet_command(*links.placed(spec).argv())])
            plan = _fault_plan_args(run_dir, links, launcher, faults) if injecting else []
            coordinator = replace(coordinator.placed(connect=(links.endpoint_of("coordinator"),)),
                                  tail=(*plan, *supervise_args))
            done = supervise_until_done([*net.exec_prefix(0),
                                         *tlfleet_command(*coordinator.argv())], capture, stop,
                                        run_dir=run_dir)
            launcher.wait_all(5.0)  # sim and agents exit by themselves after Control(stop)
        finally:
            if injecting:  # what `restart:` started again, as a child of supervise
                from tlfleet.coordinator.faults.on_hosts import stop_restarted

                stop_restarted(run_dir / "logs", kill_grace)
            codes = launcher.stop_all(kill_grace)
            if own_keys is not None:
                shutil.rmtree(own_keys, ignore_errors=True)
    try:
        _record_hosts(run_dir, links, codes, own_keys is not None)
    finally:
        lock.release()
    assert done is not None
    return HostsRun(run_dir, done.returncode, placement, codes,
                    done.stdout or "", done.stderr or "", own_keys)


def _fault_placement(scenario: Scenario, hosts: int, faults: Sequence[Fault],
                     secure: Path | None) -> tuple[tuple[Fault, ...], Placement]:
    """The run's faults (the scenario's and ``faults``) and the processes' placement on the
    hosts: ``FaultSpecError`` / ``FaultError`` / ``HostsError`` before anything starts."""
    all_faults: tuple[Fault, ...] = ()
    if scenario.faults or faults:
        from tlfleet.coordinator.faults.plan import run_faults

        all_faults = run_faults(scenario, faults)
    peers = any(f.kind == "partition" for f in all_faults)
    if peers and secure is not None:
        raise HostsError("a partition run makes its own keys (its peers' certificates carry "
                         "their hosts' addresses): leave out --secure DIR, or use --insecure")
    placement = place_peers(scenario) if peers else place(scenario, hosts)
    if all_faults:
        from tlfleet.coordinator.faults.on_hosts import check_hosts_fault

        for fault in all_faults:
            check_hosts_fault(fault, placement)
    return all_faults, placement


def _write_own_keys(scenario: Scenario, keys: Path, links: _Links) -> None:
    """A key directory for this run: the routers' certificates name their hosts' addresses,
    a peer's its own host's (the mesh policy of
    :func:`tlfleet.coordinator.security.policy.fleet_grants`)."""
    from tlfleet.coordinator.security.authority import write_keys  # cryptography: secured only

    net, placement = links.net, links.placement
    write_keys(scenario, keys, force=True, mesh=True,
               hosts=tuple(net.address(h) for h in range(net.count)),
               addresses={certificate_name(p): [net.address(placement.host_of[p])]
                          for p in placement.peers})


def _zenoh_configs(run_dir: Path, injecting: bool, peers: bool) -> tuple[Path, Path | None]:
    """The routers' zenoh config and, with faults, the clients' (``<run>/logs``)."""
    router_conf = run_dir / "logs" / "router.json5"
    router_conf.parent.mkdir(parents=True, exist_ok=True)
    # explicit router mesh only: no gossip, so no router links another over a process's port
    # peer layout: the router must not broker between two peers that lost their direct link
    # (zenoh's peers_failover_brokering), or a partition would not separate them
    router_conf.write_text("{ scouting: { gossip: { enabled: false } }"
                           + (f", {RECONNECT}" if injecting else "")
                           + (", routing: { router: { peers_failover_brokering: false } }"
                              if peers else "") + " }\n")
    client_conf = None
    if injecting:  # a cut client comes back within a retry period of the restore
        client_conf = run_dir / "logs" / "client.json5"
        client_conf.write_text(f"{{ {RECONNECT} }}\n")
    return router_conf, client_conf


@dataclass(frozen=True)
class _Links:
    """Where each process of a placement links: its host's router port, and in the peer layout
    the peer mesh too."""

    net: NetnsHosts
    placement: Placement
    scheme: str  # tcp | tls

    def endpoint_of(self, process: str) -> str:
        host, port = self.placement.link(process)
        return f"{self.scheme}/{self.net.address(host)}:{port}"

    def placed(self, spec: ProcessSpec) -> ProcessSpec:
        """Linked to its router port; in the peer layout also a peer listening on its own host
        and connected to every fleet peer before it (the mesh)."""
        name, peers = spec.name, self.placement.peers
        connect = [self.endpoint_of(name)]
        if name not in peers:
            return spec.placed(connect=tuple(connect))
        connect += [f"{self.scheme}/{self.net.address(self.placement.host_of[other])}:{PEER_PORT}"
                    for other in peers[:peers.index(name)]]
        return spec.placed(connect=tuple(connect), mode="peer", listen=(
            f"{self.scheme}/{self.net.address(self.placement.host_of[name])}:{PEER_PORT}",))


def _start_routers(links: _Links, launcher: Launcher, router: ProcessSpec, router_conf: Path,
                   timeout: float) -> None:
    """One router on every host that holds a router port, meshed with the hosts before it; wait
    until each listens."""
    net, placement, scheme = links.net, links.placement, links.scheme
    router_hosts = sorted({placement.router_host(p) for p in placement.host_of})
    for host in router_hosts:
        listen = [f"{scheme}/{net.address(host)}:{ROUTER_PORT}"] + [
            f"{scheme}/{net.address(host)}:{placement.port_of[p]}"
            for p in placement.host_of if placement.router_host(p) == host]
        spec = router.placed(listen=tuple(listen), zenoh_config=router_conf, connect=tuple(
            f"{scheme}/{net.address(other)}:{ROUTER_PORT}" for other in range(host)))
        launcher.start(f"router-{host}", [*net.exec_prefix(host),
                                          *tlfleet_command(*spec.argv())])
    for host in router_hosts:
        wait_listening(net, host, ROUTER_PORT, timeout)


def _fault_plan_args(run_dir: Path, links: _Links, launcher: Launcher,
                     faults: Sequence[Fault]) -> list[str]:
    """``tlfleet supervise``'s fault arguments: the plan file (every process's host, pid and
    command line) and the ``--fault`` specs given on the command line."""
    from tlfleet.coordinator.faults.on_hosts import PLAN_NAME, write_plan

    pids = {c.name: c.pid for c in launcher.children}
    argv = {c.name: c.argv for c in launcher.children}
    plan = ["--fault-plan", str(write_plan(run_dir / "logs" / PLAN_NAME, links.net,
                                           links.placement, pids, argv))]
    for fault in faults:
        plan += ["--fault", fault.text or fault.spec]
    return plan


def _record_hosts(run_dir: Path, links: _Links, codes: dict[str, int | None],
                  own_keys: bool) -> None:
    """``run.json`` (written by supervise) gains the placement, the hosts' exit codes and
    addresses, and what became of keys made for the run."""
    info_path = run_dir / "run.json"
    if not info_path.is_file():
        return
    net = links.net
    info = json.loads(info_path.read_text())
    if own_keys:
        info["keys"] = "generated for this run in a private temporary directory, deleted"
    info.update(hosts=links.placement.as_dict(), host_exit_codes=codes,
                addresses={net.name(h): net.address(h) for h in range(net.count)})
    info_path.write_text(json.dumps(info, indent=2, default=str) + "\n")
