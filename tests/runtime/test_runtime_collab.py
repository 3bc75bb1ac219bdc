"""Core collaboration messages ↔ wire ``CollabMessage``: lossless both ways through the codec."""

from __future__ import annotations

import dataclasses
import math

import pytest
from tlfleet.agent.runtime.collab import from_wire, funnel_from_wire, funnel_to_wire, to_wire
from tlfleet.agent.stl.funnel import Funnel
from tlfleet.agent.stl.messages import CollabRelease, CollabRequest, CollabUpdate, StatusAnnounce
from tlfleet.bus.protocol.codec import ProtocolError, decode, encode
from tlfleet.bus.protocol.messages import CollabMessage, FunnelWire

FUNNEL = Funnel.init("F", 57.0, 58.0, 0.0997524, -1.5, 34.86)


def test_funnel_fields_match_the_protocol():
    assert ([f.name for f in dataclasses.fields(Funnel)]
            == [f.name for f in dataclasses.fields(FunnelWire)])
    assert funnel_from_wire(funnel_to_wire(FUNNEL)) == FUNNEL
    assert funnel_to_wire(FUNNEL).t_r == 34.86


@pytest.mark.parametrize("message", [
    CollabRequest(3, 4, 1, FUNNEL, c=3),
    CollabUpdate(3, 4, 1, FUNNEL.repair(3, FUNNEL.lower(35.0), 35.0)),
    CollabRelease(3, 4, 1),
    StatusAnnounce(3, 4, c=0, subtask=1, kind="F", a=57.0, b=58.0),
    StatusAnnounce(3, 4, c=-1, subtask=2, kind="G", a=21.0, b=30.0, all_done=True),
])
def test_round_trip_through_the_codec(message):
    wire = to_wire(message, 34.86)
    assert wire.t == 34.86 and wire.sender == 3 and wire.receiver == 4
    assert from_wire(decode(CollabMessage, encode(wire))) == message


def test_status_without_an_active_subtask():
    idle = StatusAnnounce(5, 4, c=0, subtask=0, kind=None, a=math.nan, b=math.nan)
    wire = to_wire(idle, 1.0)
    assert wire.kind == "status" and wire.task_kind == ""
    back = from_wire(decode(CollabMessage, encode(wire)))
    assert back.kind is None and math.isnan(back.a) and math.isnan(back.b)
    assert back.relevant_deadline != back.relevant_deadline  # NaN: never "later than b_i"


@pytest.mark.parametrize("kind", ["request", "update"])
def test_a_request_or_update_without_funnel_is_a_protocol_error(kind):
    with pytest.raises(ProtocolError, match=f"a {kind} needs a funnel"):
        from_wire(CollabMessage(kind, 3, 4, 0.0, 0))


def test_only_collaboration_messages_convert():
    with pytest.raises(TypeError, match="not a collaboration message"):
        to_wire("hello", 0.0)
