"""Offline and online robustness monitors of STL tasks on sampled trajectories.

Semantics (stl-funnel.md §3; paper §II-B) with absolute windows: the samples t_k with a ≤ t_k ≤ b
count, and

    ρ^{G[a,b]ψ} = min_k ρ^ψ(x̄(t_k)),        ρ^{F[a,b]ψ} = max_k ρ^ψ(x̄(t_k)),

with ψ's conjunction either the standard min (``smooth=False``, what reports use) or the LSE of
eq. (3a) (``smooth=True``). No sample in the window yet: +∞ for G, −∞ for F (min/max over the
empty set). A robot's sequence φ′ ∧ φ″ ∧ … has the min over its sub-tasks; a fleet, the min over
robots. The online monitor's value after each sample equals the offline value on that prefix.

A :class:`Trajectory` holds times t (N,) [s] and, per robot id, an (N, 3) array of (x [m], y [m],
θ [rad]). CSV layout (architecture.md §6): header ``t,x1,y1,th1,x2,y2,th2,…``, robot ids ascending.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tlfleet.agent.stl.parser import robot_subtasks
from tlfleet.agent.stl.robustness import CompiledPsi, participants, psi_array
from tlfleet.agent.stl.syntax import Temporal
from tlfleet.agent.stl.task import Task
from tlfleet.bus.errors import TlfleetError

if TYPE_CHECKING:
    from tlfleet.agent.model import Scenario


class TrajectoryFileError(TlfleetError, ValueError):
    """A trajectory CSV that cannot be read: names the file, the 1-based line and column."""

    def __init__(self, file: str, line: int, column: int, reason: str):
        self.file, self.line, self.column, self.reason = file, line, column, reason
        super().__init__(f"{file}:{line}:{column}: {reason}")


@dataclass(frozen=True)
class Trajectory:
    """Sampled poses: ``t`` (N,) ascending [s]; ``states[j]`` (N, 3) = (x, y, θ) of robot j."""

    t: np.ndarray
    states: Mapping[int, np.ndarray]

    @property
    def robot_ids(self) -> tuple[int, ...]:
        return tuple(sorted(self.states))

    def window(self, a: float, b: float) -> np.ndarray:
        """Boolean mask of the samples with a ≤ t ≤ b."""
        return (self.t >= a) & (self.t <= b)

    def prefix(self, n: int) -> Trajectory:
        return Trajectory(self.t[:n], {j: s[:n] for j, s in self.states.items()})


def _as_temporal(task: Task | Temporal) -> Temporal:
    if isinstance(task, Task):
        return Temporal(task.kind, task.a, task.b, task.psi)
    return task


def task_robustness(task: Task | Temporal, traj: Trajectory, *, smooth: bool = False,
                    eta: float = 10.0) -> float:
    """Offline ρ^φ of one G/F task over the samples of ``traj`` inside [a, b] (vectorised)."""
    phi = _as_temporal(task)
    if isinstance(task, Task):
        eta = task.eta
    mask = traj.window(phi.a, phi.b)
    if not mask.any():
        return math.inf if phi.op == "G" else -math.inf
    robots = participants(phi.body)
    missing = [j for j in robots if j not in traj.states]
    if missing:
        raise KeyError(f"trajectory has no robot {missing[0]} (needed by {phi})")
    values = psi_array(phi.body, {j: traj.states[j][mask] for j in robots}, smooth=smooth, eta=eta)
    return float(values.min() if phi.op == "G" else values.max())


def sequence_robustness(tasks: Iterable[Task | Temporal], traj: Trajectory, *,
                        smooth: bool = False, eta: float = 10.0) -> tuple[list[float], float]:
    """(ρ of each sub-task, ρ of their conjunction = min) for one robot's sequence (§9 item 6)."""
    values = [task_robustness(task, traj, smooth=smooth, eta=eta) for task in tasks]
    return values, min(values, default=math.inf)


class OnlineMonitor:
    """Incremental ρ^φ: feed samples in time order with :meth:`update`; ``value`` is the offline
    robustness of the prefix seen so far (standard or smooth conjunction)."""

    __slots__ = ("_compiled", "_phi", "_smooth", "value")

    def __init__(self, task: Task | Temporal, *, smooth: bool = False, eta: float = 10.0):
        self._phi = _as_temporal(task)
        if isinstance(task, Task):
            eta = task.eta
        self._compiled = CompiledPsi(self._phi.body, participants(self._phi.body), eta)
        self._smooth = smooth
        self.value = math.inf if self._phi.op == "G" else -math.inf

    def update(self, t: float, poses: Mapping[int, Sequence[float]]) -> float:
        """Add the sample at time t [s] (``poses[j]`` = (x, y, θ)); returns the current ρ^φ."""
        phi = self._phi
        if phi.a <= t <= phi.b:
            s: list[float] = []
            for j in self._compiled.robots:
                pose = poses[j]
                s.extend(pose.tolist() if hasattr(pose, "tolist") else pose)
            rho = self._compiled.value(s) if self._smooth else self._compiled.value_min(s)
            self.value = min(self.value, rho) if phi.op == "G" else max(self.value, rho)
        return self.value


# --------------------------------------------------------------------------- CSV

