"""The transport flags every process shares (style.md §6): ``--mode``, ``--connect``, ``--listen``,
``--lease-ms``, ``--multicast-scouting``, ``--zenoh-runtime``, ``--zenoh-config``, ``--secure``,
turned into a :class:`bus.TransportConfig`.

``--secure DIR`` (a key directory of ``tlfleet keys``) puts every endpoint on ``tls/`` with mutual
authentication as the process's identity, and gives a router the directory's access-control
policy (:func:`tlfleet.bus.zenoh.security.secure_transport`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tlfleet.bus.transport import DEFAULT_RUNTIME, MINIMAL_RUNTIME, TransportConfig
from tlfleet.cli.arg_types import positive_int

#: ``--zenoh-runtime`` values: zenoh's thread pools with :data:`tlfleet.bus.transport.RX_WORKERS`
#: receive workers, or :data:`tlfleet.bus.transport.MINIMAL_RUNTIME`
RUNTIMES = {"default": DEFAULT_RUNTIME, "minimal": MINIMAL_RUNTIME}


def add_transport_arguments(parser: argparse.ArgumentParser, default_mode: str = "client",
                            connect_default: str | None = None, client_only: bool = False
                            ) -> None:
    """Every transport flag of a fleet process, each declared once here;
    :meth:`tlfleet.coordinator.launch.plan.Links.argv` writes them. ``client_only`` (``tlfleet
    supervise``, always a client): the endpoints to connect to, the lease, the keys and the
    zenoh file."""
    group = parser.add_argument_group("transport (zenoh)")
    if not client_only:
        group.add_argument("--mode", choices=("client", "peer", "router"), default=default_mode,
                           help=f"zenoh session mode (default {default_mode})")
    add_connect_argument(group, connect_default)
    if not client_only:
        group.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                           help="endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable)")
    add_lease_argument(group)
    if not client_only:
        group.add_argument("--multicast-scouting", action="store_true",
                           help="join zenoh multicast scouting (off by default)")
        group.add_argument("--zenoh-runtime", choices=tuple(RUNTIMES), default="default",
                           help="zenoh's threads: its pools with 8 receive workers (default), "
                                "or 'minimal' (one worker that also receives and sends: less "
                                "CPU per message, but a link lost to a partition stops it "
                                "receiving); a ZENOH_RUNTIME environment value wins")
    add_secure_argument(group)
    add_zenoh_config_argument(group)


def add_connect_argument(parser, default: str | None = None) -> None:
    parser.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                        help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable"
                             + (f"; default {default})" if default else ")"))


def add_lease_argument(parser, what: str = "this process's") -> None:
    parser.add_argument("--lease-ms", type=positive_int, default=None, metavar="MS",
                        help=f"zenoh link lease of {what} sessions [ms] (default zenoh's 10000): "
                             "how fast a hung or cut-off peer is declared gone; 500 notices a "
                             "cut within 1 s")


def add_secure_argument(parser, what: str = "") -> None:
    parser.add_argument("--secure", type=Path, default=None, metavar="DIR",
                        help="mutual TLS with the keys of DIR (`tlfleet keys SCENARIO --out DIR`): "
                             "endpoints become tls/…; a router also enforces DIR/acl.json"
                             + (f"; {what}" if what else ""))


def add_zenoh_config_argument(parser) -> None:
    parser.add_argument("--zenoh-config", type=Path, default=None, metavar="FILE.json5",
                        help="zenohd-style config file (TLS, ACL, shared memory, …) merged under "
                             "tlfleet's own settings; the endpoint flags, when given, win")


def transport_config(args: argparse.Namespace, identity: str | None = None) -> TransportConfig:
    """The flags' :class:`TransportConfig`; with ``--secure``, secured as ``identity`` (the
    process's certificate name: ``router``, ``sim``, ``robot3``…)."""
    config = TransportConfig(mode=args.mode, connect=tuple(args.connect),
                             listen=tuple(args.listen), lease_ms=args.lease_ms,
                             multicast_scouting=args.multicast_scouting,
                             runtime=RUNTIMES[getattr(args, "zenoh_runtime", "default")],
                             zenoh_config=getattr(args, "zenoh_config", None))
    secure = getattr(args, "secure", None)
    if secure is None:
        return config
    from tlfleet.bus.zenoh.security import secure_transport

    if identity is None:
        raise SystemExit("--secure: this command has no process identity")
    return secure_transport(config, secure, identity)
