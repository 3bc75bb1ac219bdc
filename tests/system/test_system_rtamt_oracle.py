"""rtamt as an independent oracle of ``tlfleet monitor``: the offline STL robustness of recorded
Scenario 1, 2 and 3 runs, computed by rtamt's discrete-time offline monitor from specifications
written here by hand (not from tlfleet's parser), equals what ``tlfleet monitor --json`` prints,
within 1e-9, for every sub-task and every robot.

rtamt is given the recorded signals (x, y per robot) and evaluates distances itself (sqrt of
squares); what it cannot express is precomputed with numpy as extra signals: sin and cos of an
orientation (Scenario 3's formation offsets) and the wrapped angle difference ``angdist``. Time is
the sample index at the recorded 100 Hz (the test checks the rows are evenly spaced), so a window
[a, b] [s] is [100 a, 100 b] samples and holds the samples with a <= t <= b, as the monitor's.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from system_helpers import SCENARIOS, load_trajectory, run

rtamt = pytest.importorskip("rtamt")

pytestmark = [pytest.mark.system, pytest.mark.slow]
RATE = 100  # [Hz] the recorder's rows: one per mocap frame


def _dist(i: int, point: str) -> str:
    """rtamt text of the distance [m] between robot i and a point given as rtamt expressions."""
    px, py = point.split("|")
    return f"sqrt((x{i} - ({px}))*(x{i} - ({px})) + (y{i} - ({py}))*(y{i} - ({py})))"


def _formation(i: int, ox: str, oy: str, limit: str) -> str:
    """|p_i - p_1 - offset| <= 0.1 and angdist(th_i, th_1) <= 0.09 (Scenario 3)."""
    return (f"(sqrt((x{i} - x1 - ({ox}))*(x{i} - x1 - ({ox})) + "
            f"(y{i} - y1 - ({oy}))*(y{i} - y1 - ({oy}))) <= 0.1) and (ad{i} <= {limit})")


# scenario -> robot -> its sub-tasks in rtamt's syntax, bounds in seconds (scaled below)
SPECS: dict[str, dict[int, list[tuple[str, float, float, str]]]] = {
    "scenario1": {
        3: [("always", 21, 30, f"{_dist(3, '0|-2')} <= 0.1"),
            ("eventually", 57, 58, f"({_dist(3, '1.5|-1.5')} <= 0.1) and "
                                   f"({_dist(3, 'x4|y4')} <= 0.7)")],
        4: [("always", 5, 30, f"({_dist(4, 'x3|y3')} <= 1) and ({_dist(4, 'x5|y5')} <= 1)"),
            ("eventually", 83, 87, f"{_dist(4, '2|2')} <= 0.1")],
        5: [("always", 21, 30, f"{_dist(5, '0|2')} <= 0.1"),
            ("eventually", 44, 47, f"{_dist(5, '-1|0.5')} <= 0.1")],
    },
    "scenario2": {
        3: [("always", 0, 90, f"{_dist(3, 'x1|y1')} <= 0.6")],
        4: [("always", 0, 90, f"{_dist(4, 'x2|y2')} <= 0.6")],
    },
    "scenario3": {
        2: [("always", 10, 100, _formation(2, "s1", "0 - c1", "0.09"))],
        3: [("always", 10, 100, _formation(3, "0 - s1", "c1", "0.09"))],
        4: [("always", 10, 100, _formation(4, "0 - c1", "0 - s1", "0.09"))],
    },
}


def _signals(t: np.ndarray, states: dict[int, np.ndarray]) -> dict[str, list[float]]:
    steps = np.round(t * RATE).astype(int)
    assert np.array_equal(steps, np.arange(steps[0], steps[0] + len(t))), "rows are not 100 Hz"
    assert np.allclose(t, steps / RATE, atol=1e-9)
    signals: dict[str, list[float]] = {"time": steps.tolist()}
    th1 = states[1][:, 2]  # robot 1: the LTL leader whose orientation Scenario 3 follows
    signals["s1"], signals["c1"] = np.sin(th1).tolist(), np.cos(th1).tolist()
    for robot, state in states.items():
        signals[f"x{robot}"], signals[f"y{robot}"] = state[:, 0].tolist(), state[:, 1].tolist()
        diff = state[:, 2] - th1  # wrapped to [-pi, pi], then its size: in [0, pi]
        signals[f"ad{robot}"] = np.abs(np.arctan2(np.sin(diff), np.cos(diff))).tolist()
    return signals


def _rtamt_robustness(op: str, a: float, b: float, body: str, signals: dict) -> float:
    spec = rtamt.StlDiscreteTimeOfflineSpecification()
    for name in signals:
        if name != "time":
            spec.declare_var(name, "float")
    spec.declare_var("out", "float")
    spec.spec = f"out = {op}[{round(a * RATE)}:{round(b * RATE)}] ({body})"
    spec.parse()
    values = spec.evaluate(signals)
    first = values[0]
    assert first[0] == signals["time"][0]
    return float(first[1])


def _monitor(scenario: Path, trajectory: Path) -> dict:
    from tlfleet.cli.main import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["monitor", str(scenario), str(trajectory), "--json"]) == 0
    return json.loads(out.getvalue())


@pytest.fixture(scope="module", params=sorted(SPECS))
def recorded(request, tmp_path_factory):
    name = request.param
    out = tmp_path_factory.mktemp(name) / "run"
    result = run(SCENARIOS / f"{name}.toml", out, report=False, rrd=False)
    assert result.verdict.label in ("clean", "degraded"), result.verdict.line
    return name, out


def test_rtamt_equals_tlfleet_monitor(recorded) -> None:
    name, run_dir = recorded
    t, states = load_trajectory(run_dir)
    assert t[0] == pytest.approx(0.0, abs=1e-9)
    signals = _signals(t, states)
    monitor = _monitor(run_dir / "scenario.toml", run_dir / "trajectory.csv")["robots"]
    assert sorted(map(int, monitor)) == sorted(SPECS[name])
    for robot, subtasks in SPECS[name].items():
        ours = monitor[str(robot)]
        assert len(ours["subtasks"]) == len(subtasks)
        oracle = []
        for (op, a, b, body), sub in zip(subtasks, ours["subtasks"], strict=True):
            assert sub["window"] == [a, b] and sub["covered"], sub
            value = _rtamt_robustness(op, a, b, body, signals)
            oracle.append(value)
            assert math.isfinite(value)
            assert sub["robustness"] == pytest.approx(value, abs=1e-9), (robot, sub["task"])
        assert ours["robustness"] == pytest.approx(min(oracle), abs=1e-9)
