"""The C decoders of ``MocapFrame`` and ``Command`` (``bus/protocol/wire_kernel.c``)
against the Python fast path they stand in front of (``tlfleet.bus.protocol.fast_paths``).

The contract: C returns a message only when the Python path returns an equal one, and ``None``
(the Python path decides) for anything else; canonical payloads do take the C path. Checked on
random valid messages, near-valid maps, other encodings of the same map, every truncation and
every one-byte change of valid payloads, and random bytes."""

from __future__ import annotations

import dataclasses
import math
import struct
import sys
import tracemalloc
import types

import msgpack
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.bus.protocol import bounds, codec, fast_paths
from tlfleet.bus.protocol.codec import SCHEMA_VERSION
from tlfleet.bus.protocol.fast_paths import CodecSettingError
from tlfleet.bus.protocol.messages import Command, MocapFrame

from tests.protocol.test_protocol_fast_paths import commands, frames, near_valid

native = fast_paths._native
# without a C compiler at install time these skip; under TLFLEET_REQUIRE_SYSTEM=1 (CI, where it
# must have been built) the skip is a failure (tests/conftest.py)
pytestmark = [pytest.mark.skipif(native is None, reason="the C decoders "
                                 "(tlfleet.bus.protocol._wire) were not built: no C compiler at "
                                 "install time, or "
                                 "TLFLEET_CODEC=python"),
              pytest.mark.needs_system]

PYTHON = {MocapFrame: fast_paths._frame_python, Command: fast_paths._command_python}
NATIVE = {MocapFrame: native.decode_frame if native else None,
          Command: native.decode_command if native else None}


def agree(cls, data) -> object:
    """C's answer, asserting it is None or what the Python path returns."""
    got = NATIVE[cls](data)
    if got is not None:
        want = PYTHON[cls](data)
        assert want is not None, f"C accepted what Python refuses: {data!r}"
        assert got == want and type(got) is cls
        assert [type(getattr(got, f.name)) for f in dataclasses.fields(cls)] == \
               [type(getattr(want, f.name)) for f in dataclasses.fields(cls)]
    return got


@settings(max_examples=examples(300), deadline=None)
@given(frames | commands)
def test_canonical_payloads_take_the_c_path_and_decode_to_the_message(msg):
    data = codec._encode_generic(msg)
    got = agree(type(msg), data)
    assert got == msg and hash(got) == hash(msg)
    if isinstance(msg, MocapFrame):
        assert all(type(row) is tuple for row in got.poses) and type(got.due) is tuple


