"""``tlfleet check SCENARIO``: validate a scenario file and print a one-screen summary.

Rejections exit 1 with file, field path and reason (``tlfleet.agent.scenario.loader``,
``tlfleet.agent.scenario.stl_checks``, and :func:`tlfleet.agent.policy.preflight.check_launch`:
every agent built as its process would build it, so ``check`` exits 0 exactly when ``tlfleet
run`` launches the fleet); warnings (a window beyond the duration, a non-concave
predicate, a G task violated at the start poses from t = 0) are printed after the summary, exit 0.
"""

from __future__ import annotations

import argparse
import json
import math

from tlfleet.agent.model import Scenario
from tlfleet.agent.policy.preflight import check_launch
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.scenario.stl_checks import stl_warnings
from tlfleet.cli.arg_types import scenario_file
from tlfleet.cli.conventions import add_json_argument

NAME = "check"
HELP = "validate a scenario file and summarise it"
EXAMPLES = (
    ("tlfleet check scenario1", "validate the bundled Scenario 1 and summarise it"),
    ("tlfleet check my.toml --json", "validate my.toml; its summary and warnings as JSON"),
)
EXIT_CODES = {0: "every file is valid (warnings may be printed)",
              1: "a file is invalid: file, field and reason on stderr"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", nargs="+", type=scenario_file,
                        help="scenario TOML file(s) or a bundled scenario's name")
    add_json_argument(parser, "print one JSON object a file (JSON Lines): its name, source, "
                              "robots with their tasks, and warnings")


def run(args: argparse.Namespace) -> int:
    if args.json:
        for path in args.scenario:
            scenario = load_scenario(path)
            check_launch(scenario)
            print(json.dumps(summary_json(scenario, stl_warnings(scenario))), flush=True)
        return 0
    for index, path in enumerate(args.scenario):
        if index:
            print()
        scenario = load_scenario(path)
        check_launch(scenario)  # every agent built as its process would: check <=> run
        print(summarise(scenario))
        for warning in stl_warnings(scenario):
            print(f"warning: {scenario.source or path}: {warning}")
    return 0


def summary_json(scenario: Scenario, warnings: list[str]) -> dict:
    """``--json``: the facts :func:`summarise` prints, as data."""
    a = scenario.arena
    return {
        "valid": True, "name": scenario.name, "source": str(scenario.source or ""),
        "fleet": scenario.fleet, "duration": scenario.duration,
        "arena": [a.xmin, a.xmax, a.ymin, a.ymax], "obstacles": len(a.obstacles),
        "regions": [{"name": r.name, "center": list(r.center), "radius": r.radius,
                     "labels": sorted(r.labels)} for r in scenario.regions],
        "robots": [{"id": r.id, "kind": r.kind, "pose": list(r.pose), "radius": r.radius,
                    "ltl": r.ltl, "stl": list(r.stl) if r.ltl is None else None}
                   for r in sorted(scenario.robots, key=lambda r: r.id)],
        "warnings": [str(w) for w in warnings],
    }


def summarise(scenario: Scenario) -> str:
    """A human-readable summary: arena, regions, robots with their tasks, parameters."""
    a = scenario.arena
    lines = [
        f"{scenario.name}: valid ({scenario.source or 'in memory'})",
        f"  {scenario.description}" if scenario.description else "",
        f"  fleet {scenario.fleet!r}, duration {scenario.duration:g} s, "
        f"arena [{a.xmin:g}, {a.xmax:g}] × [{a.ymin:g}, {a.ymax:g}] m, "
        f"{len(a.obstacles)} obstacle(s)",
        f"  regions ({len(scenario.regions)}): " + ", ".join(
            f"{r.name}@({r.center[0]:g}, {r.center[1]:g}) r={r.radius:g}"
            + ("" if r.labels == {r.name} else f" [{','.join(sorted(r.labels))}]")
            for r in scenario.regions),
        f"  robots ({len(scenario.robots)}):",
    ]
    lines = [line for line in lines if line]
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        x, y, th = robot.pose
        head = (f"    {robot.id:>3} {robot.kind:<8} at ({x:g}, {y:g}, {math.degrees(th):.0f}°) "
                f"r={robot.radius:g}")
        if robot.ltl is not None:
            lines.append(f"{head}  LTL  {robot.ltl}")
        else:
            lines.append(f"{head}  STL  {robot.stl[0]}")
            for k, text in enumerate(robot.stl[1:]):
                start = ""
                if robot.phase_start_times:
                    start = f" (from t = {robot.phase_start_times[k]:g} s)"
                lines.append(f"{'':>{len(head)}}  then {text}{start}")
    s, l, m, n = scenario.stl, scenario.ltl, scenario.sim, scenario.navigation
    lines.append(f"  stl: η={s.eta:g} K={s.n_stage1} δ={s.delta:g} ζ_l={s.zeta_l:g} "
                 f"R1={s.r1:g} m R={s.r_sense:g} m β={s.beta:g} at {s.control_rate:g} Hz")
    lines.append(f"  ltl: suffix weight β={l.suffix_weight:g}, control at {l.control_rate:g} Hz")
    lines.append(f"  navigation: coupling-aware leaders {'on' if n.coupling_aware else 'off'}"
                 f" (share {n.coupling_share:g}); robustness recovery "
                 f"{'on' if s.recovery else 'off'} (docs/coupling.md)")
    lines.append(f"  sim: mocap {m.mocap_rate:g} Hz, physics {m.physics_rate:g} Hz, "
                 f"disturbance ≤ {m.disturbance:g} m/s, noise σ={m.mocap_noise:g} m, "
                 f"seed {m.seed}, watchdog {m.watchdog:g} s")
    return "\n".join(lines)
