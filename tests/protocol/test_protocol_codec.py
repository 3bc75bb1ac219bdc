"""Codec: every message round-trips; malformed, foreign or wrong-version payloads are rejected
with a ProtocolError naming the field; keys come from one module."""

from __future__ import annotations

import math

import msgpack
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import SCHEMA_VERSION, ProtocolError, decode, encode, peek_kind
from tlfleet.bus.protocol.messages import (
    Clock,
    CollabMessage,
    CollabReply,
    Command,
    Control,
    Event,
    FunnelWire,
    LtlStatus,
    MocapFrame,
    StlStatus,
)

FUNNEL = FunnelWire("F", 57.0, 58.0, 0.0997524, 0.095, -0.0144, 0.3, 0.04, 0.25, 58.0,
                      34.86, 0.005)
EXAMPLES = [
    Clock(1.25, 125, "lockstep"),
    MocapFrame(0.5, 50, ((1, -2.0, -2.5, 1.5707963), (3, -0.5, -1.0, 0.0)), due=(3,)),
    Command(3, 0.5, 50, (0.1, -0.2, 0.0)),
    LtlStatus(1, 2.0, ("a11", "a12"), ("a12", "a11"), "a12", (0, 1), (("a11", 1),), 0, "navigate"),
    StlStatus(3, 2.0, 0, math.nan, math.nan, math.nan, math.nan, 0, 0, 0, -1),
    StlStatus(4, 30.0, 1, -0.2, 0.09, -0.5, -1.0, 3, 58, 0, -1, (2, 0, 56)),
    CollabMessage("request", 3, 4, 34.86, 1, FUNNEL, c=3),
    CollabMessage("status", 4, 3, 31.0, 1, c=0, task_kind="F", a=83.0, b=87.0),
    CollabReply(False, "already following robot 5"),
    Event(12.5, "agent/4", "repair", {"stage": 3, "r": -0.02}),
    Control("start", 0.0),
]


@pytest.mark.parametrize("msg", EXAMPLES, ids=lambda m: type(m).__name__)
def test_round_trip(msg):
    back = decode(type(msg), encode(msg))
    assert type(back) is type(msg)
    assert repr(back) == repr(msg)  # repr: NaN fields compare equal as text
    assert peek_kind(encode(msg)) == type(msg).__name__


@given(st.lists(st.tuples(st.integers(1, 99), st.floats(-5, 5), st.floats(-5, 5),
                          st.floats(-4, 4)), max_size=40),
       st.floats(0, 1e4), st.integers(0, 2**40))
def test_mocap_frames_round_trip(rows, t, seq):
    frame = MocapFrame(t, seq, tuple(rows))
    assert decode(MocapFrame, encode(frame)) == frame


def raw(**fields):
    return msgpack.packb(fields, use_bin_type=True)


