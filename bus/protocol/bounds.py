"""Limits of every message kind, declared beside the messages (architecture.md §2).

Two layers, both applied by receivers so that a payload is either a valid, plausible message or
dropped (never half-applied, never a crash):

* **Static limits** (:data:`LIMITS`, :func:`check_message`), applied by
  :func:`tlfleet.bus.protocol.codec.decode` to every payload whatever the scenario: the payload
  size, the longest array/map and string msgpack may build, the nesting depth of the one free-form
  field (``Event.data``), and the range of every number. Every float must be finite, except the
  four ``StlStatus`` fields documented as NaN while the agent is idle and the numbers inside
  ``Event.data`` (diagnostics); times lie in [0, :data:`MAX_TIME`], positions within
  :data:`MAX_COORD` of the origin, commands within :data:`MAX_SPEED`.
* **Fleet bounds** (:class:`FleetBounds`), built from the scenario by the simulator, the agents
  and the coordinator: a mocap frame's time lies inside the run (t ≤ duration + slack) and agrees
  with its sequence number (t = seq / mocap_rate, the sim's tick clock: from half a period
  before to one period after, since a realtime frame may be sampled after its tick), its rows
  name known
  robots in ascending order and put them inside a generous box around the arena; a command's
  values stay within a multiple of the robot's limits. A frame or command that fails is
  *implausible*: counted and dropped like a malformed one.

Units: times [s], positions [m], angles [rad], speeds [m/s] and [rad/s].
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

MAX_TIME = 1.0e6  # [s] sim/mission time (11.6 days): no run is longer
MAX_COORD = 1.0e4  # [m] |x|, |y| of any pose or point on the wire
MAX_ANGLE = 1.0e3  # [rad] |θ| (mocap headings are wrapped; agents' headings are not)
MAX_SPEED = 1.0e3  # [m/s] or [rad/s], |u_i| of any command value
MAX_INT = 2 ** 53  # |i| of any integer (exact in a double)
MAX_ROBOT_ID = 1_000_000
MAX_VALUE = 1.0e9  # |v| of any other finite number (robustness, funnel parameters)


@dataclass(frozen=True)
class Limits:
    """Structural limits of one message kind (what msgpack may build before we look at it)."""

    max_bytes: int  # payload size
    max_items: int  # longest array or map
    max_str: int  # longest string [bytes]
    max_depth: int = 4  # nesting of arrays/maps (Event.data is the only free-form field)
    max_nodes: int = 0  # Event.data: total values (0: not free-form)


LIMITS: dict[str, Limits] = {
    "Clock": Limits(256, 16, 32),
    "MocapFrame": Limits(256 * 1024, 4096, 32),
    "Command": Limits(512, 16, 32),
    "LtlStatus": Limits(64 * 1024, 1024, 256),
    "StlStatus": Limits(1024, 32, 32),
    "CollabMessage": Limits(4096, 32, 64),
    "CollabReply": Limits(4096, 16, 1024),
    "Event": Limits(64 * 1024, 1024, 4096, max_depth=8, max_nodes=4096),
    "Control": Limits(256, 16, 32),
    "BackfillRequest": Limits(256, 16, 32),
    # a reply's frames are bin strings of at most one MocapFrame's size each (max_str), and a
    # reply holds at most BACKFILL_REPLY_FRAMES of them within BACKFILL_REPLY_BYTES
    "BackfillReply": Limits(2 * 1024 * 1024, 4096, 256 * 1024),
}
BACKFILL_REPLY_BYTES = 1024 * 1024  # frame bytes a simulator puts in one BackfillReply at most
BACKFILL_REPLY_FRAMES = 2048  # frames a simulator puts in one BackfillReply at most
DEFAULT_LIMITS = Limits(64 * 1024, 1024, 1024)
MAX_PAYLOAD = max(limit.max_bytes for limit in LIMITS.values())

NAN_FIELDS = frozenset({"rho", "rho_max", "lower", "r"})  # StlStatus: NaN while idle


class OutOfBounds(ValueError):
    """A value outside its declared range: ``path`` (``.poses[2][1]``) and ``reason``."""

    def __init__(self, path: str, reason: str):
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}")


# --------------------------------------------------------------------------- static checks


def _number(path: str, value: float, lo: float, hi: float, nan_ok: bool = False) -> None:
    if value != value:  # NaN
        if nan_ok:
            return
        raise OutOfBounds(path, "not a finite number (NaN)")
    if not lo <= value <= hi:
        what = "not a finite number" if math.isinf(value) else f"outside [{lo:g}, {hi:g}]"
        raise OutOfBounds(path, f"{value!r} is {what}")


def _time(path: str, value: float) -> None:
    _number(path, value, 0.0, MAX_TIME)


def _int(path: str, value: int, lo: int = -MAX_INT, hi: int = MAX_INT) -> None:
    if not lo <= value <= hi:
        raise OutOfBounds(path, f"{value} is outside [{lo}, {hi}]")


def _robot(path: str, value: int) -> None:
    _int(path, value, 0, MAX_ROBOT_ID)


def _free_form(path: str, value: Any, limits: Limits) -> None:
    """Event.data: depth, node count, map keys are strings; iterative (no recursion)."""
    stack = [(value, 1, path)]
    nodes = 0
    while stack:
        node, depth, where = stack.pop()
        nodes += 1
        if nodes > limits.max_nodes:
            raise OutOfBounds(path, f"more than {limits.max_nodes} values")
        if isinstance(node, dict):
            if depth > limits.max_depth:
                raise OutOfBounds(where, f"nested deeper than {limits.max_depth}")
            for key, item in node.items():
                if type(key) is not str:
                    raise OutOfBounds(where, f"map key {type(key).__name__}: expected a string")
                stack.append((item, depth + 1, f"{where}.{key[:20]}"))
        elif isinstance(node, list):
            if depth > limits.max_depth:
                raise OutOfBounds(where, f"nested deeper than {limits.max_depth}")
            stack.extend((item, depth + 1, f"{where}[{i}]") for i, item in enumerate(node))


def check_message(msg: Any) -> None:
    """Raise :class:`OutOfBounds` when a decoded message has a number out of its range."""
    kind = type(msg).__name__
    checker = _CHECKS.get(kind)
    if checker is not None:
        checker(msg)


def _clock(msg: Any) -> None:
    _time(".t", msg.t)
    _int(".tick", msg.tick, 0)


def _mocap(msg: Any) -> None:
    _time(".t", msg.t)
    _int(".seq", msg.seq, 0)
    # the happy path builds no strings (every process checks 100 frames a second); a
    # row out of range (or NaN, which fails every comparison) is checked again below with paths
    for _robot_id, x, y, th in msg.poses:
        if not (0 <= _robot_id <= MAX_ROBOT_ID and -MAX_COORD <= x <= MAX_COORD
                and -MAX_COORD <= y <= MAX_COORD and -MAX_ANGLE <= th <= MAX_ANGLE):
            break
    else:
        for robot in msg.due:
            if not 0 <= robot <= MAX_ROBOT_ID:
                break
        else:
            return
    for i, (robot, x, y, th) in enumerate(msg.poses):
        _robot(f".poses[{i}][0]", robot)
        _number(f".poses[{i}][1]", x, -MAX_COORD, MAX_COORD)
        _number(f".poses[{i}][2]", y, -MAX_COORD, MAX_COORD)
        _number(f".poses[{i}][3]", th, -MAX_ANGLE, MAX_ANGLE)
    for i, robot in enumerate(msg.due):
        _robot(f".due[{i}]", robot)


def _command(msg: Any) -> None:
    _robot(".robot", msg.robot)
    _time(".t", msg.t)
    _int(".seq", msg.seq, -1)  # -1: the stale-mocap stop sent before any frame
    for value in msg.u:  # the happy path builds no strings (as _mocap)
        if not -MAX_SPEED <= value <= MAX_SPEED:
            break
    else:
        return
    for i, value in enumerate(msg.u):
        _number(f".u[{i}]", value, -MAX_SPEED, MAX_SPEED)


def _ltl_status(msg: Any) -> None:
    _robot(".robot", msg.robot)
    _time(".t", msg.t)
    for i, state in enumerate(msg.buchi_states):
        _int(f".buchi_states[{i}]", state)
    for i, (_name, count) in enumerate(msg.visits):
        _int(f".visits[{i}][1]", count)
    _int(".rounds", msg.rounds)


def _stl_status(msg: Any) -> None:
    _robot(".robot", msg.robot)
    _time(".t", msg.t)
    for name in ("rho", "rho_max", "lower", "r"):
        _number(f".{name}", getattr(msg, name), -MAX_VALUE, MAX_VALUE, nan_ok=True)
    for name in ("subtask", "stage", "ce", "c"):
        _int(f".{name}", getattr(msg, name))
    _int(".follow", msg.follow)
    for i, count in enumerate(msg.events):
        _int(f".events[{i}]", count)


def _collab(msg: Any) -> None:
    _robot(".sender", msg.sender)
    _robot(".receiver", msg.receiver)
    _time(".t", msg.t)
    _int(".subtask", msg.subtask)
    _int(".c", msg.c)
    _number(".a", msg.a, -MAX_TIME, MAX_TIME, nan_ok=True)  # NaN: no active sub-task
    _number(".b", msg.b, -MAX_TIME, MAX_TIME, nan_ok=True)
    if msg.funnel is not None:  # the receiving core validates the funnel itself (NaN: unset)
        for name in ("a", "b", "t_star", "t_r", "t_knee"):
            _number(f".funnel.{name}", getattr(msg.funnel, name), -MAX_TIME, MAX_TIME, True)
        for name in ("rho_opt", "rho_max", "r", "gamma0", "gamma_inf", "l", "zeta_u", "ramp"):
            _number(f".funnel.{name}", getattr(msg.funnel, name), -MAX_VALUE, MAX_VALUE, True)


def _event(msg: Any) -> None:
    _time(".t", msg.t)
    _free_form(".data", msg.data, LIMITS["Event"])


def _control(msg: Any) -> None:
    _time(".t0", msg.t0)


def _backfill_request(msg: Any) -> None:
    _int(".first", msg.first, 0)
    _int(".last", msg.last, msg.first)


def _backfill_reply(msg: Any) -> None:
    _int(".first", msg.first, 0)
    _int(".last", msg.last, msg.first)
    _int(".oldest", msg.oldest, -1)
    if len(msg.frames) > msg.last - msg.first + 1:
        raise OutOfBounds(".frames", f"{len(msg.frames)} frames for the {msg.last - msg.first + 1}"
                                     f" seqs {msg.first}..{msg.last} the reply covers")


_CHECKS = {"Clock": _clock, "MocapFrame": _mocap, "Command": _command, "LtlStatus": _ltl_status,
           "StlStatus": _stl_status, "CollabMessage": _collab, "Event": _event,
           "Control": _control, "BackfillRequest": _backfill_request,
           "BackfillReply": _backfill_reply}


# --------------------------------------------------------------------------- fleet bounds

_WRAPPED = 4 * math.pi  # [rad] |θ| of a mocap heading (wrapped to (−π, π], noise included)
ARENA_MARGIN = 2.0  # [m] a pose this far outside the arena walls is not a real robot
SPEED_FACTOR = 100.0  # a command above this multiple of the robot's limits is not a real one
TIME_SLACK = 1.0  # [s] beyond the run's duration


#: the C form of :meth:`FleetBounds.frame_problem`'s checks (``_wire.frame_plausible``, installed
#: by :mod:`tlfleet.bus.protocol.fast_paths` when the C codec runs, :func:`use_frame_check`): it can
#: only confirm a frame (True); on False the Python checks below decide and word the problem
_frame_plausible: Callable[..., bool] | None = None


def use_frame_check(check: Callable[..., bool] | None) -> None:
    """Install (or with None remove) the C confirmation of frames (the check runs on
    every frame an agent or the recorder receives, 30 rows at 30 robots)."""
    global _frame_plausible
    _frame_plausible = check


@dataclass(frozen=True)
class FleetBounds:
    """Plausibility of frames and commands in one run (see the module docstring).

    ``box`` = (xmin, xmax, ymin, ymax) [m] of the arena, ``duration`` [s] of the run,
    ``mocap_rate`` [Hz], ``limits`` robot id → (max linear [m/s], max angular [rad/s]).
    """

    box: tuple[float, float, float, float]
    duration: float
    mocap_rate: float
    limits: Mapping[int, tuple[float, float]] = field(default_factory=dict)
    margin: float = ARENA_MARGIN
    speed_factor: float = SPEED_FACTOR
    time_slack: float = TIME_SLACK

    @property
    def t_max(self) -> float:
        return self.duration + self.time_slack

    def _time_and_seq(self, t: float, seq: int) -> str | None:
        if not 0.0 <= t <= self.t_max:
            return f"t = {t!r} s lies outside the run [0, {self.t_max:g}] s"
        # from half a period before the tick to the next tick: a realtime frame sampled after
        # its tick (SimParams.spread_frames) has t = t_seq + s·dt with s·dt < one period
        period = 1.0 / self.mocap_rate
        if not -0.5 * period - 1e-9 <= t - seq / self.mocap_rate < period:
            return (f"t = {t!r} s does not match seq {seq} at {self.mocap_rate:g} Hz "
                    f"(expected {seq / self.mocap_rate:g} s, or up to one period later)")
        return None

    @cached_property
    def _frame_check_args(self) -> tuple[Any, ...] | None:
        """The bounds as ``_wire.frame_plausible`` takes them (exact floats, the limits as a dict
        or None), or None when a bound is not such a value (then only Python checks)."""
        xmin, xmax, ymin, ymax = self.box
        m = self.margin
        values = (self.t_max, self.mocap_rate, xmin - m, xmax + m, ymin - m, ymax + m, _WRAPPED)
        if any(float(v) != v for v in values) or type(self.limits) is not dict:
            return None
        return (*map(float, values), self.limits)

    def frame_problem(self, frame: Any) -> str | None:
        """Why ``frame`` (a MocapFrame) is implausible, or None. The C check, where installed,
        confirms a plausible frame in one call; anything it cannot confirm is judged here."""
        check, args = _frame_plausible, self._frame_check_args
        if check is not None and args is not None and \
                check(frame.t, frame.seq, frame.poses, frame.due, *args):
            return None
        why = self._time_and_seq(frame.t, frame.seq)
        if why:
            return why
        xmin, xmax, ymin, ymax = self.box
        m = self.margin
        x_lo, x_hi, y_lo, y_hi = xmin - m, xmax + m, ymin - m, ymax + m
        limits = self.limits
        previous = -1
        for robot, x, y, th in frame.poses:
            if limits and robot not in limits:
                return f"pose of unknown robot {robot}"
            if robot <= previous:
                return f"robot ids not strictly ascending ({previous}, {robot})"
            previous = robot
            if not (x_lo <= x <= x_hi and y_lo <= y <= y_hi):
                return f"robot {robot} at ({x!r}, {y!r}) lies outside the arena"
            if not -_WRAPPED <= th <= _WRAPPED:
                return f"robot {robot} heading {th!r} rad is not wrapped"
        if limits:
            for robot in frame.due:
                if robot not in limits:
                    return f"due robot {robot} is unknown"
        return None

    def command_problem(self, command: Any) -> str | None:
        """Why ``command`` (a Command) is implausible, or None."""
        if command.seq == -1 and command.t == 0.0:
            pass  # the stale-mocap stop sent before any frame
        else:
            why = self._time_and_seq(command.t, command.seq)
            if why:
                return why
        limit = self.limits.get(command.robot)
        if limit is None:  # an unknown robot: the simulator counts it as such
            return None
        lin, ang = limit
        caps = (lin, lin, ang) if len(command.u) == 3 else (lin, ang)
        for value, cap in zip(command.u, caps, strict=False):
            if abs(value) > self.speed_factor * cap + 1.0:
                return (f"command value {value!r} exceeds {self.speed_factor:g}× the robot's "
                        f"limit {cap:g}")
        return None
