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

#: ``--zenoh-runtime`` values: zenoh's thread pools with :data:`tlfleet.bus.transport.RX_WORKERS`
#: receive workers, or :data:`tlfleet.bus.transport.MINIMAL_RUNTIME`
RUNTIMES = {"default": DEFAULT_RUNTIME, "minimal": MINIMAL_RUNTIME}


def add_transport_arguments(parser: argparse.ArgumentParser, default_mode: str = "client") -> None:
    group = parser.add_argument_group("transport (zenoh)")
    group.add_argument("--mode", choices=("client", "peer", "router"), default=default_mode,
                       help=f"zenoh session mode (default {default_mode})")
    group.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                       help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    group.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                       help="endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable)")
    group.add_argument("--lease-ms", type=int, default=None, metavar="MS",
                       help="link lease in ms (zenoh default 10000)")
    group.add_argument("--multicast-scouting", action="store_true",
                       help="join zenoh multicast scouting (off by default)")
    group.add_argument("--zenoh-runtime", choices=tuple(RUNTIMES), default="default",
                       help="zenoh's threads: its pools with 8 receive workers (default), or "
                            "'minimal' (one worker that also receives and sends: less CPU per "
                            "message, but a link lost to a partition stops it receiving); a "
                            "ZENOH_RUNTIME environment value wins")
    group.add_argument("--secure", type=Path, default=None, metavar="DIR",
                       help="mutual TLS with the keys of DIR (`tlfleet keys`): endpoints become "
                            "tls/…; a router also enforces DIR/acl.json")
    add_zenoh_config_argument(group)


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
