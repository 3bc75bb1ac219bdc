"""The pymunk world: arena walls, static obstacles and velocity-tracking robots.

Plays the robots' hardware as in the paper's experiments (§IV): each robot tracks its last
velocity command with a low-level controller, modelled here as first-order velocity tracking
with acceleration limits,

    v̇ = sat_a((u − v) / τ),        u = sat_max(command),                       (tracking)

where ``sat_max`` clips the command to the robot's velocity limits and ``sat_a`` clips the
acceleration to its acceleration limits. The paper's system (1), ẋ_i = f_i + g_i u_i + w_i, is
completed by the bounded additive disturbance w_i ∈ ℝ³ (world-frame (vx [m/s], vy [m/s],
ω [rad/s]), ‖w_i‖ ≤ ``SimParams.disturbance``), drawn uniformly in that ball once per
:meth:`World.step` and held constant over it.

* Omnidirectional robots track the world-frame command ``(vx, vy, ω)``; the linear part is
  clipped in norm (‖(vx, vy)‖ ≤ ``max_lin``), the linear acceleration in norm too.
* Unicycles track ``(v, ω)``: the linear velocity is always along the heading (no lateral slip;
  only the disturbance, which is part of the model (1), moves them sideways).

Collisions stay physical (stack-notes.md §3): robots are dynamic, frictionless, inelastic discs
whose velocity is set in the body's velocity update function — i.e. before pymunk's contact
solver, never by writing ``body.velocity`` before ``space.step`` — and the tracking starts from
the velocity the solver left, so a robot pushed back by a wall or a robot re-accelerates within
its limits. The update function is the one place where speed matters (robots × physics rate
laws per second: 30 000/s for 30 robots at 1 kHz), so it is installed as a C callback of
Chipmunk's ``cpBodySetVelocityUpdateFunc`` through pymunk's own cffi module and reads and writes
the body with Chipmunk's getters and setters: what ``body.velocity_func`` and the ``Body``
properties do, without a ``Vec2d`` per read and a Python ``__setattr__`` per write (half the
physics time); and one such callback per physics step runs the law of every robot
(:meth:`World._install_tracking`), instead of one per robot. That one callback runs
the law in C (``sim/tracking.c``, built at install time as ``tlfleet.sim._tracking``; several times
cheaper than 5 Python laws) or, where the extension was not built or
``WorldConfig.tracking = "python"``, in Python (:meth:`SimRobot.track`): the same IEEE operations
in the same order, so both give the same trajectories to the last bit (tests/sim). The law's
norm is ``sqrt(x² + y²)``, correctly rounded in C and in Python alike (``math.hypot``'s CPython
and libm versions may differ in the last bit).

Contacts (robot–robot, robot–wall/obstacle) are recorded on each contact *begin* and drained with
:meth:`World.drain_contacts`. The command watchdog (architecture.md §1, contract) stops a robot
whose last command is older than ``SimParams.watchdog`` seconds of sim time.

Only this package imports pymunk (architecture.md §4); this module knows nothing of zenoh.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pymunk
from pymunk._chipmunk_cffi import ffi as _ffi
from pymunk._chipmunk_cffi import lib as _cp
from tlfleet.agent.model.scenario import DiscObstacle, RectObstacle, Robot, Scenario
from tlfleet.bus.errors import TlfleetError

try:  # the C tracking law (setup.py builds it where a C compiler is; optional)
    from tlfleet.sim import _tracking as _native
except ImportError:  # pragma: no cover - depends on the install
    _native = None

TRACKING_CHOICES = ("auto", "native", "python")


class TrackingConfigError(TlfleetError, ValueError):
    """``WorldConfig.tracking`` (or ``$TLFLEET_TRACKING``) is unknown or asks for a C law that
    was not built."""

ROBOT_TYPE = 1  # pymunk collision types
WALL_TYPE = 2
WALL = "wall"  # the "robot id" of a wall or obstacle in contact records
# Chipmunk's accessors, looked up once (the tracking law runs 5 000 times per sim second)
_get_velocity, _set_velocity = _cp.cpBodyGetVelocity, _cp.cpBodySetVelocity
_get_angular_velocity = _cp.cpBodyGetAngularVelocity
_set_angular_velocity = _cp.cpBodySetAngularVelocity
_get_angle = _cp.cpBodyGetAngle
_get_position = _cp.cpBodyGetPosition
_space_step = _cp.cpSpaceStep
_sqrt, _cos, _sin = math.sqrt, math.cos, math.sin


def native_tracking_available() -> bool:
    """Whether the C tracking law (``tlfleet.sim._tracking``) was built at install time."""
    return _native is not None


def _default_tracking() -> str:
    return os.environ.get("TLFLEET_TRACKING", "auto")


# tl_chipmunk's fields (sim/tracking.h) in order, and the Chipmunk function each one points to
_CHIPMUNK_ACCESSORS = (
    ("get_velocity", "cpBodyGetVelocity"),
    ("set_velocity", "cpBodySetVelocity"),
    ("get_angular_velocity", "cpBodyGetAngularVelocity"),
    ("set_angular_velocity", "cpBodySetAngularVelocity"),
    ("get_angle", "cpBodyGetAngle"),
    ("get_position", "cpBodyGetPosition"),
)


@dataclass(frozen=True)
class WorldConfig:
    """Physical constants of the simulated world (not part of the scenario file)."""

    tracking_tau: float = 0.02  # [s] time constant τ of the first-order velocity tracking
    robot_mass: float = 2.0  # [kg]
    wall_radius: float = 0.05  # [m] thickness/2 of the arena's wall segments (outside the arena)
    collision_slop: float = 0.001  # [m] allowed overlap (pymunk's default 0.1 is pixel-scale)
    solver_iterations: int = 10
    # where the tracking law runs: "native" (C, tlfleet.sim._tracking), "python", or "auto" (C when
    # it was built); the same trajectories either way. Default: $TLFLEET_TRACKING, else "auto".
    tracking: str = field(default_factory=_default_tracking)

    def __post_init__(self) -> None:
        if self.tracking not in TRACKING_CHOICES:
            raise TrackingConfigError(
                f"WorldConfig.tracking (or $TLFLEET_TRACKING): expected one of "
                f"{', '.join(TRACKING_CHOICES)}, got {self.tracking!r}")
        if self.tracking == "native" and _native is None:
            raise TrackingConfigError(
                "WorldConfig.tracking (or $TLFLEET_TRACKING) = 'native', but the C tracking law "
                "(tlfleet.sim._tracking) was not built: reinstall with a C compiler")

    @property
    def native_tracking(self) -> bool:
        """Whether worlds of this configuration run the C law."""
        return self.tracking == "native" or (self.tracking == "auto" and _native is not None)


@dataclass(frozen=True)
class Contact:
    """One contact begin: robot ``a`` touched robot ``b`` (``a < b``) or a wall/obstacle.

    ``what`` names the static shape ("arena" or "obstacle:<name>") for wall contacts.
    """

    a: int
    b: int | str
    what: str = ""


def wrap_angle(theta: float) -> float:
    """θ wrapped to (−π, π] [rad]."""
    wrapped = math.atan2(math.sin(theta), math.cos(theta))
    return math.pi if wrapped <= -math.pi else wrapped


def _limit_norm(x: float, y: float, bound: float) -> tuple[float, float]:
    """(x, y) scaled down to norm ≤ ``bound`` (exactly: rounding never leaves it above)."""
    norm = math.hypot(x, y)
    if norm <= bound:
        return x, y
    scale = bound / norm
    while math.hypot(x * scale, y * scale) > bound:
        scale = math.nextafter(scale, 0.0)
    return x * scale, y * scale


def _limit_norm_sqrt(x: float, y: float, bound: float) -> tuple[float, float]:
    """The tracking law's :func:`_limit_norm`: the norm as ``sqrt(x² + y²)``, the operations
    of ``limit_norm`` in ``sim/tracking.c``."""
    norm = _sqrt(x * x + y * y)
    if norm <= bound:
        return x, y
    scale = bound / norm
    while True:
        xs, ys = x * scale, y * scale
        if not _sqrt(xs * xs + ys * ys) > bound:
            break
        scale = math.nextafter(scale, 0.0)
    return x * scale, y * scale


def _limit(value: float, bound: float) -> float:
    return min(bound, max(-bound, value))


def _idle(space: pymunk.Space) -> bool:
    """True when pymunk's ``Space.step`` would only call ``cpSpaceStep``: no body added since
    the last step (the wrapper checks their mass), no deferred addition, removal or post-step
    callback, not the threaded solver."""
    return not (space._bodies_to_check or space._add_later or space._remove_later
                or space._post_step_callbacks or space.threaded)


class SimRobot:
    """One robot's body, shape and low-level velocity tracking (see the module docstring).

    ``target`` is the clipped command: world-frame ``(vx, vy, ω)`` for omni robots, ``(v, ω)``
    for unicycles. ``disturbance`` is w_i = (wx, wy, wω), the part of the body's velocity that is
    not the tracked velocity.
    """

    def __init__(self, robot: Robot, config: WorldConfig):
        self.id = robot.id
        self.kind = robot.kind
        self.radius = robot.radius
        self._tau = config.tracking_tau
        if robot.kind == "omni":
            lim = robot.omni
            self.max_lin, self.max_ang = lim.max_lin, lim.max_ang
            self.acc_lin, self.acc_ang = lim.acc_lin, lim.acc_ang
            self._target: tuple[float, ...] = (0.0, 0.0, 0.0)
        else:
            lim = robot.unicycle
            self.max_lin, self.max_ang = lim.max_v, lim.max_omega
            self.acc_lin, self.acc_ang = lim.acc_v, lim.acc_omega
            self._target = (0.0, 0.0)
        self._disturbance = (0.0, 0.0, 0.0)  # w_i to apply from the next physics step on
        self._applied = (0.0, 0.0, 0.0)  # w_i inside the body's current velocity (Python law)
        self._native = None  # this robot's tl_robot when the world runs the C law
        self.last_command_t: float | None = None  # [s] sim time of the last accepted command
        self.watchdog_tripped = False
        # the last command clipped and its result: the simulator checks a command when it
        # arrives and applies the same tuple at the tick (one clip per command)
        self._clipped_for: object = None
        self._clipped: tuple[float, ...] = ()

        self.body = pymunk.Body(config.robot_mass,
                                pymunk.moment_for_circle(config.robot_mass, 0, robot.radius))
        x, y, theta = robot.pose
        self.body.position = (x, y)
        self.body.angle = theta
        self._cbody = self.body._body  # Chipmunk's cpBody* of this body
        self._omni = robot.kind == "omni"
        self._dt = math.nan  # [s] the physics step the cached constants below belong to
        self._gain = self._dv_max = self._dw_max = math.nan
        self.shape = pymunk.Circle(self.body, robot.radius)
        self.shape.friction = 0.0
        self.shape.elasticity = 0.0
        self.shape.collision_type = ROBOT_TYPE

    @property
    def target(self) -> tuple[float, ...]:
        """The clipped command the law tracks: ``(vx, vy, ω)`` or ``(v, ω)``."""
        return self._target

    @target.setter
    def target(self, value: tuple[float, ...]) -> None:
        self._target = value
        if self._native is not None:
            if self._omni:
                self._native.target = value
            else:
                self._native.target = (value[0], 0.0, value[1])

    @property
    def disturbance(self) -> tuple[float, float, float]:
        """w_i = (wx, wy, wω) applied from the next physics step on."""
        return self._disturbance

    @disturbance.setter
    def disturbance(self, value: tuple[float, float, float]) -> None:
        self._disturbance = value
        if self._native is not None:
            self._native.disturbance = value

    def bind_native(self, native: object) -> None:
        """Run this robot's law in C from now on: ``native`` is its ``tl_robot`` (the state
        so far is copied in; :class:`World` calls this before the first step)."""
        native.body = _native.ffi.cast("void *", int(_ffi.cast("uintptr_t", self._cbody)))
        native.omni = int(self._omni)
        native.tau, native.acc_lin, native.acc_ang = self._tau, self.acc_lin, self.acc_ang
        native.dt = native.gain = native.dv_max = native.dw_max = math.nan
        native.applied = self._applied
        self._native = native
        self.target, self.disturbance = self._target, self._disturbance

    def clipped(self, u: Sequence[float]) -> tuple[float, ...]:
        """``u`` clipped to the velocity limits; ``ValueError`` if it is malformed.

        The result for the very object ``u`` last clipped is reused (identity, not equality:
        −0.0 == 0.0, and a list may change in between)."""
        if u is self._clipped_for and type(u) is tuple:
            return self._clipped
        clipped = self._clip(u)
        self._clipped_for, self._clipped = u, clipped
        return clipped

    def _clip(self, u: Sequence[float]) -> tuple[float, ...]:
        expected = 3 if self.kind == "omni" else 2
        if len(u) != expected:
            raise ValueError(f"robot {self.id} ({self.kind}) expects {expected} command values, "
                             f"got {len(u)}")
        if not all(math.isfinite(v) for v in u):
            raise ValueError(f"robot {self.id}: non-finite command {tuple(u)!r}")
        if self.kind == "omni":
            vx, vy = _limit_norm(float(u[0]), float(u[1]), self.max_lin)
            return (vx, vy, _limit(float(u[2]), self.max_ang))
        return (_limit(float(u[0]), self.max_lin), _limit(float(u[1]), self.max_ang))

    def stop(self) -> None:
        self.target = (0.0, 0.0, 0.0) if self.kind == "omni" else (0.0, 0.0)

    def track(self, dt: float) -> None:
        """One physics step ``dt`` [s] of the tracking law on this body's velocity: called by
        :meth:`World._track_all` from Chipmunk's velocity update (after the positions are
        integrated, before the contact solver).

        Runs for every robot at every physics step (5 robots at 1 kHz: 5 000 calls per sim
        second) where the C law (``sim/tracking.c``) is not used, so the per-step constants are
        cached per ``dt`` and the omni and unicycle laws are separate straight-line paths; the
        floating-point operations and their order are those of the plain law and of the C law
        (tests/sim: byte-identical trajectories).
        """
        if dt != self._dt:
            self._dt = dt
            self._gain = dt / max(self._tau, dt)  # first-order step, never overshooting
            self._dv_max, self._dw_max = self.acc_lin * dt, self.acc_ang * dt
        gain = self._gain
        cbody = self._cbody
        old_wx, old_wy, old_ww = self._applied
        vel = _get_velocity(cbody)
        vx, vy = vel.x - old_wx, vel.y - old_wy  # tracked linear velocity the solver left [m/s]
        omega = _get_angular_velocity(cbody) - old_ww  # [rad/s]
        # min(b, max(-b, x)) written as comparisons (no builtin calls): the same value for every
        # x, ties included (max and min return their first argument on a tie)
        if self._omni:
            ux, uy, uw = self._target
            dvx, dvy = (ux - vx) * gain, (uy - vy) * gain
            if _sqrt(dvx * dvx + dvy * dvy) > self._dv_max:  # the limit's own test, inline
                dvx, dvy = _limit_norm_sqrt(dvx, dvy, self._dv_max)
            vx, vy = vx + dvx, vy + dvy
        else:
            u_lin, uw = self._target
            angle = _get_angle(cbody)
            c, s = _cos(angle), _sin(angle)
            v = vx * c + vy * s  # forward speed; the lateral part is dropped (no slip)
            dv_max = self._dv_max
            dv = (u_lin - v) * gain
            dv = dv if dv > -dv_max else -dv_max
            v += dv if dv < dv_max else dv_max
            vx, vy = v * c, v * s
        dw_max = self._dw_max
        dw = (uw - omega) * gain
        dw = dw if dw > -dw_max else -dw_max
        omega += dw if dw < dw_max else dw_max
        wx, wy, ww = self._applied = self._disturbance
        _set_velocity(cbody, (vx + wx, vy + wy))
        _set_angular_velocity(cbody, omega + ww)


class World:
    """The simulated fleet: one pymunk space, walls, obstacles and :class:`SimRobot` s.

    Build it with :meth:`from_scenario`; the random generator (disturbance, mocap noise) is
    passed in and is the world's only source of randomness, so equal seeds give equal runs.
    """

    def __init__(self, scenario: Scenario, rng: np.random.Generator,
                 config: WorldConfig | None = None):
        self.config = config or WorldConfig()
        self.rng = rng
        self.physics_dt = 1.0 / scenario.sim.physics_rate  # [s]
        self.disturbance_bound = scenario.sim.disturbance  # [m/s] bound on ‖w_i‖
        self.mocap_noise = scenario.sim.mocap_noise  # [m] and [rad], standard deviation
        self.watchdog = scenario.sim.watchdog  # [s]
        self.time = 0.0  # [s] sim time of the physics state
        self.space = pymunk.Space()
        self.space.gravity = (0.0, 0.0)
        self.space.collision_slop = self.config.collision_slop
        self.space.iterations = self.config.solver_iterations
        self._contacts: list[Contact] = []
        self._static_names: dict[pymunk.Shape, str] = {}
        self._add_arena(scenario)
        self.robots: dict[int, SimRobot] = {}
        for robot in sorted(scenario.robots, key=lambda r: r.id):
            sim_robot = SimRobot(robot, self.config)
            self.space.add(sim_robot.body, sim_robot.shape)
            self.robots[robot.id] = sim_robot
        self.ids = tuple(self.robots)  # ascending
        self._native_cp: Any = None  # the C law's accessors and robots (_install_tracking)
        self._native_robots: Any = None
        self._install_tracking()
        self._robot_of_shape = {r.shape: r.id for r in self.robots.values()}
        self.space.on_collision(ROBOT_TYPE, ROBOT_TYPE, begin=self._on_robot_robot)
        self.space.on_collision(ROBOT_TYPE, WALL_TYPE, begin=self._on_robot_wall)

    @classmethod
    def from_scenario(cls, scenario: Scenario, rng: np.random.Generator,
                      config: WorldConfig | None = None) -> World:
        return cls(scenario, rng, config)

    # ----------------------------------------------------------------- building

    def _add_static(self, shape: pymunk.Shape, name: str) -> None:
        shape.friction = 0.0
        shape.elasticity = 0.0
        shape.collision_type = WALL_TYPE
        self._static_names[shape] = name
        self.space.add(shape)

    def _add_arena(self, scenario: Scenario) -> None:
        arena, r = scenario.arena, self.config.wall_radius
        static = self.space.static_body
        # Segments lie ``r`` outside the border, so their inner face is the arena's edge.
        x0, x1, y0, y1 = arena.xmin - r, arena.xmax + r, arena.ymin - r, arena.ymax + r
        for a, b in (((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)), ((x1, y1), (x0, y1)),
                     ((x0, y1), (x0, y0))):
            self._add_static(pymunk.Segment(static, a, b, r), "arena")
        for obstacle in arena.obstacles:
            name = f"obstacle:{obstacle.name}" if obstacle.name else "obstacle"
            if isinstance(obstacle, RectObstacle):
                box = [(obstacle.xmin, obstacle.ymin), (obstacle.xmax, obstacle.ymin),
                       (obstacle.xmax, obstacle.ymax), (obstacle.xmin, obstacle.ymax)]
                self._add_static(pymunk.Poly(static, box), name)
            elif isinstance(obstacle, DiscObstacle):
                self._add_static(pymunk.Circle(static, obstacle.radius, obstacle.center), name)

    def _install_tracking(self) -> None:
        """One Chipmunk velocity callback per physics step runs every robot's tracking law
        (a Python callback costs about as much as the law itself; 5 robots at 1 kHz
        made 5 000 of them per sim second).

        Chipmunk's step integrates every body's position, finds the contacts, then calls each
        body's velocity update in turn before the solver. The callback sits on the first robot's
        body; when it runs, every robot's velocity is still what the solver left and every angle
        is already integrated, exactly as each robot's own callback saw them, and each robot's
        law reads only its own body. The other bodies keep Chipmunk's ``cpBodyUpdateVelocity``,
        v ← v·damping + (g + f/m)·dt, ω ← ω·damping + τ/I·dt, which with no gravity, a damping
        of 1 and no forces or torques (nothing here applies any) leaves v and ω as set: x·1.0 and
        x + 0.0 are x for every double but −0.0, and no tracked velocity is −0.0 (it ends with a
        sum whose disturbance term is +0.0 or non-zero). So the trajectories are bit-identical
        to one callback per body (tests/sim).
        """
        space = self.space
        if space.damping != 1.0 or tuple(space.gravity) != (0.0, 0.0):
            raise ValueError("World: the batched tracking law needs damping 1 and no gravity "
                             "(the other bodies' default velocity update must change nothing)")
        self._tracked = tuple(self.robots.values())
        if not self._tracked:
            return
        update = self._track_all
        if self.config.native_tracking:
            ffi = _native.ffi
            self._native_robots = ffi.new("tl_robot[]", len(self._tracked))
            for i, robot in enumerate(self._tracked):
                robot.bind_native(self._native_robots[i])
            fields = dict(ffi.typeof("tl_chipmunk").fields)  # pymunk's pointers, C's types
            self._native_cp = ffi.new("tl_chipmunk *", {
                name: ffi.cast(fields[name].type,
                               int(_ffi.cast("uintptr_t", _ffi.addressof(_cp, symbol))))
                for name, symbol in _CHIPMUNK_ACCESSORS})
            update = self._track_all_native
            self._pose_buffer = ffi.new("double[]", 3 * len(self._tracked))
        # kept referenced: Chipmunk holds only the raw function pointer
        self._velocity_update = _ffi.callback("void(cpBody *, cpVect, cpFloat, cpFloat)", update)
        _cp.cpBodySetVelocityUpdateFunc(self._tracked[0]._cbody, self._velocity_update)

    def _track_all(self, _body: object, _gravity: object, _damping: float, dt: float) -> None:
        """Chipmunk's velocity update of the first robot's body: every robot's tracking law."""
        for robot in self._tracked:
            robot.track(dt)

    def _track_all_native(self, _body: object, _gravity: object, _damping: float, dt: float
                          ) -> None:
        """:meth:`_track_all` with the law in C: one call for every robot."""
        _native.lib.tl_track_all(self._native_cp, self._native_robots, len(self._tracked), dt)

    # ----------------------------------------------------------------- contacts

    def _on_robot_robot(self, arbiter: pymunk.Arbiter, _space: pymunk.Space, _data: object
                        ) -> None:
        a, b = (self._robot_of_shape[s] for s in arbiter.shapes)
        self._contacts.append(Contact(min(a, b), max(a, b)))

    def _on_robot_wall(self, arbiter: pymunk.Arbiter, _space: pymunk.Space, _data: object
                       ) -> None:
        robot_shape, wall_shape = arbiter.shapes
        self._contacts.append(Contact(self._robot_of_shape[robot_shape], WALL,
                                      self._static_names.get(wall_shape, "")))

    def drain_contacts(self) -> list[Contact]:
        """Contact begins since the last call, in the order pymunk reported them."""
        contacts, self._contacts = self._contacts, []
        return contacts

    # ----------------------------------------------------------------- commands

    def set_command(self, robot: int, u: Sequence[float], t: float) -> None:
        """Robot ``robot`` tracks ``u`` from now on (zero-order hold); ``t`` = sim time [s].

        ``KeyError`` for an unknown robot, ``ValueError`` for a command of the wrong length or
        with non-finite values (the previous command then stays in force).
        """
        sim_robot = self.robots[robot]
        sim_robot.target = sim_robot.clipped(u)
        sim_robot.last_command_t = t
        sim_robot.watchdog_tripped = False

    def check_command(self, robot: int, u: Sequence[float]) -> None:
        """Raise as :meth:`set_command` would, without applying anything."""
        self.robots[robot].clipped(u)

    def check_watchdog(self, t: float) -> list[int]:
        """Stop every robot whose last command is older than the watchdog period at sim time
        ``t``; return the robots stopped *now* (each once until it is commanded again).

        A robot that was never commanded is at rest with a zero command and is not reported.
        """
        stopped = []
        for sim_robot in self.robots.values():
            last = sim_robot.last_command_t
            if last is None or sim_robot.watchdog_tripped:
                continue
            if t - last > self.watchdog + 1e-9:
                sim_robot.stop()
                sim_robot.watchdog_tripped = True
                stopped.append(sim_robot.id)
        return stopped

    # ----------------------------------------------------------------- time

    def substeps(self, duration: float) -> int:
        return max(1, round(duration / self.physics_dt))

    def step(self, duration: float, *, draw_disturbance: bool = True) -> None:
        """Advance the physics by ``duration`` [s] in physics-rate sub-steps.

        A fresh disturbance w_i (uniform in the ball ‖w‖ ≤ bound) is drawn for every robot first
        and held over the whole call; ``draw_disturbance=False`` keeps the last one (a mocap
        period stepped in parts, for frames sampled between its ticks, holds one draw).
        """
        if draw_disturbance:
            self._draw_disturbance()
        n = self.substeps(duration)
        dt = duration / n
        space = self.space
        # Chipmunk's cpSpaceStep, called as pymunk's wrapper calls it (the wrapper's
        # Python costs ≈ 3 µs per sub-step), while the wrapper would have nothing else to do: no
        # new body to check, nothing deferred (the contact callbacks only record), not the
        # threaded solver. Otherwise the wrapper runs the first sub-step and does what waits.
        if not _idle(space):
            space.step(dt)
            n -= 1
        if _idle(space):
            cspace = space._space
            space._locked = True
            try:
                for _ in range(n):
                    _space_step(cspace, dt)
            finally:
                space._locked = False
            space._removed_shapes.clear()
        else:
            for _ in range(n):
                space.step(dt)
        self.time += duration

    def _draw_disturbance(self) -> None:
        if self.disturbance_bound <= 0.0:
            return
        n = len(self.ids)
        direction = self.rng.normal(size=(n, 3))
        norms = np.linalg.norm(direction, axis=1, keepdims=True)
        norms[norms == 0.0] = 1.0
        radius = self.disturbance_bound * self.rng.random((n, 1)) ** (1.0 / 3.0)
        w = direction / norms * radius
        for (wx, wy, ww), robot in zip(w.tolist(), self.robots.values(), strict=True):
            robot.disturbance = (wx, wy, ww)

    # ----------------------------------------------------------------- read-out

    def poses(self) -> tuple[tuple[int, float, float, float], ...]:
        """True poses ``(id, x [m], y [m], θ [rad] in (−π, π])``, ids ascending."""
        if self._native_cp is not None:
            return self._read_native(None)
        out = []
        for rid, sim_robot in self.robots.items():
            cbody = sim_robot._cbody  # Chipmunk's values, as body.position and body.angle give
            p = _get_position(cbody)
            out.append((rid, p.x, p.y, wrap_angle(_get_angle(cbody))))
        return tuple(out)

    def mocap_poses(self) -> tuple[tuple[int, float, float, float], ...]:
        """What the motion-capture system reports: the true poses plus Gaussian noise
        (σ = ``mocap_noise`` on x [m], y [m] and θ [rad]), θ wrapped to (−π, π]."""
        if self.mocap_noise <= 0.0:
            return self.poses()
        noise = self.rng.normal(0.0, self.mocap_noise, size=(len(self.ids), 3))
        if self._native_cp is not None:
            return self._read_native(noise)
        return tuple((rid, x + nx, y + ny, wrap_angle(th + nth))
                     for (rid, x, y, th), (nx, ny, nth) in zip(self.poses(), noise.tolist(),
                                                               strict=True))

    def _read_native(self, noise: np.ndarray | None) -> tuple[tuple[int, float, float, float],
                                                               ...]:
        """:meth:`poses` (``noise`` None) or :meth:`mocap_poses` (``noise``: n × 3, C order) read
        by ``tl_read_poses`` in one call (30 robots pose by pose in Python cost ≈ 40 µs
        per frame from cold caches); the same values to the last bit (tests/sim)."""
        ffi, out, n = _native.ffi, self._pose_buffer, len(self._tracked)
        _native.lib.tl_read_poses(self._native_cp, self._native_robots, n,
                                  ffi.NULL if noise is None else ffi.from_buffer("double[]", noise),
                                  out)
        values = iter(ffi.unpack(out, 3 * n))
        return tuple(zip(self.ids, values, values, values, strict=True))

    def velocities(self) -> dict[int, tuple[float, float, float]]:
        """Each robot's world-frame body velocity ``(vx [m/s], vy [m/s], ω [rad/s])``."""
        return {rid: (r.body.velocity.x, r.body.velocity.y, r.body.angular_velocity)
                for rid, r in self.robots.items()}
