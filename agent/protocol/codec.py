"""The one codec of tlfleet messages: ``encode(msg) -> bytes``, ``decode(T, data) -> T``.

Wire format (msgpack map, string keys): ``{"v": SCHEMA_VERSION, "k": "<type name>", <fields>}``.
Tuples travel as arrays, nested dataclasses as maps, ``None`` as nil. ``decode`` checks the
version, the kind and the type of every field against the dataclass annotations and raises
``ProtocolError`` naming the message, the field path and what was expected, so a malformed or
foreign payload is rejected whole and never half-applied.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from typing import Any, Literal, TypeVar, Union

import msgpack

from agent.errors import TlfleetError
from agent.protocol import messages

SCHEMA_VERSION = 1
T = TypeVar("T")

_KINDS: dict[str, type] = {
    cls.__name__: cls
    for cls in (messages.Clock, messages.MocapFrame, messages.Command, messages.LtlStatus,
                messages.StlStatus, messages.CollabMessage, messages.CollabReply,
                messages.Event, messages.Control)
}


class ProtocolError(TlfleetError, ValueError):
    """A payload that is not a valid message of the expected type and schema version."""


def encode(msg: Any) -> bytes:
    """Serialise one message dataclass."""
    kind = type(msg).__name__
    if _KINDS.get(kind) is not type(msg):
        raise TypeError(f"not a protocol message: {type(msg).__name__}")
    body = {"v": SCHEMA_VERSION, "k": kind}
    body.update(_to_wire(msg))
    return msgpack.packb(body, use_bin_type=True, default=_default)


def decode(cls: type[T], data: bytes) -> T:
    """Parse ``data`` as a message of type ``cls``; ``ProtocolError`` on anything else."""
    try:
        body = msgpack.unpackb(data, raw=False, strict_map_key=True)
    except Exception as exc:  # msgpack raises several unrelated types on garbage
        raise ProtocolError(f"{cls.__name__}: not a msgpack payload ({exc})") from None
    if not isinstance(body, dict):
        raise ProtocolError(f"{cls.__name__}: expected a map, got {type(body).__name__}")
    version = body.get("v")
    if version != SCHEMA_VERSION:
        raise ProtocolError(f"{cls.__name__}: schema version {version!r}, expected "
                            f"{SCHEMA_VERSION}")
    if body.get("k") != cls.__name__:
        raise ProtocolError(f"{cls.__name__}: payload is a {body.get('k')!r} message")
    return _from_wire(cls, body, cls.__name__)


def peek_kind(data: bytes) -> str | None:
    """The message kind of a payload, or ``None`` when it is not a tlfleet message."""
    try:
        body = msgpack.unpackb(data, raw=False)
    except Exception:
        return None
    return body.get("k") if isinstance(body, dict) and isinstance(body.get("k"), str) else None


# --------------------------------------------------------------------------- encoding


def _to_wire(msg: Any) -> dict[str, Any]:
    out = {}
    for f in dataclasses.fields(msg):
        value = getattr(msg, f.name)
        out[f.name] = _to_wire(value) if dataclasses.is_dataclass(value) else value
    return out


def _default(value: Any) -> Any:
    """msgpack fallback: numpy scalars and arrays become Python numbers and lists."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"cannot encode {type(value).__name__}")


# --------------------------------------------------------------------------- decoding


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _from_wire(cls: type, body: Any, path: str) -> Any:
    if not isinstance(body, dict):
        raise ProtocolError(f"{path}: expected a map, got {_show(body)}")
    kwargs = {}
    for f in dataclasses.fields(cls):
        where = f"{path}.{f.name}"
        if f.name not in body:
            if f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING:
                continue
            raise ProtocolError(f"{where}: missing")
        kwargs[f.name] = _convert(_hints(cls)[f.name], body[f.name], where)
    return cls(**kwargs)


def _convert(hint: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ProtocolError(f"{where}: expected a number, got {_show(value)}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ProtocolError(f"{where}: expected an integer, got {_show(value)}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise ProtocolError(f"{where}: expected true or false, got {_show(value)}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ProtocolError(f"{where}: expected a string, got {_show(value)}")
        return value
    if hint is object:
        return value
    if origin is Literal:
        if value not in typing.get_args(hint):
            allowed = ", ".join(repr(a) for a in typing.get_args(hint))
            raise ProtocolError(f"{where}: expected one of {allowed}, got {_show(value)}")
        return value
    if origin in (Union, types.UnionType):
        args = typing.get_args(hint)
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, where)
            except ProtocolError as exc:
                errors.append(str(exc))
        if len(errors) == 1:
            raise ProtocolError(errors[0])
        raise ProtocolError(f"{where}: unexpected {_show(value)}")
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ProtocolError(f"{where}: expected an array, got {_show(value)}")
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ProtocolError(f"{where}: expected {len(args)} items, got {len(value)}")
        return tuple(_convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value,
                                                                                        strict=True)))
    if origin is dict:
        if not isinstance(value, dict):
            raise ProtocolError(f"{where}: expected a map, got {_show(value)}")
        return dict(value)
    if dataclasses.is_dataclass(hint):
        return _from_wire(hint, value, where)
    raise TypeError(f"{where}: unsupported annotation {hint!r}")  # a bug in messages.py


def _show(value: Any) -> str:
    text = repr(value)
    if isinstance(value, float) and not math.isfinite(value):
        text = str(value)
    return f"{type(value).__name__} {text[:40]}"
