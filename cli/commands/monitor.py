"""``tlfleet monitor SCENARIO TRAJECTORY.csv [--json]``: STL robustness of a recorded trajectory.

For every STL robot of the scenario, prints the robustness of each sub-task and of their conjunction
(min) with the standard min/max semantics (stl-funnel.md §3, §9 item 6), computed offline from the
CSV (``t,x1,y1,th1,x2,y2,th2,…``, robot ids ascending; architecture.md §6). ``--smooth`` uses the
LSE conjunction of eq. (3a) instead. A window with no sample is reported as +inf (G) or −inf (F).
"""

from __future__ import annotations

import argparse
import json
import math

from agent.scenario import load_scenario
from agent.stl.monitor import evaluate_trajectory, read_trajectory_csv

NAME = "monitor"
HELP = "STL robustness of a recorded trajectory"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario TOML file")
    parser.add_argument("trajectory", help="trajectory CSV (t,x1,y1,th1,...)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--smooth", action="store_true",
                        help="LSE conjunction (eq. 3a) instead of the standard min")


def _number(value: float) -> float | str:
    return value if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def evaluate(scenario_path: str, trajectory_path: str, smooth: bool = False) -> dict:
    """{robot id: {"subtasks": [{"task", "window", "robustness"}], "robustness": min}}."""
    return evaluate_trajectory(load_scenario(scenario_path), read_trajectory_csv(trajectory_path),
                               trajectory_path, smooth=smooth)


def run(args: argparse.Namespace) -> int:
    report = evaluate(args.scenario, args.trajectory, smooth=args.smooth)
    if args.json:
        print(json.dumps({
            "semantics": "smooth" if args.smooth else "standard",
            "robots": {str(rid): {"robustness": _number(entry["robustness"]),
                                  "subtasks": [{**sub, "robustness": _number(sub["robustness"])}
                                               for sub in entry["subtasks"]]}
                       for rid, entry in report.items()},
        }, indent=2))
        return 0
    print(f"STL robustness ({'smooth' if args.smooth else 'standard'} semantics) of "
          f"{args.trajectory}")
    for rid, entry in report.items():
        print(f"robot {rid}: {entry['robustness']:+.4f}")
        for sub in entry["subtasks"]:
            print(f"    {sub['robustness']:+.4f}  {sub['task']}")
    return 0
