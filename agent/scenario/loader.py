"""Validating loader for scenario TOML files (architecture.md §5).

``load_scenario(path)`` reads a file and returns a ``Scenario``; ``parse_scenario(data, source)``
does the same for an already-decoded TOML table. Every problem is a ``ScenarioError`` that names
the file, the field path (``robots[id=3].pose``: a robot is named by its id,
:mod:`tlfleet.agent.scenario.fields`) and what was expected. Unknown keys are errors, so a
typo never silently falls back to a default.

File layout (every section but ``robots`` is optional)::

    name = "scenario1"            # fleet defaults to the name; used in Zenoh keys
    duration = 90.0               # [s]
    [arena]   xmin/xmax/ymin/ymax [m], [[arena.obstacles]] shape = "rect"|"disc"
    [ltl]     suffix_weight, control_rate, stagger      (LtlParams)
    [stl]     eta, n_stage1, delta, zeta_l, r1, r_sense, beta, control_rate, hold_f_above_r,
              complete_f_on_satisfaction, complete_f_at_goal, lookahead, saturation_aware,
              saturation_share, rho_opt_from_arena, coupled_radii, coupled_r1_margin,
              coupled_r_margin, wall_avoidance, wall_r1_margin, wall_r_margin, route_around,
              recovery   (StlParams; recovery: docs/coupling.md; the others:
              docs/stl-saturation.md)
    [sim]     physics_rate, mocap_rate, disturbance, mocap_noise, seed, watchdog, spread_frames,
              frame_slots
              (SimParams)
    [navigation] coupling_aware, coupling_share   (NavParams, docs/coupling.md)
    [[regions]] name, center = [x, y], radius, labels = [...]
    [[robots]]  id, kind = "unicycle"|"omni", pose = [x, y, θ], radius,
                ltl = "..." | stl = ["...", ...], phase_start_times, rho_opt, [robots.limits]
    [[faults]]  spec = "cut:robot3@20+3" | kind, target (targets for a partition), at, duration
                (agent/model/faults.py)
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tlfleet.agent.model.faults import (
    Fault,
    FaultSpecError,
    check_duration,
    check_fault,
    check_time,
    parse_fault,
    parse_kind,
    parse_targets,
)
from tlfleet.agent.model.scenario import (
    Arena,
    DiscObstacle,
    LtlParams,
    NavParams,
    OmniLimits,
    RectObstacle,
    Region,
    Robot,
    Scenario,
    SimParams,
    StlParams,
    UnicycleLimits,
)
from tlfleet.agent.scenario import validation
from tlfleet.agent.scenario.fields import ordinal_table, robot_field
from tlfleet.bus.errors import FormulaSyntaxError, ScenarioError

if TYPE_CHECKING:
    from tlfleet.agent.ltl.formula import Formula
    from tlfleet.agent.stl.syntax import Temporal

#: keys a ``[[robots]]`` table holds and the top level holds: a TOML table runs until the next
#: header, so a robot key written after ``[robots.limits]`` (or a top-level key after ``[sim]``)
#: lands in that table; :meth:`_Table.finish` names the trap instead of an unknown key
ROBOT_KEYS = frozenset({"id", "kind", "pose", "radius", "ltl", "stl", "phase_start_times",
                        "rho_opt", "limits"})
TOP_KEYS = frozenset({"name", "fleet", "duration", "description"})
ATOM_RE = re.compile(r"[a-z_][a-z0-9_]*\Z")
FLEET_RE = re.compile(r"[A-Za-z0-9_-]+\Z")
RESERVED_ATOMS = frozenset({"true", "false", "xor"})


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file; ``ScenarioError`` on any problem."""
    path = Path(path)
    data = validation.parse_toml(validation.read_text(path), str(path))  # file limits
    return parse_scenario(data, source=str(path))