_COLUMN_RE = re.compile(r"^(x|y|th)(\d+)$")


def read_trajectory_csv(path: str | Path) -> Trajectory:
    """Read ``t,x1,y1,th1,…`` (robot ids ascending); errors name the file, line and column."""
    name = str(path)
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise TrajectoryFileError(name, 0, 0, f"cannot open: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise TrajectoryFileError(name, 0, 0, f"not UTF-8 text: {exc.reason}") from None
    except csv.Error as exc:  # a field past the csv module's limit, a NUL byte
        raise TrajectoryFileError(name, 0, 0, f"not CSV: {exc}") from None
    if not rows:
        raise TrajectoryFileError(name, 1, 1, "empty file: expected a header t,x1,y1,th1,...")
    header = [h.strip() for h in rows[0]]
    if not header or header[0] != "t":
        raise TrajectoryFileError(name, 1, 1, f"first column must be 't', found {header[0]!r}"
                                  if header else "missing header")
    if (len(header) - 1) % 3 != 0 or len(header) == 1:
        raise TrajectoryFileError(name, 1, len(header), "expected columns t followed by "
                                  "x<id>,y<id>,th<id> triples")
    ids: list[int] = []
    for k in range(1, len(header), 3):
        triple = header[k:k + 3]
        parsed = [_COLUMN_RE.match(h) for h in triple]
        for offset, (h, m, comp) in enumerate(zip(triple, parsed, ("x", "y", "th"), strict=True)):
            if m is None or m.group(1) != comp:
                raise TrajectoryFileError(name, 1, k + offset + 1,
                                          f"expected column {comp}<id>, found {h!r}")
        robot = int(parsed[0].group(2))
        if {int(m.group(2)) for m in parsed} != {robot}:
            raise TrajectoryFileError(name, 1, k + 1, f"columns {','.join(triple)} must name one "
                                      f"robot")
        if ids and robot <= ids[-1]:
            raise TrajectoryFileError(name, 1, k + 1, f"robot ids must be ascending, {robot} "
                                      f"follows {ids[-1]}")
        ids.append(robot)
    data = np.empty((len(rows) - 1, len(header)))
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise TrajectoryFileError(name, line, min(len(row), len(header)) + 1,
                                      f"expected {len(header)} values, found {len(row)}")
        for col, cell in enumerate(row):
            try:
                value = float(cell)
            except ValueError:
                raise TrajectoryFileError(name, line, col + 1,
                                          f"{header[col]} is not a number: {cell!r}") from None
            if not math.isfinite(value):
                raise TrajectoryFileError(name, line, col + 1, f"{header[col]} is not finite")
            data[line - 2, col] = value
    if len(data) == 0:
        raise TrajectoryFileError(name, 2, 1, "no samples after the header")
    backwards = np.nonzero(np.diff(data[:, 0]) <= 0)[0]
    if backwards.size:
        raise TrajectoryFileError(name, int(backwards[0]) + 3, 1, "time must increase strictly")
    return Trajectory(data[:, 0].copy(),
                      {robot: data[:, 1 + 3 * k:4 + 3 * k].copy() for k, robot in enumerate(ids)})


def write_trajectory_csv(path: str | Path, traj: Trajectory) -> None:
    """Write the CSV layout read by :func:`read_trajectory_csv` (full float precision)."""
    ids = traj.robot_ids
    header = ["t"] + [f"{c}{j}" for j in ids for c in ("x", "y", "th")]
    columns = np.column_stack([traj.t] + [traj.states[j] for j in ids])
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows([[repr(float(v)) for v in row] for row in columns])


def evaluate_trajectory(scenario: Scenario, traj: Trajectory, trajectory_path: str | Path,
                        smooth: bool = False) -> dict:
    """Robustness of every STL robot's sub-tasks (standard min/max, stl-funnel.md §3, §9 item 6)
    of a loaded scenario on a loaded trajectory: ``{robot id: {"subtasks": [{"task", "window",
    "robustness"}], "robustness": min}}`` (``trajectory_path`` only
    names the file in errors)."""
    from tlfleet.agent.stl.errors import StlTaskError
    from tlfleet.agent.stl.sequencer import merge_and_check
    from tlfleet.agent.stl.syntax import robots_of, to_text

    report: dict = {}
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        if not robot.is_stl:
            continue
        tasks = merge_and_check(robot.id, list(robot_subtasks(robot)))
        missing = sorted(frozenset().union(*(robots_of(t) for t in tasks)) - set(traj.states))
        if missing:
            raise StlTaskError(f"{trajectory_path}: no columns for robot {missing[0]}, which robot "
                               f"{robot.id}'s task needs (columns x{missing[0]},y{missing[0]},"
                               f"th{missing[0]})")
        values = [task_robustness(task, traj, smooth=smooth, eta=scenario.stl.eta)
                  for task in tasks]
        report[robot.id] = {
            "subtasks": [{"task": to_text(task), "window": [task.a, task.b], "robustness": value,
                          "covered": bool(len(traj.t)) and float(traj.t[0]) <= task.a + 1e-9
                          and float(traj.t[-1]) >= task.b - 1e-9}
                         for task, value in zip(tasks, values, strict=True)],
            "robustness": min(values),
        }
    return report
