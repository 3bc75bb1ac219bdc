"""Helpers of the visual tests: a small finished run directory, written by the real
:class:`tlfleet.coordinator.record.recorder.Recorder`, and what rerun's own reader finds in an .rrd.


Robot 1 (LTL unicycle, ``G F a1 & G F a2``) drives from a1 to a2; robot 2 (STL omni) follows it.
Frames at 100 Hz from t = 0.5 s to 3.0 s (251 rows), so the sim-time range is not [0, …].
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from tlfleet.bus.protocol.messages import Event, LtlStatus, MocapFrame, StlStatus
from tlfleet.coordinator.record.recorder import Recorder

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "tests" / "system" / "two_robots.toml"
T0, T1, DT = 0.5, 3.0, 0.01  # [s]
N_FRAMES = 251


def pose(robot: int, t: float) -> tuple[float, float, float]:
    if robot == 1:
        return -1.0 + 0.5 * t, 0.2 * math.sin(t), 0.3 * t
    return -1.0 + 0.5 * t, -0.5, -0.2 * t


def write_run(run_dir: Path) -> dict[str, Any]:
    """Write the run; returns what was written (for assertions)."""
    recorder = Recorder(run_dir, [1, 2])
    recorder.copy_scenario(SCENARIO)
    recorder.start()
    times = [round(T0 + k * DT, 10) for k in range(N_FRAMES)]
    for seq, t in enumerate(times):
        recorder.on_mocap(MocapFrame(t=t, seq=seq, poses=tuple(
            (robot, *pose(robot, t)) for robot in (1, 2))))
    statuses = []
    for k, t in enumerate(times[::10]):
        statuses.append(LtlStatus(robot=1, t=t, prefix=("a1", "a2"), suffix=("a2", "a1", "a2"),
                                  target="a1" if t < 1.5 else "a2", buchi_states=(0,),
                                  visits=(("a1", 1), ("a2", int(t >= 2.0))), rounds=0,
                                  mode="navigate"))
        idle = k < 2  # the first two STL statuses are idle (NaN): not logged
        nan = math.nan
        statuses.append(StlStatus(robot=2, t=t, subtask=0, rho=nan if idle else 0.1 * k,
                                  rho_max=nan if idle else 0.8, lower=nan if idle else -0.5,
                                  r=nan if idle else 0.2, stage=1, ce=1, c=0, follow=-1,
                                  events=(1, 0, 0)))
    for status in statuses:
        recorder.on_status(status)
    events = [
        Event(t=0.5, source="agent/1", kind="plan_ready",
              data={"prefix": ["a1", "a2"], "suffix": ["a2", "a1", "a2"]}),
        Event(t=1.2, source="agent/2", kind="critical_event",
              data={"stage": 1, "ce": 1, "rho": -0.3, "subtask": 0}),
        Event(t=1.2, source="agent/2", kind="repair",
              data={"stage": 1, "r": 0.15, "rho_max": 0.8, "lower": -0.5, "subtask": 0}),
        Event(t=3.0, source="sim", kind="sim_done", data={"ticks": N_FRAMES}),
    ]
    for event in events:
        recorder.on_event(event)
    recorder.close()
    return {"times": times, "statuses": statuses, "events": events}


def read_rrd(path: Path) -> dict[str, Any]:
    """What rerun's own reader finds: rows per entity (``rows``: all; ``timed``: on the sim_time
    timeline, i.e. not static), the sim_time range, and the record batches of the timed
    (``batches``) and ``static`` chunks per entity."""
    from rerun.chunk import RrdReader

    rows: Counter[str] = Counter()
    timed: Counter[str] = Counter()
    batches: dict[str, list[Any]] = {}
    static: dict[str, list[Any]] = {}
    lo, hi = math.inf, -math.inf
    timelines: set[str] = set()
    for chunk in RrdReader(str(path)).stream().to_chunks():
        rows[chunk.entity_path] += chunk.num_rows
        timelines.update(chunk.timeline_names)
        if "sim_time" in chunk.timeline_names:
            batch = chunk.to_record_batch()
            batches.setdefault(chunk.entity_path, []).append(batch)
            timed[chunk.entity_path] += chunk.num_rows
            ns = np.array(batch.column("sim_time").cast("int64").to_pylist(), dtype=np.int64)
            lo, hi = min(lo, ns.min() / 1e9), max(hi, ns.max() / 1e9)
        elif chunk.is_static:
            static.setdefault(chunk.entity_path, []).append(chunk.to_record_batch())
    return {"rows": rows, "timed": timed, "batches": batches, "static": static,
            "t_range": (lo, hi), "timelines": timelines}