def parse_scenario(data: dict[str, Any], source: str = "<scenario>") -> Scenario:
    """Validate a decoded TOML table and build the ``Scenario``."""
    top = _Table(data, "", source)
    name = top.string("name")
    if not name:
        raise ScenarioError(source, "name", "expected a non-empty string")
    validation.check_name(source, name)
    fleet = top.string("fleet", default=name)
    if not FLEET_RE.match(fleet):
        raise ScenarioError(
            source, "fleet", f"{fleet!r} is not usable in a key expression: "
                             "use letters, digits, _ and -")
    duration = top.number("duration", positive=True)
    description = top.string("description", default="")
    arena = _arena(top.table("arena", required=False, outer_keys=TOP_KEYS))
    ltl = _params(top.table("ltl", required=False, outer_keys=TOP_KEYS), LtlParams)
    stl = _params(top.table("stl", required=False, outer_keys=TOP_KEYS), StlParams)
    sim = _params(top.table("sim", required=False, outer_keys=TOP_KEYS), SimParams)
    navigation = _navigation(top.table("navigation", required=False, outer_keys=TOP_KEYS), source)
    if stl.r1 >= stl.r_sense:
        raise ScenarioError(source, "stl.r1",
                            f"must be below stl.r_sense = {stl.r_sense}, got {stl.r1}")
    if stl.saturation_share > 1.0:
        raise ScenarioError(source, "stl.saturation_share",
                            f"must be in (0, 1] (a share of the achievable rate), got "
                            f"{stl.saturation_share}")
    for inner, outer in (("coupled_r1_margin", "coupled_r_margin"),
                         ("wall_r1_margin", "wall_r_margin")):
        if getattr(stl, inner) >= getattr(stl, outer):
            raise ScenarioError(source, f"stl.{inner}",
                                f"must be below stl.{outer} = {getattr(stl, outer)}, got "
                                f"{getattr(stl, inner)}")
    regions = tuple(_region(t, arena) for t in top.array_of_tables("regions", required=False))
    _unique(source, "regions", [(r.name, i) for i, r in enumerate(regions)], "region name")
    robots = tuple(_robot(t, arena, i) for i, t in enumerate(top.array_of_tables("robots")))
    if not robots:
        raise ScenarioError(source, "robots", "expected at least one [[robots]] table")
    _unique(source, "robots", [(r.id, i) for i, r in enumerate(robots)], "robot id")
    faults = tuple(_fault(t, [r.id for r in robots], duration)
                   for t in top.array_of_tables("faults", required=False))
    top.finish()

    scenario = Scenario(
        name=name,
        fleet=fleet,
        duration=duration,
        arena=arena,
        regions=regions,
        robots=robots,
        ltl=ltl,
        stl=stl,
        sim=sim,
        navigation=navigation,
        description=description,
        source=Path(source) if source and not source.startswith("<") else None,
        faults=faults,
    )
    validation.check_scenario(scenario, source)  # sizes, rates, geometry
    _check_start_poses(scenario, source)
    for index, robot in enumerate(robots):
        where = robot_field(index, robot.id)
        if robot.ltl is not None:
            _check_ltl_task(robot.ltl, scenario, source, f"{where}.ltl")
        for k, text in enumerate(robot.stl):
            _check_stl_task(text, scenario.robot_ids, source, f"{where}.stl[{k}]")
    validation.check_tasks(scenario, source)  # satisfiability, STL windows
    from tlfleet.agent.scenario.stl_checks import check_stl_tasks

    check_stl_tasks(scenario, source)
    return scenario


# --------------------------------------------------------------------------- sections


def _arena(table: _Table | None) -> Arena:
    if table is None:
        return Arena()
    defaults = Arena()
    xmin = table.number("xmin", default=defaults.xmin)
    xmax = table.number("xmax", default=defaults.xmax)
    ymin = table.number("ymin", default=defaults.ymin)
    ymax = table.number("ymax", default=defaults.ymax)
    if xmin >= xmax:
        table.fail("xmax", f"must exceed xmin = {xmin}, got {xmax}")
    if ymin >= ymax:
        table.fail("ymax", f"must exceed ymin = {ymin}, got {ymax}")
    obstacles = tuple(_obstacle(t) for t in table.array_of_tables("obstacles", required=False))
    table.finish()
    return Arena(xmin=xmin, xmax=xmax, ymin=ymin, ymax=ymax, obstacles=obstacles)


