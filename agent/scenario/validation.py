"""The scenario checks beyond types, called by the loader (architecture.md §5): what a well-typed
file could still get wrong.

Every problem is a :class:`~tlfleet.bus.errors.ScenarioError` naming the file, the field path and
the reason; no input — however large, deep, strange or hostile — gives a traceback:

* **the file** (:func:`read_text`): only regular files (not /dev/zero, a FIFO, a directory), at
  most :data:`MAX_FILE_BYTES`, UTF-8; TOML nesting deeper than :data:`MAX_DEPTH` (or deep enough
  to exhaust the parser's recursion) is rejected (:func:`check_depth`, :func:`parse_toml`);
* **keys**: a misspelt key is named as unknown, with the closest valid key
  (:func:`closest_key`), even when it shadows a required one (``duraton`` is not reported as a
  missing ``duration``);
* **names**: the scenario ``name`` names the run directory ``runs/<name>-<time>``, so it is
  restricted to :data:`SAFE_NAME` (letters, digits, ``.``, ``_``, ``-``; no path separator, no
  ``..``, at most 64 characters);
* **sizes and rates** (:func:`check_sizes`): robots, regions, obstacles, sub-tasks, formula and
  text lengths, arena size, robot and region radii, ids, rates (mocap, physics, control),
  duration, watchdog, noise, disturbance and velocity limits within sane bounds
  (:data:`RANGES`);
* **geometry** (:func:`check_geometry`): no robot's disc over the arena's wall or an obstacle at
  its start pose, no region centre
  inside an obstacle, no two regions overlapping (a robot inside both could not tell which
  proposition holds);
* **tasks** (:func:`check_ltl`, :func:`check_stl_windows`): an LTL task with more than
  :data:`MAX_LTL_ATOMS` propositions (its Büchi automaton grows exponentially) or whose language
  is empty (translated at check time: ``F a & G !a``) is rejected; a robot's STL sub-tasks must
  have ordered, non-overlapping windows ending before :data:`MAX_DURATION` (not necessarily
  before the scenario's duration: runs are often shortened), and a phase may not start after its
  sub-task's window opened.
"""

from __future__ import annotations

import difflib
import functools
import math
import os
import re
import stat
import tomllib
from pathlib import Path
from typing import Any

from tlfleet.agent.scenario.fields import robot_field
from tlfleet.bus.errors import FormulaSyntaxError, ScenarioError

MAX_FILE_BYTES = 1 << 20  # 1 MiB: the paper's scenarios are ~3 kB
MAX_DEPTH = 16  # nesting of tables and arrays (a scenario needs 4)
SAFE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}\Z")
MAX_TEXT = 10_000  # [characters] description
MAX_FORMULA = 2_000  # [characters] one LTL task or one STL sub-task
MAX_ROBOTS = 200
MAX_REGIONS = 500
MAX_OBSTACLES = 500
MAX_SUBTASKS = 20
MAX_LTL_ATOMS = 8  # an 8-proposition reachability task already takes ~3 s to translate
MAX_ROBOT_ID = 99_999
MAX_ARENA_SIDE = 100.0  # [m]
MAX_DURATION = 86_400.0  # [s]

# (section, field) -> (lowest, highest) allowed; None: no bound on that side
RANGES: dict[tuple[str, str], tuple[float | None, float | None]] = {
    ("sim", "mocap_rate"): (1.0, 1000.0),  # [Hz]
    ("sim", "physics_rate"): (None, 100_000.0),  # [Hz], and ≥ mocap_rate
    ("sim", "watchdog"): (None, 60.0),  # [s]
    ("sim", "mocap_noise"): (None, 1.0),  # [m]
    ("sim", "disturbance"): (None, 10.0),  # [m/s]
    ("stl", "control_rate"): (0.1, None),  # [Hz], and ≤ mocap_rate
    ("ltl", "control_rate"): (0.1, None),  # [Hz], and ≤ mocap_rate
    ("limits", "max_lin"): (None, 10.0),  # [m/s]
    ("limits", "max_v"): (None, 10.0),  # [m/s]
    ("limits", "max_ang"): (None, 100.0),  # [rad/s]
    ("limits", "max_omega"): (None, 100.0),  # [rad/s]
    ("limits", "acc_lin"): (None, 1000.0),  # [m/s²]
    ("limits", "acc_v"): (None, 1000.0),
    ("limits", "acc_ang"): (None, 10_000.0),  # [rad/s²]
    ("limits", "acc_omega"): (None, 10_000.0),
}

