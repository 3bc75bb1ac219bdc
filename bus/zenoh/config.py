"""``--zenoh-config FILE.json5``: a zenohd-style configuration file under tlfleet's own settings.

A process's zenoh session is built in two layers:

1. the user's file, as zenoh reads it (``zenoh.Config.from_json5``): anything zenoh can configure
   — TLS or QUIC endpoints and their certificates, access control, shared memory, timeouts;
2. on top, tlfleet's own settings from the transport flags (:func:`own_settings`): the session
   mode, multicast scouting (off unless ``--multicast-scouting``; docs/stack-notes.md §0), the lease
   when ``--lease-ms`` is given (and, as long, the wait before a link with a blocked send queue
   is closed), and the endpoints **when the flags give any** — with no
   ``--listen``/``--connect`` flag, the file's endpoints stay.

When zenoh refuses the file, :func:`refusal` names the file and the key: zenoh's own messages
say *what* is wrong (``unknown field `bogus`, expected one of …``, ``error parsing number``) but
not *where*, so the file is read again here (:func:`parse_json5`, enough of JSON5 for config
files: comments, unquoted keys, single quotes, trailing commas) and each leaf is tried on its own
(:func:`first_refused`) until zenoh refuses one.

This module does not import zenoh (:mod:`tlfleet.bus.zenoh.transport` does and calls these
functions).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tlfleet.bus.errors import TlfleetError

if TYPE_CHECKING:
    from tlfleet.bus.transport import TransportConfig


class ZenohConfigError(TlfleetError, ValueError):
    """A ``--zenoh-config`` file that cannot be used: names the file, the key when known, and
    zenoh's reason."""

    def __init__(self, file: str | Path, key: str | None, reason: str):
        self.file, self.key, self.reason = str(file), key, reason
        where = f"{file}: key {key}" if key else str(file)
        super().__init__(f"zenoh config {where}: {reason}")


def read_text(path: str | Path) -> str:
    """The file's text; :class:`ZenohConfigError` if it cannot be read."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ZenohConfigError(path, None, f"cannot read it ({exc})") from exc


def file_keys(text: str | None) -> frozenset[str]:
    """The leaf paths a config file sets (empty when there is no file or it cannot be read)."""
    if text is None:
        return frozenset()
    try:
        return frozenset(path for path, _ in leaves(parse_json5(text)))
    except ValueError:
        return frozenset()


def own_settings(config: TransportConfig, from_file: frozenset[str] = frozenset()
                 ) -> list[tuple[str, Any]]:
    """tlfleet's settings, applied over the file's: ``[(zenoh config path, JSON value)]``.

    An endpoint list is set from the flags when they give endpoints or when the file
    (``from_file``: the paths it sets) does not: zenoh's defaults listen on all interfaces, so
    nothing listens there unless someone asked for it.
    """
    settings: list[tuple[str, Any]] = [("mode", config.mode)]
    for key, flags in (("listen/endpoints", config.listen),
                       ("connect/endpoints", config.connect)):
        if flags or key not in from_file:
            settings.append((key, list(flags)))
    settings.append(("scouting/multicast/enabled", config.multicast_scouting))
    if config.lease_ms:
        settings.append(("transport/link/tx/lease", config.lease_ms))
        # a link whose send queue stays full is closed after the same time as a silent one:
        # zenoh waits 5 s by default, and a sender with congestion control "block" (a query, a
        # reply) can be held that long on a link a partition blackholed. (This was first taken
        # for the cause of a stall of agents whose stage-2 partner was partitioned away; that one
        # was zenoh's receive runtime blocked in close(2), tlfleet.bus.transport.RX_WORKERS. The
        # bound stays: no sender should wait longer for a dead link than the lease takes to call it
        # dead.)
        settings.append((BLOCK_WAIT_BEFORE_CLOSE, config.lease_ms * 1000))
    settings.extend(config.extra.items())
    return settings


BLOCK_WAIT_BEFORE_CLOSE = "transport/link/tx/queue/congestion_control/block/wait_before_close"  # µs


# ----------------------------------------------------------------- finding the refused key

_TOKEN = re.compile(r"""
    (?P<ws>\s+|//[^\n]*|/\*.*?\*/)
  | (?P<str>"(?:[^"\\]|\\.)*"|'(?:[^'\\]|\\.)*')
  | (?P<punct>[{}\[\],:])
  | (?P<word>[^\s{}\[\],:'"/]+)
""", re.VERBOSE | re.DOTALL)


def parse_json5(text: str) -> Any:
    """The value of a JSON5 text (the subset config files use); ``ValueError`` otherwise."""
    out: list[str] = []
    pos = 0
    while pos < len(text):
        match = _TOKEN.match(text, pos)
        if match is None:
            raise ValueError(f"unexpected character {text[pos]!r} at offset {pos}")
        pos = match.end()
        kind, token = match.lastgroup, match.group()
        if kind == "ws":
            continue
        if kind == "str" and token.startswith("'"):
            token = json.dumps(token[1:-1].replace("\\'", "'"))
        elif kind == "word":
            nxt = _TOKEN.match(text, pos)
            while nxt is not None and nxt.lastgroup == "ws":
                nxt = _TOKEN.match(text, nxt.end())
            is_key = nxt is not None and nxt.group() == ":"
            if is_key or not re.fullmatch(r"[-+]?(\d|\.\d|true|false|null|Infinity|NaN)\S*",
                                          token):
                token = json.dumps(token)
            elif token.lower().startswith(("0x", "-0x", "+0x")):
                token = str(int(token, 16))
        if token in ("}", "]") and out and out[-1] == ",":
            out.pop()  # trailing comma
        out.append(token)
    return json.loads("".join(out))


def leaves(tree: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """``(path, value)`` of every leaf; lists and empty objects are leaves."""
    if isinstance(tree, dict) and tree:
        for key, value in tree.items():
            yield from leaves(value, f"{prefix}/{key}" if prefix else str(key))
    else:
        yield prefix, tree


def first_refused(text: str, try_insert: Callable[[str, str], str | None]
                  ) -> tuple[str, str] | None:
    """The first leaf of the file that ``try_insert(path, json_value)`` refuses → (path, reason),
    or None when every leaf is accepted on its own (or the file is not JSON5 this parser reads)."""
    try:
        tree = parse_json5(text)
    except ValueError:
        return None
    if not isinstance(tree, dict):
        return None
    for path, value in leaves(tree):
        reason = try_insert(path, json.dumps(value))
        if reason is not None:
            return path, reason
    return None


def refusal(path: str | Path, text: str, reason: str,
            try_insert: Callable[[str, str], str | None]) -> ZenohConfigError:
    """The error for a file zenoh refused with ``reason``, naming the refused key if it can be
    found."""
    found = first_refused(text, try_insert)
    if found is None:
        return ZenohConfigError(path, None, clean_reason(reason))
    return ZenohConfigError(path, found[0], clean_reason(reason))


def clean_reason(reason: str) -> str:
    """zenoh's messages carry a Rust source location after ` at /…`: keep the message."""
    text = re.sub(r" at /\S+\.rs:\d+\.?$", "", reason.strip())
    match = re.search(r'msg: "([^"]*)"', text)  # Json5Err(Message { msg: "…", … })
    if match:
        text = match.group(1)
    return " ".join(text.split())