@settings(max_examples=examples(600), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(near_valid())
def test_near_valid_payloads_are_refused_or_agree(case):
    cls, data = case
    agree(cls, data)


@settings(max_examples=examples(300), deadline=None)
@given(st.sampled_from([MocapFrame, Command]), st.binary(max_size=300))
def test_random_bytes_are_refused_or_agree(cls, data):
    agree(cls, data)


def payloads() -> list[tuple[type, bytes]]:
    frame = MocapFrame(12.34, 1234, ((1, 0.5, -0.25, 3.0), (200, -1e4, 1e4, -1e3)), (1, 200))
    return [(MocapFrame, codec._encode_generic(frame)),
            (MocapFrame, codec._encode_generic(dataclasses.replace(frame, due=()))),
            (Command, codec._encode_generic(Command(3, 2.0, -1, (0.1, -1e3, 1e3))))]


@pytest.mark.parametrize("cls,data", payloads())
def test_every_truncation_and_every_one_byte_change_is_refused_or_agrees(cls, data):
    assert agree(cls, data) is not None
    for n in range(len(data)):
        assert agree(cls, data[:n]) is None
        assert agree(cls, data + data[n:n + 1]) is None  # trailing bytes
    for i in range(len(data)):
        for value in range(256):
            agree(cls, data[:i] + bytes([value]) + data[i + 1:])


def pack(body: dict, *, key=lambda k: msgpack.packb(k), value=msgpack.packb,
         header: bytes | None = None) -> bytes:
    """A map payload with a chosen encoding of its header, keys and values."""
    out = header if header is not None else bytes([0x80 | len(body)])
    return out + b"".join(key(k) + value(v) for k, v in body.items())


def frame_body() -> dict:
    return {"v": SCHEMA_VERSION, "k": "MocapFrame", "t": 1.5, "seq": 7,
            "poses": [[1, 0.5, 0.25, 0.0]], "due": [1]}


def int_as(width: str):
    """A value packer that writes ints with a wider msgpack code than needed."""
    codes = {"u8": (0xcc, ">B"), "u16": (0xcd, ">H"), "u32": (0xce, ">I"), "u64": (0xcf, ">Q"),
             "i8": (0xd0, ">b"), "i16": (0xd1, ">h"), "i32": (0xd2, ">i"), "i64": (0xd3, ">q")}
    code, fmt = codes[width]

    def packer(v):
        if type(v) is int:
            return bytes([code]) + struct.pack(fmt, v)
        if type(v) is list:
            return bytes([0x90 | len(v)]) + b"".join(packer(x) for x in v)
        return msgpack.packb(v)
    return packer


@pytest.mark.parametrize("width", ["u8", "u16", "u32", "u64", "i8", "i16", "i32", "i64"])
def test_every_int_width_is_read(width):
    data = pack(frame_body(), value=int_as(width))
    assert agree(MocapFrame, data) == MocapFrame(1.5, 7, ((1, 0.5, 0.25, 0.0),), (1,))
    if width.startswith("i"):  # a negative value keeps its sign
        body = {"v": SCHEMA_VERSION, "k": "Command", "robot": 2, "t": 1.0, "seq": -1,
                "u": [0.5, -0.5]}
        assert agree(Command, pack(body, value=int_as(width))) == Command(2, 1.0, -1,
                                                                            (0.5, -0.5))


def test_other_encodings_of_the_map_are_left_to_python_or_agree():
    body = frame_body()
    single = msgpack.packb(body, use_single_float=True)  # float32: widened as msgpack does
    assert agree(MocapFrame, single) is not None
    reordered = pack(dict(reversed(list(body.items()))))
    assert agree(MocapFrame, reordered) is not None
    no_due = dict(body)
    del no_due["due"]
    assert agree(MocapFrame, pack(no_due)).due == ()
    cases = {
        "map16 header": pack(body, header=b"\xde\x00\x06"),
        "str8 keys": pack(body, key=lambda k: b"\xd9" + bytes([len(k)]) + k.encode()),
        "a repeated key": pack(body) [:-2] + b"\xa1t\xcb" + struct.pack(">d", 2.0),
        "an unknown key": pack({**body, "x": 1}),
        "a bool seq": pack({**body, "seq": True}),
        "an int t": pack({**body, "t": 2}),
        "a NaN t": pack({**body, "t": math.nan}),
        "a negative seq": pack({**body, "seq": -1}),
        "a row of 3": pack({**body, "poses": [[1, 0.5, 0.25]]}),
        "an id too large": pack({**body, "poses": [[1_000_001, 0.5, 0.25, 0.0]]}),
        "a wrong kind": pack({**body, "k": "Command"}),
        "a wrong version": pack({**body, "v": SCHEMA_VERSION + 1}),
        "a missing seq": pack({k: v for k, v in body.items() if k != "seq"}),
        "a list payload": msgpack.packb([1, 2]),
    }
    for what, data in cases.items():
        assert native.decode_frame(data) is None, what
        agree(MocapFrame, data)
    assert agree(MocapFrame, bytearray(pack(body))) is None  # only bytes, as the Python path


@settings(max_examples=examples(400), deadline=None)
@given(frames | commands | st.builds(Command, st.integers(0, 2 ** 63 - 1), st.floats(),
                                     st.integers(-2 ** 63, 2 ** 63 - 1),
                                     st.lists(st.floats(), max_size=20).map(tuple)))
def test_the_c_encoder_writes_the_python_encoders_bytes(msg):
    """Every int width, any float (NaN and infinities too), long arrays."""
    encoder = native.encode_command if type(msg) is Command else native.encode_frame
    assert encoder(msg) == fast_paths._encode_python(msg) == codec._encode_generic(msg)


def test_the_c_encoder_chooses_msgpacks_int_forms_at_every_boundary():
    edges = [0, 1, 127, 128, 255, 256, 65535, 65536, 2 ** 32 - 1, 2 ** 32, 2 ** 63 - 1,
             -1, -32, -33, -128, -129, -32768, -32769, -2 ** 31, -2 ** 31 - 1, -2 ** 63]
    for v in edges:
        for msg in (Command(abs(v) % 2 ** 63, 1.0, v, (0.5,)),
                    MocapFrame(1.0, v, ((abs(v) % 2 ** 63, 0.0, 0.0, 0.0),), (v,))):
            encoder = native.encode_command if type(msg) is Command else native.encode_frame
            assert encoder(msg) == fast_paths._encode_python(msg), msg
    for n in (0, 1, 15, 16, 65535, 65536, 70_000):  # fixarray, array16, array32 and edges
        command = Command(1, 1.0, 2, tuple(float(i) for i in range(n)))
        assert native.encode_command(command) == fast_paths._encode_python(command), n
    for n in (15, 16):
        frame = MocapFrame(1.0, 2, tuple((i, 0.0, 0.0, 0.0) for i in range(n)), tuple(range(n)))
        assert native.encode_frame(frame) == fast_paths._encode_python(frame), n


def test_the_c_encoder_leaves_other_types_to_python():
    for msg in (Command(True, 1.0, 2, (0.5,)), Command(1, 1, 2, (0.5,)),
                Command(1, 1.0, 2, [0.5]), Command(1, 1.0, 2 ** 64, (0.5,)),
                Command(1, 1.0, 2, (np.float64(0.5),)),
                MocapFrame(1.0, 2, [(1, 0.0, 0.0, 0.0)], ()),
                MocapFrame(1.0, 2, ((1, 0.0, 0.0),), ()),
                MocapFrame(1.0, 2, ((1, 0, 0.0, 0.0),), ()),
                MocapFrame(1.0, 2, ((1, 0.0, 0.0, 0.0),), (np.int64(1),))):
        encoder = native.encode_command if type(msg) is Command else native.encode_frame
        assert encoder(msg) is None, msg
    assert native.encode_frame(Command(1, 1.0, 2, (0.5,))) is None
    assert native.encode_command("Command") is None


def test_the_message_classes_have_no_post_init():
    """C builds the messages slot by slot, as the dataclass __init__ does; a __post_init__
    would be skipped, so adding one must come with a change to wire_kernel.c."""
    for cls in (MocapFrame, Command):
        assert not hasattr(cls, "__post_init__")
        assert cls.__dataclass_params__.frozen and hasattr(cls, "__slots__")


def test_no_memory_is_kept_per_decode():
    _, data = payloads()[0]
    for _ in range(1000):
        native.decode_frame(data)
    tracemalloc.start()
    try:
        before = tracemalloc.take_snapshot()
        for _ in range(20_000):
            native.decode_frame(data)
            native.decode_frame(data[:-1])
        after = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    grown = sum(s.size_diff for s in after.compare_to(before, "filename"))
    assert grown < 20_000, f"{grown} bytes kept over 40 000 decodes"
    message = native.decode_frame(data)
    counts = sys.getrefcount(message), sys.getrefcount(message.poses)
    for _ in range(1000):
        native.encode_frame(message)
    assert (sys.getrefcount(message), sys.getrefcount(message.poses)) == counts


def test_settings():
    assert fast_paths._load_native("python") is None
    assert fast_paths._load_native("auto") is native
    assert fast_paths._load_native("native") is native
    with pytest.raises(CodecSettingError, match="expected one of auto, native, python"):
        fast_paths._load_native("fast")


@settings(max_examples=examples(300), deadline=None)
@given(frames | commands | st.builds(Command, st.integers(0, 2 ** 63 - 1), st.floats(),
                                     st.integers(-2 ** 63, 2 ** 63 - 1),
                                     st.lists(st.floats(), max_size=20).map(tuple)))
def test_command_bytes_are_the_encoders_bytes_of_the_command(msg):
    """``command_bytes(robot, t, seq, u)`` (the agents' per-tick command, no message built) writes
    what the encoder writes for ``Command(robot, t, seq, u)``."""
    if type(msg) is MocapFrame:  # a frame's fields as a command's
        msg = Command(msg.seq, msg.t, msg.seq, tuple(float(r[1]) for r in msg.poses))
    want = codec._encode_generic(msg)
    assert native.command_bytes(msg.robot, msg.t, msg.seq, msg.u) == want
    assert fast_paths.command_bytes(msg.robot, msg.t, msg.seq, msg.u) == want


def test_command_bytes_leave_other_types_to_the_caller():
    for fields in ((True, 1.0, 2, (0.5,)), (1, 1, 2, (0.5,)), (1, 1.0, 2, [0.5]),
                   (1, 1.0, 2 ** 64, (0.5,)), (1, 1.0, 2, (np.float64(0.5),)),
                   (1, 1.0, 2, (0, 0.5))):
        assert native.command_bytes(*fields) is None, fields
    with pytest.raises(TypeError, match="4 arguments"):
        native.command_bytes(1, 1.0, 2)


ROWS = st.lists(st.tuples(st.integers(0, 40), st.floats(), st.floats(), st.floats()),
                max_size=40).map(tuple)


@settings(max_examples=examples(300), deadline=None)
@given(ROWS)
def test_pose_map_is_the_comprehension_over_the_rows(rows):
    """Ids repeated too (the last row wins, as in the comprehension); the values are the rows'
    own float objects."""
    want = {row[0]: row[1:] for row in rows}
    for got in (native.pose_map(rows), fast_paths.pose_map(rows)):
        assert type(got) is dict and list(got) == list(want)
        for robot, pose in want.items():  # the very float objects (NaN != NaN for ==)
            assert type(got[robot]) is tuple
            assert all(a is b for a, b in zip(got[robot], pose, strict=True)), robot


def test_pose_map_leaves_other_rows_to_python():
    for rows in ([(1, 0.0, 0.0, 0.0)], ((1, 0.0, 0.0),), ([1, 0.0, 0.0, 0.0],), "rows"):
        assert native.pose_map(rows) is None, rows
    assert fast_paths.pose_map([(1, 0.0, 0.0, 0.0)]) == {1: (0.0, 0.0, 0.0)}
    assert fast_paths.pose_map(([1, 0.5, 0.0, 0.0],)) == {1: [0.5, 0.0, 0.0]}


def _python_problem(fleet_bounds, frame):
    """``FleetBounds.frame_problem`` with the C confirmation removed: the reference."""
    saved = bounds._frame_plausible
    bounds.use_frame_check(None)
    try:
        return fleet_bounds.frame_problem(frame)
    finally:
        bounds.use_frame_check(saved)


@st.composite
def bounds_and_frames(draw):
    """Fleet bounds and frames whose every value sits near an edge of what they allow: times
    around the seq's window, coordinates and headings at the box's and the wrap's limits and one
    ulp beyond, ids unknown, repeated or out of order, non-finite values."""
    rate = draw(st.sampled_from([100.0, 50.0, 30.0, 1000.0, 7.0]))
    xmin = draw(st.floats(-10.0, 0.0))
    ymin = draw(st.floats(-10.0, 0.0))
    box = (xmin, xmin + draw(st.floats(0.1, 20.0)), ymin, ymin + draw(st.floats(0.1, 20.0)))
    margin = draw(st.sampled_from([0.0, 0.5, 2.0]))
    known = draw(st.sampled_from([(), (1, 2, 3), (0, 2, 5, 7, 9)]))
    fb = bounds.FleetBounds(box, draw(st.floats(1.0, 500.0)), rate,
                            {r: (0.2, 1.0) for r in known}, margin=margin)
    lo_x, hi_x, lo_y, hi_y = box[0] - margin, box[1] + margin, box[2] - margin, box[3] + margin

    def edge(lo, hi):
        return st.floats(lo, hi) | st.sampled_from([lo, hi]) | st.sampled_from(
            [math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf), math.nan, math.inf,
             -math.inf])

    wrap = bounds._WRAPPED
    ids = st.sampled_from(known) if known and draw(st.booleans()) else st.integers(-2, 10)
    rows = draw(st.lists(st.tuples(ids, edge(lo_x, hi_x), edge(lo_y, hi_y), edge(-wrap, wrap)),
                         max_size=6))
    if draw(st.booleans()):  # mostly well-formed: ascending distinct ids
        rows = sorted({r[0]: r for r in rows}.values())
    last = int(fb.t_max * rate)
    seq = draw(st.integers(-3, last + 3) | st.sampled_from([0, last, 2 ** 53, 2 ** 53 + 1,
                                                             -(2 ** 53)]))
    period = 1.0 / rate
    lag_lo = -0.5 * period - 1e-9
    lag = draw(st.sampled_from([lag_lo, math.nextafter(lag_lo, -math.inf), period,
                                math.nextafter(period, -math.inf), 0.0])
               | st.floats(-2 * period, 2 * period))
    t = draw(st.sampled_from([seq / rate + lag] * 6 + [fb.t_max, math.nextafter(fb.t_max, math.inf),
                                                     -0.0, math.nan]))
    due = tuple(draw(st.lists(ids, max_size=3)))
    return fb, MocapFrame(t, seq, tuple(rows), due)