def _obstacle(table: _Table) -> RectObstacle | DiscObstacle:
    shape = table.choice("shape", ("rect", "disc"))
    name = table.string("name", default="")
    if shape == "rect":
        xmin, xmax = table.number("xmin"), table.number("xmax")
        ymin, ymax = table.number("ymin"), table.number("ymax")
        if xmin >= xmax or ymin >= ymax:
            table.fail("", f"empty rectangle: expected xmin < xmax and ymin < ymax, got "
                           f"x [{xmin}, {xmax}], y [{ymin}, {ymax}]")
        table.finish()
        return RectObstacle(xmin=xmin, ymin=ymin, xmax=xmax, ymax=ymax, name=name)
    center = table.vector("center", 2)
    radius = table.number("radius", positive=True)
    table.finish()
    return DiscObstacle(center=(center[0], center[1]), radius=radius, name=name)


def _region(table: _Table, arena: Arena) -> Region:
    name = table.string("name")
    _check_atom(table, "name", name)
    center = table.vector("center", 2)
    if not arena.contains(*center):
        table.fail("center", f"{list(center)} lies outside the arena "
                             f"[{arena.xmin}, {arena.xmax}] × [{arena.ymin}, {arena.ymax}]")
    radius = table.number("radius", default=Region.__dataclass_fields__["radius"].default,
                          positive=True)
    labels_raw = table.list_of("labels", str, "string", default=[name])
    for k, label in enumerate(labels_raw):
        _check_atom(table, f"labels[{k}]", label)
    table.finish()
    return Region(name=name, center=(center[0], center[1]), radius=radius,
                  declared_labels=frozenset(labels_raw))


def _robot(table: _Table, arena: Arena, index: int) -> Robot:
    try:
        robot_id = table.integer("id")
        if robot_id < 1:
            table.fail("id", f"expected a positive integer, got {robot_id}")
        if robot_id > validation.MAX_ROBOT_ID:
            table.fail("id", f"{robot_id} is too large: at most {validation.MAX_ROBOT_ID}")
    except ScenarioError as exc:  # no id to name it by: say which table it is
        raise ScenarioError(exc.file, exc.field, f"{exc.reason} (in {ordinal_table(index)})"
                            ) from None
    table.path = robot_field(index, robot_id)  # from now on named by its id
    kind = table.choice("kind", ("unicycle", "omni"))
    pose = table.vector("pose", 3)
    if not arena.contains(pose[0], pose[1]):
        table.fail("pose", f"position ({pose[0]}, {pose[1]}) lies outside the arena "
                           f"[{arena.xmin}, {arena.xmax}] × [{arena.ymin}, {arena.ymax}]")
    radius = table.number("radius", default=0.2, positive=True)
    ltl = _hoa_task(table) if isinstance(table.raw("ltl"), dict) else table.string("ltl",
                                                                                   default=None)
    stl_value = table.raw("stl")
    if isinstance(stl_value, str):
        stl: tuple[str, ...] = (stl_value,)
    else:
        stl = tuple(table.list_of("stl", str, "string", default=[]))
    if ltl is not None and stl:
        table.fail("stl", "a robot has either an `ltl` or an `stl` task, not both")
    if ltl is None and not stl:
        limits_raw = table.data.get("limits")
        for key in ("ltl", "stl"):
            if isinstance(limits_raw, dict) and key in limits_raw:
                table.fail(f"limits.{key}", trap_reason(key, "[robots.limits]"))
        table.fail("", "expected a task: `ltl = \"...\"` (unicycle) or `stl = [\"...\"]` (omni)")
    if ltl is not None and kind != "unicycle":
        table.fail("ltl", f"LTL tasks run on unicycle robots (navigation stack), got kind {kind!r}")
    if stl and kind != "omni":
        table.fail("stl", f"STL tasks run on omni robots (funnel control), got kind {kind!r}")
    for k, text in enumerate(stl):
        if not text.strip():
            table.fail(f"stl[{k}]", "expected a non-empty STL formula")
    if ltl is not None and not ltl.strip():
        table.fail("ltl", "expected a non-empty LTL formula")

    phase_start_times = None
    if table.has("phase_start_times"):
        phase_start_times = tuple(table.list_of("phase_start_times", (int, float), "number"))
        if len(phase_start_times) != max(len(stl) - 1, 0):
            table.fail("phase_start_times", f"expected {max(len(stl) - 1, 0)} times (one per "
                       f"sub-task after the first), got {len(phase_start_times)}")
        if any(b < a for a, b in itertools.pairwise(phase_start_times)):
            table.fail("phase_start_times", f"expected non-decreasing times, got "
                                            f"{list(phase_start_times)}")
        phase_start_times = tuple(float(t) for t in phase_start_times)
    rho_opt: tuple[float | None, ...] = ()
    if table.has("rho_opt"):
        values = table.list_of("rho_opt", (int, float), "number")
        if len(values) != len(stl):
            table.fail("rho_opt", f"expected one value per STL sub-task ({len(stl)}), "
                                  f"got {len(values)}")
        rho_opt = tuple(float(v) for v in values)

    limits_table = table.table("limits", required=False, outer_keys=ROBOT_KEYS)
    unicycle, omni = UnicycleLimits(), OmniLimits()
    if limits_table is not None:
        if kind == "unicycle":
            unicycle = _params(limits_table, UnicycleLimits)
        else:
            omni = _params(limits_table, OmniLimits)
    table.finish()
    return Robot(id=robot_id, kind=kind, pose=(pose[0], pose[1], pose[2]), radius=radius,
                 ltl=ltl, stl=stl, phase_start_times=phase_start_times, rho_opt=rho_opt,
                 unicycle=unicycle, omni=omni)


