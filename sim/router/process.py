"""The fleet's zenoh router process (architecture.md §1; stack-notes.md §0: one router, every
other process a client): a session in ``router`` mode that declares ``alive/router/0`` and waits
for SIGINT/SIGTERM; the session is closed in ``finally``.

A secured router (``--secure DIR``: ``access_control`` in its transport's entries,
:mod:`tlfleet.bus.zenoh.security`) logs every distinct ACL denial on stderr
(:mod:`tlfleet.sim.router.denials`).

The router has no default endpoint: ``--listen`` is required (``tlfleet run`` gives it
``tcp/127.0.0.1:<free port>``, or ``tls/…`` when secured); zenoh's own default for a router
without endpoints would be every interface (``tcp/[::]:7447``), which tlfleet never uses."""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field

from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol import keys
from tlfleet.bus.signals import install_signal_handlers
from tlfleet.bus.transport import TransportConfig
from tlfleet.bus.zenoh.transport import open_transport

logger = logging.getLogger(__name__)


class RouterConfigError(TlfleetError, ValueError):
    """A router setting that cannot work (names the setting)."""


@dataclass(frozen=True)
class RouterConfig:
    """How the router runs: its fleet name (for the liveliness token) and its transport."""

    fleet: str = "default"
    transport: TransportConfig = field(default_factory=lambda: TransportConfig(mode="router"))

    def __post_init__(self) -> None:
        if self.transport.mode != "router":
            raise RouterConfigError(f"--mode must be router, got {self.transport.mode}")
        if not self.transport.listen and self.transport.zenoh_config is None:
            raise RouterConfigError("give at least one --listen endpoint, e.g. "
                                    "tcp/127.0.0.1:7447 (or a --zenoh-config file with "
                                    "listen/endpoints)")


def main(config: RouterConfig, stop: threading.Event | None = None) -> int:
    """Run the router until ``stop`` is set (by default: SIGINT or SIGTERM)."""
    if stop is None:
        stop = threading.Event()
        install_signal_handlers(stop)
    denials = None
    if "access_control" in config.transport.extra:
        from tlfleet.bus.zenoh.transport import init_log
        from tlfleet.sim.router.denials import LOG_SPEC, DenialLog

        denials = DenialLog()
        denials.start()
        init_log(LOG_SPEC)
    try:
        transport = open_transport(config.transport)
    except BaseException:
        if denials is not None:
            denials.close()
        raise
    try:
        transport.declare_alive(keys.alive(config.fleet, "router", 0))
        listening = ", ".join(config.transport.listen) or "the --zenoh-config endpoints"
        logger.info("router: listening on %s for fleet %s; waiting for clients (stop with "
                    "Ctrl-C)", listening, config.fleet)
        while not stop.wait(0.2):
            pass
        return 0
    finally:
        transport.close()
        if denials is not None:
            denials.close()
