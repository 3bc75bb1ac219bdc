"""Every key of a scenario file, from the model: the source of ``docs/scenario.md`` and of the JSON
Schema ``tlfleet schema`` prints.

The parameter tables (``[ltl]``, ``[stl]``, ``[sim]``, ``[navigation]``, ``[robots.limits]``) are
the model's dataclasses (:mod:`tlfleet.agent.model.scenario`) field by field: the type and the
default are the field's, the unit and the meaning the comment written beside it (or just above
it) in the model — ``max_v: float = 0.3  # [m/s] ...``. The structural keys (the top level,
``[arena]``, ``[[regions]]``, ``[[robots]]``, ``[[faults]]``) are listed here, beside the loader
that reads them (:mod:`tlfleet.agent.scenario.loader`). ``tests/scenario/test_reference.py``
checks that every key the loader accepts is here, that ``docs/scenario.md`` is
:func:`markdown` of it, and that the schema accepts the shipped scenarios and rejects a wrong type.
"""

from __future__ import annotations

import dataclasses
import inspect
import io
import re
import tokenize
from dataclasses import dataclass
from typing import Any

from tlfleet.agent.model import scenario as model

REQUIRED = "required"


@dataclass(frozen=True)
class Key:
    """One key: its table (``""`` for the top level, ``robots[]`` for each ``[[robots]]``
    table), name, TOML type, unit, default (:data:`REQUIRED` when it must be given), meaning, an
    example line and the JSON Schema of its value."""

    table: str
    name: str
    type: str
    unit: str
    default: Any
    meaning: str
    example: str
    schema: dict[str, Any]

    @property
    def path(self) -> str:
        return f"{self.table}.{self.name}" if self.table else self.name


NUMBER: dict[str, Any] = {"type": "number"}
POSITIVE: dict[str, Any] = {"type": "number", "exclusiveMinimum": 0}
POINT: dict[str, Any] = {"type": "array", "items": NUMBER, "minItems": 2, "maxItems": 2}
STRINGS: dict[str, Any] = {"type": "array", "items": {"type": "string"}}
NUMBERS: dict[str, Any] = {"type": "array", "items": NUMBER}


def _k(table: str, name: str, type_: str, unit: str, default: Any, meaning: str, example: str,
       schema: dict[str, Any]) -> Key:
    return Key(table, name, type_, unit, default, meaning, example, schema)


