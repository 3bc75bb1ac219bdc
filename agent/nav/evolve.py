"""``evolve``: :func:`dataclasses.replace` for the immutable states an agent steps every tick.

``replace`` builds the new instance through ``__init__``; for the 24 fields of the navigation's
``ExecutorState`` that costs ≈ 7.5 µs, and an LTL step made four or five of them (issue 17: the
step is on the fleet's latency path). ``evolve`` copies the instance's ``__dict__`` and
overwrites the changed fields: ≈ 1.1 µs, the same new instance.

That is only the same as ``replace`` where ``__init__`` does nothing but assign, so ``evolve``
takes only frozen dataclasses without slots, ``__post_init__``, fields left out of ``__init__``
or cached properties (whose cached values a copied ``__dict__`` would carry over), checked once
per class; an unknown field name is a ``TypeError``, as with ``replace``.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, TypeVar

T = TypeVar("T")


@functools.cache
def _field_names(cls: type) -> frozenset[str]:
    if not (dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen):
        raise TypeError(f"evolve: {cls.__name__} is not a frozen dataclass")
    if "__slots__" in cls.__dict__ or hasattr(cls, "__post_init__"):
        raise TypeError(f"evolve: {cls.__name__} has slots or __post_init__; use "
                        "dataclasses.replace")
    fields = dataclasses.fields(cls)
    if any(not f.init for f in fields):
        raise TypeError(f"evolve: {cls.__name__} has fields outside __init__; use "
                        "dataclasses.replace")
    if any(isinstance(v, functools.cached_property) for k in cls.__mro__ for v in vars(k).values()):
        raise TypeError(f"evolve: {cls.__name__} has cached properties; use dataclasses.replace")
    return frozenset(f.name for f in fields)


def evolve(instance: T, **changes: Any) -> T:
    """A copy of the frozen dataclass ``instance`` with ``changes`` applied."""
    cls = type(instance)
    names = _field_names(cls)
    if not changes.keys() <= names:
        raise TypeError(f"evolve: {cls.__name__} has no field {sorted(changes.keys() - names)}")
    new = object.__new__(cls)
    state = new.__dict__
    state.update(instance.__dict__)
    state.update(changes)
    return new
