"""The codec is total: for arbitrary bytes and for arbitrary structurally valid msgpack,
``decode`` returns a valid message or raises ``ProtocolError`` — never anything else; bounds on
sizes, nesting, lengths and every number; the schema version is an exact integer."""

from __future__ import annotations

import dataclasses
import math

import msgpack
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.bus.protocol import messages
from tlfleet.bus.protocol.bounds import LIMITS, FleetBounds, check_message
from tlfleet.bus.protocol.codec import SCHEMA_VERSION, ProtocolError, decode, encode, peek_kind
from tlfleet.bus.protocol.messages import Command, Event, LtlStatus, MocapFrame, StlStatus

KINDS = [messages.Clock, messages.MocapFrame, messages.Command, messages.LtlStatus,
         messages.StlStatus, messages.CollabMessage, messages.CollabReply, messages.Event,
         messages.Control, messages.BackfillRequest, messages.BackfillReply]


def decode_or_protocol_error(cls, data):
    """The property: a valid message of ``cls`` or ProtocolError; anything else fails."""
    try:
        msg = decode(cls, data)
    except ProtocolError:
        return None
    assert type(msg) is cls
    check_message(msg)  # a returned message is within its declared bounds
    assert decode(cls, encode(msg)) is not None  # and re-encodes
    return msg


@settings(max_examples=examples(200), deadline=None)
@given(st.sampled_from(KINDS), st.binary(max_size=512))
def test_arbitrary_bytes_decode_or_raise_the_codec_error(cls, data):
    decode_or_protocol_error(cls, data)


scalars = (st.none() | st.booleans() | st.integers(-(2 ** 63), 2 ** 64 - 1)
           | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=20)
           | st.binary(max_size=20))
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=5)
                      | st.dictionaries(st.text(max_size=8), inner, max_size=5), max_leaves=15)


def field_names(cls):
    names = [f.name for f in dataclasses.fields(cls)]
    if cls is messages.CollabMessage:
        names += [f.name for f in dataclasses.fields(messages.FunnelWire)]
    return names


@st.composite
def message_shaped(draw):
    """A map that looks like a message: a version (sometimes wrong), a kind, and the kind's
    field names with arbitrary values, some fields dropped, some foreign ones added."""
    cls = draw(st.sampled_from(KINDS))
    body = {"v": draw(st.sampled_from([SCHEMA_VERSION, 1.0, True, 2, "1", None])),
            "k": draw(st.sampled_from([cls.__name__, cls.__name__, "Event", "x"]))}
    for name in field_names(cls):
        if draw(st.integers(0, 5)):
            body[name] = draw(values)
    return cls, body