def _params(table: _Table | None, cls: type) -> Any:
    """Build a flat dataclass of numbers and flags from a table; every field optional. Numbers are
    positive except those whose default is 0 (disturbance, noise, seed), which must be ≥ 0."""
    if table is None:
        return cls()
    values: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if not table.has(f.name):
            continue
        if isinstance(f.default, bool):
            values[f.name] = table.boolean(f.name)
            continue
        if isinstance(f.default, int):
            values[f.name] = table.integer(f.name)
        else:
            values[f.name] = table.number(f.name)
        if f.default == 0 and values[f.name] < 0:
            table.fail(f.name, f"expected a number ≥ 0, got {values[f.name]}")
        if f.default != 0 and values[f.name] <= 0:
            table.fail(f.name, f"expected a positive number, got {values[f.name]}")
    table.finish()
    return cls(**values)


def _navigation(table: _Table | None, source: str) -> NavParams:
    """``[navigation]``: coupling_aware (bool), coupling_share in (0, 1] (docs/coupling.md)."""
    if table is None:
        return NavParams()
    if table.has("coupling_share"):
        share = table.number("coupling_share", positive=True)
        if share > 1.0:
            table.fail("coupling_share", f"expected a number in (0, 1], got {share}")
    return _params(table, NavParams)


# --------------------------------------------------------------------------- cross checks


def _check_start_poses(scenario: Scenario, source: str) -> None:
    robots = scenario.robots
    index = {r.id: i for i, r in enumerate(robots)}
    for i, a in enumerate(robots):
        for b in robots[i + 1:]:
            gap = math.hypot(a.pose[0] - b.pose[0], a.pose[1] - b.pose[1])
            if gap < a.radius + b.radius:
                raise ScenarioError(
                    source, f"{robot_field(index[b.id], b.id)}.pose",
                    f"robot {b.id} starts {gap:.3f} m from robot {a.id}, closer than their radii "
                    f"allow ({a.radius + b.radius:.3f} m)")


