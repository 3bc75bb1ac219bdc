"""Helpers of the system tests: run a fleet with real processes on loopback, read its outputs.

Robustness is recomputed here with numpy from ``trajectory.csv`` (independently of
``tlfleet.agent.stl.monitor``): G[a,b] → min over the samples with a ≤ t ≤ b, F[a,b] → max.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import psutil
from tlfleet.coordinator.live.supervisor import SupervisorConfig
from tlfleet.coordinator.run import RunConfig, RunResult, run_fleet
from trajectory_csv import load_trajectory

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "scenarios"
HERE = Path(__file__).resolve().parent


def run(scenario: Path, out: Path, mode: str = "lockstep", **kwargs) -> RunResult:
    """One ``tlfleet run`` in this process (the children are real processes)."""
    supervisor = kwargs.pop("supervisor", SupervisorConfig(ready_timeout=60.0,
                                                           wall_timeout=400.0))
    return run_fleet(RunConfig(scenario, mode=mode, out=out, supervisor=supervisor, **kwargs))


def events(run_dir: Path) -> list[dict]:
    return [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()
            if line.strip()]


def dist_to(states: dict[int, np.ndarray], robot: int, target) -> np.ndarray:
    """‖p_robot − target‖ [m] per sample; ``target`` a point or another robot's id."""
    p = states[robot][:, :2]
    q = states[target][:, :2] if isinstance(target, int) else np.asarray(target, dtype=float)
    return np.hypot(*(p - q).T)


def g_rob(t: np.ndarray, values: np.ndarray, a: float, b: float) -> float:
    """ρ of G[a,b] for a sampled predicate robustness ``values``."""
    window = (t >= a) & (t <= b)
    return float(values[window].min()) if window.any() else math.inf


def f_rob(t: np.ndarray, values: np.ndarray, a: float, b: float) -> float:
    window = (t >= a) & (t <= b)
    return float(values[window].max()) if window.any() else -math.inf


def entries(xy: np.ndarray, center, radius: float, hysteresis: float = 0.05) -> int:
    """Entries of a path into a disc (starting inside counts), re-entry after leaving by
    ``hysteresis`` [m]."""
    d = np.hypot(xy[:, 0] - center[0], xy[:, 1] - center[1])
    count, inside = 0, False
    for value in d:
        if not inside and value <= radius:
            count, inside = count + 1, True
        elif inside and value > radius + hysteresis:
            inside = False
    return count


def robot_robot_contacts(run_dir: Path) -> list[dict]:
    return [e for e in events(run_dir) if e["kind"] == "contact"
            and "wall" not in (e["data"].get("a"), e["data"].get("b"))]


def leftover_in_groups(run_dir: Path) -> list[psutil.Process]:
    """Live processes in the process groups of a run's children (``run.json`` pids = pgids)."""
    pgids = set(json.loads((run_dir / "run.json").read_text())["pids"].values())
    assert pgids, "the run started no child"
    found = []
    for proc in psutil.process_iter(["status"]):
        try:
            if proc.info["status"] != psutil.STATUS_ZOMBIE and os.getpgid(proc.pid) in pgids:
                found.append(proc)
        except (ProcessLookupError, psutil.NoSuchProcess):
            continue
    return found


def angdist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Wrapped angle difference in [0, π] [rad]."""
    return np.abs(np.remainder(a - b + np.pi, 2 * np.pi) - np.pi)


def formation_psi(states: dict[int, np.ndarray], robot: int, leader: int, side: str
                  ) -> np.ndarray:
    """ρ^ψ (standard min semantics) of Scenario 3's formation task of ``robot``: 1 m to the
    ``side`` ("right", "left", "behind") of ``leader`` and aligned with its heading."""
    x, y, th = states[leader].T
    offset = {"right": (np.sin(th), -np.cos(th)), "left": (-np.sin(th), np.cos(th)),
              "behind": (-np.cos(th), -np.sin(th))}[side]
    p = states[robot]
    slot = np.hypot(p[:, 0] - x - offset[0], p[:, 1] - y - offset[1])
    return np.minimum(0.1 - slot, 0.09 - angdist(p[:, 2], th))


def still_while(t: np.ndarray, xy: np.ndarray, wants: np.ndarray, window: float = 5.0
                ) -> list[float]:
    """Start times of ``window``-second spans in which the robot moved < 5 cm while ``wants``
    (per sample) held throughout: the robot stood still although its task wanted motion."""
    n = round(window / float(np.median(np.diff(t))))
    out = []
    for k in range(0, len(t) - n, 10):
        if wants[k:k + n + 1].all() and np.hypot(*(xy[k + n] - xy[k])) < 0.05:
            out.append(float(t[k]))
    return out



def assert_restarted_agent_drove_again(run_dir: Path, robot: int) -> None:
    """After ``restart:robot<N>``: one death and one recovery, one log holding both
    processes, and robot N driven again from a second after the recovery."""
    evs = events(run_dir)
    kinds = [e["kind"] for e in evs]
    assert kinds.count("process_died") == 1 and kinds.count("process_recovered") == 1
    logs = (run_dir / "logs" / f"agent-{robot}.log").read_text()
    assert logs.count("waiting for start") == 2  # one log, two processes
    t, states = load_trajectory(run_dir)
    recovered = next(e for e in evs if e["kind"] == "process_recovered")
    after = t > recovered["t"] + 1.0
    assert after.sum() > 100
    assert np.ptp(states[robot][after, 0]) + np.ptp(states[robot][after, 1]) > 0.05
