"""Frozen dataclasses to JSON and back, driven by their annotations: the one codec of the run
record (``summary.json``, ``report.json``; :mod:`tlfleet.coordinator.record.run_record`).

:func:`to_json` turns a dataclass into plain JSON data: an object per dataclass with one key per
field in declaration order, tuples as arrays, mappings as objects with string keys (an ``int`` key
as its decimal text), paths as strings; floats stay floats (±inf and NaN become ``"inf"`` /
``"-inf"`` / null only when written, :func:`tlfleet.coordinator.record.rundir.json_ready`).
:func:`from_json` reads that data back into the annotated type and checks every value on the way,
raising :class:`RecordError` with the field's path (``stl.3.subtasks[1].r_bar``) and what was
expected; keys the type does not declare are ignored (written by a newer schema of the same
record), fields with a default may be missing (an older one).

A class may take over its own form with a ``to_json(self)`` method and a ``from_json(cls, value)``
classmethod (derived values written beside the fields, a schema number checked on the way in).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, TypeVar, Union

from tlfleet.bus.errors import TlfleetError

T = TypeVar("T")

#: what :func:`to_json` returns and :func:`from_json` reads: JSON data as Python values
Json = None | bool | int | float | str | list["Json"] | dict[str, "Json"]


class RecordError(TlfleetError, ValueError):
    """A value that does not fit the record's type: ``where`` is the field's path."""

    def __init__(self, where: str, message: str) -> None:
        super().__init__(f"{where or 'the record'}: {message}")
        self.where, self.message = where, message


def to_json(value: object) -> Json:
    """``value`` (a dataclass, or what its fields hold) as JSON data (module docstring)."""
    custom = getattr(value, "to_json", None)
    if custom is not None and dataclasses.is_dataclass(value):
        return custom()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return fields_to_json(value)
    if isinstance(value, Mapping):
        return {str(k): to_json(v) for k, v in value.items()}
    if isinstance(value, tuple | list):
        return [to_json(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, bool | int | float | str):
        return value
    raise TypeError(f"not JSON data: {type(value).__name__}")


def fields_to_json(value: object) -> dict[str, Json]:
    """The fields of the dataclass ``value`` as a JSON object, without its own ``to_json``."""
    return {f.name: to_json(getattr(value, f.name)) for f in dataclasses.fields(value)}


def from_json(kind: type[T], value: object, where: str = "") -> T:
    """``value`` (JSON data) read as ``kind``; :class:`RecordError` when it does not fit."""
    return _read(kind, value, where)


def fields_from_json(kind: type[T], value: object, where: str = "") -> T:
    """The dataclass ``kind`` from the JSON object ``value``, without its own ``from_json``."""
    if not isinstance(value, Mapping):
        raise RecordError(where, f"expected an object ({kind.__name__}), got {_what(value)}")
    hints = _hints(kind)
    values: dict[str, object] = {}
    for f in dataclasses.fields(kind):
        if not f.init:
            continue
        if f.name not in value:
            if (f.default is dataclasses.MISSING
                    and f.default_factory is dataclasses.MISSING):
                raise RecordError(_join(where, f.name), "missing")
            continue
        values[f.name] = _read(hints[f.name], value[f.name], _join(where, f.name))
    return kind(**values)


@functools.cache
def _hints(kind: type) -> dict[str, object]:
    return typing.get_type_hints(kind)


def _join(where: str, name: str) -> str:
    return f"{where}.{name}" if where else name


def _what(value: object) -> str:
    return "null" if value is None else f"{type(value).__name__} {value!r:.40}"


def _read(kind: Any, value: object, where: str) -> Any:
    origin = typing.get_origin(kind)
    if kind is Any or kind is object:
        return value
    if origin in (Union, types.UnionType):
        return _read_union(typing.get_args(kind), value, where)
    if origin is Literal:
        if value not in typing.get_args(kind):
            raise RecordError(where, f"expected one of {typing.get_args(kind)}, got "
                                     f"{_what(value)}")
        return value
    if origin is tuple:
        return _read_tuple(typing.get_args(kind), value, where)
    if origin in (Mapping, dict, typing.Mapping):
        key_kind, value_kind = typing.get_args(kind)
        if not isinstance(value, Mapping):
            raise RecordError(where, f"expected an object, got {_what(value)}")
        return {_read_key(key_kind, k, where): _read(value_kind, v, _join(where, str(k)))
                for k, v in value.items()}
    if isinstance(kind, type) and dataclasses.is_dataclass(kind):
        custom = kind.__dict__.get("from_json")
        if custom is not None:
            return kind.from_json(value, where)
        return fields_from_json(kind, value, where)
    return _read_scalar(kind, value, where)


def _read_union(options: tuple[Any, ...], value: object, where: str) -> Any:
    if value is None and type(None) in options:
        return None
    errors = []
    for option in options:
        if option is type(None):
            continue
        try:
            return _read(option, value, where)
        except RecordError as exc:
            errors.append(str(exc).removeprefix(f"{where}: "))
    raise RecordError(where, " or ".join(errors) if errors else f"got {_what(value)}")


def _read_tuple(args: tuple[Any, ...], value: object, where: str) -> tuple[Any, ...]:
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise RecordError(where, f"expected an array, got {_what(value)}")
    if len(args) == 2 and args[1] is Ellipsis:
        return tuple(_read(args[0], v, f"{where}[{k}]") for k, v in enumerate(value))
    if len(value) != len(args):
        raise RecordError(where, f"expected {len(args)} items, got {len(value)}")
    return tuple(_read(a, v, f"{where}[{k}]") for k, (a, v) in enumerate(zip(args, value,
                                                                             strict=True)))


def _read_key(kind: Any, key: object, where: str) -> Any:
    if kind is int:
        if isinstance(key, str) and key.lstrip("-").isdigit():
            return int(key)
        raise RecordError(where, f"expected an integer key, got {key!r}")
    return _read(kind, key, where)


def _read_scalar(kind: Any, value: object, where: str) -> Any:
    if kind is float:
        if isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
        if value in ("inf", "-inf"):  # how json_ready writes ±inf
            return math.inf if value == "inf" else -math.inf
        raise RecordError(where, f"expected a number, got {_what(value)}")
    if kind is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise RecordError(where, f"expected an integer, got {_what(value)}")
    if kind is bool or kind is str:
        if isinstance(value, kind):
            return value
        raise RecordError(where, f"expected {'true or false' if kind is bool else 'a string'}, "
                                 f"got {_what(value)}")
    if kind is Path:
        if isinstance(value, str):
            return Path(value)
        raise RecordError(where, f"expected a path, got {_what(value)}")
    raise TypeError(f"{where}: no JSON form for {kind!r}")