@settings(max_examples=examples(1500), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(bounds_and_frames())
def test_frame_plausible_confirms_exactly_the_frames_python_finds_nothing_wrong_with(case):
    """On the values the decoders build (exact ints, floats, tuples) the C check is the Python
    check: True exactly when ``frame_problem`` returns None; and ``frame_problem`` with it
    installed says what it says without."""
    fb, frame = case
    want = _python_problem(fb, frame)
    got = native.frame_plausible(frame.t, frame.seq, frame.poses, frame.due,
                                 *fb._frame_check_args)
    assert got is (want is None), (want, frame)
    assert fb.frame_problem(frame) == want


def test_frame_plausible_leaves_other_types_to_python():
    fb = bounds.FleetBounds((-2.0, 2.0, -2.0, 2.0), 10.0, 100.0, {1: (0.2, 1.0), 2: (0.2, 1.0)})
    good = MocapFrame(0.5, 50, ((1, 0.0, 0.0, 0.0), (2, 1.0, 1.0, 0.0)), (1,))
    assert native.frame_plausible(good.t, good.seq, good.poses, good.due, *fb._frame_check_args)
    for frame in (dataclasses.replace(good, poses=((1, 0, 0.0, 0.0), (2, 1.0, 1.0, 0.0))),
                  dataclasses.replace(good, poses=([1, 0.0, 0.0, 0.0], (2, 1.0, 1.0, 0.0))),
                  dataclasses.replace(good, poses=((True, 0.0, 0.0, 0.0),)),
                  dataclasses.replace(good, poses=list(good.poses)),
                  dataclasses.replace(good, due=[1]),
                  dataclasses.replace(good, t=1),
                  dataclasses.replace(good, seq=50.0)):
        assert native.frame_plausible(frame.t, frame.seq, frame.poses, frame.due,
                                      *fb._frame_check_args) is False, frame
        assert fb.frame_problem(frame) == _python_problem(fb, frame)  # Python decides
    # bounds that are no exact floats, or limits that are no dict: Python checks alone
    assert bounds.FleetBounds((-2, 2, -2, 2), 10, 100, {1: (0.2, 1.0)})._frame_check_args \
        is not None  # ints that are floats' values are passed as floats
    assert bounds.FleetBounds((-2.0, 2.0, -2.0, 2.0), 10.0, 100.0,
                              types.MappingProxyType({1: (0.2, 1.0)}))._frame_check_args is None
