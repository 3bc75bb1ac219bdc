"""The straight-line codec paths of the per-tick messages (``tlfleet.bus.protocol.fast_paths``,
issue 17) agree with the generic codec: a payload the fast path accepts decodes to the message the
generic decoder builds, a payload the generic decoder rejects is never accepted by the fast path,
valid messages do take the fast path, and the fast encoder writes the generic encoder's bytes."""

from __future__ import annotations

import copy
import math

import msgpack
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.bus.protocol import codec
from tlfleet.bus.protocol.bounds import MAX_COORD, MAX_SPEED, MAX_TIME
from tlfleet.bus.protocol.codec import SCHEMA_VERSION, ProtocolError, decode
from tlfleet.bus.protocol.fast_paths import decode_fast, encode_fast
from tlfleet.bus.protocol.messages import Clock, Command, MocapFrame

ids = st.integers(0, 1_000_000)
seqs = st.integers(0, 2 ** 53)
times = st.floats(0.0, MAX_TIME)
coords = st.floats(-MAX_COORD, MAX_COORD)
angles = st.floats(-math.pi, math.pi)
speeds = st.floats(-MAX_SPEED, MAX_SPEED)
rows = st.tuples(ids, coords, coords, angles)
frames = st.builds(MocapFrame, times, seqs, st.lists(rows, max_size=8).map(tuple),
                   st.lists(ids, max_size=4).map(tuple))
commands = st.builds(Command, ids, times, st.integers(-1, 2 ** 53),
                     st.lists(speeds, min_size=2, max_size=3).map(tuple))
clocks = st.builds(Clock, times, st.integers(0, 2 ** 53),
                   st.sampled_from(["lockstep", "realtime"]))

# values that are nearly right: the wrong number type, out of range, NaN, wrong shapes; each
# draw a fresh copy, since near_valid mutates the lists it puts in (a shared [1.0] once ended up
# inside itself and msgpack hit its recursion limit while the case was generated)
odd_numbers = st.sampled_from([0, 1, -1, 2 ** 60, 0.5, -0.5, math.nan, math.inf, -math.inf,
                               1e300, -1e300, True, False, None, "1", [], [1.0]]).map(copy.deepcopy)


def generic(cls, data):
    """The generic decoder alone: the message, or None when it raises ProtocolError."""
    try:
        return codec._decode(cls, data)
    except ProtocolError:
        return None


@st.composite
def near_valid(draw):
    """A valid frame or command's wire map with one to three values replaced by odd ones, some
    fields dropped or foreign ones added, and sometimes a wrong version or kind."""
    msg = draw(frames | commands)
    body = msgpack.unpackb(codec._encode_generic(msg))
    for _ in range(draw(st.integers(1, 3))):
        name = draw(st.sampled_from([*sorted(body), "extra"]))
        choice = draw(st.integers(0, 3))
        if choice == 0:
            body.pop(name, None)
        elif choice == 1 or not isinstance(body.get(name), list) or not body[name]:
            body[name] = draw(odd_numbers)
        else:  # one item (or one number of one pose row) of an array
            items = body[name]
            i = draw(st.integers(0, len(items) - 1))
            if isinstance(items[i], list) and items[i]:
                items[i][draw(st.integers(0, len(items[i]) - 1))] = draw(odd_numbers)
            else:
                items[i] = draw(odd_numbers)
    return type(msg), msgpack.packb(body, use_bin_type=True)


@settings(max_examples=examples(300), deadline=None)
@given(frames | commands)
def test_valid_messages_take_the_fast_path_and_decode_as_the_generic_decoder(msg):
    data = codec._encode_generic(msg)
    fast = decode_fast(type(msg), data)
    assert fast is not None
    assert fast == generic(type(msg), data) == msg
    assert type(fast.poses if isinstance(fast, MocapFrame) else fast.u) is tuple


@settings(max_examples=examples(600), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(near_valid())
def test_the_fast_path_accepts_only_what_the_generic_decoder_accepts_and_agrees(case):
    cls, data = case
    fast = decode_fast(cls, data)
    slow = generic(cls, data)
    if fast is not None:
        assert slow is not None and fast == slow
    if slow is None:  # decode() then raises the generic decoder's error
        assert fast is None
        try:
            decode(cls, data)
        except ProtocolError:
            pass
        else:
            raise AssertionError("decode accepted what the generic decoder rejects")


@settings(max_examples=examples(200), deadline=None)
@given(st.sampled_from([MocapFrame, Command]), st.binary(max_size=300))
def test_garbage_never_takes_the_fast_path(cls, data):
    fast = decode_fast(cls, data)
    assert fast is None or fast == generic(cls, data)


def test_ints_where_floats_are_allowed_are_left_to_the_generic_decoder():
    data = msgpack.packb({"v": SCHEMA_VERSION, "k": "Command", "robot": 3, "t": 1, "seq": 100,
                          "u": [0, 0.5, 0]})
    assert decode_fast(Command, data) is None
    assert decode(Command, data) == Command(3, 1.0, 100, (0.0, 0.5, 0.0))


@settings(max_examples=examples(300), deadline=None)
@given(frames | commands | clocks)
def test_the_fast_encoder_writes_the_generic_encoders_bytes(msg):
    assert encode_fast(msg) == codec._encode_generic(msg)
    assert codec.encode(msg) == codec._encode_generic(msg)