@settings(max_examples=examples(300), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(message_shaped())
def test_structurally_valid_msgpack_decodes_or_raises_the_codec_error(case):
    cls, body = case
    decode_or_protocol_error(cls, msgpack.packb(body, use_bin_type=True))


@settings(max_examples=examples(200), deadline=None)
@given(st.sampled_from(KINDS), values)
def test_arbitrary_msgpack_values_decode_or_raise(cls, value):
    decode_or_protocol_error(cls, msgpack.packb(value, use_bin_type=True))


def pack(**fields):
    return msgpack.packb({"v": SCHEMA_VERSION, **fields}, use_bin_type=True)


def nested(depth):
    value: object = 0
    for _ in range(depth):
        value = [value]
    return value


CONTROL_OK = dict(k="Control", cmd="start", t0=0.0)
MOCAP_OK = dict(k="MocapFrame", t=0.5, seq=50, poses=[[1, 0.0, 0.0, 0.0]])

# (class, payload, what the error says): each one crashed or fooled a receiver on main
HOSTILE = [
    (messages.Control, pack(k="Control", cmd=["start"], t0=0.0), r"Control.cmd: expected one of"),
    (messages.Control, pack(k="Control", cmd=nested(900), t0=0.0), "Control: payload"),
    (Event, pack(k="Event", t=0.0, source="x", kind="y", data={"a": nested(900)}), "Event"),
    (Event, pack(k="Event", t=0.0, source="x", kind="y", data={"a": nested(9)}),
     r"Event.data.*nested deeper than 8"),
    (Event, pack(k="Event", t=0.0, source=nested(900), kind="y", data={}), "Event"),
    (MocapFrame, pack(k="MocapFrame", t=0.5, seq=50, poses=[[1, math.nan, 0.0, 0.0]]),
     r"MocapFrame.poses\[0\]\[1\]: not a finite number"),
    (MocapFrame, pack(k="MocapFrame", t=0.5, seq=50, poses=[[1, math.inf, 0.0, 0.0]]),
     r"MocapFrame.poses\[0\]\[1\]: inf is not a finite number"),
    (MocapFrame, pack(k="MocapFrame", t=1e9, seq=50, poses=[]), r"MocapFrame.t: .* outside"),
    (MocapFrame, pack(k="MocapFrame", t=-1.0, seq=50, poses=[]), r"MocapFrame.t: .* outside"),
    (MocapFrame, pack(k="MocapFrame", t=0.5, seq=-5, poses=[]), r"MocapFrame.seq: -5"),
    (MocapFrame, pack(k="MocapFrame", t=0.5, seq=1, poses=[[1, 0.0, 0.0, 0.0]] * 5000),
     "not a msgpack payload"),
    (Command, pack(k="Command", robot=3, t=0.5, seq=50, u=[1e308, 0.0, 0.0]),
     r"Command.u\[0\]: 1e\+308 is outside"),
    (Command, pack(k="Command", robot=3, t=0.5, seq=50, u=[math.nan, 0.0]),
     r"Command.u\[0\]: not a finite number"),
    (StlStatus, pack(k="StlStatus", robot=3, t=1.0, subtask=0, rho=math.inf, rho_max=0.1,
                     lower=0.0, r=0.0, stage=0, ce=0, c=0, follow=-1),
     r"StlStatus.rho: inf is not a finite number"),
    (LtlStatus, pack(k="LtlStatus", robot=1, t=1.0, prefix=["a" * 1_000_000], suffix=[],
                     target=None, buchi_states=[], visits=[], rounds=0, mode="x"),
     "exceeds"),
    (messages.Control, pack(**CONTROL_OK) + b"\x00" * 300, "exceeds 256"),
    (messages.Control, msgpack.packb({"v": 1.0, **CONTROL_OK}), "schema version 1.0"),
    (messages.Control, msgpack.packb({"v": True, **CONTROL_OK}), "schema version True"),
    (messages.Control, msgpack.packb({"v": [1], **CONTROL_OK}), "schema version a list"),
    (MocapFrame, msgpack.packb({"v": 1, **MOCAP_OK, "k": nested(900)}), "MocapFrame"),
    # the backfill's request and reply
    (messages.BackfillRequest, pack(k="BackfillRequest", first=10, last=3),
     r"BackfillRequest.last: 3 is outside \[10, "),
    (messages.BackfillRequest, pack(k="BackfillRequest", first=-1, last=3),
     r"BackfillRequest.first: -1 is outside"),
    (messages.BackfillRequest, pack(k="BackfillRequest", first=1.0, last=3),
     r"BackfillRequest.first: expected an integer, got float"),
    (messages.BackfillRequest, pack(k="BackfillRequest", first=1),
     r"BackfillRequest.last: missing"),
    (messages.BackfillRequest, pack(k="BackfillRequest", first=2 ** 60, last=2 ** 60),
     r"BackfillRequest.first: \d+ is outside"),
    (messages.BackfillReply, pack(k="BackfillReply", first=0, last=0, oldest=-2, frames=[]),
     r"BackfillReply.oldest: -2 is outside"),
    (messages.BackfillReply, pack(k="BackfillReply", first=5, last=6, oldest=0,
                                  frames=[b"a", b"b", b"c"]),
     r"BackfillReply.frames: 3 frames for the 2 seqs 5..6"),
    (messages.BackfillReply, pack(k="BackfillReply", first=0, last=9, oldest=0,
                                  frames=["not bytes"]),
     r"BackfillReply.frames\[0\]: expected bytes, got str"),
    (messages.BackfillReply, pack(k="BackfillReply", first=0, last=9, oldest=0, frames=b"x"),
     r"BackfillReply.frames: expected an array, got bytes"),
    (messages.BackfillReply, pack(k="BackfillReply", first=0, last=9, oldest=0,
                                  frames=[b"x" * (LIMITS["BackfillReply"].max_str + 1)]),
     "not a msgpack payload"),
    (messages.BackfillReply, pack(k="BackfillReply", first=0, last=9000, oldest=0,
                                  frames=[b""] * 5000), "not a msgpack payload"),
    (messages.BackfillReply, pack(k="BackfillReply", first=0, last=9, oldest=0,
                                  frames=[b"x" * 200_000] * 11), "exceeds"),
]


@pytest.mark.parametrize(("cls", "payload", "message"), HOSTILE,
                         ids=[f"{i}-{h[0].__name__}" for i, h in enumerate(HOSTILE)])
def test_hostile_payloads_raise_the_codec_error_naming_the_field(cls, payload, message):
    with pytest.raises(ProtocolError, match=message):
        decode(cls, payload)


def test_non_bytes_and_huge_inputs_are_codec_errors():
    with pytest.raises(ProtocolError, match="expected bytes, got str"):
        decode(messages.Control, "not bytes")  # type: ignore[arg-type]
    with pytest.raises(ProtocolError, match="exceeds"):
        decode(MocapFrame, b"\x00" * (LIMITS["MocapFrame"].max_bytes + 1))
    assert peek_kind(b"\x91" * 5000) is None


def test_documented_nan_fields_still_decode():
    idle = StlStatus(3, 2.0, 0, math.nan, math.nan, math.nan, math.nan, 0, 0, 0, -1)
    assert math.isnan(decode(StlStatus, encode(idle)).rho)


BOUNDS = FleetBounds(box=(-3.5, 3.5, -3.5, 3.5), duration=90.0, mocap_rate=100.0,
                     limits={1: (0.3, 1.0), 3: (0.2, 6.28)})


@pytest.mark.parametrize(("frame", "problem"), [
    (MocapFrame(0.5, 50, ((1, 0.0, 0.0, 0.0), (3, 1.0, 1.0, 0.0))), None),
    (MocapFrame(0.0, 0, ((1, 0.0, 0.0, 0.0),)), None),
    (MocapFrame(95.0, 9500, ()), "outside the run"),
    (MocapFrame(0.5, 5000, ()), "does not match seq 5000"),
    (MocapFrame(0.5, 50, ((2, 0.0, 0.0, 0.0),)), "unknown robot 2"),
    (MocapFrame(0.5, 50, ((3, 0.0, 0.0, 0.0), (1, 0.0, 0.0, 0.0))), "not strictly ascending"),
    (MocapFrame(0.5, 50, ((1, 50.0, 0.0, 0.0),)), "outside the arena"),
    (MocapFrame(0.5, 50, ((1, 0.0, 0.0, 100.0),)), "not wrapped"),
    (MocapFrame(0.5, 50, ((1, 0.0, 0.0, 0.0),), due=(7,)), "due robot 7"),
])
def test_fleet_bounds_of_frames(frame, problem):
    found = BOUNDS.frame_problem(frame)
    assert (found is None) if problem is None else (problem in found)


@pytest.mark.parametrize(("command", "problem"), [
    (Command(3, 0.5, 50, (0.2, 0.0, 1.0)), None),
    (Command(3, 0.0, -1, (0.0, 0.0, 0.0)), None),  # the stale stop before any frame
    (Command(3, 0.5, 50, (25.0, 0.0, 0.0)), "exceeds 100× the robot's limit 0.2"),
    (Command(1, 0.5, 50, (0.3, 500.0)), "exceeds"),
    (Command(3, 0.5, 51, (0.0, 0.0, 0.0)), "does not match seq"),
    (Command(9, 0.5, 50, (0.0, 0.0, 0.0)), None),  # unknown robots: counted by the sim
])
def test_fleet_bounds_of_commands(command, problem):
    found = BOUNDS.command_problem(command)
    assert (found is None) if problem is None else (problem in found)


def test_backfill_messages_round_trip_and_a_reply_carries_frames_as_published():
    frames = tuple(encode(MocapFrame(k / 100, k, ((1, 0.5 * k, -1.0, 0.25),))) for k in (3, 5))
    reply = messages.BackfillReply(first=3, last=6, oldest=2, frames=frames)
    assert decode(messages.BackfillReply, encode(reply)) == reply
    assert [decode(MocapFrame, f).seq for f in reply.frames] == [3, 5]
    request = messages.BackfillRequest(first=7, last=7)
    assert decode(messages.BackfillRequest, encode(request)) == request
    with pytest.raises(ProtocolError, match="payload is a 'BackfillRequest' message"):
        decode(messages.BackfillReply, encode(request))
