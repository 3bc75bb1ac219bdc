"""A corpus of broken scenario files: each case is a file a careless user or an attacker
could hand to ``tlfleet check`` / ``tlfleet run``, with the field path and the reason a specific
error must give. Used by ``tests/scenario/test_broken_corpus.py`` (every case specific) and by
``bench/scenario_corpus.py`` (the before/after table: specific / vague / crash / accepted).

A case's ``field`` is the expected ``ScenarioError.field`` ("" for the whole file) and ``reason``
a regular expression its reason must match.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

BASE = """\
name = "corpus"
duration = 40.0

[arena]
xmin = -3.5
xmax = 3.5
ymin = -3.5
ymax = 3.5

[[arena.obstacles]]
shape = "disc"
center = [0.0, 2.5]
radius = 0.4

[sim]
mocap_rate = 100.0
seed = 1

[[regions]]
name = "a1"
center = [-2.0, -2.0]
radius = 0.25

[[regions]]
name = "a2"
center = [2.0, -2.0]
radius = 0.25

[[robots]]
id = 1
kind = "unicycle"
pose = [-2.0, 0.0, 0.0]
ltl = "G F a1 & G F a2"

[[robots]]
id = 2
kind = "omni"
pose = [1.0, 1.0, 0.0]
stl = ["G[5,15] (dist(p2, [1,0]) <= 0.2)", "F[20,30] (dist(p2, [0,-1]) <= 0.2)"]
phase_start_times = [15.0]

[[robots]]
id = 3
kind = "omni"
pose = [-1.0, 1.0, 0.0]
stl = ["G[0,40] (dist(p3, p2) <= 2.5)"]
"""


@dataclass(frozen=True)
class Case:
    name: str
    make: Callable[[Path], Path]  # tmp dir -> the file to load
    field: str
    reason: str


def _text(body: str) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        path = tmp / "scenario.toml"
        path.write_text(body, encoding="utf-8")
        return path
    return make


def edit(old: str, new: str) -> Callable[[Path], Path]:
    assert old in BASE, old
    return _text(BASE.replace(old, new, 1))


def append(extra: str) -> Callable[[Path], Path]:
    """``extra`` at the end of the file: inside the last table unless it opens a new one."""
    return _text(BASE + extra)


def prepend(extra: str) -> Callable[[Path], Path]:
    """``extra`` at the top level (before any table)."""
    return _text(extra + BASE)


def raw(make_bytes: Callable[[], bytes]) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        path = tmp / "scenario.toml"
        path.write_bytes(make_bytes())
        return path
    return make


def _directory(tmp: Path) -> Path:
    (tmp / "dir.toml").mkdir()
    return tmp / "dir.toml"


def _fifo(tmp: Path) -> Path:
    path = tmp / "fifo.toml"
    os.mkfifo(path)
    return path


def _dev_zero(_tmp: Path) -> Path:
    return Path("/dev/zero")


def _missing(tmp: Path) -> Path:
    return tmp / "nope.toml"


def _huge(tmp: Path) -> Path:
    path = tmp / "huge.toml"
    with open(path, "w", encoding="utf-8") as f:
        f.write(BASE)
        f.write('description = "' + "x" * (50 * 1024 * 1024) + '"\n')
    return path


def _nested_array(depth: int) -> str:
    return "x = " + "[" * depth + "1" + "]" * depth + "\n"


def _nested_table(depth: int) -> str:
    return "x = " + "{a = " * depth + "1" + "}" * depth + "\n"


ROBOT3 = '''[[robots]]
id = 3
kind = "omni"
pose = [-1.0, 1.0, 0.0]
stl = ["G[0,40] (dist(p3, p2) <= 2.5)"]
'''
STL2 = 'stl = ["G[5,15] (dist(p2, [1,0]) <= 0.2)", "F[20,30] (dist(p2, [0,-1]) <= 0.2)"]'
PHASES = "phase_start_times = [15.0]"


def stl2(tasks: list[str], phases: str | None = PHASES) -> Callable[[Path], Path]:
    """Robot 2's STL task list (and phase start times) replaced."""
    new = "stl = [" + ", ".join(f'"{t}"' for t in tasks) + "]"
    return edit(STL2 + "\n" + PHASES, new + ("\n" + phases if phases else ""))