# every key the loader reads somewhere: a data key equal to one of these is never "misspelt"
KNOWN_KEYS = frozenset({
    "name", "fleet", "duration", "description", "arena", "ltl", "stl", "sim", "regions",
    "robots", "xmin", "xmax", "ymin", "ymax", "obstacles", "shape", "center", "radius",
    "labels", "id", "kind", "pose", "phase_start_times", "rho_opt", "limits",
    "suffix_weight", "control_rate", "stagger", "eta", "n_stage1", "delta", "zeta_l", "r1",
    "r_sense",
    "beta", "hold_f_above_r", "complete_f_on_satisfaction", "physics_rate", "mocap_rate",
    "disturbance", "mocap_noise", "seed", "watchdog", "spread_frames", "frame_slots",
    "max_v", "max_omega",
    "acc_v", "acc_omega", "max_lin", "max_ang", "acc_lin", "acc_ang",
})


# --------------------------------------------------------------------------- the file


def read_text(path: Path) -> str:
    """The file's text; ``ScenarioError`` unless it is a regular UTF-8 file of sane size."""
    source = str(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise ScenarioError(source, "", "no such file") from None
    except OSError as exc:
        raise ScenarioError(source, "", f"cannot read: {exc.strerror}") from None
    if stat.S_ISDIR(info.st_mode):
        raise ScenarioError(source, "", "is a directory, expected a .toml file")
    if not stat.S_ISREG(info.st_mode):
        raise ScenarioError(source, "", "not a regular file (a device, FIFO or socket): "
                                        "expected a .toml file")
    if info.st_size > MAX_FILE_BYTES:
        raise ScenarioError(source, "", f"{info.st_size} bytes: larger than "
                                        f"{MAX_FILE_BYTES >> 20} MiB, not a scenario file")
    try:
        with open(path, "rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ScenarioError(source, "", f"cannot read: {exc.strerror}") from None
    if len(data) > MAX_FILE_BYTES:  # grew since the stat
        raise ScenarioError(source, "", f"larger than {MAX_FILE_BYTES >> 20} MiB")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(source, "", f"not UTF-8 text ({exc.reason})") from None


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """``tomllib.loads`` with the recursion of very deep nesting turned into a ScenarioError."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(source, "", f"not valid TOML: {exc}") from None
    except (RecursionError, MemoryError):
        raise ScenarioError(source, "", f"nested too deeply (more than {MAX_DEPTH} levels of "
                                        "tables or arrays)") from None
    check_depth(data, source)
    return data


def check_depth(data: Any, source: str) -> None:
    """Reject tables/arrays nested deeper than :data:`MAX_DEPTH` (iterative: no recursion)."""
    stack: list[tuple[Any, int, str]] = [(data, 0, "")]
    while stack:
        node, depth, where = stack.pop()
        if depth > MAX_DEPTH:
            raise ScenarioError(source, "", f"nested deeper than {MAX_DEPTH} levels "
                                            f"(at {where or 'top'})")
        if isinstance(node, dict):
            stack.extend((v, depth + 1, f"{where}.{k}" if where else str(k)[:40])
                         for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((v, depth + 1, f"{where}[{i}]") for i, v in enumerate(node))


# --------------------------------------------------------------------------- keys and names


def closest_key(key: str, candidates: Any) -> str | None:
    """The valid key ``key`` is most likely a misspelling of, or None."""
    matches = difflib.get_close_matches(key, sorted(candidates), n=1, cutoff=0.6)
    return matches[0] if matches else None


def unknown_key_reason(key: str, allowed: Any) -> str:
    """The reason of an unknown key, with the closest allowed key when there is one."""
    near = closest_key(key, allowed)
    shown = ", ".join(sorted(allowed)) or "none"
    hint = f"; did you mean {near!r}?" if near else ""
    return f"unknown key {key[:40]!r} (allowed here: {shown}){hint}"


def misspelling_of(missing: str, data: dict[str, Any]) -> str | None:
    """A key of ``data`` that is no known key but close to the ``missing`` required one."""
    unknown = [k for k in data if isinstance(k, str) and k not in KNOWN_KEYS]
    return closest_key(missing, unknown) if unknown else None


def check_name(source: str, name: str) -> None:
    """The scenario name becomes a directory name: a safe character set only."""
    if not SAFE_NAME.match(name) or ".." in name:
        shown = name if len(name) <= 40 else name[:37] + "..."
        raise ScenarioError(source, "name", f"{shown!r} is not a safe run name: use at most 64 "
                                            "letters, digits, '.', '_' and '-' (starting with a "
                                            "letter or digit, no '..'): it names the run "
                                            "directory")


# --------------------------------------------------------------------------- sizes and rates


def _bound(source: str, field: str, value: float, lo: float | None, hi: float | None,
           unit: str = "") -> None:
    if lo is not None and value < lo:
        raise ScenarioError(source, field, f"{value:g}{unit} is too small: at least {lo:g}{unit}")
    if hi is not None and value > hi:
        raise ScenarioError(source, field, f"{value:g}{unit} is too large: at most {hi:g}{unit}")


def check_sizes(scenario: Any, source: str) -> None:
    """Counts, lengths, sizes and rates within sane bounds (see the module docstring)."""
    s = scenario
    _bound(source, "duration", s.duration, None, MAX_DURATION, " s")
    if len(s.description) > MAX_TEXT:
        raise ScenarioError(source, "description", f"{len(s.description)} characters: longer "
                                                   f"than {MAX_TEXT}")
    a = s.arena
    _bound(source, "arena.xmax", a.xmax - a.xmin, None, MAX_ARENA_SIDE, " m (arena width)")
    _bound(source, "arena.ymax", a.ymax - a.ymin, None, MAX_ARENA_SIDE, " m (arena height)")
    for what, items, limit in (("robots", s.robots, MAX_ROBOTS),
                               ("regions", s.regions, MAX_REGIONS),
                               ("arena.obstacles", a.obstacles, MAX_OBSTACLES)):
        if len(items) > limit:
            raise ScenarioError(source, what, f"{len(items)} entries: at most {limit}")
    side = min(a.xmax - a.xmin, a.ymax - a.ymin)
    for i, region in enumerate(s.regions):
        _bound(source, f"regions[{i}].radius", region.radius, None, side / 2, " m")
    mocap = s.sim.mocap_rate
    for (section, name), (lo, hi) in RANGES.items():
        if section == "limits":
            continue
        value = getattr(getattr(s, section), name)
        if name == "physics_rate":
            lo = mocap
        if name == "control_rate":
            hi = mocap
        _bound(source, f"{section}.{name}", value, lo, hi)
    for i, robot in enumerate(s.robots):
        where = robot_field(i, robot.id)
        _bound(source, f"{where}.id", robot.id, None, MAX_ROBOT_ID)
        _bound(source, f"{where}.radius", robot.radius, None, side / 4, " m")
        limits = robot.omni if robot.kind == "omni" else robot.unicycle
        for (section, name), (lo, hi) in RANGES.items():
            if section == "limits" and hasattr(limits, name):
                _bound(source, f"{where}.limits.{name}", getattr(limits, name), lo, hi)
        if len(robot.stl) > MAX_SUBTASKS:
            raise ScenarioError(source, f"{where}.stl", f"{len(robot.stl)} sub-tasks: at most "
                                                        f"{MAX_SUBTASKS}")
        texts = [("ltl", robot.ltl)] if robot.ltl is not None else []
        texts += [(f"stl[{k}]", text) for k, text in enumerate(robot.stl)]
        for field, text in texts:
            if len(text) > MAX_FORMULA:
                raise ScenarioError(source, f"{where}.{field}", f"{len(text)} characters: longer "
                                                                f"than {MAX_FORMULA}")


# --------------------------------------------------------------------------- geometry


def _disc_hits_obstacle(x: float, y: float, r: float, obstacle: Any) -> bool:
    if hasattr(obstacle, "center"):
        cx, cy = obstacle.center
        return math.hypot(x - cx, y - cy) < r + obstacle.radius
    dx = max(obstacle.xmin - x, 0.0, x - obstacle.xmax)
    dy = max(obstacle.ymin - y, 0.0, y - obstacle.ymax)
    return math.hypot(dx, dy) < r


def check_geometry(scenario: Any, source: str) -> None:
    """No obstacle over a start pose, no region centre inside an obstacle, no overlapping
    regions."""
    obstacles = scenario.arena.obstacles
    arena = scenario.arena
    for i, robot in enumerate(scenario.robots):
        x, y, _ = robot.pose
        gap = min(x - arena.xmin, arena.xmax - x, y - arena.ymin, arena.ymax - y)
        if gap < robot.radius:
            raise ScenarioError(source, f"{robot_field(i, robot.id)}.pose",
                                f"robot {robot.id} (radius {robot.radius:g} m) at ({x:g}, {y:g}) "
                                f"overlaps the arena's wall at its start: its centre is "
                                f"{gap:g} m from the wall, at least {robot.radius:g} m needed")
        for k, obstacle in enumerate(obstacles):
            if _disc_hits_obstacle(x, y, robot.radius, obstacle):
                raise ScenarioError(source, f"{robot_field(i, robot.id)}.pose",
                                    f"robot {robot.id} (radius {robot.radius:g} m) at "
                                    f"({x:g}, {y:g}) overlaps arena.obstacles[{k}] at its start")
    for i, region in enumerate(scenario.regions):
        x, y = region.center
        for k, obstacle in enumerate(obstacles):
            if _disc_hits_obstacle(x, y, 0.0, obstacle):
                raise ScenarioError(source, f"regions[{i}].center",
                                    f"region {region.name!r} at ({x:g}, {y:g}) lies inside "
                                    f"arena.obstacles[{k}]: no robot can reach it")
    regions = scenario.regions
    for j, b in enumerate(regions):
        for i in range(j):
            a = regions[i]
            gap = math.hypot(a.center[0] - b.center[0], a.center[1] - b.center[1])
            if gap < a.radius + b.radius:
                raise ScenarioError(source, f"regions[{j}]",
                                    f"region {b.name!r} overlaps regions[{i}] ({a.name!r}): "
                                    f"centres {gap:.3f} m apart, radii sum "
                                    f"{a.radius + b.radius:.3f} m")


# --------------------------------------------------------------------------- tasks


@functools.lru_cache(maxsize=256)
def _ltl_empty(text: str) -> bool:
    from tlfleet.agent.ltl.emptiness import is_empty
    from tlfleet.agent.ltl.task import text_automaton

    return is_empty(text_automaton(text))  # the automaton the agent then plans with


def check_ltl(text: str, source: str, where: str) -> None:
    """At most :data:`MAX_LTL_ATOMS` propositions, and a non-empty language (translated now),
    on the tree the loader parsed (:func:`tlfleet.agent.ltl.task.task_formula`: one parse a
    text)."""
    from tlfleet.agent.ltl.parser import atoms
    from tlfleet.agent.ltl.task import task_formula

    try:
        tree = task_formula(text)
    except FormulaSyntaxError:
        return  # reported by the loader's syntax check
    if isinstance(tree, str):
        return  # an automaton from a HOA file: no formula to count
    names = atoms(tree)
    if len(names) > MAX_LTL_ATOMS:
        raise ScenarioError(source, where, f"{len(names)} propositions: at most "
                                           f"{MAX_LTL_ATOMS} (the automaton grows exponentially)")
    try:
        empty = _ltl_empty(text)
    except RecursionError:
        raise ScenarioError(source, where, "formula nested too deeply") from None
    if empty:
        raise ScenarioError(source, where, f"unsatisfiable: no behaviour satisfies {text!r} "
                                           "(its Büchi automaton accepts nothing)")


def check_stl_windows(robot: Any, index: int, duration: float, robot_ids: Any,
                      source: str) -> None:
    """Ordered, non-overlapping windows inside the run; phases not starting after their
    window opened. On the trees the loader parsed (:func:`tlfleet.agent.stl.parser.parsed_task`:
    one parse a text; the loader has checked the robots they name)."""
    from tlfleet.agent.stl.parser import parsed_task

    where = robot_field(index, robot.id)
    windows = []
    for text in robot.stl:
        try:
            task = parsed_task(text)
        except (FormulaSyntaxError, RecursionError):
            return  # reported by the loader's syntax check
        windows.append((task.op, task.a, task.b))
    for k, (_op, a, b) in enumerate(windows):
        if b > MAX_DURATION:  # (a window beyond the scenario's duration is allowed: runs are
            # often shortened; one beyond any possible run is a mistake)
            raise ScenarioError(source, f"{where}.stl[{k}]",
                                f"window [{a:g}, {b:g}] ends after the longest possible run "
                                f"({MAX_DURATION:g} s)")
        if k == 0:
            continue
        _, pa, pb = windows[k - 1]
        if a < pa:
            raise ScenarioError(source, f"{where}.stl[{k}]",
                                f"window [{a:g}, {b:g}] starts before the window [{pa:g}, "
                                f"{pb:g}] of stl[{k - 1}]: sub-tasks run in order")
        if a < pb:
            raise ScenarioError(source, f"{where}.stl[{k}]",
                                f"window [{a:g}, {b:g}] overlaps the window [{pa:g}, {pb:g}] of "
                                f"stl[{k - 1}]")
    for k, start in enumerate(robot.phase_start_times or ()):
        _, a, b = windows[k + 1]
        if start > a + 1e-9:
            raise ScenarioError(source, f"{where}.phase_start_times[{k}]",
                                f"phase {k + 1} starts at {start:g} s, after its window "
                                f"[{a:g}, {b:g}] opened")


def check_scenario(scenario: Any, source: str) -> None:
    """Every check of this module on a built scenario (sizes first: the others loop over it)."""
    check_sizes(scenario, source)
    check_geometry(scenario, source)


def check_tasks(scenario: Any, source: str) -> None:
    """The task checks, after the loader's syntax checks."""
    for index, robot in enumerate(scenario.robots):
        if robot.ltl is not None:
            check_ltl(robot.ltl, source, f"{robot_field(index, robot.id)}.ltl")
        if robot.stl:
            check_stl_windows(robot, index, scenario.duration, scenario.robot_ids, source)
