"""Frame conventions between tlfleet and ROS 2 (REP 103, REP 105; docs/hardware.md §Conventions).

Units are SI (m, rad, s); frames are right-handed, Z up; a body frame has x forward, y left;
yaw increases counter-clockwise. The motion-capture world must be Z-up with x/y in the
scenario's arena coordinates. tlfleet's poses are planar ``(x, y, θ)`` [m, m, rad]; its omni
command ``(vx, vy, ω)`` is **world-frame** [m/s, m/s, rad/s] (architecture.md §2) while a ROS
base (``mecanum_drive_controller``, any ``cmd_vel``) takes **body-frame** velocities; its unicycle
command ``(v, ω)`` is ``linear.x``, ``angular.z`` already.

Pure functions, no ROS: the hardware bridge, the ROS mirror and the MCAP export all use them.
"""

from __future__ import annotations

import math


def yaw_of_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Yaw ψ [rad] in (−π, π] of the rotation ``(x, y, z, w)`` (any norm > 0): the Z-Y-X Euler
    angle ψ = atan2(2(wz + xy), 1 − 2(y² + z²)), computed on the normalised quaternion."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not n > 0.0 or not math.isfinite(n):
        raise ValueError(f"quaternion ({x}, {y}, {z}, {w}) has no rotation: norm {n}")
    x, y, z, w = x / n, y / n, z / n, w / n
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_of_yaw(yaw: float) -> tuple[float, float, float, float]:
    """The unit quaternion ``(x, y, z, w)`` of a rotation by ``yaw`` [rad] about Z."""
    half = 0.5 * yaw
    return 0.0, 0.0, math.sin(half), math.cos(half)


def wrap_angle(angle: float) -> float:
    """``angle`` [rad] wrapped to (−π, π]."""
    wrapped = math.atan2(math.sin(angle), math.cos(angle))
    return math.pi if wrapped == -math.pi else wrapped


def world_to_body(vx: float, vy: float, yaw: float) -> tuple[float, float]:
    """A world-frame planar velocity ``(vx, vy)`` [m/s] in the body frame of a robot at ``yaw``
    [rad]: v_b = R(ψ)ᵀ v_w, i.e. vx_b = cos ψ·vx + sin ψ·vy, vy_b = −sin ψ·vx + cos ψ·vy."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * vx + s * vy, -s * vx + c * vy


def body_to_world(vx_b: float, vy_b: float, yaw: float) -> tuple[float, float]:
    """The inverse of :func:`world_to_body`: v_w = R(ψ) v_b."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * vx_b - s * vy_b, s * vx_b + c * vy_b


def apply_offset(x: float, y: float, yaw: float,
                 offset: tuple[float, float, float]) -> tuple[float, float, float]:
    """The robot's pose from its rigid body's pose ``(x, y, yaw)`` and the calibration
    ``offset = (dx, dy, dψ)``: the robot's origin and heading expressed in the rigid body's frame
    [m, m, rad]. Returns ``(x + R(ψ)(dx, dy), ψ + dψ)`` with the heading wrapped to (−π, π]."""
    dx, dy, dpsi = offset
    c, s = math.cos(yaw), math.sin(yaw)
    return x + c * dx - s * dy, y + s * dx + c * dy, wrap_angle(yaw + dpsi)


def twist_of_command(kind: str, u: tuple[float, ...], yaw: float) -> tuple[float, float, float]:
    """``(linear.x, linear.y, angular.z)`` of a ROS body-frame twist for tlfleet command ``u``:
    a unicycle's ``(v, ω)`` → ``(v, 0, ω)``; an omni robot's world-frame ``(vx, vy, ω)`` → its
    body frame at the robot's newest yaw [rad] (:func:`world_to_body`)."""
    if kind == "unicycle":
        v, omega = u
        return float(v), 0.0, float(omega)
    if kind == "omni":
        vx, vy, omega = u
        bx, by = world_to_body(float(vx), float(vy), yaw)
        return bx, by, float(omega)
    raise ValueError(f"robot kind {kind!r}: expected 'unicycle' or 'omni'")
