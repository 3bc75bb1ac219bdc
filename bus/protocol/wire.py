"""What every encoding of a message shares (architecture.md §2): the schema version each payload
carries as ``v``, and msgpack's fallback for numpy values. Both the generic codec
(:mod:`tlfleet.bus.protocol.codec`) and its straight-line paths
(:mod:`tlfleet.bus.protocol.fast_paths`) encode with these, so the two cannot drift apart."""

from __future__ import annotations

from typing import Any

SCHEMA_VERSION = 1


def to_plain(value: Any) -> Any:
    """msgpack fallback: numpy scalars and arrays become Python numbers and lists."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"cannot encode {type(value).__name__}")