LTL1 = 'ltl = "G F a1 & G F a2"'


CASES: list[Case] = [
    # ---------------------------------------------------------------- the file itself
    Case("missing file", _missing, "", "no such file"),
    Case("directory", _directory, "", "is a directory"),
    Case("fifo", _fifo, "", "not a regular file"),
    Case("/dev/zero", _dev_zero, "", "not a regular file"),
    Case("50 MB file", _huge, "", r"larger than .* MiB"),
    Case("binary garbage", raw(lambda: bytes(range(256)) * 4), "", "not UTF-8"),
    Case("empty file", _text(""), "name", "missing"),
    Case("toml syntax error", prepend("duration = \n"), "", "not valid TOML"),
    Case("duplicate key", prepend('name = "again"\n'), "", "not valid TOML"),
    Case("nested arrays 5000 deep", prepend(_nested_array(5000)), "", "nested"),
    Case("nested inline tables 2000 deep", prepend(_nested_table(2000)), "", "nested"),
    Case("nested arrays 40 deep", prepend(_nested_array(40)), "", "nested deeper than"),
    Case("dotted keys 40 deep", prepend("x." + ".".join(["a"] * 40) + " = 1\n"), "",
         "nested deeper than"),
    # ---------------------------------------------------------------- keys and types
    Case("misspelt required key", edit("duration = 40.0", "duraton = 40.0"), "duraton",
         "unknown key 'duraton'.*did you mean 'duration'"),
    Case("misspelt robot key", edit('id = 3\nkind = "omni"', 'id = 3\nkidn = "omni"'),
         "robots[id=3].kidn", "unknown key 'kidn'.*did you mean 'kind'"),
    Case("misspelt section", edit("[sim]", "[simm]"), "simm",
         "unknown key 'simm'.*did you mean 'sim'"),
    Case("misspelt optional key", edit("seed = 1", "sed = 1"), "sim.sed",
         "unknown key 'sed'.*did you mean 'seed'"),
    Case("misspelt array of tables", _text(BASE.replace("[[robots]]", "[[robot]]")), "robot",
         "unknown key 'robot'.*did you mean 'robots'"),
    Case("unknown key", prepend("colour = 'red'\n"), "colour", "unknown key 'colour'"),
    Case("duration string", edit("duration = 40.0", 'duration = "40"'), "duration",
         "expected a number"),
    Case("duration negative", edit("duration = 40.0", "duration = -1.0"), "duration",
         "positive"),
    Case("duration nan", edit("duration = 40.0", "duration = nan"), "duration", "finite"),
    Case("pose wrong length", edit("pose = [-2.0, 0.0, 0.0]", "pose = [-2.0, 0.0]"),
         "robots[id=1].pose", "list of 3 numbers"),
    Case("pose inf", edit("pose = [-2.0, 0.0, 0.0]", "pose = [-2.0, inf, 0.0]"),
         "robots[id=1].pose", "finite"),
    Case("robot id string", edit("id = 1", 'id = "one"'), "robots[0].id", "integer"),
    Case("robot id huge", edit("id = 1", "id = 123456789012"), "robots[0].id", "at most"),
    Case("kind unknown", edit('kind = "unicycle"', 'kind = "tank"'), "robots[id=1].kind",
         "expected one of"),
    Case("duplicate robot id", edit("id = 3", "id = 2"), "robots[2]", "duplicate robot id"),
    Case("no robots", _text(BASE.split("[[robots]]")[0]), "robots", "missing"),
    # ---------------------------------------------------------------- names
    Case("name with ../", edit('name = "corpus"', 'name = "../../escape"\nfleet = "ok"'),
         "name", "not a safe run name"),
    Case("name with /", edit('name = "corpus"', 'name = "a/b"\nfleet = "ok"'), "name",
         "not a safe run name"),
    Case("name absolute", edit('name = "corpus"', 'name = "/tmp/x"\nfleet = "ok"'), "name",
         "not a safe run name"),
    Case("name with NUL", edit('name = "corpus"', 'name = "a\\u0000b"\nfleet = "ok"'), "name",
         "not a safe run name"),
    Case("name too long", edit('name = "corpus"', f'name = "{"n" * 300}"\nfleet = "ok"'),
         "name", "not a safe run name"),
    Case("fleet with space", edit('name = "corpus"', 'name = "corpus"\nfleet = "my fleet"'),
         "fleet", "not usable in a key expression"),
    Case("description 100 kB", edit('name = "corpus"',
                                    f'name = "corpus"\ndescription = "{"d" * 100_000}"'),
         "description", "longer than"),
    # ---------------------------------------------------------------- geometry
    Case("obstacle over a start pose", edit("center = [0.0, 2.5]\nradius = 0.4",
                                            "center = [-2.0, 0.2]\nradius = 0.4"),
         "robots[id=1].pose", "overlaps arena.obstacles\\[0\\]"),
    Case("rect obstacle over a start pose",
         edit('shape = "disc"\ncenter = [0.0, 2.5]\nradius = 0.4',
              'shape = "rect"\nxmin = 0.5\nxmax = 1.5\nymin = 0.5\nymax = 1.5'),
         "robots[id=2].pose", "overlaps arena.obstacles\\[0\\]"),
    Case("region inside an obstacle", edit("center = [0.0, 2.5]\nradius = 0.4",
                                           "center = [2.0, -2.0]\nradius = 0.6"),
         "regions[1].center", "inside arena.obstacles\\[0\\]"),
    Case("overlapping regions", edit('center = [2.0, -2.0]\nradius = 0.25',
                                     'center = [-1.8, -2.0]\nradius = 0.25'),
         "regions[1]", "overlaps regions\\[0\\]"),
    Case("robot outside the arena", edit("pose = [1.0, 1.0, 0.0]", "pose = [9.0, 1.0, 0.0]"),
         "robots[id=2].pose", "outside the arena"),
    Case("robot wider than the arena", edit("pose = [-1.0, 1.0, 0.0]",
                                            "pose = [-1.0, 1.0, 0.0]\nradius = 50.0"),
         "robots[id=3].radius", "too large"),
    Case("robots overlapping at start", edit("pose = [-1.0, 1.0, 0.0]", "pose = [0.9, 1.0, 0.0]"),
         "robots[id=3].pose", "closer than their radii"),
    Case("huge arena", edit("xmax = 3.5", "xmax = 1000000.0"), "arena.xmax", "at most"),
    Case("empty arena", edit("xmax = 3.5", "xmax = -4.0"), "arena.xmax", "must exceed"),
    Case("too many obstacles", append("".join(
        f'[[arena.obstacles]]\nshape = "disc"\ncenter = [3.0, {-3 + i * 1e-4}]\nradius = 0.01\n'
        for i in range(600))), "arena.obstacles", "at most"),
    Case("region radius huge", edit("name = \"a1\"\ncenter = [-2.0, -2.0]\nradius = 0.25",
                                    "name = \"a1\"\ncenter = [-2.0, -2.0]\nradius = 100.0"),
         "regions[0].radius", "too large"),
    # ---------------------------------------------------------------- LTL
    Case("ltl syntax error", edit(LTL1, 'ltl = "G F (a1 &"'), "robots[id=1].ltl",
         "LTL syntax error"),
    Case("ltl unknown proposition", edit(LTL1, 'ltl = "G F a1 & G F a3"'), "robots[id=1].ltl",
         "carried by no region"),
    Case("ltl unsatisfiable F a & G !a", edit(LTL1, 'ltl = "F a1 & G !a1"'), "robots[id=1].ltl",
         "unsatisfiable"),
    Case("ltl unsatisfiable G a & F !a", edit(LTL1, 'ltl = "G a1 & F !a1"'), "robots[id=1].ltl",
         "unsatisfiable"),
    Case("ltl false", edit(LTL1, 'ltl = "false"'), "robots[id=1].ltl", "unsatisfiable"),
    Case("ltl too many propositions", _text(BASE.replace(LTL1, 'ltl = "' + " & ".join(
        f"G F a{i}" for i in range(1, 13)) + '"').replace(
        '[[robots]]\nid = 1', "".join(f'[[regions]]\nname = "a{i}"\ncenter = [-3.0, '
                                      f'{-3 + 0.5 * i}]\nradius = 0.1\n\n'
                                      for i in range(3, 13)) + '[[robots]]\nid = 1', 1)),
         "robots[id=1].ltl", "propositions"),
    Case("ltl formula 5000 chars", edit(LTL1, 'ltl = "' + " & ".join(["G F a1"] * 600) + '"'),
         "robots[id=1].ltl", "longer than"),
    Case("ltl on omni", edit('kind = "unicycle"', 'kind = "omni"'), "robots[id=1].ltl",
         "unicycle"),
    # ---------------------------------------------------------------- STL
    Case("stl syntax error", stl2(["G[5,15] (dist(p2, [1,0]) <= )"], None),
         "robots[id=2].stl[0]", "STL task error"),
    Case("stl unknown robot", stl2(["G[5,15] (dist(p9, [1,0]) <= 0.2)"], None),
         "robots[id=2].stl[0]", "STL task error"),
    Case("stl overlapping windows", stl2(["G[5,25] (dist(p2, [1,0]) <= 0.2)",
                                          "F[20,30] (dist(p2, [0,-1]) <= 0.2)"]),
         "robots[id=2].stl[1]", "overlaps the window"),
    Case("stl ill-ordered windows", stl2(["F[20,30] (dist(p2, [0,-1]) <= 0.2)",
                                          "G[5,15] (dist(p2, [1,0]) <= 0.2)"], None),
         "robots[id=2].stl[1]", "before"),
    Case("stl window after the run", stl2(["G[5,15] (dist(p2, [1,0]) <= 0.2)",
                                           "F[20,1e6] (dist(p2, [0,-1]) <= 0.2)"]),
         "robots[id=2].stl[1]", "after the longest possible run"),
    Case("stl phase start after its window opens",
         edit("phase_start_times = [15.0]", "phase_start_times = [25.0]"),
         "robots[id=2].phase_start_times[0]", "after"),
    Case("stl formula 5000 chars", stl2(["G[5,15] (" + " & ".join(
        ["dist(p2, [1,0]) <= 0.2"] * 250) + ")"], None),
         "robots[id=2].stl[0]", "longer than"),
    Case("stl too many sub-tasks", stl2([f"F[{i},{i}.5] (x2 >= 0)" for i in range(40)], None),
         "robots[id=2].stl", "at most"),
    Case("stl on unicycle", edit('id = 3\nkind = "omni"', 'id = 3\nkind = "unicycle"'),
         "robots[id=3].stl", "omni"),
    # ------------------------------------------- what used to pass `check` and fail the run
    # (every case below is rejected by `tlfleet check` and by `tlfleet run` before launching)
    Case("ltl robot starts in the region its task forbids",
         _text(BASE.replace(LTL1, 'ltl = "G !a1 & G F a2"').replace(
             "pose = [-2.0, 0.0, 0.0]", "pose = [-2.0, -2.0, 0.0]")),
         "robots[id=1].ltl", "cannot be satisfied"),
    Case("ltl region walled in by obstacles", append("".join(
        f'[[arena.obstacles]]\nshape = "rect"\nxmin = {x0}\nxmax = {x1}\nymin = {y0}\n'
        f'ymax = {y1}\n' for x0, x1, y0, y1 in ((1.2, 2.8, -1.3, -1.1), (1.2, 2.8, -2.9, -2.7),
                                                  (1.2, 1.4, -2.9, -1.1), (2.6, 2.8, -2.9, -1.1)))),
         "robots[id=1].ltl", "cannot be satisfied"),
    Case("ltl G a & G b on disjoint regions", edit(LTL1, 'ltl = "G a1 & G a2"'),
         "robots[id=1].ltl", "cannot be satisfied"),
    Case("stl half-plane without rho_opt", _text(BASE.replace("[sim]", "[stl]\n"
                                                              "rho_opt_from_arena = false\n\n[sim]")
                                               .replace(STL2, 'stl = ["G[5,15] (dist(p2, [1,0]) '
                                                              '<= 0.2)", "F[20,30] (x2 >= 0.5)"]')),
         "robots[id=2].stl", "unbounded"),
    Case("robot over the arena wall at its start", edit("pose = [1.0, 1.0, 0.0]",
                                                        "pose = [3.45, 1.0, 0.0]"),
         "robots[id=2].pose", "arena's wall"),
    Case("stl bodies asked to overlap", edit('stl = ["G[0,40] (dist(p3, p2) <= 2.5)"]',
                                             'stl = ["G[0,40] (dist(p3, p2) <= 0.3)"]'),
         "robots[id=3].stl[0]", "closer than their bodies allow"),
    Case("stl window beyond the duration", edit('stl = ["G[0,40] (dist(p3, p2) <= 2.5)"]',
                                                'stl = ["G[0,45] (dist(p3, p2) <= 2.5)"]'),
         "robots[id=3].stl[0]", "ends after the run"),
    # ---------------------------------------------------------------- TOML beginners' traps
    Case("stl written after [robots.limits]", edit(
        ROBOT3, ROBOT3.replace('stl = ["G[0,40] (dist(p3, p2) <= 2.5)"]\n', '')
        + '[robots.limits]\nmax_lin = 0.3\nstl = ["G[0,40] (dist(p3, p2) <= 2.5)"]\n'),
         "robots[id=3].limits.stl", r"written after the \[robots.limits\] line"),
    Case("radius written after [robots.limits]", edit(
        ROBOT3, ROBOT3 + "[robots.limits]\nmax_lin = 0.3\nradius = 0.15\n"),
         "robots[id=3].limits.radius", r"move `radius = …` above \[robots.limits\]"),
    Case("top-level key written after [sim]", edit("seed = 1", 'seed = 1\ndescription = "x"'),
         "sim.description", r"written after the \[sim\] line"),
    Case("top-level key written after [[robots]]", append('fleet = "f2"\n'),
         "robots[id=3].fleet", r"written after the \[\[robots\]\] line"),
    Case("bounded LTL F[0,60]", edit(LTL1, 'ltl = "G F a1 & F[0,60] a2"'), "robots[id=1].ltl",
         "counts steps of the robot's region word.*not seconds.*STL task"),
    Case("bounded LTL X[3]", edit(LTL1, 'ltl = "G F a1 & G F a2 & X[3] a1"'),
         "robots[id=1].ltl", "bounded LTL operator"),
    # ---------------------------------------------------------------- rates and sizes
    Case("mocap_rate 1e9", edit("mocap_rate = 100.0", "mocap_rate = 1e9"), "sim.mocap_rate",
         "at most"),
    Case("mocap_rate 0.001", edit("mocap_rate = 100.0", "mocap_rate = 0.001"),
         "sim.mocap_rate", "at least"),
    Case("physics below mocap", edit("mocap_rate = 100.0", "mocap_rate = 100.0\n"
                                                           "physics_rate = 50.0"),
         "sim.physics_rate", "at least"),
    Case("physics_rate 1e9", edit("mocap_rate = 100.0", "mocap_rate = 100.0\n"
                                                        "physics_rate = 1e9"),
         "sim.physics_rate", "at most"),
    Case("stl control_rate 1e6", append("[stl]\ncontrol_rate = 1e6\n"), "stl.control_rate",
         "at most"),
    Case("ltl control_rate 1e-6", append("[ltl]\ncontrol_rate = 1e-6\n"), "ltl.control_rate",
         "at least"),
    Case("duration 1e9", edit("duration = 40.0", "duration = 1e9"), "duration", "at most"),
    Case("watchdog 1e6", edit("seed = 1", "seed = 1\nwatchdog = 1e6"), "sim.watchdog",
         "at most"),
    Case("mocap noise 1e3", edit("seed = 1", "seed = 1\nmocap_noise = 1e3"),
         "sim.mocap_noise", "at most"),
    Case("disturbance 1e3", edit("seed = 1", "seed = 1\ndisturbance = 1e3"),
         "sim.disturbance", "at most"),
    Case("max_lin 1e6", edit(ROBOT3, ROBOT3 + "[robots.limits]\nmax_lin = 1e6\n"),
         "robots[id=3].limits.max_lin", "at most"),
    Case("max_omega 1e6", edit(LTL1, LTL1 + "\n[robots.limits]\nmax_omega = 1e6"),
         "robots[id=1].limits.max_omega", "at most"),
    Case("too many robots", append("".join(
        f'[[robots]]\nid = {i}\nkind = "omni"\npose = [{-3.4 + 0.022 * ((i - 10) % 300)}, '
        f'{3.3 - 0.05 * ((i - 10) // 300)}, 0.0]\n'
        f'radius = 0.01\nstl = ["F[0,1] (x{i} >= 0)"]\n' for i in range(10, 320))),
         "robots", "at most"),
]
