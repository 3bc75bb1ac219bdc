"""Fleets across hosts, with network namespaces as stand-in hosts.

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

**Peer layout** (``layout="peers"``, chosen by :func:`tlfleet.coordinator.run_hosts.run_on_hosts`
when a fault partitions two processes): one router only, on host 0 with the
coordinator; the simulator on host 1 and robot number ``j`` on host ``2 + j``, each a zenoh **peer**
listening on
``PEER_PORT`` of its own host, connected to its port on router 0 and, explicitly, to every fleet
peer before it (a full mesh; gossip off). A router does not relay between peers (fault-injection
notes §5.5, and checked again on zenoh 1.10: a router's client gets every peer's data, a peer gets
another peer's only over their direct link), so dropping the bridge traffic between two hosts
(:meth:`NetnsHosts.partition`) separates exactly those two processes while both keep their links to
the router and to everyone else; the explicit connect brings their link back after the heal. A cut
in this layout is the process's host's carrier loss (all of its links).

Because every process reaches the fleet through its own port, one process's link can be cut and
restored on command (:meth:`NetnsHosts.cut_process` / :meth:`NetnsHosts.restore_process`: an nft
table in the host's namespace that drops that port, a silent partition) and so can a whole host's
(:meth:`NetnsHosts.cut_host`: its bridge port down, carrier loss). The fault-injection issue builds
on these.

The fleet's launch and supervision on these hosts is
:func:`tlfleet.coordinator.run_hosts.run_on_hosts`.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from dataclasses import dataclass, field

from tlfleet.agent.model import Scenario
from tlfleet.bus.errors import TlfleetError

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

    def _add_namespace(self, ns: str) -> None:
        """``ip netns add ns``; a namespace of that name left by a run that was killed before
        its ``down`` (SIGKILL, a lost CI runner) is deleted first: the names carry this
        object's prefix, so a leftover is a dead run's, and without this every later run of the
        same prefix would fail with "File exists"."""
        if os.path.exists(f"/run/netns/{ns}"):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
        _ip("netns", "add", ns)

    def up(self) -> NetnsHosts:
        require_root()
        try:
            self._add_namespace(self.bridge)
            self.created.append(self.bridge)
            _ip("-n", self.bridge, "link", "set", "lo", "up")
            _ip("-n", self.bridge, "link", "add", "br0", "type", "bridge")
            _ip("-n", self.bridge, "link", "set", "br0", "up")
            for host in range(self.count):
                ns = self.name(host)
                self._add_namespace(ns)
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
