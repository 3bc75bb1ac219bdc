"""tlfleet: a distributed runtime for robot fleets under LTL and STL tasks.

The package's subpackages are its layers, from the ground up (docs/architecture.md §4):

* ``tlfleet.bus`` — the ground floor: the error hierarchy (``bus.errors``), the wire protocol
  (``bus.protocol``: messages, codec, key expressions) and the transports (``bus.transport``, the
  in-memory ``bus.fake``, the Eclipse Zenoh implementation ``bus.zenoh``);
* ``tlfleet.agent`` — the robot side: the scenario model (``agent.model``), the pure cores
  (``agent.ltl``, ``agent.stl``, ``agent.nav``, ``agent.control``), scenario files
  (``agent.scenario``), the policies (``agent.policy``) and the agent process (``agent.runtime``);
* ``tlfleet.sim`` — the world's side: the simulator process and the zenoh router process
  (``sim.router``);
* ``tlfleet.coordinator`` — launching, recording, supervising and reporting a run;
* ``tlfleet.cli`` — the ``tlfleet`` command (``python -m tlfleet.cli``).

A small public API for scripts and notebooks is re-exported here, loaded on first use (``import
tlfleet`` stays cheap; ``make api-docs`` writes its page, build/api/tlfleet.html, from these
docstrings with pdoc):

* LTL (paper §II-A, Algorithm 1): :func:`translate`, :func:`to_hoa`, :func:`read_hoa`,
  :func:`transition_system` (from regions), :func:`plan`, :class:`Buchi`, :class:`Plan`;
* STL (paper §II-B, eq. (2)): :func:`parse_stl`, :func:`robustness`, :func:`robustness_all`,
  :class:`OnlineMonitor`, :class:`Trajectory`, :func:`read_trajectory_csv`;
* scenarios and runs: :func:`load_scenario`, :func:`bundled_scenarios`, :func:`read_run`,
  :func:`monitor_run` (what ``tlfleet monitor`` prints), :func:`trajectory_frame` (pandas).

``docs/api_example.py`` uses each of them; a test runs it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

# public name -> (module, attribute)
_EXPORTS: dict[str, tuple[str, str]] = {
    "translate": ("tlfleet.agent.ltl.buchi", "translate"),
    "Buchi": ("tlfleet.agent.ltl.buchi", "Buchi"),
    "to_hoa": ("tlfleet.agent.ltl.hoa", "to_hoa"),
    "read_hoa": ("tlfleet.agent.ltl.hoa_reader", "read_hoa"),
    "transition_system": ("tlfleet.agent.ltl.transition_system", "from_regions"),
    "TransitionSystem": ("tlfleet.agent.ltl.transition_system", "TransitionSystem"),
    "plan": ("tlfleet.agent.ltl.planner", "plan"),
    "Plan": ("tlfleet.agent.ltl.planner", "Plan"),
    "parse_stl": ("tlfleet.agent.stl.parser", "parse_task"),
    "robustness": ("tlfleet.agent.stl.monitor", "task_robustness"),
    "robustness_all": ("tlfleet.agent.stl.monitor", "sequence_robustness"),
    "OnlineMonitor": ("tlfleet.agent.stl.monitor", "OnlineMonitor"),
    "Trajectory": ("tlfleet.agent.stl.monitor", "Trajectory"),
    "read_trajectory_csv": ("tlfleet.agent.stl.monitor", "read_trajectory_csv"),
    "Region": ("tlfleet.agent.model", "Region"),
    "Scenario": ("tlfleet.agent.model", "Scenario"),
    "load_scenario": ("tlfleet.agent.scenario", "load_scenario"),
    "bundled_scenarios": ("tlfleet.agent.scenario.bundled", "bundled_scenarios"),
    "read_run": ("tlfleet.coordinator.record.rundir", "read_run"),
    "RunFiles": ("tlfleet.coordinator.record.rundir", "RunFiles"),
}

__all__ = [  # _EXPORTS' names (a test checks they agree) and this module's own functions
    "Buchi", "OnlineMonitor", "Plan", "Region", "RunFiles", "Scenario", "Trajectory",
    "TransitionSystem", "bundled_scenarios", "load_scenario", "monitor_run", "parse_stl", "plan",
    "read_hoa", "read_run", "read_trajectory_csv", "robustness", "robustness_all", "to_hoa",
    "trajectory_frame", "transition_system", "translate",
]

if TYPE_CHECKING:  # for type checkers and pdoc; at run time __getattr__ imports on first use
    from tlfleet.agent.ltl.buchi import Buchi, translate
    from tlfleet.agent.ltl.hoa import to_hoa
    from tlfleet.agent.ltl.hoa_reader import read_hoa
    from tlfleet.agent.ltl.planner import Plan, plan
    from tlfleet.agent.ltl.transition_system import TransitionSystem
    from tlfleet.agent.ltl.transition_system import from_regions as transition_system
    from tlfleet.agent.model import Region, Scenario
    from tlfleet.agent.scenario import load_scenario
    from tlfleet.agent.scenario.bundled import bundled_scenarios
    from tlfleet.agent.stl.monitor import OnlineMonitor, Trajectory, read_trajectory_csv
    from tlfleet.agent.stl.monitor import sequence_robustness as robustness_all
    from tlfleet.agent.stl.monitor import task_robustness as robustness
    from tlfleet.agent.stl.parser import parse_task as parse_stl
    from tlfleet.coordinator.record.rundir import RunFiles, read_run


def __getattr__(name: str) -> Any:
    try:
        module, attribute = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'tlfleet' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value  # the next access is a plain attribute
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


def monitor_run(run_dir: Any, *, smooth: bool = False) -> dict[int, dict[str, Any]]:
    """The STL robustness of every STL robot of a recorded run, as ``tlfleet monitor`` computes it
    from ``run_dir/scenario.toml`` and ``run_dir/trajectory.csv``: ``{robot id: {"robustness":
    ρ, "subtasks": [{"task", "window", "robustness", "covered"}, …]}}``, the standard min/max
    semantics of paper §II-B (``smooth``: the LSE conjunction of eq. (3a) instead). A window the
    trace does not cover has ``covered`` false and no verdict."""
    from pathlib import Path

    from tlfleet.agent.scenario import load_scenario
    from tlfleet.agent.stl.monitor import evaluate_trajectory, read_trajectory_csv

    csv = Path(run_dir) / "trajectory.csv"
    return evaluate_trajectory(load_scenario(Path(run_dir) / "scenario.toml"),
                               read_trajectory_csv(csv), csv, smooth=smooth)


def trajectory_frame(trajectory: Any) -> Any:
    """A :class:`Trajectory` (``read_run(d).trajectory``) as a pandas DataFrame: column ``t``
    [s], then ``x<id>``, ``y<id>`` [m] and ``th<id>`` [rad] per robot, ids ascending (the
    columns of ``trajectory.csv``). Needs pandas (``pip install pandas``), which tlfleet itself
    does not."""
    try:
        import pandas
    except ImportError as exc:
        raise ImportError("tlfleet.trajectory_frame needs pandas: pip install pandas") from exc
    columns: dict[str, Any] = {"t": trajectory.t}
    for robot in sorted(trajectory.states):
        state = trajectory.states[robot]
        columns.update({f"x{robot}": state[:, 0], f"y{robot}": state[:, 1],
                        f"th{robot}": state[:, 2]})
    return pandas.DataFrame(columns)
