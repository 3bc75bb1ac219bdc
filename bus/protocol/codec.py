"""The one codec of tlfleet messages: ``encode(msg) -> bytes``, ``decode(T, data) -> T``.

Wire format (msgpack map, string keys): ``{"v": SCHEMA_VERSION, "k": "<type name>", <fields>}``.
Tuples travel as arrays, nested dataclasses as maps, ``None`` as nil, ``bytes`` as msgpack bin
(a :class:`~tlfleet.bus.protocol.messages.BackfillReply` carries encoded frames). ``decode`` checks
the version, the kind and the type of every field against the dataclass annotations and raises
``ProtocolError`` naming the message, the field path and what was expected, so a malformed or
foreign payload is rejected whole and never half-applied.

``decode`` is *total*: whatever the bytes, it returns a valid message or raises
``ProtocolError``, never anything else. Before unpacking, the payload size is checked against the
kind's :data:`tlfleet.bus.protocol.bounds.LIMITS`, and msgpack is told the longest array, map and
string it may build; after conversion, every number is checked against its declared range
(:func:`tlfleet.bus.protocol.bounds.check_message`: finite, times in [0, MAX_TIME], positions and
speeds bounded). The schema version must be exactly the integer :data:`SCHEMA_VERSION` (not
``1.0``, not ``True``). Any other exception on the way (a bug, ``RecursionError``,
``MemoryError``) is turned into ``ProtocolError`` too, so receivers need one ``except``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from typing import Any, Literal, TypeVar, Union

import msgpack
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol import messages
from tlfleet.bus.protocol.bounds import (
    DEFAULT_LIMITS,
    LIMITS,
    MAX_PAYLOAD,
    OutOfBounds,
    check_message,
)
from tlfleet.bus.protocol.fast_paths import decode_fast, encode_fast
from tlfleet.bus.protocol.wire import SCHEMA_VERSION, to_plain

T = TypeVar("T")

_KINDS: dict[str, type] = {
    cls.__name__: cls
    for cls in (messages.Clock, messages.MocapFrame, messages.Command, messages.LtlStatus,
                messages.StlStatus, messages.CollabMessage, messages.CollabReply,
                messages.Event, messages.Control, messages.BackfillRequest,
                messages.BackfillReply)
}


class ProtocolError(TlfleetError, ValueError):
    """A payload that is not a valid message of the expected type and schema version."""


def encode(msg: Any) -> bytes:
    """Serialise one message dataclass (the per-tick kinds by :func:`encode_fast`, same bytes)."""
    fast = encode_fast(msg)
    return fast if fast is not None else _encode_generic(msg)


def _encode_generic(msg: Any) -> bytes:
    kind = type(msg).__name__
    if _KINDS.get(kind) is not type(msg):
        raise TypeError(f"not a protocol message: {type(msg).__name__}")
    body = {"v": SCHEMA_VERSION, "k": kind}
    body.update(_to_wire(msg))
    return msgpack.packb(body, use_bin_type=True, default=to_plain)


def decode(cls: type[T], data: bytes) -> T:
    """Parse ``data`` as a message of type ``cls``; ``ProtocolError`` on anything else.

    The per-tick kinds try :func:`~tlfleet.bus.protocol.fast_paths.decode_fast` first: it returns
    the message only for a payload that passes every check below, so the result is the same."""
    name = getattr(cls, "__name__", "message")
    try:
        fast = decode_fast(cls, data)
        if fast is not None:
            return fast
        return _decode(cls, data)
    except ProtocolError:
        raise
    except Exception as exc:  # total: RecursionError, MemoryError, a converter bug...
        raise ProtocolError(f"{name}: undecodable payload ({type(exc).__name__})") from None


def _decode(cls: type[T], data: bytes) -> T:
    name = cls.__name__
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ProtocolError(f"{name}: expected bytes, got {type(data).__name__}")
    limits = LIMITS.get(name, DEFAULT_LIMITS)
    if len(data) > limits.max_bytes:
        raise ProtocolError(f"{name}: payload of {len(data)} bytes exceeds {limits.max_bytes}")
    try:
        body = msgpack.unpackb(data, raw=False, strict_map_key=True,
                               max_str_len=limits.max_str, max_bin_len=limits.max_str,
                               max_array_len=limits.max_items, max_map_len=limits.max_items,
                               max_ext_len=0)
    except Exception as exc:  # msgpack raises several unrelated types on garbage
        raise ProtocolError(f"{name}: not a msgpack payload ({str(exc)[:80]})") from None
    if not isinstance(body, dict):
        raise ProtocolError(f"{name}: expected a map, got {type(body).__name__}")
    version = body.get("v")
    if type(version) is not int or version != SCHEMA_VERSION:
        raise ProtocolError(f"{name}: schema version {_show_short(version)}, expected "
                            f"{SCHEMA_VERSION}")
    if body.get("k") != name:
        raise ProtocolError(f"{name}: payload is a {_show_short(body.get('k'))} message")
    msg = _from_wire(cls, body, name)
    try:
        check_message(msg)
    except OutOfBounds as exc:
        raise ProtocolError(f"{name}{exc.path}: {exc.reason}") from None
    return msg


def _show_short(value: Any) -> str:
    if isinstance(value, (dict, list, tuple)):
        return f"a {type(value).__name__}"
    return repr(value)[:40]


def peek_kind(data: bytes) -> str | None:
    """The message kind of a payload, or ``None`` when it is not a tlfleet message."""
    try:
        if len(data) > MAX_PAYLOAD:
            return None
        body = msgpack.unpackb(data, raw=False, max_str_len=4096, max_bin_len=4096,
                               max_array_len=4096, max_map_len=4096, max_ext_len=0)
    except Exception:
        return None
    return body.get("k") if isinstance(body, dict) and isinstance(body.get("k"), str) else None


def decode_any(data: bytes) -> Any:
    """The message a payload holds, whatever its kind (``tlfleet echo``); ``ProtocolError`` when
    it is no tlfleet message or not a valid one. Checked as :func:`decode` checks."""
    kind = peek_kind(data)
    cls = _KINDS.get(kind) if kind is not None else None
    if cls is None:
        raise ProtocolError(f"not a tlfleet message (kind {_show_short(kind)})")
    return decode(cls, data)


# --------------------------------------------------------------------------- encoding


#: field values that are never dataclasses: encoded as they are, without asking (a
#: command, a frame or a status is encoded 100 times a second in every process)
_PLAIN = frozenset({float, int, str, bool, bytes, tuple, list, dict, type(None)})


@functools.cache
def _field_names(cls: type) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls))


def _to_wire(msg: Any) -> dict[str, Any]:
    out = {}
    for name in _field_names(type(msg)):
        value = getattr(msg, name)
        out[name] = value if type(value) in _PLAIN or not dataclasses.is_dataclass(value) \
            else _to_wire(value)
    return out


# --------------------------------------------------------------------------- decoding
#
# Each annotation is compiled once into a converter ``value -> value`` that raises ``_Bad`` with a
# reason; containers prepend the index or field to ``_Bad.path`` on the way out. The happy path
# builds no strings, which matters for 100 Hz mocap frames (a 30-robot frame is 120 numbers).


class _Bad(Exception):
    def __init__(self, reason: str):
        self.reason = reason
        self.path = ""


Converter = Any  # Callable[[Any], Any]


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _from_wire(cls: type, body: Any, path: str) -> Any:
    try:
        return _dataclass_converter(cls)(body)
    except _Bad as bad:
        raise ProtocolError(f"{path}{bad.path}: {bad.reason}") from None


def _float(value: Any) -> float:
    if type(value) is float:
        return value
    if type(value) is int:
        return float(value)
    raise _Bad(f"expected a number, got {_show(value)}")


def _int(value: Any) -> int:
    if type(value) is int:
        return value
    raise _Bad(f"expected an integer, got {_show(value)}")


def _bool(value: Any) -> bool:
    if type(value) is bool:
        return value
    raise _Bad(f"expected true or false, got {_show(value)}")


def _str(value: Any) -> str:
    if type(value) is str:
        return value
    raise _Bad(f"expected a string, got {_show(value)}")


def _bytes(value: Any) -> bytes:
    if type(value) is bytes:
        return value
    raise _Bad(f"expected bytes, got {_show(value)}")


def _any(value: Any) -> Any:
    return value


def _map(value: Any) -> dict:
    if type(value) is dict:
        return dict(value)
    raise _Bad(f"expected a map, got {_show(value)}")


@functools.cache
def _converter(hint: Any) -> Converter:
    simple = {float: _float, int: _int, bool: _bool, str: _str, bytes: _bytes, object: _any}
    if hint in simple:
        return simple[hint]
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is Literal:
        allowed = frozenset(args)
        text = ", ".join(repr(a) for a in args)

        def literal(value: Any) -> Any:
            if type(value) in (str, int, float) and value in allowed:
                return value
            raise _Bad(f"expected one of {text}, got {_show(value)}")

        return literal
    if origin in (Union, types.UnionType):
        optional = type(None) in args
        options = [_converter(a) for a in args if a is not type(None)]

        def union(value: Any) -> Any:
            if value is None and optional:
                return None
            if len(options) == 1:
                return options[0](value)
            for option in options:
                try:
                    return option(value)
                except _Bad:
                    continue
            raise _Bad(f"unexpected {_show(value)}")

        return union
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        item = _converter(args[0])

        def variadic(value: Any) -> tuple:
            if type(value) is not list:
                raise _Bad(f"expected an array, got {_show(value)}")
            return tuple(_at(item, v, i) for i, v in enumerate(value))

        return _with_fast_path(args[0], variadic)
    if origin is tuple:
        items = tuple(_converter(a) for a in args)
        size = len(items)

        def fixed(value: Any) -> tuple:
            if type(value) is not list:
                raise _Bad(f"expected an array, got {_show(value)}")
            if len(value) != size:
                raise _Bad(f"expected {size} items, got {len(value)}")
            try:
                return tuple(convert(v) for convert, v in zip(items, value, strict=True))
            except _Bad as bad:
                index = next(i for i, (c, v) in enumerate(zip(items, value, strict=True))
                             if _fails(c, v))
                bad.path = f"[{index}]{bad.path}"
                raise

        return fixed
    if origin is dict:
        return _map
    if dataclasses.is_dataclass(hint):
        return _dataclass_converter(hint)
    raise TypeError(f"unsupported annotation {hint!r}")  # a bug in messages.py


_EXACT = (int, float, str)  # a value of exactly this type converts to itself


def _with_fast_path(item_hint: Any, general: Converter) -> Converter:
    """``general`` (a variadic tuple converter) behind a check that needs no per-item Python
    call when every item already has its exact wire type: an array of ``int``/``float``/``str``,
    or of fixed arrays of them (mocap rows ``[id, x, y, θ]``). Anything else (an int where a
    float is expected, a bool, a short row, garbage) goes through ``general``, which converts or
    raises the usual error, so the result is the same either way."""
    if item_hint in _EXACT:
        allowed = frozenset((item_hint,))

        def scalars(value: Any) -> tuple:
            if type(value) is list and allowed.issuperset(map(type, value)):
                return tuple(value)
            return general(value)

        return scalars
    if (typing.get_origin(item_hint) is tuple and (row := typing.get_args(item_hint))
            and Ellipsis not in row and all(t in _EXACT for t in row)):

        def rows(value: Any) -> tuple:
            if type(value) is list:
                for r in value:
                    if type(r) is not list or tuple(map(type, r)) != row:
                        break
                else:
                    return tuple(map(tuple, value))
            return general(value)

        return rows
    return general


def _at(convert: Converter, value: Any, index: int) -> Any:
    try:
        return convert(value)
    except _Bad as bad:
        bad.path = f"[{index}]{bad.path}"
        raise


def _fails(convert: Converter, value: Any) -> bool:
    try:
        convert(value)
    except _Bad:
        return True
    return False


@functools.cache
def _dataclass_converter(cls: type) -> Converter:
    hints = _hints(cls)
    fields = [(f.name, _converter(hints[f.name]),
               f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING)
              for f in dataclasses.fields(cls)]

    def convert(body: Any) -> Any:
        if type(body) is not dict:
            raise _Bad(f"expected a map, got {_show(body)}")
        kwargs = {}
        for name, field_converter, optional in fields:
            if name not in body:
                if optional:
                    continue
                bad = _Bad("missing")
                bad.path = f".{name}"
                raise bad
            try:
                kwargs[name] = field_converter(body[name])
            except _Bad as bad:
                bad.path = f".{name}{bad.path}"
                raise
        return cls(**kwargs)

    return convert


def _show(value: Any) -> str:
    if isinstance(value, (dict, list, tuple)):
        return f"{type(value).__name__} of {len(value)}"
    text = repr(value)
    if isinstance(value, float) and not math.isfinite(value):
        text = str(value)
    return f"{type(value).__name__} {text[:40]}"