def _hoa_task(table: _Table) -> str:
    """``ltl = { hoa = "file.hoa" }``: a Büchi automaton from another tool (docs/ltl.md), carried
    as ``hoa:<absolute path>`` (``tlfleet.agent.ltl.hoa_reader.HOA_TASK_PREFIX``); the path is
    relative to the scenario file."""
    from tlfleet.agent.ltl.hoa_reader import HOA_TASK_PREFIX

    sub = table.table("ltl")
    name = sub.string("hoa")
    sub.finish()
    base = Path(table.source).parent if table.source and table.source != "<scenario>" else Path()
    path = (base / name).resolve()
    if not path.is_file():
        sub.fail("hoa", f"no such HOA file: {path}")
    return HOA_TASK_PREFIX + str(path)


def _check_ltl_task(text: str, scenario: Scenario, source: str, where: str) -> Formula | None:
    """Parse the LTL task (or read its HOA automaton) and check every proposition it uses is
    carried by some region; the parsed formula (None for a HOA task: it has no formula). The
    parse is the process's one parse of this text (:func:`tlfleet.agent.ltl.task.task_formula`)."""
    from tlfleet.agent.ltl.hoa_reader import HOA_TASK_PREFIX, read_hoa_file
    from tlfleet.agent.ltl.parser import atoms
    from tlfleet.agent.ltl.task import task_formula
    from tlfleet.bus.errors import LtlError

    formula = None
    if text.startswith(HOA_TASK_PREFIX):
        try:
            used = frozenset(read_hoa_file(text[len(HOA_TASK_PREFIX):]).atoms)
        except LtlError as exc:
            raise ScenarioError(source, f"{where}.hoa", str(exc)) from None
    else:
        try:
            formula = task_formula(text)
            used = atoms(formula)
        except FormulaSyntaxError as exc:
            raise ScenarioError(source, where, f"LTL syntax error at column {exc.column}: "
                                               f"{exc.reason} in {text!r}") from None
        _refuse_bounded_operators(text, source, where)
    carried = scenario.propositions
    for atom in sorted(used):
        if atom not in carried:
            known = ", ".join(sorted(carried)) or "none"
            raise ScenarioError(source, where, f"proposition {atom!r} is carried by no region "
                                               f"(region labels: {known})")
    return formula


def _refuse_bounded_operators(text: str, source: str, where: str) -> None:
    """A scenario's LTL task may not use Spot's bounded operators (``F[0,60] a``, ``G[2:5] a``,
    ``X[3] a``): they count *steps* of the robot's word — one letter per region it enters — where
    an STL task written alike counts *seconds*, so ``F[0,60] a12`` would silently mean "within 60
    region visits". A deadline in seconds is an STL task; a bound in steps is written with the X
    operators it stands for (``tlfleet translate`` still reads the sugar)."""
    from tlfleet.agent.ltl.lexer import REPEAT, tokenize

    for token in tokenize(text):
        if token.kind == REPEAT:
            raise ScenarioError(
                source, where,
                f"{token.text!r} at column {token.column} of {text!r}: a bounded LTL operator "
                f"counts steps of the robot's region word (one per region entered), not "
                f"seconds. For a deadline in seconds write an STL task on an omni robot, e.g. "
                f"`stl = [\"F[0,60] (dist(p1, [x, y]) <= 0.2)\"]` (docs/stl.md); for a bound in "
                f"steps write the X operators out (`X X a` for 'a at the 3rd letter')")


def _check_stl_task(text: str, robot_ids: Iterable[int], source: str, where: str) -> Temporal:
    """Parse an STL sub-task (stl-funnel.md §2) and check every robot it names exists.

    Syntax errors and unknown robot ids become ``ScenarioError`` naming the field and the column.
    Concavity warnings need to know which robots are LTL (exogenous), so they are issued when the
    agents are built (``tlfleet.agent.policy.stl.build_agents``), not here.
    """
    from tlfleet.agent.stl.parser import parse_task, parsed_task
    from tlfleet.agent.stl.syntax import robots_of

    try:
        tree = parsed_task(text)  # the process's one parse of this text
        if robots_of(tree) <= frozenset(robot_ids):
            return tree
        return parse_task(text, robot_ids)  # raises, naming the unknown robot at its column
    except FormulaSyntaxError as exc:
        raise ScenarioError(source, where, f"STL task error at column {exc.column}: "
                                           f"{exc.reason} in {text!r}") from None


