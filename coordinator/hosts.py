"""Fleets across hosts, with network namespaces as stand-in hosts (issue 12 §3).

``tlfleet run SCENARIO --hosts N`` places the fleet on N **hosts**, each with its own zenoh router;
the routers connect to each other and every process connects to its own host's router — the
scale-out path when one machine's cores are not enough. Here the hosts are network namespaces
that tlfleet creates (fault-injection notes §5.1), joined by a bridge that lives in a namespace
of its own; nothing is attached to the root namespace, so nothing can leave the machine:

* ``<prefix>-br`` holds bridge ``br0``; ``<prefix>-h<i>`` has ``veth0`` with
  ``10.251.<k>.<11+i>/24`` whose peer ``p<i>`` is a port of ``br0`` (``k`` from the prefix, so
  two fleets do not collide);
* placement (:func:`place`): the simulator and the coordinator on host 0, robot number ``j``
  (ids ascending, ``j = 0, 1, …``) on host ``j mod N``;
* router ``i`` listens on ``ROUTER_PORT`` (routers and anyone) **and on one port of its own per
  process placed on it**; it connects to the routers ``0 … i-1`` (explicit endpoints: the links
  come back after a cut, fault-injection notes §5.5).

**Peer layout** (``layout="peers"``, chosen by :func:`run_on_hosts` when a fault partitions two
processes, issue 13 §1): one router only, on host 0 with the coordinator; the simulator on host 1
and robot number ``j`` on host ``2 + j``, each a zenoh **peer** listening on ``PEER_PORT`` of its
own host, connected to its port on router 0 and, explicitly, to every fleet peer before it (a full
mesh; gossip off). A router does not relay between peers (fault-injection notes §5.5, and checked
again on zenoh 1.10: a router's client gets every peer's data, a peer gets another peer's only
over their direct link), so dropping the bridge traffic between two hosts
(:meth:`NetnsHosts.partition`) separates exactly those two processes while both keep their links
to the router and to everyone else; the explicit connect brings their link back after the heal.
A cut in this layout is the process's host's carrier loss (all of its links).

Because every process reaches the fleet through its own port, one process's link can be cut and
restored on command (:meth:`NetnsHosts.cut_process` / :meth:`NetnsHosts.restore_process`: an nft
table in the host's namespace that drops that port, a silent partition) and so can a whole host's
(:meth:`NetnsHosts.cut_host`: its bridge port down, carrier loss). The fault-injection issue builds
on these.

:func:`run_on_hosts` is launch + supervise: the routers, the simulator and the agents start in
their namespaces (:class:`coordinator.launcher.Launcher`, logs in ``<run>/logs``), then
``tlfleet supervise`` runs on host 0 (:mod:`coordinator.supervise`, the code of ``tlfleet run``)
and writes the run directory. Everything it started is stopped and every namespace deleted, also
on error. Needs root (``ip netns``); nft only for process cuts.

Secured by default (issue 14): every link is ``tls/`` with mutual authentication and every
router enforces the fleet's access-control policy. Without ``keys``, a fresh key directory for
this run (a CA, one certificate per process, the routers' names being the hosts' addresses, the
mesh policy of :func:`coordinator.acl.fleet_grants`) is written to a private temporary directory
and deleted with the namespaces; ``run.json`` records the fingerprints. ``insecure`` keeps plain
TCP.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from agent.errors import TlfleetError
from agent.scenario import Scenario, load_scenario
from agent.scenario.faults import Fault
from coordinator.launcher import Launcher, tlfleet_command
from coordinator.rundir import default_run_dir

logger = logging.getLogger(__name__)

ROUTER_PORT = 7447
# zenoh's connect retry (default 1 s doubling to 4 s) shortened for fault runs: a client whose
# link was cut is back within about 0.25 s of the restore (fault-injection notes §5.3)
RECONNECT = ("connect: { retry: { period_init_ms: 250, period_max_ms: 250, "
             "period_increase_factor: 1.0 } }")
PROCESS_PORT0 = 7500  # process k of a host gets PROCESS_PORT0 + k on its host's router
PEER_PORT = 7700  # peer layout: where every fleet peer listens on its own host
LAYOUTS = ("routers", "peers")


class HostsError(TlfleetError, RuntimeError):
    """Namespace hosts that cannot be set up (not root, ``ip`` missing, a command failing)."""


def _ip(*args: str) -> None:
    done = subprocess.run(["ip", *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise HostsError(f"`ip {' '.join(args)}` failed: {done.stderr.strip()}")


def require_root() -> None:
    """``HostsError`` saying why namespace hosts cannot work here."""
    if os.geteuid() != 0:
        raise HostsError("--hosts needs root: the hosts are network namespaces (ip netns)")
    if shutil.which("ip") is None:
        raise HostsError("--hosts needs the `ip` command (Debian package iproute2)")


@dataclass
class NetnsHosts:
    """``count`` namespace hosts on one bridge; a context manager (``up`` … ``down``)."""

    count: int
    prefix: str = field(default_factory=lambda: f"tlf{os.getpid() % 100000}")
    subnet: int = -1  # third octet of 10.251.X.0/24 (default: from the prefix)
    created: list[str] = field(default_factory=list)
    cuts: set[str] = field(default_factory=set)  # nft tables of process cuts, "<ns>/<table>"

    def __post_init__(self) -> None:
        if self.count < 1:
            raise HostsError(f"hosts = {self.count}: need at least 1")
        if self.count > 200:
            raise HostsError(f"hosts = {self.count}: at most 200 fit in one /24")
        if self.subnet < 0:
            self.subnet = sum(map(ord, self.prefix)) % 250

    # ------------------------------------------------------------ naming

    def name(self, host: int) -> str:
        return f"{self.prefix}-h{host}"

    @property
    def bridge(self) -> str:
        return f"{self.prefix}-br"

    def address(self, host: int) -> str:
        return f"10.251.{self.subnet}.{11 + host}"

    def exec_prefix(self, host: int) -> list[str]:
        """argv prefix running a command on ``host`` (``ip netns exec`` execs: same pid)."""
        return ["ip", "netns", "exec", self.name(host)]

    # ------------------------------------------------------------ lifetime

    def up(self) -> NetnsHosts:
        require_root()
        try:
            _ip("netns", "add", self.bridge)
            self.created.append(self.bridge)
            _ip("-n", self.bridge, "link", "set", "lo", "up")
            _ip("-n", self.bridge, "link", "add", "br0", "type", "bridge")
            _ip("-n", self.bridge, "link", "set", "br0", "up")
            for host in range(self.count):
                ns = self.name(host)
                _ip("netns", "add", ns)
                self.created.append(ns)
                _ip("link", "add", "veth0", "netns", ns, "type", "veth", "peer", "name",
                    f"p{host}", "netns", self.bridge)
                _ip("-n", self.bridge, "link", "set", f"p{host}", "master", "br0")
                _ip("-n", self.bridge, "link", "set", f"p{host}", "up")
                _ip("-n", ns, "link", "set", "lo", "up")
                _ip("-n", ns, "addr", "add", f"{self.address(host)}/24", "dev", "veth0")
                _ip("-n", ns, "link", "set", "veth0", "up")
        except BaseException:
            self.down()
            raise
        return self

    def down(self) -> None:
        """Delete every namespace this object created (their veths go with them)."""
        for ns in reversed(self.created):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
        self.created.clear()
        self.cuts.clear()

    def __enter__(self) -> NetnsHosts:
        return self.up()

    def __exit__(self, *exc: object) -> None:
        self.down()

    # ------------------------------------------------------------ link faults

    def cut_host(self, host: int) -> None:
        """Carrier loss of ``host``'s link to the bridge (every process on it is cut off)."""
        _ip("-n", self.bridge, "link", "set", f"p{host}", "down")

    def restore_host(self, host: int) -> None:
        _ip("-n", self.bridge, "link", "set", f"p{host}", "up")

    def cut_port(self, host: int, port: int) -> None:
        """Silently drop TCP port ``port`` in ``host``'s namespace, both ways (nft)."""
        table = f"tlfleet_cut_{port}"
        rules = (f"add table inet {table}; "
                 f"add chain inet {table} in {{ type filter hook input priority 0; }}; "
                 f"add chain inet {table} out {{ type filter hook output priority 0; }}; "
                 f"add rule inet {table} in tcp dport {port} drop; "
                 f"add rule inet {table} in tcp sport {port} drop; "
                 f"add rule inet {table} out tcp dport {port} drop; "
                 f"add rule inet {table} out tcp sport {port} drop")
        self._nft(host, rules)
        self.cuts.add(f"{self.name(host)}/{table}")

    def restore_port(self, host: int, port: int) -> None:
        table = f"tlfleet_cut_{port}"
        self._nft(host, f"delete table inet {table}")
        self.cuts.discard(f"{self.name(host)}/{table}")

    def cut_process(self, placement: Placement, process: str) -> None:
        """Cut the link of one process (``sim``, ``agent-3``…) to its host's router."""
        host, port = placement.link(process)
        self.cut_port(host, port)

    def restore_process(self, placement: Placement, process: str) -> None:
        host, port = placement.link(process)
        self.restore_port(host, port)

    def partition(self, a: int, b: int) -> None:
        """Drop every frame the bridge would forward between hosts ``a`` and ``b`` (both ways;
        an nft bridge-family table in the bridge's namespace, fault-injection notes §5.5); both
        keep their links to every other host."""
        table = self._pair_table(a, b)
        rules = (f"add table bridge {table}; "
                 f"add chain bridge {table} filt {{ type filter hook forward priority 0; }}; "
                 f"add rule bridge {table} filt iifname \"p{a}\" oifname \"p{b}\" drop; "
                 f"add rule bridge {table} filt iifname \"p{b}\" oifname \"p{a}\" drop")
        self._nft_in(self.bridge, rules)
        self.cuts.add(f"{self.bridge}/{table}")

    def heal(self, a: int, b: int) -> None:
        table = self._pair_table(a, b)
        self._nft_in(self.bridge, f"delete table bridge {table}")
        self.cuts.discard(f"{self.bridge}/{table}")

    @staticmethod
    def _pair_table(a: int, b: int) -> str:
        if a == b:
            raise HostsError(f"a partition needs two hosts, got host {a} twice")
        low, high = sorted((a, b))
        return f"tlfleet_part_{low}_{high}"

    def _nft(self, host: int, rules: str) -> None:
        self._nft_in(self.name(host), rules)

    def _nft_in(self, namespace: str, rules: str) -> None:
        if shutil.which("nft") is None:
            raise HostsError("cutting a process link needs `nft` (Debian package nftables)")
        done = subprocess.run(["ip", "netns", "exec", namespace, "nft", rules],
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise HostsError(f"nft in {namespace} failed: {done.stderr.strip()}")


@dataclass(frozen=True)
class Placement:
    """Which host each process runs on and which port of its host's router it connects to."""

    hosts: int
    host_of: dict[str, int]  # process name (sim, agent-<id>, coordinator) -> host
    port_of: dict[str, int]  # process name -> its port on its router (host 0's in "peers")
    layout: str = "routers"  # "routers": a router per host; "peers": see the module docstring

    def router_host(self, process: str) -> int:
        """The host whose router ``process`` connects to."""
        return 0 if self.layout == "peers" else self.host_of[process]

    @property
    def peers(self) -> list[str]:
        """Peer layout: the fleet's peers in mesh order (sim, then agents by robot number)."""
        return [p for p in self.host_of if p != "coordinator"] if self.layout == "peers" else []

    def link(self, process: str) -> tuple[int, int]:
        if process not in self.host_of:
            raise HostsError(f"no process {process!r} (known: {', '.join(self.host_of)})")
        return self.router_host(process), self.port_of[process]

    def on(self, host: int) -> list[str]:
        return [p for p, h in self.host_of.items() if h == host]

    def as_dict(self) -> dict[str, object]:
        return {"hosts": self.hosts, "host_of": self.host_of, "port_of": self.port_of,
                "layout": self.layout}

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> Placement:
        return cls(int(data["hosts"]), dict(data["host_of"]), dict(data["port_of"]),
                   str(data.get("layout", "routers")))


def place(scenario: Scenario, hosts: int) -> Placement:
    """sim and coordinator on host 0, robot number j (ids ascending) on host j mod N."""
    host_of = {"coordinator": 0, "sim": 0}
    for j, robot in enumerate(sorted(scenario.robot_ids)):
        host_of[f"agent-{robot}"] = j % hosts
    port_of: dict[str, int] = {}
    for host in range(hosts):
        for k, process in enumerate(p for p, h in host_of.items() if h == host):
            port_of[process] = PROCESS_PORT0 + k
    return Placement(hosts, host_of, port_of)


def certificate_name(process: str) -> str:
    """The certificate name of a launched process: ``agent-3`` → ``robot3``; others as named."""
    return f"robot{process[6:]}" if process.startswith("agent-") else process


def place_peers(scenario: Scenario) -> Placement:
    """Peer layout: coordinator (and the one router) on host 0, the sim on host 1, robot number
    j (ids ascending) on host 2 + j; every process has its own port on router 0."""
    host_of = {"coordinator": 0, "sim": 1}
    for j, robot in enumerate(sorted(scenario.robot_ids)):
        host_of[f"agent-{robot}"] = 2 + j
    port_of = {process: PROCESS_PORT0 + k for k, process in enumerate(host_of)}
    return Placement(len(host_of), host_of, port_of, "peers")


def wait_listening(hosts: NetnsHosts, host: int, port: int, timeout: float) -> None:
    """Block until ``port`` accepts connections inside ``host``'s namespace."""
    code = ("import socket, sys, time\n"
            f"end = time.monotonic() + {timeout}\n"
            "while time.monotonic() < end:\n"
            "    try:\n"
            f"        socket.create_connection(('{hosts.address(host)}', {port}), 0.5).close()\n"
            "        sys.exit(0)\n"
            "    except OSError:\n"
            "        time.sleep(0.05)\n"
            "sys.exit(1)\n")
    done = subprocess.run([*hosts.exec_prefix(host), sys.executable, "-c", code])
    if done.returncode != 0:
        raise HostsError(f"the router of {hosts.name(host)} did not listen on port {port} "
                         f"within {timeout:g} s")


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
                 prefix: str | None = None, keys: Path | None = None,
                 insecure: bool = False, lease_ms: int | None = None,
                 faults: Sequence[Fault] = ()) -> HostsRun:
    """``tlfleet run SCENARIO --hosts N`` (see the module docstring). With ``faults`` (issue 13)
    the supervisor on host 0 injects them from a fault plan (:mod:`coordinator.fault_hosts`) and
    every client reconnects fast (``RECONNECT``); ``lease_ms`` goes to every process. A
    partition fault puts the fleet in the peer layout (:func:`place_peers`; ``hosts`` is then
    the layout's own count)."""
    require_root()
    scenario = load_scenario(scenario_path)  # ScenarioError before anything starts
    if keys is not None and insecure:
        raise HostsError("--secure DIR and --insecure exclude each other")
    if keys is not None:
        from coordinator.keys import check_keys

        check_keys(scenario, keys)
    path = str(Path(scenario_path).resolve())
    run_dir = Path(out) if out else default_run_dir(scenario.name)
    all_faults: tuple[Fault, ...] = ()
    if scenario.faults or faults:  # FaultSpecError before anything starts
        from coordinator.faults import run_faults

        all_faults = run_faults(scenario, faults)
    peers = any(f.kind == "partition" for f in all_faults)
    if peers and keys is not None:
        raise HostsError("a partition run makes its own keys (its peers' certificates carry "
                         "their hosts' addresses): leave out --secure DIR, or use --insecure")
    placement = place_peers(scenario) if peers else place(scenario, hosts)
    hosts = placement.hosts
    if all_faults:  # FaultError before anything starts
        from coordinator.fault_hosts import check_hosts_fault

        for fault in all_faults:
            check_hosts_fault(fault, placement)
    injecting = bool(all_faults)
    net = NetnsHosts(hosts, **({"prefix": prefix} if prefix else {}))
    launcher = Launcher(run_dir / "logs")
    done: subprocess.CompletedProcess | None = None
    codes: dict[str, int | None] = {}
    run_dir.mkdir(parents=True, exist_ok=True)
    router_conf = run_dir / "logs" / "router.json5"
    router_conf.parent.mkdir(parents=True, exist_ok=True)
    # explicit router mesh only: no gossip, so no router links another over a process's port
    # peer layout: the router must not broker between two peers that lost their direct link
    # (zenoh's peers_failover_brokering), or a partition would not separate them
    router_conf.write_text("{ scouting: { gossip: { enabled: false } }"
                           + (f", {RECONNECT}" if injecting else "")
                           + (", routing: { router: { peers_failover_brokering: false } }"
                              if peers else "") + " }\n")
    scheme = "tcp" if insecure else "tls"
    own_keys = None if insecure or keys is not None else Path(
        tempfile.mkdtemp(prefix="tlfleet-keys-"))  # 0700: private to this user
    lease = ["--lease-ms", str(lease_ms)] if lease_ms else []
    client = []
    if injecting:  # a cut client comes back within a retry period of the restore
        client_conf = run_dir / "logs" / "client.json5"
        client_conf.write_text(f"{{ {RECONNECT} }}\n")
        client = ["--zenoh-config", str(client_conf)]
    # with faults, agents that read only every d-th frame watch the sim's clock key too, so they
    # notice a lost simulator within --stale-after like the others (issue 13 §2)
    beat = ["--heartbeat"] if injecting else []
    with net:
        try:
            if own_keys is not None:
                from coordinator.keys import write_keys  # cryptography: secured runs only

                write_keys(scenario, own_keys, force=True, mesh=True,
                           hosts=tuple(net.address(h) for h in range(hosts)),
                           addresses={certificate_name(p): [net.address(placement.host_of[p])]
                                      for p in placement.peers})
            keydir = own_keys or keys
            secure = () if keydir is None else ("--secure", str(Path(keydir).resolve()))
            for host in sorted({placement.router_host(p) for p in placement.host_of}):
                listen = [f"{scheme}/{net.address(host)}:{ROUTER_PORT}"] + [
                    f"{scheme}/{net.address(host)}:{placement.port_of[p]}"
                    for p in placement.host_of if placement.router_host(p) == host]
                argv = ["router", "--fleet", scenario.fleet, "--zenoh-config", str(router_conf),
                        *secure, *lease]
                for endpoint in listen:
                    argv += ["--listen", endpoint]
                for other in range(host):
                    argv += ["--connect", f"{scheme}/{net.address(other)}:{ROUTER_PORT}"]
                launcher.start(f"router-{host}", [*net.exec_prefix(host),
                                                  *tlfleet_command(*argv)])
            for host in sorted({placement.router_host(p) for p in placement.host_of}):
                wait_listening(net, host, ROUTER_PORT, router_timeout)

            def endpoint_of(process: str) -> str:
                host, port = placement.link(process)
                return f"{scheme}/{net.address(host)}:{port}"

            def links_of(process: str) -> list[str]:
                """--connect to its router port; in the peer layout also --mode peer, --listen
                on its own host and --connect to every fleet peer before it (the mesh)."""
                links = ["--connect", endpoint_of(process)]
                if process in placement.peers:
                    links += ["--mode", "peer", "--listen",
                              f"{scheme}/{net.address(placement.host_of[process])}:{PEER_PORT}"]
                    for other in placement.peers[:placement.peers.index(process)]:
                        links += ["--connect", f"{scheme}/"
                                  f"{net.address(placement.host_of[other])}:{PEER_PORT}"]
                return links

            launcher.start("sim", [*net.exec_prefix(placement.host_of["sim"]), *tlfleet_command(
                "sim", path, f"--{mode}", *sim_args, *links_of("sim"), *secure, *lease,
                *client)])
            for robot in sorted(scenario.robot_ids):
                name = f"agent-{robot}"
                launcher.start(name, [*net.exec_prefix(placement.host_of[name]),
                                      *tlfleet_command("agent", path, "--robot", str(robot),
                                                       *agent_args, *beat, *links_of(name),
                                                       *secure, *lease, *client)])
            plan: list[str] = []
            if injecting:
                from coordinator.fault_hosts import PLAN_NAME, write_plan

                pids = {c.name: c.pid for c in launcher.children}
                argv = {c.name: c.argv for c in launcher.children}
                plan = ["--fault-plan", str(write_plan(run_dir / "logs" / PLAN_NAME, net,
                                                       placement, pids, argv))]
                for fault in faults:
                    plan += ["--fault", fault.text or fault.spec]
            coordinator = [*net.exec_prefix(0), *tlfleet_command(
                "supervise", path, f"--{mode}", "--connect", endpoint_of("coordinator"),
                "--out", str(run_dir), *secure, *lease, *client, *plan, *supervise_args)]
            done = subprocess.run(coordinator, capture_output=capture, text=True)
            launcher.wait_all(5.0)  # sim and agents exit by themselves after Control(stop)
        finally:
            if injecting:  # what `restart:` started again, as a child of supervise
                from coordinator.fault_hosts import stop_restarted

                stop_restarted(run_dir / "logs", kill_grace)
            codes = launcher.stop_all(kill_grace)
            if own_keys is not None:
                shutil.rmtree(own_keys, ignore_errors=True)
    info_path = run_dir / "run.json"
    if info_path.is_file():
        info = json.loads(info_path.read_text())
        if own_keys is not None:
            info["keys"] = "generated for this run in a private temporary directory, deleted"
        info.update(hosts=placement.as_dict(), host_exit_codes=codes,
                    addresses={net.name(h): net.address(h) for h in range(hosts)})
        info_path.write_text(json.dumps(info, indent=2, default=str) + "\n")
    assert done is not None
    return HostsRun(run_dir, done.returncode, placement, codes,
                    done.stdout or "", done.stderr or "", own_keys)
