"""Looking at a running fleet from outside (``tlfleet echo``, ``topics``, ``hz``): which fleet
and endpoint, the key expression a user's short name stands for, one sample as a JSON line, and
rates over a sliding window. The messages are decoded by the one codec; the key layout is
architecture.md §2 (``tlfleet.bus.protocol.keys``)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import ProtocolError, decode_any
from tlfleet.bus.transport import TransportConfig
from tlfleet.cli.transport_flags import add_connect_argument, add_secure_argument

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


class TapError(TlfleetError, ValueError):
    """A fleet that cannot be reached or named as asked."""


def add_tap_arguments(parser: argparse.ArgumentParser) -> None:
    """Which fleet, where, and as whom: ``--run DIR`` reads the fleet and endpoint a running
    ``tlfleet run`` wrote to its run.json; otherwise ``--fleet`` (default every fleet) and
    ``--connect`` (default the usual router port)."""
    parser.add_argument("--run", type=Path, default=None, metavar="RUN_DIR",
                        help="the run directory of a running `tlfleet run`: its fleet and "
                             "router endpoint (run.json)")
    parser.add_argument("--fleet", default=None,
                        help="the fleet's name (the scenario's [fleet] or name; default: any "
                             "fleet, `*`)")
    add_connect_argument(parser, DEFAULT_ENDPOINT)
    add_secure_argument(parser, "connect as --identity, whose certificate needs read rights")
    parser.add_argument("--identity", default="coordinator",
                        help="--secure: the certificate to use (default coordinator: it may "
                             "subscribe to every key of the fleet)")


def where(args: argparse.Namespace) -> tuple[str, tuple[str, ...]]:
    """``(fleet or "*", endpoints)`` from ``--run``, ``--fleet`` and ``--connect``."""
    fleet, connect = args.fleet, tuple(args.connect)
    if args.run is not None:
        info_path = Path(args.run) / "run.json"
        try:
            info = json.loads(info_path.read_text())
        except (OSError, ValueError) as exc:
            raise TapError(f"{info_path}: cannot read the run's endpoint ({exc})") from None
        fleet = fleet or info.get("fleet") or info.get("scenario")
        endpoint = info.get("endpoint")
        if not connect and isinstance(endpoint, str) and endpoint:
            connect = tuple(e.strip() for e in endpoint.split(","))
    return (fleet or "*"), (connect or (DEFAULT_ENDPOINT,))


def key_expression(fleet: str, name: str) -> str:
    """The key expression ``name`` stands for: a full one (``tlfleet/…``) as it is, else under
    the fleet's prefix: ``mocap`` → ``tlfleet/<fleet>/mocap``, ``robot/*/cmd``, ``**``."""
    name = name.strip().strip("/")
    if not name:
        raise TapError("an empty key name")
    if name == keys.ROOT or name.startswith(keys.ROOT + "/"):
        return name
    return f"{keys.ROOT}/{fleet}/{name}"


def transport_config(args: argparse.Namespace, connect: tuple[str, ...]) -> TransportConfig:
    config = TransportConfig(mode="client", connect=connect)
    if args.secure is None:
        return config
    from tlfleet.bus.zenoh.security import secure_transport

    return secure_transport(config, args.secure, args.identity)


@contextmanager
def open_tap(args: argparse.Namespace) -> Iterator[tuple[Any, str]]:
    """A client session to the fleet's router (``TapError`` naming the endpoint when none
    answers) and the fleet name; closed on exit."""
    from tlfleet.bus.zenoh.transport import open_transport

    fleet, connect = where(args)
    try:
        transport = open_transport(transport_config(args, connect))
    except TlfleetError:
        raise
    except Exception as exc:  # zenoh raises ZError, not a stable type
        raise TapError(f"no zenoh router answers at {', '.join(connect)} ({exc}); is the fleet "
                       "running? `--run RUN_DIR` reads a run's endpoint") from None
    try:
        yield transport, fleet
    finally:
        transport.close()


def plain(value: Any) -> Any:
    """A message as JSON-ready data: dataclasses as maps, tuples as lists, bytes by size,
    non-finite floats as strings."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (bytes, bytearray, memoryview)):
        return f"<{len(value)} bytes>"
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return value


def sample_line(key: str, payload: bytes, received: float) -> dict[str, Any]:
    """One sample as ``{"key", "received" (Unix time [s]), "from", "kind", "msg"}``; a payload
    that is no valid message gets ``"error"`` and its size instead."""
    line: dict[str, Any] = {"key": key, "received": round(received, 6),
                            "from": keys.publisher_of(key)}
    try:
        message = decode_any(bytes(payload))
    except ProtocolError as exc:
        line.update(kind=None, bytes=len(payload), error=str(exc))
        return line
    line.update(kind=type(message).__name__, msg=plain(message))
    return line


class Rates:
    """Samples a second per key over the last ``window`` seconds (thread-safe: zenoh calls
    :meth:`add` from its threads)."""

    def __init__(self, window: float, clock: Callable[[], float] = time.monotonic):
        self.window = window
        self.clock = clock
        self._times: dict[str, deque[float]] = {}
        self.counts: dict[str, int] = {}
        self.kinds: dict[str, str | None] = {}
        self._lock = threading.Lock()

    def add(self, key: str, kind: str | None = None) -> None:
        now = self.clock()
        with self._lock:
            self._times.setdefault(key, deque()).append(now)
            self.counts[key] = self.counts.get(key, 0) + 1
            self.kinds.setdefault(key, kind)

    def snapshot(self) -> dict[str, dict[str, Any]]:
        """Per key: ``hz`` over the window (samples − 1 over their span; 0 with fewer than
        two), ``count`` in all, the largest gap between two samples in the window [s]."""
        now = self.clock()
        out: dict[str, dict[str, Any]] = {}
        with self._lock:
            for key in sorted(self._times):
                times = self._times[key]
                while times and now - times[0] > self.window:
                    times.popleft()
                span = times[-1] - times[0] if len(times) > 1 else 0.0
                gaps = [b - a for a, b in zip(times, list(times)[1:], strict=False)]
                out[key] = {"hz": (len(times) - 1) / span if span > 0 else 0.0,
                            "count": self.counts[key], "max_gap": max(gaps, default=0.0),
                            "kind": self.kinds.get(key), "from": keys.publisher_of(key)}
        return out