def _check_atom(table: _Table, key: str, name: str) -> None:
    if not ATOM_RE.match(name) or name in RESERVED_ATOMS:
        table.fail(key, f"{name!r} is not a valid proposition name: expected lower-case letters, "
                        f"digits and _ starting with a letter or _ (and not true/false)")


def _fault(table: _Table, robot_ids: list[int], duration: float) -> Fault:
    """One ``[[faults]]`` table: ``spec = "KIND:TARGET@T[+D]"`` or its parts ``kind``,
    ``target`` (``targets`` for a partition), ``at`` [s] sim time, ``duration`` [s] wall time."""
    if table.has("spec"):
        spec = table.string("spec")
        table.finish()
        try:
            fault = parse_fault(spec)
            check_fault(fault, robot_ids, duration)
        except FaultSpecError as exc:
            table.fail("spec", f"{exc.part} of {spec!r}: {exc.reason}")
        return fault
    kind = table.string("kind")
    field_of = {"kind": "kind", "target": "targets" if kind == "partition" else "target",
                "time": "at", "duration": "duration"}
    text = f"{kind}:…"
    try:
        parse_kind(text, kind)
        if kind == "partition":
            targets = parse_targets(text, ",".join(table.list_of("targets", str, "string")),
                                    kind)
        else:
            targets = parse_targets(text, table.string("target"), kind)
        at = check_time(text, table.number("at"))
        fault = Fault(kind, targets, at, check_duration(text, kind, table.number(
            "duration", default=None)))
        table.finish()
        check_fault(fault, robot_ids, duration)
    except FaultSpecError as exc:
        table.fail(field_of[exc.part], exc.reason)
    return fault


def _unique(source: str, field: str, items: list[tuple[Any, int]], what: str) -> None:
    seen: dict[Any, int] = {}
    for value, index in items:
        if value in seen:
            raise ScenarioError(source, f"{field}[{index}]",
                                f"duplicate {what} {value!r} (first at {field}[{seen[value]}]: "
                                f"{ordinal_table(index, field)} repeats "
                                f"{ordinal_table(seen[value], field)}'s)")
        seen[value] = index


# --------------------------------------------------------------------------- table access


_MISSING = object()


