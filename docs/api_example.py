"""The public API in one script: LTL to a plan, an STL task's robustness offline and online, and a
run directory read back and monitored. Run it as ``python docs/api_example.py [RUN_DIR]``: without
a run directory it makes a small one from a straight-line trajectory it computes itself.
tests/project/test_api.py runs it and checks what it prints against independent computations.
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import tlfleet


def ltl_example() -> None:
    # Paper Algorithm 1: task -> Büchi automaton -> product with the regions' transition system
    # -> the cheapest prefix-suffix run, cost = prefix + beta * suffix (lengths [m]).
    buchi = tlfleet.translate("G F a & G F b & G !c")
    print(f"buchi: {buchi.num_states} states, {buchi.num_edges} edges")
    print(tlfleet.to_hoa(buchi).splitlines()[0])  # HOA v1, for Spot's autfilt & co.
    regions = [tlfleet.Region("a", (0.0, 0.0)), tlfleet.Region("b", (3.0, 4.0)),
               tlfleet.Region("c", (3.0, 0.0))]
    ts = tlfleet.transition_system(regions, start=(0.0, -1.0))
    plan = tlfleet.plan(buchi, ts, beta=10.0)
    print(f"plan: prefix {' -> '.join(plan.prefix)}, suffix ({' -> '.join(plan.suffix)})^w, "
          f"cost {plan.cost:.3f}")


def straight_line(t: np.ndarray) -> tlfleet.Trajectory:
    """Robot 1 drives from (0, 0) along x at 0.1 m/s; robot 2 stays at (1, 0.5)."""
    one = np.stack([0.1 * t, np.zeros_like(t), np.zeros_like(t)], axis=1)
    two = np.tile([1.0, 0.5, 0.0], (len(t), 1))
    return tlfleet.Trajectory(t, {1: one, 2: two})


def stl_example() -> None:
    # Paper eq. (2): robot 1 within 0.6 m of robot 2 at some time in [5, 15] s.
    task = tlfleet.parse_stl("F[5,15] (dist(p1, p2) <= 0.6)")
    trajectory = straight_line(np.arange(0.0, 20.0 + 1e-9, 0.01))
    print(f"robustness: {tlfleet.robustness(task, trajectory):.6f}")
    monitor = tlfleet.OnlineMonitor(task)  # the same value, sample by sample
    for k, t in enumerate(trajectory.t):
        monitor.update(float(t), {j: s[k] for j, s in trajectory.states.items()})
    print(f"online: {monitor.value:.6f}")


def make_run_dir(folder: Path) -> Path:
    """A minimal run directory: a scenario and its trajectory.csv (``tlfleet run`` writes more)."""
    run = folder / "example-run"
    run.mkdir()
    scenario = tlfleet.bundled_scenarios()["scenario2"]
    (run / "scenario.toml").write_text(scenario.read_text())
    t = np.arange(0.0, 90.0 + 1e-9, 0.1)
    lines = ["t,x1,y1,th1,x2,y2,th2,x3,y3,th3,x4,y4,th4"]
    for time in t:  # robots 3 and 4 sit 0.3 m beside robots 1 and 2, which circle slowly
        x1, y1 = -2.0 + 0.5 * math.cos(time / 10), -0.5 + 0.5 * math.sin(time / 10)
        x2, y2 = 2.5, -2.0 + 0.04 * time
        row = [time, x1, y1, 0.0, x2, y2, 0.0, x1 + 0.3, y1, 0.0, x2, y2 + 0.3, 0.0]
        lines.append(",".join(f"{v:.6f}" for v in row))
    (run / "trajectory.csv").write_text("\n".join(lines) + "\n")
    return run


def run_example(run_dir: Path) -> None:
    files = tlfleet.read_run(run_dir)
    traj = files.trajectory
    print(f"run: {files.scenario.name}, {len(traj.t)} samples, robots {list(traj.robot_ids)}")
    for robot, entry in tlfleet.monitor_run(run_dir).items():
        print(f"robot {robot}: rho = {entry['robustness']:+.6f}")


def main(argv: list[str]) -> int:
    ltl_example()
    stl_example()
    if argv:
        run_example(Path(argv[0]))
        return 0
    with tempfile.TemporaryDirectory() as folder:
        run_example(make_run_dir(Path(folder)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
