"""``trajectory.csv`` read with the csv module, independently of tlfleet's own reader
(``tlfleet.coordinator.record.rundir``), so the tests and corpora that judge a run from its
trajectory do not trust the code they judge."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np


def load_trajectory(run_dir: Path) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """(t (N,) [s], {robot: (N, 3) x [m], y [m], θ [rad]}) of ``run_dir/trajectory.csv``
    (header ``t,x1,y1,th1,x2,y2,th2,…``)."""
    with open(Path(run_dir) / "trajectory.csv", newline="") as handle:
        rows = list(csv.reader(handle))
    header, data = rows[0], np.array(rows[1:], dtype=float)
    ids = [int(h[1:]) for h in header[1::3]]
    return data[:, 0], {r: data[:, 1 + 3 * k:4 + 3 * k] for k, r in enumerate(ids)}
