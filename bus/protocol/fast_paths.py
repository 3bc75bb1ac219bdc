"""Straight-line codec paths of the three messages sent every tick (architecture.md §2).

Every simulator tick a ``MocapFrame`` and a ``Clock`` go out and one ``Command`` per due robot
comes back; every agent and the recorder decode the frame. The generic codec
(:mod:`tlfleet.bus.protocol.codec`) walks the dataclass annotations field by field and calls a
converter and a range check per value. On a process woken 100 times a second from cold caches
that walk costs 4–5× its warm time (a 5-robot frame: ≈ 78 µs of an STL agent's ≈ 400 µs tick), so
these kinds get one function each that does the same work in a few lines:

* :func:`decode_fast` ``(cls, data) -> message | None`` unpacks with tuples for arrays and checks,
  in one pass, exactly what the generic path checks (size, schema version, kind, the type of
  every field, every static range of :mod:`tlfleet.bus.protocol.bounds`). It returns the message
  only when every check passes; for anything else (an ``int`` where a float is allowed, a NaN,
  garbage) it returns ``None`` and the generic decoder decides — and converts, or raises its
  specific error. So a payload decodes to an equal message or fails with the same error either way
  (``tests/protocol/test_protocol_fast_paths.py`` checks both on random payloads).
* :func:`encode_fast` ``(msg) -> bytes | None`` builds the wire map of these kinds directly; the
  bytes are those of the generic encoder (same keys in the same order, same msgpack options).

**In C.** Where the install built ``tlfleet.bus.protocol._wire`` (``bus/protocol/wire_kernel.c``,
``setup.py``), ``MocapFrame`` and ``Command`` are read by it first: it returns the message only
for a canonical payload that passes every check of :func:`_frame` / :func:`_command` below — the
same message — and ``None`` for anything else, and then these Python functions decide. It also
writes them: the same bytes as the Python encoder, for messages of exact ints, floats and
tuples (``None`` otherwise, and the Python encoder writes them). A 5-robot frame is decoded in
≈ 43 µs instead of ≈ 100 µs after a 10 ms sleep (docs/performance.md).
The same switch installs the C confirmation of a frame's fleet bounds
(``_wire.frame_plausible``, :func:`tlfleet.bus.protocol.bounds.use_frame_check`).
``$TLFLEET_CODEC``: ``auto`` (default: C when built), ``native`` (C, an error when not built),
``python``; read once, at import (:func:`use_codec` switches later).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import msgpack
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol.bounds import (
    LIMITS,
    MAX_ANGLE,
    MAX_COORD,
    MAX_INT,
    MAX_ROBOT_ID,
    MAX_SPEED,
    MAX_TIME,
    use_frame_check,
)
from tlfleet.bus.protocol.messages import Clock, Command, MocapFrame
from tlfleet.bus.protocol.wire import SCHEMA_VERSION, to_plain

CODEC_CHOICES = ("auto", "native", "python")


class CodecSettingError(TlfleetError, ValueError):
    """``$TLFLEET_CODEC`` is unknown, or asks for the C decoders, which were not built."""


def _load_native(setting: str) -> Any:
    """The configured ``tlfleet.bus.protocol._wire`` module for ``setting``, or ``None``
    (Python)."""
    if setting not in CODEC_CHOICES:
        raise CodecSettingError(f"$TLFLEET_CODEC = {setting!r}: expected one of "
                                f"{', '.join(CODEC_CHOICES)}")
    if setting == "python":
        return None
    try:
        from tlfleet.bus.protocol import _wire
    except ImportError:
        if setting == "native":
            raise CodecSettingError("$TLFLEET_CODEC = 'native', but the C decoders "
                                    "(tlfleet.bus.protocol._wire) were not built: reinstall with a "
                                    "C compiler, or use 'auto'") from None
        return None
    frame, command = LIMITS["MocapFrame"], LIMITS["Command"]
    _wire.configure(MocapFrame, Command, SCHEMA_VERSION, MAX_TIME, MAX_COORD, MAX_ANGLE,
                    MAX_SPEED, MAX_INT, MAX_ROBOT_ID, frame.max_bytes, frame.max_items,
                    command.max_bytes, command.max_items)
    return _wire


_native = _load_native(os.environ.get("TLFLEET_CODEC", "auto"))
use_frame_check(_native.frame_plausible if _native is not None else None)


def native_codec() -> bool:
    """Whether the C codec runs (built, and not turned off by ``$TLFLEET_CODEC``)."""
    return _native is not None


def use_codec(setting: str) -> None:
    """Switch the codec as ``$TLFLEET_CODEC`` does at import (``auto``, ``native``,
    ``python``): for benchmarks that time both in one run, and tests."""
    global _native
    _native = _load_native(setting)
    use_frame_check(_native.frame_plausible if _native is not None else None)


def _unpacked(name: str, data: Any) -> dict | None:
    """The payload's map when it is a map of the right version and kind, unpacked with tuples for
    arrays and msgpack's limits of the kind; ``None`` for anything else."""
    limits = LIMITS[name]
    if type(data) is not bytes or len(data) > limits.max_bytes:
        return None
    try:
        body = msgpack.unpackb(data, use_list=False, raw=False, strict_map_key=True,
                               max_str_len=limits.max_str, max_bin_len=limits.max_str,
                               max_array_len=limits.max_items, max_map_len=limits.max_items,
                               max_ext_len=0)
    except Exception:  # the generic decoder reports what is wrong
        return None
    if type(body) is not dict or body.get("k") != name:
        return None
    version = body.get("v")
    if type(version) is not int or version != SCHEMA_VERSION:
        return None
    return body