BAD = [
    (MocapFrame, b"\xc1garbage", "MocapFrame: not a msgpack payload"),
    (MocapFrame, msgpack.packb([1, 2]), "MocapFrame: expected a map, got list"),
    (MocapFrame, raw(v=99, k="MocapFrame", t=0.0, seq=1, poses=[]),
     "MocapFrame: schema version 99, expected 1"),
    (MocapFrame, raw(k="MocapFrame", t=0.0, seq=1, poses=[]), "schema version None"),
    (MocapFrame, raw(v=SCHEMA_VERSION, k="Command", robot=1, t=0.0, seq=1, u=[0.0]),
     "MocapFrame: payload is a 'Command' message"),
    (MocapFrame, raw(v=SCHEMA_VERSION, k="MocapFrame", t=0.0, poses=[]),
     r"MocapFrame.seq: missing"),
    (MocapFrame, raw(v=SCHEMA_VERSION, k="MocapFrame", t="now", seq=1, poses=[]),
     "MocapFrame.t: expected a number, got str 'now'"),
    (MocapFrame, raw(v=SCHEMA_VERSION, k="MocapFrame", t=0.0, seq=1, poses=[[1, 0.0, 0.0]]),
     r"MocapFrame.poses\[0\]: expected 4 items, got 3"),
    (MocapFrame, raw(v=SCHEMA_VERSION, k="MocapFrame", t=0.0, seq=1, poses=[[1.5, 0, 0, 0]]),
     r"MocapFrame.poses\[0\]\[0\]: expected an integer, got float 1.5"),
    (Command, raw(v=SCHEMA_VERSION, k="Command", robot=True, t=0.0, seq=1, u=[0.0]),
     "Command.robot: expected an integer, got bool True"),
    (Clock, raw(v=SCHEMA_VERSION, k="Clock", t=0.0, tick=1, mode="warp"),
     "Clock.mode: expected one of 'lockstep', 'realtime', got str 'warp'"),
    (CollabMessage, raw(v=SCHEMA_VERSION, k="CollabMessage", kind="request", sender=3, receiver=4,
                        t=1.0, subtask=0, funnel={"kind": "F"}),
     r"CollabMessage.funnel.a: missing"),
    (Control, raw(v=SCHEMA_VERSION, k="Control", cmd="pause"), "Control.cmd: expected one of"),
    (MocapFrame, raw(v=SCHEMA_VERSION, k="MocapFrame", t=0.0, seq=1,
                     poses=[[1, 0.0, 0.0, 0.0], [True, 0.0, 0.0, 0.0]]),
     r"MocapFrame.poses\[1\]\[0\]: expected an integer, got bool True"),
    (MocapFrame, raw(v=SCHEMA_VERSION, k="MocapFrame", t=0.0, seq=1, poses=[(1, 0.0, 0.0, "x")]),
     r"MocapFrame.poses\[0\]\[3\]: expected a number, got str 'x'"),
    (MocapFrame, raw(v=SCHEMA_VERSION, k="MocapFrame", t=0.0, seq=1, poses=[[1, 0.0, 0.0, 0.0]],
                     due=[3, 4.0]), r"MocapFrame.due\[1\]: expected an integer, got float 4.0"),
    (Command, raw(v=SCHEMA_VERSION, k="Command", robot=1, t=0.0, seq=1, u=[0.0, None]),
     r"Command.u\[1\]: expected a number, got NoneType None"),
]


@pytest.mark.parametrize(("cls", "payload", "message"), BAD, ids=[b[2][:40] for b in BAD])
def test_malformed_payloads_are_rejected_with_a_specific_error(cls, payload, message):
    with pytest.raises(ProtocolError, match=message):
        decode(cls, payload)


def test_integers_where_numbers_are_expected_decode_as_floats():
    """The fast path for arrays of exact wire types must not change what the general one
    gives: an integer coordinate or command value still becomes a float."""
    frame = decode(MocapFrame, raw(v=SCHEMA_VERSION, k="MocapFrame", t=0, seq=1,
                                   poses=[[1, 0.5, 2, 0.0], [2, 1.0, 1.0, 1.0]], due=[]))
    assert frame == MocapFrame(0.0, 1, ((1, 0.5, 2.0, 0.0), (2, 1.0, 1.0, 1.0)))
    assert [type(x) for x in frame.poses[0]] == [int, float, float, float]
    command = decode(Command, raw(v=SCHEMA_VERSION, k="Command", robot=1, t=0.0, seq=1,
                                  u=[1, 0.5, 0]))
    assert command.u == (1.0, 0.5, 0.0) and all(type(x) is float for x in command.u)


def test_encode_refuses_non_messages():
    with pytest.raises(TypeError, match="not a protocol message: dict"):
        encode({"t": 0.0})


def test_numpy_values_encode_as_plain_numbers():
    np = pytest.importorskip("numpy")
    msg = Event(1.0, "sim", "contact", {"gap": np.float64(0.39), "pair": np.array([1, 2])})
    assert decode(Event, encode(msg)).data == {"gap": 0.39, "pair": [1, 2]}


def test_keys():
    assert keys.mocap("scenario1") == "tlfleet/scenario1/mocap"
    assert keys.cmd("s", 3) == "tlfleet/s/robot/3/cmd"
    assert keys.collab("s", 4) == "tlfleet/s/robot/4/collab"
    assert keys.alive("s", "agent", 3) == "tlfleet/s/alive/agent/3"
    assert keys.robot_of(keys.status("s", 12)) == 12
    assert keys.robot_of(keys.mocap("s")) is None
    assert keys.parse_alive(keys.alive("s", "sim", 0)) == ("sim", "0")
    with pytest.raises(ValueError, match="fleet 'a/b' is not a key segment"):
        keys.mocap("a/b")
    with pytest.raises(ValueError, match="unknown role 'robot'"):
        keys.alive("s", "robot", 1)
