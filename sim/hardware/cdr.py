"""The planar pose straight from a serialized mocap message (docs/hardware.md §The bridge).

The bridge takes its pose messages serialized (:meth:`tlfleet.sim.hardware.ros_link.RosLink.poll`)
and needs seven numbers of the newest: the position and the orientation quaternion. rclpy's
``deserialize_message`` builds the whole message as Python objects (a header, a stamp, points,
a quaternion, a 36-value covariance...), about ten times the cost of reading the seven doubles
where the wire format puts them. This module reads them there, for the lab's four mocap types,
in the classic OMG CDR encoding (XCDR1, little- or big-endian; what ROS 2's Fast DDS, Cyclone DDS
and Connext publish by default). Any other encapsulation, or a message too short for its type,
gives ``None``: the caller then deserializes with rclpy (which reads whatever its middleware
writes, and raises on garbage).

XCDR1, as the ROS 2 type support lays these types out (offsets after the 4-byte encapsulation
header; a primitive is aligned to its own size, at most 8):

* ``std_msgs/Header``: ``int32 sec``, ``uint32 nanosec``, ``string frame_id`` (a ``uint32``
  length counting the terminating NUL, then the bytes);
* ``PoseStamped``: Header, then ``Pose`` = ``Point position`` (3 float64) and ``Quaternion
  orientation`` (4 float64);
* ``PoseWithCovarianceStamped``: Header, then ``PoseWithCovariance`` whose ``Pose`` comes first;
* ``TransformStamped``: Header, ``string child_frame_id``, then ``Transform`` = ``Vector3
  translation`` and ``Quaternion rotation``;
* ``nav_msgs/Odometry``: Header, ``string child_frame_id``, then ``PoseWithCovariance``.

So every one of them is a Header, for two of them one more string, then seven float64.
"""

from __future__ import annotations

import struct

# encapsulation identifiers (OMG DDS-XTypes 1.3, 7.6.3.1.2): classic CDR, big / little endian
CDR_BE, CDR_LE = 0x0000, 0x0001
_SEVEN = {CDR_BE: struct.Struct(">7d"), CDR_LE: struct.Struct("<7d")}
_U32 = {CDR_BE: struct.Struct(">I"), CDR_LE: struct.Struct("<I")}
# the types with a child_frame_id string between the header and the pose
_CHILD_FRAME = ("geometry_msgs/msg/TransformStamped", "nav_msgs/msg/Odometry")
TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped",
         *_CHILD_FRAME)


def pose_fields(type_name: str, data: bytes) -> tuple[float, ...] | None:
    """``(x, y, z, qx, qy, qz, qw)`` of the serialized message ``data`` of type ``type_name``
    (one of :data:`TYPES`); None for an encapsulation other than XCDR1, a type not in
    :data:`TYPES`, or too few bytes."""
    if len(data) < 4 or data[0] != 0 or data[1] not in _SEVEN or type_name not in TYPES:
        return None
    kind = data[1]
    u32 = _U32[kind]
    try:
        offset = 4 + 8  # past the header and the stamp (body offsets 0-7)
        strings = 2 if type_name in _CHILD_FRAME else 1
        for _ in range(strings):
            offset += (-(offset - 4)) % 4  # a uint32 length, aligned to 4 in the body
            (length,) = u32.unpack_from(data, offset)
            offset += 4 + length
        offset += (-(offset - 4)) % 8  # float64: aligned to 8 in the body
        return _SEVEN[kind].unpack_from(data, offset)
    except struct.error:
        return None