def _frame(data: Any) -> MocapFrame | None:
    if _native is not None:
        frame = _native.decode_frame(data)
        if frame is not None:
            return frame
    return _frame_python(data)


def _frame_python(data: Any) -> MocapFrame | None:
    body = _unpacked("MocapFrame", data)
    if body is None:
        return None
    t, seq, poses = body.get("t"), body.get("seq"), body.get("poses")
    due = body.get("due", ())
    if not (type(t) is float and 0.0 <= t <= MAX_TIME and type(seq) is int
            and 0 <= seq <= MAX_INT and type(poses) is tuple and type(due) is tuple):
        return None
    for row in poses:
        if type(row) is not tuple or len(row) != 4:
            return None
        robot, x, y, theta = row
        if not (type(robot) is int and type(x) is float and type(y) is float
                and type(theta) is float and 0 <= robot <= MAX_ROBOT_ID
                and -MAX_COORD <= x <= MAX_COORD and -MAX_COORD <= y <= MAX_COORD
                and -MAX_ANGLE <= theta <= MAX_ANGLE):
            return None
    for robot in due:
        if type(robot) is not int or not 0 <= robot <= MAX_ROBOT_ID:
            return None
    return MocapFrame(t, seq, poses, due)


def _command(data: Any) -> Command | None:
    if _native is not None:
        command = _native.decode_command(data)
        if command is not None:
            return command
    return _command_python(data)


def _command_python(data: Any) -> Command | None:
    body = _unpacked("Command", data)
    if body is None:
        return None
    robot, t, seq, u = body.get("robot"), body.get("t"), body.get("seq"), body.get("u")
    if not (type(robot) is int and type(t) is float and type(seq) is int and type(u) is tuple
            and 0 <= robot <= MAX_ROBOT_ID and 0.0 <= t <= MAX_TIME and -1 <= seq <= MAX_INT):
        return None
    for value in u:
        if type(value) is not float or not -MAX_SPEED <= value <= MAX_SPEED:
            return None
    return Command(robot, t, seq, u)


_DECODERS: dict[type, Callable[[Any], Any]] = {MocapFrame: _frame, Command: _command}


def decode_fast(cls: type, data: Any) -> Any:
    """``data`` as a message of type ``cls`` when ``cls`` has a straight-line path and the
    payload passes every check on it; ``None`` otherwise (then the generic decoder decides)."""
    decoder = _DECODERS.get(cls)
    return decoder(data) if decoder is not None else None


def encode_fast(msg: Any) -> bytes | None:
    """The wire bytes of a ``MocapFrame``, ``Command`` or ``Clock`` (the generic encoder's bytes:
    ``{"v", "k", <fields in declaration order>}``); ``None`` for any other message."""
    kind = type(msg)
    if _native is not None and (kind is Command or kind is MocapFrame):
        data = (_native.encode_command if kind is Command else _native.encode_frame)(msg)
        if data is not None:
            return data
    return _encode_python(msg)


def command_bytes(robot: Any, t: Any, seq: Any, u: Any) -> bytes | None:
    """``encode_fast(Command(robot, t, seq, u))`` without building the message when the C codec
    runs and the fields are exact ints, a float and a tuple of floats (an agent sends one command
    a tick); ``None`` otherwise: build the ``Command`` and encode it."""
    if _native is not None:
        return _native.command_bytes(robot, t, seq, u)
    return None


def pose_map(rows: Any) -> dict:
    """``{row[0]: row[1:] for row in rows}``: a frame's ``poses`` as {id: (x [m], y [m],
    θ [rad])}, built in C when the codec runs and the rows are 4-tuples in a tuple (as every
    decoder returns them)."""
    if _native is not None:
        poses = _native.pose_map(rows)
        if poses is not None:
            return poses
    return {row[0]: row[1:] for row in rows}


def _encode_python(msg: Any) -> bytes | None:
    kind = type(msg)
    if kind is Command:
        body = {"v": SCHEMA_VERSION, "k": "Command", "robot": msg.robot, "t": msg.t,
                "seq": msg.seq, "u": msg.u}
    elif kind is MocapFrame:
        body = {"v": SCHEMA_VERSION, "k": "MocapFrame", "t": msg.t, "seq": msg.seq,
                "poses": msg.poses, "due": msg.due}
    elif kind is Clock:
        body = {"v": SCHEMA_VERSION, "k": "Clock", "t": msg.t, "tick": msg.tick,
                "mode": msg.mode}
    else:
        return None
    return msgpack.packb(body, use_bin_type=True, default=to_plain)