STRUCTURE: tuple[Key, ...] = (
    _k("", "name", "string", "", REQUIRED, "the scenario's name; names the run directory "
       "(letters, digits, `.`, `_`, `-`; at most 64)", 'name = "warehouse"',
       {"type": "string", "pattern": r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"}),
    _k("", "fleet", "string", "", "the name", "the fleet's name in every Zenoh key",
       'fleet = "lab-a"', {"type": "string", "pattern": r"^[A-Za-z0-9_-]+$"}),
    _k("", "duration", "number", "s", REQUIRED, "sim time of the mission; every STL window must "
       "end by it", "duration = 90.0", POSITIVE),
    _k("", "description", "string", "", '""', "one line for the reports",
       'description = "two pickers and an escort"', {"type": "string"}),
    _k("arena", "xmin", "number", "m", -3.5, "left wall", "xmin = -3.5", NUMBER),
    _k("arena", "xmax", "number", "m", 3.5, "right wall (> xmin)", "xmax = 3.5", NUMBER),
    _k("arena", "ymin", "number", "m", -3.5, "bottom wall", "ymin = -3.5", NUMBER),
    _k("arena", "ymax", "number", "m", 3.5, "top wall (> ymin)", "ymax = 3.5", NUMBER),
    _k("arena.obstacles[]", "shape", "string", "", REQUIRED, "`rect` (axis-aligned) or `disc`",
       'shape = "rect"', {"enum": ["rect", "disc"]}),
    _k("arena.obstacles[]", "name", "string", "", '""', "a name for messages and figures",
       'name = "shelf"', {"type": "string"}),
    _k("arena.obstacles[]", "xmin", "number", "m", "rect: required", "a rect's left side",
       "xmin = -2.5", NUMBER),
    _k("arena.obstacles[]", "xmax", "number", "m", "rect: required", "a rect's right side",
       "xmax = -1.5", NUMBER),
    _k("arena.obstacles[]", "ymin", "number", "m", "rect: required", "a rect's bottom side",
       "ymin = -1.0", NUMBER),
    _k("arena.obstacles[]", "ymax", "number", "m", "rect: required", "a rect's top side",
       "ymax = 1.5", NUMBER),
    _k("arena.obstacles[]", "center", "[x, y]", "m", "disc: required", "a disc's centre",
       "center = [0.0, 2.5]", POINT),
    _k("arena.obstacles[]", "radius", "number", "m", "disc: required", "a disc's radius",
       "radius = 0.4", POSITIVE),
    _k("regions[]", "name", "string", "", REQUIRED, "the region's name, an LTL proposition "
       "(lower-case letters, digits, `_`)", 'name = "dock"',
       {"type": "string", "pattern": r"^[a-z_][a-z0-9_]*$"}),
    _k("regions[]", "center", "[x, y]", "m", REQUIRED, "the region disc's centre, inside the "
       "arena", "center = [0.0, -2.3]", POINT),
    _k("regions[]", "radius", "number", "m", 0.25, "the region disc's radius; regions may not "
       "overlap", "radius = 0.3", POSITIVE),
    _k("regions[]", "labels", "[string]", "", "[name]", "the propositions true inside it (one "
       "proposition may label several regions)", 'labels = ["dock", "safe"]', STRINGS),
    _k("robots[]", "id", "integer", "", REQUIRED, "the robot's id (1 ... 99999, unique); "
       "messages name a robot by it: `robots[id=3]`; STL writes its state p3, x3, y3, th3",
       "id = 3", {"type": "integer", "minimum": 1, "maximum": 99999}),
    _k("robots[]", "kind", "string", "", REQUIRED, "`unicycle` (an LTL task, navigation) or "
       "`omni` (STL sub-tasks, funnel control)", 'kind = "omni"',
       {"enum": ["unicycle", "omni"]}),
    _k("robots[]", "pose", "[x, y, θ]", "m, m, rad", REQUIRED, "start pose; the robot's disc "
       "must clear the walls, the obstacles and the other robots", "pose = [-1.0, 0.5, 0.0]",
       {"type": "array", "items": NUMBER, "minItems": 3, "maxItems": 3}),
    _k("robots[]", "radius", "number", "m", 0.2, "the robot's disc", "radius = 0.15", POSITIVE),
    _k("robots[]", "ltl", "string or {hoa = file}", "", "unicycle: required",
       "the LTL task in Spot's syntax over the regions' propositions (docs/ltl.md), or a Büchi "
       "automaton from another tool; bounded operators (`F[0,60]`) are refused: they count "
       "steps, not seconds", 'ltl = "G F dock & G F aisle & G !charger"',
       {"oneOf": [{"type": "string"}, {"type": "object", "properties": {
           "hoa": {"type": "string"}}, "required": ["hoa"], "additionalProperties": False}]}),
    _k("robots[]", "stl", "string or [string]", "", "omni: required",
       "the STL sub-tasks, run in order, windows in seconds of mission time (docs/stl.md)",
       'stl = ["F[0,20] (dist(p3, [2, 0]) <= 0.15)"]',
       {"oneOf": [{"type": "string"}, STRINGS]}),
    _k("robots[]", "phase_start_times", "[number]", "s", "none",
       "forced start of sub-tasks 2, 3, ... (one per sub-task after the first)",
       "phase_start_times = [30.0]", NUMBERS),
    _k("robots[]", "rho_opt", "[number]", "m", "from the arena",
       "per sub-task, the funnel's ρ_opt (the supremum of the robustness) instead of the one "
       "computed", "rho_opt = [0.5]", NUMBERS),
    _k("robots[]", "limits", "table", "", "the kind's defaults", "`[robots.limits]`: the "
       "velocity and acceleration limits below; write it after the robot's other keys (a TOML "
       "table runs to the next header)", "[robots.limits]", {"type": "object"}),
    _k("faults[]", "spec", "string", "", "or the keys below", "a whole fault in one string "
       "(README \"Faults\")", 'spec = "cut:robot3@20+3"', {"type": "string"}),
    _k("faults[]", "kind", "string", "", "without spec: required",
       "`cut`, `partition`, `freeze`, `kill` or `restart`", 'kind = "freeze"',
       {"enum": ["cut", "partition", "freeze", "kill", "restart"]}),
    _k("faults[]", "target", "string", "", "without spec: required", "`robot<N>`, `sim`, "
       "`router` or `host<i>`", 'target = "robot3"', {"type": "string"}),
    _k("faults[]", "targets", "[string]", "", "partition: required", "the two sides of a "
       "partition", 'targets = ["robot1", "robot2"]', STRINGS),
    _k("faults[]", "at", "number", "s", "without spec: required", "sim time the fault starts",
       "at = 20.0", NUMBER),
    _k("faults[]", "duration", "number", "s", "kill, restart: none", "wall time the fault lasts",
       "duration = 3.0", POSITIVE),
)

#: the parameter tables: (table, model dataclass, what it is)
PARAMETERS: tuple[tuple[str, type, str], ...] = (
    ("ltl", model.LtlParams, "the LTL planner and the LTL robots' loop"),
    ("stl", model.StlParams, "the STL agents (funnel, repair, avoidance), scenario-wide"),
    ("sim", model.SimParams, "the simulator"),
    ("navigation", model.NavParams, "the LTL robots' navigation"),
    ("robots[].limits", model.UnicycleLimits, "a unicycle robot's `[robots.limits]`"),
    ("robots[].limits", model.OmniLimits, "an omni robot's `[robots.limits]`"),
)

_UNIT = re.compile(r"^\[([^]]+)\]\s*,?\s*")

#: meanings of the fields the model's source leaves without a comment of their own (a comment
#: above several fields describes the first); keyed by (table, name)
MEANINGS: dict[tuple[str, str], str] = {
    ("ltl", "control_rate"): "control rate of the LTL robots (navigation steps)",
    ("stl", "control_rate"): "control rate of the STL robots (funnel control steps)",
    ("stl", "hold_f_above_r"): "an F sub-task's robot holds still once ρ > r (the authors' "
                               "code); false runs the funnel through the whole window (Alg. 2)",
    ("stl", "complete_f_on_satisfaction"): "an F sub-task is done at the first instant of its "
                                           "window with r < ρ < ρ_max",
    ("stl", "complete_f_at_goal"): "an F sub-task is done once its goal is reached inside the "
                                   "window",
    ("stl", "saturation_share"): "the share of the speed limit a saturation-aware funnel may "
                                 "plan with",
    ("stl", "coupled_r1_margin"): "coupled robots' full-repulsion radius: r_i + r_j + this",
    ("stl", "coupled_r_margin"): "coupled robots' sensing radius: r_i + r_j + this",
    ("stl", "wall_r1_margin"): "full repulsion from a wall or obstacle below r + this",
    ("stl", "wall_r_margin"): "a wall or obstacle is sensed below r + this",
    ("stl", "route_around"): "an STL robot's goal behind an obstacle is reached around it "
                             "(waypoints on the map) instead of straight at it",
    ("sim", "seed"): "seed of the disturbance and noise generators (a lockstep run is the same "
                     "for the same seed)",
    ("navigation", "coupling_aware"): "an LTL robot that STL tasks depend on limits its speed "
                                      "to what those robots can follow (false: the paper's "
                                      "reactive leaders)",
    ("navigation", "coupling_share"): "the share κ ∈ (0, 1] of a dependant's speed the leader "
                                      "may use up",
    ("robots[].limits", "max_v"): "unicycle: linear speed limit",
    ("robots[].limits", "max_omega"): "unicycle: angular speed limit",
    ("robots[].limits", "acc_v"): "unicycle: linear acceleration limit",
    ("robots[].limits", "acc_omega"): "unicycle: angular acceleration limit",
    ("robots[].limits", "max_lin"): "omni: bound on the speed ‖(vx, vy)‖",
    ("robots[].limits", "max_ang"): "omni: bound on |ω|",
    ("robots[].limits", "acc_lin"): "omni: linear acceleration of the velocity tracking",
    ("robots[].limits", "acc_ang"): "omni: angular acceleration of the velocity tracking",
}


def _first_sentence(text: str) -> str:
    text = text.strip()
    cut = re.search(r"(?<=[a-z)])\.\s+(?=[A-Z])", text)
    return text[:cut.start()] if cut else text.rstrip(".")


def field_comments(cls: type) -> dict[str, str]:
    """Field name → the comment written beside the field in the model's source (or, when there
    is none, the comment lines just above it)."""
    source = inspect.getsource(cls)
    comments: dict[str, str] = {}
    above: list[str] = []
    lines = source.splitlines()
    tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    inline = {tok.start[0]: tok.string for tok in tokens if tok.type == tokenize.COMMENT}
    names = {f.name for f in dataclasses.fields(cls)}
    for number, line in enumerate(lines, start=1):
        stripped = line.strip()
        if stripped.startswith("#"):
            above.append(stripped.lstrip("# ").strip())
            continue
        match = re.match(r"\s+(\w+)\s*:", line)
        if match and match.group(1) in names:
            text = inline.get(number, "")
            text = text.lstrip("# ").strip() if text and not stripped.startswith("#") else ""
            comments[match.group(1)] = text or " ".join(above)
        above = [] if stripped else above
    return comments


def parameter_keys() -> tuple[Key, ...]:
    """Every field of the parameter dataclasses as a :class:`Key`."""
    out: list[Key] = []
    for table, cls, _what in PARAMETERS:
        comments = field_comments(cls)
        for f in dataclasses.fields(cls):
            comment = comments.get(f.name, "")
            unit_match = _UNIT.match(comment)
            unit = unit_match.group(1) if unit_match else ""
            meaning = comment[unit_match.end():] if unit_match else comment
            meaning = MEANINGS.get((table, f.name)) or _first_sentence(meaning)
            default = f.default
            if isinstance(default, bool):
                type_, schema = "boolean", {"type": "boolean"}
                example = f"{f.name} = {'false' if default else 'true'}"
            elif isinstance(default, int):
                type_ = "integer"
                schema = {"type": "integer", "minimum": 0 if default == 0 else 1}
                example = f"{f.name} = {default}"
            else:
                type_ = "number"
                schema = {"type": "number", "minimum": 0} if default == 0 else POSITIVE
                example = f"{f.name} = {default!r}"
            out.append(Key(table, f.name, type_, unit, default, meaning.strip(), example,
                           schema))
    return tuple(out)


def keys() -> tuple[Key, ...]:
    """Every key of a scenario file."""
    return STRUCTURE + parameter_keys()


def json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a scenario file read as TOML: types, enums, required
    keys and no unknown key. What it cannot say (geometry, formulas, windows, plans) the loader
    and ``tlfleet check`` do."""
    by_table: dict[str, dict[str, Any]] = {}
    required: dict[str, list[str]] = {}
    for key in keys():
        table = key.table
        if table == "robots[].limits":
            continue
        by_table.setdefault(table, {})[key.name] = {
            **key.schema, "description": f"{key.meaning}" + (f" [{key.unit}]" if key.unit
                                                              else "")}
        if key.default == REQUIRED:
            required.setdefault(table, []).append(key.name)
    limits = {k.name: {**k.schema, "description": k.meaning + (f" [{k.unit}]" if k.unit else "")}
              for k in parameter_keys() if k.table == "robots[].limits"}

    def obj(table: str, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        properties = {**by_table.get(table, {}), **(extra or {})}
        out: dict[str, Any] = {"type": "object", "properties": properties,
                               "additionalProperties": False}
        if required.get(table):
            out["required"] = required[table]
        return out

    robot = obj("robots[]", {"limits": {"type": "object", "properties": limits,
                                        "additionalProperties": False}})
    arena = obj("arena", {"obstacles": {"type": "array", "items": obj("arena.obstacles[]")}})
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://tlfleet.invalid/scenario.schema.json",
        "title": "tlfleet scenario",
        "description": "A tlfleet scenario file (docs/scenario.md); `tlfleet check` checks "
                       "what a schema cannot.",
        **obj("", {
            "arena": arena,
            "ltl": obj("ltl"), "stl": obj("stl"), "sim": obj("sim"),
            "navigation": obj("navigation"),
            "regions": {"type": "array", "items": obj("regions[]")},
            "robots": {"type": "array", "minItems": 1, "items": robot},
            "faults": {"type": "array", "items": obj("faults[]")},
        }),
        "required": ["name", "duration", "robots"],
    }


def markdown() -> str:
    """``docs/scenario.md``: every key with its type, unit, default, meaning and an example."""
    titles = {
        "": "Top level", "arena": "`[arena]`", "arena.obstacles[]": "`[[arena.obstacles]]`",
        "regions[]": "`[[regions]]`", "robots[]": "`[[robots]]`", "faults[]": "`[[faults]]`",
        "ltl": "`[ltl]`", "stl": "`[stl]`", "sim": "`[sim]`", "navigation": "`[navigation]`",
        "robots[].limits": "`[robots.limits]`"}
    what = {table: text for table, _cls, text in PARAMETERS}
    out = [
        "# Scenario files: every key",
        "",
        "<!-- generated by `python -m tlfleet.agent.scenario.reference > docs/scenario.md` "
        "from the model (agent/model/scenario.py) and the loader; a test checks it is "
        "current -->",
        "",
        "A scenario is a TOML file. Every section but `[[robots]]` is optional; an unknown key is "
        "an error (with the closest known key), so a typo never falls back to a default. Units: "
        "metres, seconds, radians, hertz. Errors name the file, the field and the reason; a "
        "robot is named by its id (`robots[id=3].stl[0]`: robot 3's first STL sub-task). "
        "`tlfleet check FILE` runs every check `tlfleet run` runs before it launches anything "
        "(the plans of the LTL robots and the STL agents included); `tlfleet schema` prints the "
        "JSON Schema of this page for an editor (a `#:schema` first line).",
        "",
        "A TOML table runs until the next header: write a robot's keys before its "
        "`[robots.limits]` line, and the top-level keys before the first `[table]`.",
        "",
    ]
    current: str | None = None
    for key in keys():
        heading = key.table
        if key.table == "robots[].limits":
            heading = f"robots[].limits {key.example.split()[0]}"
        if key.table != current:
            current = key.table
            out += [f"## {titles[key.table]}", ""]
            if key.table in what:
                out += [what[key.table].capitalize() + ".", ""]
            out += ["| key | type | unit | default | meaning | example |",
                    "|---|---|---|---|---|---|"]
        del heading
        default = "**required**" if key.default == REQUIRED else (
            f"`{str(key.default).lower()}`" if isinstance(key.default, bool)
            else f"`{key.default}`" if isinstance(key.default, int | float) else key.default)
        meaning = key.meaning.replace("|", "\\|")
        out.append(f"| `{key.name}` | {key.type} | {key.unit or '–'} | {default} | {meaning} "
                   f"| `{key.example}` |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    print(markdown(), end="")
