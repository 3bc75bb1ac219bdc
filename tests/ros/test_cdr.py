"""The bridge reads its mocap poses straight from the CDR bytes (tlfleet.sim.hardware.cdr):
checked against rclpy's own serializer for every mocap type of the lab file and random
messages, against big-endian bytes laid out here by hand, and for what it must refuse."""

from __future__ import annotations

import importlib.util
import math
import struct
from types import SimpleNamespace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.agent.scenario.lab import MOCAP_TYPES
from tlfleet.sim.hardware.cdr import TYPES, pose_fields

HAVE_RCLPY = importlib.util.find_spec("rclpy") is not None

doubles = st.floats(allow_nan=True, allow_infinity=True, width=64)
names = st.text(max_size=24)  # any Unicode: the string's length is its UTF-8 bytes


def same(a: float, b: float) -> bool:
    return struct.pack("<d", a) == struct.pack("<d", b)  # bit for bit (NaN, -0.0)


def test_every_mocap_type_of_the_lab_file_is_read():
    assert set(TYPES) == set(MOCAP_TYPES)


@pytest.mark.ros
@pytest.mark.skipif(not HAVE_RCLPY, reason="needs rclpy: the tlfleet[ros2] extra")
@pytest.mark.parametrize("type_name", MOCAP_TYPES)
@settings(max_examples=examples(200), deadline=None)
@given(p=st.tuples(doubles, doubles, doubles), q=st.tuples(doubles, doubles, doubles, doubles),
       frame=names, child=names, sec=st.integers(-2**31, 2**31 - 1),
       cov=st.lists(doubles, min_size=36, max_size=36))
def test_the_seven_numbers_are_rclpys(type_name, p, q, frame, child, sec, cov):
    from rclpy.serialization import serialize_message
    from tlfleet.sim.hardware.ros_link import message_class

    msg = message_class(type_name)()
    msg.header.frame_id = frame
    msg.header.stamp.sec = sec
    if type_name.endswith("TransformStamped"):
        msg.child_frame_id = child
        t, r = msg.transform.translation, msg.transform.rotation
    elif type_name.endswith("/PoseStamped"):
        t, r = msg.pose.position, msg.pose.orientation
    else:
        if type_name.endswith("Odometry"):
            msg.child_frame_id = child
        msg.pose.covariance = cov
        t, r = msg.pose.pose.position, msg.pose.pose.orientation
    t.x, t.y, t.z = p
    r.x, r.y, r.z, r.w = q
    fields = pose_fields(type_name, serialize_message(msg))
    assert fields is not None
    assert all(same(a, b) for a, b in zip(fields, (*p, *q), strict=True)), (fields, p, q)


def big_endian_pose_stamped(frame: bytes, child: bytes | None, seven: tuple[float, ...]) -> bytes:
    """A classic-CDR big-endian message laid out by hand: header, optional child frame, pose."""
    body = struct.pack(">iI", 7, 9)
    for text in (frame, child) if child is not None else (frame,):
        body += b"\0" * (-len(body) % 4) + struct.pack(">I", len(text) + 1) + text + b"\0"
    body += b"\xaa" * (-len(body) % 8)  # padding is not zeroed on the wire either
    return b"\x00\x00\x00\x00" + body + struct.pack(">7d", *seven) + b"\0" * 8


@pytest.mark.parametrize("frame", [b"", b"w", b"wor", b"world", b"mocap_frame"])
@pytest.mark.parametrize("type_name", MOCAP_TYPES)
def test_big_endian_by_hand(type_name, frame):
    seven = (1.5, -2.25, 0.125, 0.0, 0.0, math.sin(0.3), math.cos(0.3))
    child = b"rb" if type_name in ("geometry_msgs/msg/TransformStamped",
                                   "nav_msgs/msg/Odometry") else None
    assert pose_fields(type_name, big_endian_pose_stamped(frame, child, seven)) == seven


def test_what_it_does_not_read_is_none():
    good = big_endian_pose_stamped(b"world", None, (1.0,) * 7)
    assert pose_fields("geometry_msgs/msg/PoseStamped", good) == (1.0,) * 7
    for data in (b"", b"\x00", good[:40],  # too short
                 b"\x00\x03" + good[2:],  # PL_CDR_LE: not classic CDR
                 b"\x00\x07" + good[2:],  # XCDR2 little endian
                 b"\x01\x00" + good[2:]):
        assert pose_fields("geometry_msgs/msg/PoseStamped", data) is None
    assert pose_fields("geometry_msgs/msg/Twist", good) is None
    huge = good[:12] + struct.pack(">I", 10**6) + good[16:]  # a string longer than the message
    assert pose_fields("geometry_msgs/msg/PoseStamped", huge) is None


@pytest.mark.ros
@pytest.mark.skipif(not HAVE_RCLPY, reason="needs rclpy: the tlfleet[ros2] extra")
def test_the_newest_usable_pose_of_a_batch_is_taken():
    """A batch of serialized poses: the newest usable one goes to the world; a zero quaternion
    and bytes no reader understands are counted, and the pose before them is used."""
    from geometry_msgs.msg import PoseStamped
    from rclpy.serialization import serialize_message
    from tlfleet.sim.hardware.ros_link import RosLink, _Mocap

    def pose(x, w):
        msg = PoseStamped()
        msg.pose.position.x, msg.pose.orientation.w = x, w
        return serialize_message(msg)

    got = []
    link = SimpleNamespace(bad_poses=0, _on_pose=lambda *a: got.append(a))
    body = _Mocap(2, "/b", "geometry_msgs/msg/PoseStamped", PoseStamped, None)
    RosLink._newest(link, body, [pose(1.0, 1.0), pose(2.0, 1.0), pose(3.0, 0.0)])
    assert got == [(2, 2.0, 0.0, 0.0)] and link.bad_poses == 1
    RosLink._newest(link, body, [pose(4.0, 1.0), b"\x00\x03garbage"])
    assert got[-1] == (2, 4.0, 0.0, 0.0) and link.bad_poses == 2
