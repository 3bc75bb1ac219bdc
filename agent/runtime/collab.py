"""Conversions between the STL core's collaboration messages and the wire protocol.

``tlfleet.agent.stl.messages`` (what the pure step reads and writes) ↔
``tlfleet.bus.protocol.messages`` (what travels on ``robot/<id>/collab``, stl-funnel.md §7.5,
architecture.md §2):

=====================  =================================================================
core message           ``CollabMessage`` kind and fields
=====================  =================================================================
``CollabRequest``      ``request``: subtask, funnel (``FunnelWire``, t_r included), c
``CollabUpdate``       ``update``: subtask, funnel
``CollabRelease``      ``release``: subtask
``StatusAnnounce``     ``status``: c, subtask, task_kind ("" = no active sub-task), a, b [s],
                       all_done
=====================  =================================================================

The funnel travels whole: ``tlfleet.agent.stl.funnel.Funnel`` and the protocol's ``FunnelWire`` have
the same twelve fields (kind, a, b [s], ρ_opt, ρ_max, r, γ_0, γ_∞, l [1/s], t* [s], t_r [s], ζ_u).
"""

from __future__ import annotations

import dataclasses
import math

from tlfleet.agent.stl.funnel import Funnel
from tlfleet.agent.stl.messages import (
    CollabRelease,
    CollabRequest,
    CollabUpdate,
    Message,
    StatusAnnounce,
)
from tlfleet.bus.protocol.codec import ProtocolError
from tlfleet.bus.protocol.messages import CollabMessage, FunnelWire

_FUNNEL_FIELDS = tuple(f.name for f in dataclasses.fields(Funnel))  # = FunnelWire's (tested)


def funnel_to_wire(funnel: Funnel) -> FunnelWire:
    return FunnelWire(**{name: getattr(funnel, name) for name in _FUNNEL_FIELDS})


def funnel_from_wire(params: FunnelWire) -> Funnel:
    return Funnel(**{name: getattr(params, name) for name in _FUNNEL_FIELDS})


def to_wire(message: Message, t: float) -> CollabMessage:
    """The protocol message for a core message sent at sim time ``t`` [s]."""
    match message:
        case CollabRequest(sender=s, receiver=r, subtask=k, funnel=f, c=c):
            return CollabMessage("request", s, r, t, k, funnel_to_wire(f), c=c)
        case CollabUpdate(sender=s, receiver=r, subtask=k, funnel=f):
            return CollabMessage("update", s, r, t, k, funnel_to_wire(f))
        case CollabRelease(sender=s, receiver=r, subtask=k):
            return CollabMessage("release", s, r, t, k)
        case StatusAnnounce():
            return CollabMessage("status", message.sender, message.receiver, t, message.subtask,
                                 c=message.c, task_kind=message.kind or "", a=message.a,
                                 b=message.b, all_done=message.all_done)
    raise TypeError(f"not a collaboration message: {type(message).__name__}")


def from_wire(msg: CollabMessage) -> Message:
    """The core message of a decoded ``CollabMessage``; ``ProtocolError`` when a request or an
    update carries no funnel (the codec cannot tell: the field is optional on the wire)."""
    if msg.kind in ("request", "update"):
        if msg.funnel is None:
            raise ProtocolError(f"CollabMessage.funnel: a {msg.kind} needs a funnel")
        funnel = funnel_from_wire(msg.funnel)
        if msg.kind == "request":
            return CollabRequest(msg.sender, msg.receiver, msg.subtask, funnel, c=msg.c)
        return CollabUpdate(msg.sender, msg.receiver, msg.subtask, funnel)
    if msg.kind == "release":
        return CollabRelease(msg.sender, msg.receiver, msg.subtask)
    kind = msg.task_kind or None
    return StatusAnnounce(sender=msg.sender, receiver=msg.receiver, c=msg.c, subtask=msg.subtask,
                          kind=kind, a=msg.a if kind else math.nan, b=msg.b if kind else math.nan,
                          all_done=msg.all_done)