class _Table:
    """Typed, path-aware access to one TOML table; ``finish()`` rejects unread keys."""

    def __init__(self, data: dict[str, Any], path: str, source: str,
                 header: str | None = None, outer_keys: frozenset[str] = frozenset()):
        self.data = data
        self.path = path
        self.source = source
        self.read: set[str] = set()
        self.header = header  # the TOML header that opens this table ("[robots.limits]")
        self.outer_keys = outer_keys  # keys of the table around it (the trap of finish())

    def where(self, key: str) -> str:
        if not key:
            return self.path
        if key.startswith("["):
            return f"{self.path}{key}"
        return f"{self.path}.{key}" if self.path else key

    def fail(self, key: str, reason: str) -> None:
        raise ScenarioError(self.source, self.where(key), reason)

    def has(self, key: str) -> bool:
        self.read.add(key)
        return key in self.data

    def raw(self, key: str) -> Any:
        self.read.add(key)
        return self.data.get(key)

    def _get(self, key: str, default: Any, expected: str) -> Any:
        self.read.add(key)
        if key in self.data:
            return self.data[key]
        if default is _MISSING:
            typo = validation.misspelling_of(key, self.data)
            if typo is not None:
                self.fail(typo, validation.unknown_key_reason(typo, self.read))
            self.fail(key, f"missing, expected {expected}")
        return default

    def string(self, key: str, default: Any = _MISSING) -> Any:
        value = self._get(key, default, "a string")
        if value is not default and not isinstance(value, str):
            self.fail(key, f"expected a string, got {_show(value)}")
        return value

    def boolean(self, key: str, default: Any = _MISSING) -> Any:
        value = self._get(key, default, "true or false")
        if value is not default and not isinstance(value, bool):
            self.fail(key, f"expected true or false, got {_show(value)}")
        return value

    def integer(self, key: str, default: Any = _MISSING) -> Any:
        value = self._get(key, default, "an integer")
        if value is not default and (isinstance(value, bool) or not isinstance(value, int)):
            self.fail(key, f"expected an integer, got {_show(value)}")
        return value

    def number(self, key: str, default: Any = _MISSING, positive: bool = False) -> Any:
        value = self._get(key, default, "a number")
        if value is default:
            return value
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(key, f"expected a number, got {_show(value)}")
        if not math.isfinite(value):
            self.fail(key, f"expected a finite number, got {value}")
        if positive and value <= 0:
            self.fail(key, f"expected a positive number, got {value}")
        return float(value)

    def choice(self, key: str, options: tuple[str, ...]) -> str:
        value = self.string(key)
        if value not in options:
            self.fail(key, f"expected one of {', '.join(repr(o) for o in options)}, "
                           f"got {value!r}")
        return value

    def vector(self, key: str, size: int) -> tuple[float, ...]:
        value = self._get(key, _MISSING, f"a list of {size} numbers")
        if (not isinstance(value, list) or len(value) != size
                or any(isinstance(v, bool) or not isinstance(v, int | float) for v in value)):
            self.fail(key, f"expected a list of {size} numbers, got {_show(value)}")
        if not all(math.isfinite(v) for v in value):
            self.fail(key, f"expected finite numbers, got {value}")
        return tuple(float(v) for v in value)

    def list_of(self, key: str, kind: type | tuple[type, ...], name: str,
                default: Any = _MISSING) -> list[Any]:
        value = self._get(key, default, f"a list of {name}s")
        if value is default:
            return value
        if not isinstance(value, list):
            self.fail(key, f"expected a list of {name}s, got {_show(value)}")
        for k, item in enumerate(value):
            if isinstance(item, bool) or not isinstance(item, kind):
                self.fail(f"{key}[{k}]", f"expected a {name}, got {_show(item)}")
        return value

    def table(self, key: str, required: bool = True, outer_keys: frozenset[str] = frozenset()
              ) -> _Table | None:
        value = self._get(key, _MISSING if required else None, "a table")
        if value is None:
            return None
        if not isinstance(value, dict):
            self.fail(key, f"expected a table ([{self.where(key)}]), got {_show(value)}")
        return _Table(value, self.where(key), self.source, self._header(key, "[", "]"),
                      outer_keys)

    def _header(self, key: str, left: str, right: str) -> str:
        """The TOML header of the sub-table ``key`` as a file writes it (``[robots.limits]``:
        an array's element is named by the array)."""
        base = re.sub(r"\[[^]]*\]", "", self.path)
        return f"{left}{base + '.' if base else ''}{key}{right}"

    def array_of_tables(self, key: str, required: bool = True) -> list[_Table]:
        value = self._get(key, _MISSING if required else [], "an array of tables")
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            self.fail(key, f"expected an array of tables ([[{self.where(key)}]]), "
                           f"got {_show(value)}")
        outer = TOP_KEYS if not self.path else frozenset()
        return [_Table(v, f"{self.where(key)}[{i}]", self.source,
                       self._header(key, "[[", "]]"), outer) for i, v in enumerate(value)]

    def finish(self) -> None:
        unknown = sorted(set(self.data) - self.read)
        if unknown:
            key = min(unknown, key=lambda k: (k not in self.outer_keys, k))
            if key in self.outer_keys and self.header:
                self.fail(key, trap_reason(key, self.header))
            self.fail(key, validation.unknown_key_reason(key, self.read))


def trap_reason(key: str, header: str) -> str:
    """Why ``key`` is in the table ``header`` opens although it belongs to the one around it."""
    return (f"`{key}` belongs to the table around {header}, but it is written after the "
            f"{header} line, and a TOML table runs until the next header: move `{key} = …` above "
            f"{header}")


def _show(value: Any) -> str:
    kinds: dict[type, str] = {str: "string", bool: "boolean", int: "integer", float: "number",
                              list: "list", dict: "table"}
    text = repr(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{kinds.get(type(value), type(value).__name__)} {text}"

