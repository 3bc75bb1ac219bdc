"""The run report: values against independent recomputation, LTL acceptance, figures,
paper values and bad inputs.

Run directories: a synthetic one written here from analytic trajectories (exact recomputation),
and ``fixtures/s1..s3``: real lockstep runs of the paper's scenarios thinned by
``make_fixtures.py`` (2 Hz trajectory, 1 Hz STL status). Reports are written into copies in
``tmp_path``, never into the fixtures.
"""

from __future__ import annotations

import csv
import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis_budget import examples
from ltl.ltl_helpers import formulas, lasso_words
from matplotlib.image import imread
from tlfleet.agent.ltl.buchi import translate
from tlfleet.agent.ltl.emptiness import accepts_lasso
from tlfleet.agent.ltl.lasso import holds
from tlfleet.cli.main import main as cli_main
from tlfleet.coordinator.record.run_record import Visits
from tlfleet.coordinator.report import paper_values
from tlfleet.coordinator.report.figures import robustness_figure
from tlfleet.coordinator.report.ltl_words import completed_cycles, plan_cycle
from tlfleet.coordinator.report.paper_comparison import RepairEvent
from tlfleet.coordinator.report.render import render_markdown, render_table
from tlfleet.coordinator.report.run_report import RunDirectoryError, build_report, write_report
from tlfleet.coordinator.report.summary import summarise_run

FIXTURES = Path(__file__).resolve().parent / "fixtures"
DT = 0.1  # [s] sample period of the synthetic run
T_END = 60.0  # [s]
PERIOD = 20.0  # [s] robot 1 shuttles a → b → a

SCENARIO = """\
name = "synthetic"
duration = 60.0

[[regions]]
name = "a"
center = [-2.0, 0.0]
radius = 0.25

[[regions]]
name = "b"
center = [2.0, 0.0]
radius = 0.25

[[robots]]
id = 1
kind = "unicycle"
pose = [-2.0, 0.0, 0.0]
ltl = "G F a & G F b"

[[robots]]
id = 2
kind = "unicycle"
pose = [0.0, -2.0, 0.0]
ltl = "G F a & G F b"

[[robots]]
id = 3
kind = "omni"
pose = [0.0, -1.0, 0.0]
stl = ["G[2,4] (dist(p3, [0.2,-1]) <= 0.5)",
       "F[5,8] (dist(p3, p4) <= 0.7 & dist(p3, [0.5,-1]) <= 0.3)"]

[[robots]]
id = 4
kind = "omni"
pose = [1.0, -1.5, 0.0]
stl = ["G[1,9] (dist(p4, [1,-1.5]) <= 1)", "F[10,12] (dist(p4, [0.3,-1.5]) <= 0.1)"]
"""


def poses(t: np.ndarray) -> dict[int, np.ndarray]:
    """Analytic poses (N, 3) of robots 1–4 at times t (N,) [s]."""
    zero = np.zeros_like(t)
    x1 = -2.0 * np.cos(2 * np.pi * t / PERIOD)  # a at t = 0, 20, 40, 60; b at 10, 30, 50
    s2 = np.clip(t / 20.0, 0.0, 1.0)  # robot 2: (0, -2) → b, then stays
    return {
        1: np.column_stack([x1, zero, zero]),
        2: np.column_stack([2.0 * s2, -2.0 + 2.0 * s2, zero]),
        3: np.column_stack([0.05 * t, -1.0 + zero, zero]),
        4: np.column_stack([1.0 - 0.05 * t, -1.5 + 0.1 * np.sin(t), zero]),
    }


def write_synthetic(run_dir: Path, *, status: bool = True) -> None:
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "scenario.toml").write_text(SCENARIO, encoding="utf-8")
    t = np.round(np.arange(0.0, T_END + DT / 2, DT), 2)
    p = poses(t)
    with open(run_dir / "trajectory.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t"] + [f"{c}{j}" for j in (1, 2, 3, 4) for c in ("x", "y", "th")])
        for k, tk in enumerate(t):
            w.writerow([f"{tk:.2f}"] + [repr(float(v)) for j in (1, 2, 3, 4) for v in p[j][k]])
    header = ["t", "robot", "kind", "subtask", "rho", "rho_max", "lower", "r", "stage", "ce", "c",
              "follow", "events", "target", "mode", "rounds", "visits", "prefix", "suffix",
              "buchi_states"]
    rows = []
    if status:
        for tk in np.arange(0.0, 12.01, 0.5):
            for robot in (3, 4):
                sub = 0 if tk <= (4 if robot == 3 else 9) else 1
                idle = robot == 3 and 4 < tk < 5  # agent idle between sub-tasks: empty cells
                rows.append({"t": f"{tk:.2f}", "robot": robot, "kind": "stl",
                             "subtask": "" if idle else sub,
                             "rho": "" if idle else f"{-0.5 + 0.05 * tk:.4f}",
                             "rho_max": "" if idle else "0.2",
                             "lower": "" if idle else f"{-1 + 0.07 * tk:.4f}",
                             "r": "" if idle else f"{0.02 - 0.001 * tk:.4f}",
                             "events": json.dumps([1, 0, int(tk)] if sub else [2, 0, 0])})
        for robot in (1, 2):
            rows.append({"t": "60.00", "robot": robot, "kind": "ltl", "rounds": 2,
                         "visits": json.dumps([["a", 3], ["b", 3]]),
                         "prefix": json.dumps(["a", "b"] if robot == 1 else ["start", "b"]),
                         "suffix": json.dumps(["b", "a", "b"]), "mode": "navigate"})
    with open(run_dir / "status.csv", "w", newline="") as f:
        w = csv.DictWriter(f, header)
        w.writeheader()
        w.writerows(rows)
    events = [
        {"t": 1.0, "source": "agent/3", "kind": "repair", "data": {"stage": 1, "r": 0.01,
                                                                  "subtask": 0}},
        {"t": 6.0, "source": "agent/4", "kind": "repair", "data": {"stage": 3, "subtask": 0}},
        {"t": 6.5, "source": "agent/4", "kind": "repair", "data": {"stage": 3, "r": -0.2,
                                                                  "subtask": 0}},
        {"t": 3.0, "source": "sim", "kind": "contact", "data": {"a": 3, "b": "wall"}},
        {"t": 60.0, "source": "sim", "kind": "sim_stats",
         "data": {"due": 1000, "missed": 2, "latency_p50_ms": 1.5, "latency_p99_ms": 7.25}},
    ]
    (run_dir / "events.jsonl").write_text("".join(json.dumps(e) + "\n" for e in events))


def read_csv(run_dir: Path) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    data = np.loadtxt(run_dir / "trajectory.csv", delimiter=",", skiprows=1)
    return data[:, 0], {j: data[:, 1 + 3 * k:4 + 3 * k] for k, j in enumerate((1, 2, 3, 4))}


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory) -> tuple[Path, dict]:
    run_dir = tmp_path_factory.mktemp("synthetic")
    write_synthetic(run_dir)
    write_report(run_dir)
    return run_dir, json.loads((run_dir / "report.json").read_text())


# -- STL values against a recomputation that does not use tlfleet.agent.stl
# ------------------------------

def test_stl_robustness_equals_direct_recomputation(synthetic) -> None:
    run_dir, data = synthetic
    t, s = read_csv(run_dir)

    def window(a: float, b: float) -> np.ndarray:
        return (t >= a) & (t <= b)

    def dist(p: np.ndarray, q) -> np.ndarray:
        return np.hypot(p[:, 0] - np.asarray(q)[..., 0], p[:, 1] - np.asarray(q)[..., 1])

    p3, p4 = s[3][:, :2], s[4][:, :2]
    w = window(2, 4)
    g3 = np.min(0.5 - dist(p3[w], [0.2, -1]))
    w = window(5, 8)  # coupled F: max over t of the min of both predicates
    f3 = np.max(np.minimum(0.7 - dist(p3[w], p4[w]), 0.3 - dist(p3[w], [0.5, -1])))
    w = window(1, 9)
    g4 = np.min(1.0 - dist(p4[w], [1, -1.5]))
    w = window(10, 12)
    f4 = np.max(0.1 - dist(p4[w], [0.3, -1.5]))
    got = {(r, i): data["stl"][str(r)]["subtasks"][i]["robustness"] for r in (3, 4) for i in (0, 1)}
    assert got[(3, 0)] == pytest.approx(g3, abs=1e-12)
    assert got[(3, 1)] == pytest.approx(f3, abs=1e-12)
    assert got[(4, 0)] == pytest.approx(g4, abs=1e-12)
    assert got[(4, 1)] == pytest.approx(f4, abs=1e-12)
    assert data["stl"]["3"]["robustness"] == pytest.approx(min(g3, f3), abs=1e-12)


def test_stl_r_bar_repairs_and_no_paper_values(synthetic) -> None:
    _run_dir, data = synthetic
    sub = data["stl"]["4"]["subtasks"]
    # r decreases along the status rows, so the least r in force is the last row's
    assert sub[1]["r_bar"] == sub[1]["r_final"] == pytest.approx(0.02 - 0.001 * 12.0)
    assert sub[1]["repairs"] == {"stage1": 1, "stage2": 0, "stage3": 12}
    assert sub[0]["repair_events"] == {"stage1": 0, "stage2": 0, "stage3": 2}
    assert data["stl"]["3"]["subtasks"][0]["repair_events"]["stage1"] == 1
    assert [s["label"] for s in data["stl"]["3"]["subtasks"]] == ["r3.1", "r3.2"]
    assert all(s["paper"] is None for e in data["stl"].values() for s in e["subtasks"])
    assert "not one of the paper's scenarios" in data["paper_note"]


R0, R_DIP = 0.0225, -0.11  # robot 4's φ of sub-task 1: r before the repairs, after them


def write_repair_then_recovery(run_dir: Path, *, done: bool) -> None:
    """The synthetic run with robot 4's sub-task 1 repaired at 10.2 s (r → −0.05) and 10.6 s
    (r → R_DIP), then recovered at 10.9 s (r → R0): no 0.5 s status row falls inside the dip,
    so only the events show it; ``done``: the agent's ``subtask_done`` (r = R_DIP) is there too
    (else the run is cut short before it)."""
    write_synthetic(run_dir)
    with open(run_dir / "status.csv", newline="") as f:
        reader = csv.DictReader(f)
        header, rows = reader.fieldnames, list(reader)
    for row in rows:
        if row["robot"] == "4" and row["subtask"] == "1":
            row["r"] = f"{R0}"
    with open(run_dir / "status.csv", "w", newline="") as f:
        w = csv.DictWriter(f, header)
        w.writeheader()
        w.writerows(rows)
    events = [
        {"t": 10.2, "source": "agent/4", "kind": "repair", "data": {"stage": 3, "r": -0.05,
                                                                   "subtask": 1}},
        {"t": 10.6, "source": "agent/4", "kind": "repair", "data": {"stage": 3, "r": R_DIP,
                                                                   "subtask": 1}},
        {"t": 10.9, "source": "agent/4", "kind": "recovery",
         "data": {"r": R0, "r_before": R_DIP, "subtask": 1}},
    ]
    if done:
        events.append({"t": 12.0, "source": "agent/4", "kind": "subtask_done",
                       "data": {"subtask": 1, "satisfied": False, "r": R_DIP, "recoveries": 1}})
    with open(run_dir / "events.jsonl", "a") as f:
        f.write("".join(json.dumps(e) + "\n" for e in events))


@pytest.mark.parametrize("done", [True, False])
def test_r_bar_is_the_least_r_in_force_after_repairs_and_recovery(tmp_path: Path, done) -> None:
    """Repairs lower r, a recovery raises it again: r̄ (report.json r_bar, report.md, the console
    table, summary.txt) is the least r in force, as the agent's subtask_done says, with the final
    funnel's r beside it; without subtask_done it comes from the repair/recovery events."""
    run_dir = tmp_path / "run"
    write_repair_then_recovery(run_dir, done=done)
    report = write_report(run_dir, figures=False)
    sub = json.loads((run_dir / "report.json").read_text())["stl"]["4"]["subtasks"][1]
    assert sub["r_bar"] == pytest.approx(R_DIP) and sub["r_final"] == pytest.approx(R0)
    assert sub["robustness_ge_r_bar"] == (sub["robustness"] >= R_DIP)
    md = (run_dir / "report.md").read_text()
    assert "| r̄ (least) | r final |" in md
    row = next(line for line in md.splitlines() if "`F[10,12]" in line)
    assert f"| {R_DIP:+.4f} | {R0:+.4f} |" in row
    table = next(line for line in render_table(report).splitlines()
                 if line.lstrip().startswith("r4.2"))
    assert table.split()[2:4] == [f"{R_DIP:+.4f}", f"{R0:+.4f}"]
    text, summary = summarise_run(run_dir)
    assert summary.stl[4].subtasks[1].r_least == pytest.approx(R_DIP)
    assert f"r̄ (least r in force) = {R_DIP:+.4f}, final r = {R0:+.4f}" in text


def test_contacts_and_timing(synthetic) -> None:
    _run_dir, data = synthetic
    assert data["contacts"]["robot_wall"] == 1 and data["contacts"]["robot_robot"] == 0
    assert data["timing"]["control_due"] == 1000 and data["timing"]["control_missed"] == 2
    assert data["timing"]["latency_p99_ms"] == 7.25


# -- LTL: visits, word, cycles, acceptance -----------------------------------------------------

def entry_times(t: np.ndarray, xy: np.ndarray, center, radius: float,
                hysteresis: float = 0.05) -> list[float]:
    d = np.hypot(xy[:, 0] - center[0], xy[:, 1] - center[1])
    out, inside = [], False
    for tk, dk in zip(t, d, strict=True):
        if not inside and dk <= radius:
            out.append(float(tk))
            inside = True
        elif inside and dk > radius + hysteresis:
            inside = False
    return out


def test_ltl_visits_word_and_cycles_recomputed(synthetic) -> None:
    run_dir, data = synthetic
    t, s = read_csv(run_dir)
    a = entry_times(t, s[1][:, :2], (-2, 0), 0.25)
    b = entry_times(t, s[1][:, :2], (2, 0), 0.25)
    assert len(a) == 4 and len(b) == 3  # t = 0, 20, 40, 60 and 10, 30, 50 (approximately)
    r1 = data["ltl"]["1"]
    assert r1["visits"] == {"a": {"agent": 3, "trajectory": 4}, "b": {"agent": 3, "trajectory": 3}}
    word = sorted([(x, "a") for x in a] + [(x, "b") for x in b])
    assert [(w["t"], w["region"]) for w in r1["word"]] == word
    # suffix (b a b) → cycle (b, a); completions at the 2nd and 3rd entry into b
    assert r1["cycle"] == ["b", "a"] and r1["cycles_completed"] == 2
    assert r1["cycle_times"] == pytest.approx([b[1] - b[0], b[2] - b[1]])
    assert r1["cycle_time_mean"] == pytest.approx(PERIOD, abs=DT)
    assert r1["lasso"]["loop"] == ["b", "a"] and r1["lasso"]["prefix"] == ["a", "b", "a"]
    assert r1["accepting"] == {"lasso": True, "buchi": True, "agree": True, "met": True}


def test_ltl_robot_that_never_completes_its_cycle_does_not_meet_the_task(synthetic) -> None:
    _run_dir, data = synthetic
    r2 = data["ltl"]["2"]
    assert [w["region"] for w in r2["word"]] == ["start", "b"]
    assert r2["cycles_completed"] == 0 and r2["cycle_times"] == []
    assert r2["lasso"]["loop"] == ["b"]
    assert r2["accepting"] == {"lasso": False, "buchi": False, "agree": True, "met": False}


def test_plan_recomputed_without_status_rows(tmp_path: Path) -> None:
    write_synthetic(tmp_path, status=False)
    report = build_report(tmp_path)
    r1 = report.ltl[1]
    assert r1.plan.source.startswith("recomputed")
    assert set(r1.cycle) == {"a", "b"} and r1.cycles_completed >= 2
    assert r1.accepting.met and not report.ltl[2].accepting.met


@pytest.mark.parametrize(("suffix", "cycle"), [
    (["b", "a", "b"], ["b", "a"]), (["a2"], ["a2"]), (["a", "a", "b"], ["a", "b"]),
    (["a", "b", "c", "a", "a"], ["a", "b", "c"]),
])
def test_plan_cycle_collapses_cyclically(suffix, cycle) -> None:
    assert plan_cycle(suffix) == cycle


def test_completed_cycles_need_the_whole_cycle() -> None:
    assert completed_cycles(["a", "b", "a", "b", "c", "b"], ["b", "a"]) == [3]
    assert completed_cycles(["a", "b", "a"], ["a"]) == []


@settings(max_examples=examples(60), deadline=None)
@given(formulas(atoms=("a", "b"), max_depth=3), lasso_words(atoms=("a", "b")))
def test_buchi_on_lasso_agrees_with_exact_evaluation(formula, word) -> None:
    prefix, loop = word
    assert accepts_lasso(translate(formula), prefix, loop) == holds(formula, prefix, loop)


# -- the paper's scenarios (thinned real runs) ----------------------------------------------------

@pytest.fixture(scope="module")
def scenarios(tmp_path_factory) -> dict[str, tuple[Path, object]]:
    out = {}
    for name in ("s1", "s2", "s3"):
        run_dir = tmp_path_factory.mktemp(name)
        shutil.copytree(FIXTURES / name, run_dir, dirs_exist_ok=True)
        out[name] = (run_dir, write_report(run_dir))
    return out


def test_scenario1_paper_values_and_sic_note(scenarios) -> None:
    run_dir, report = scenarios["s1"]
    subs = {s.label: s for e in report.stl.values() for s in e.subtasks}
    assert set(subs) == {"φ′3", "φ″3", "φ′4", "φ″4", "φ′5", "φ″5"}
    assert subs["φ″5"].paper.bound == 0.05 and "0.5 (sic)" in subs["φ″5"].paper.printed
    assert subs["φ′4"].paper.best == -0.9
    for s in subs.values():
        assert s.paper.met == (s.robustness >= s.paper.bound)
    assert "judged against 0.05" in render_markdown(report) and "φ″5" in render_table(report)
    # the standard robustness of φ′3 recomputed from the CSV: min over [21, 30] of 0.1 − ‖p3 − c‖
    data = np.loadtxt(run_dir / "trajectory.csv", delimiter=",", skiprows=1)
    t, p3 = data[:, 0], data[:, 7:9]
    w = (t >= 21) & (t <= 30)
    assert subs["φ′3"].robustness == pytest.approx(
        np.min(0.1 - np.hypot(p3[w, 0], p3[w, 1] + 2)), abs=1e-12)
    assert all(e.accepting.met for e in report.ltl.values())
    assert report.figure_windows == ((0.0, 30.0), (30.0, 90.0))


def test_scenario2_and_3_labels(scenarios) -> None:
    labels = [s.label for e in scenarios["s2"][1].stl.values() for s in e.subtasks]
    assert labels == ["φ3", "φ4"]
    s3 = scenarios["s3"][1]
    assert all(s.paper is None for e in s3.stl.values() for s in e.subtasks)
    # the paper names the formation tasks φ2–φ4 (no bound); the table adds the robot
    assert [s.label for e in s3.stl.values() for s in e.subtasks] == ["φ2", "φ3", "φ4"]
    assert "φ3 (r3)" in render_table(s3)
    assert "reports no robustness bound" in render_markdown(s3)
    assert "reports no robustness bound" in render_table(s3)
    r1 = s3.ltl[1]
    assert r1.cycle == ("a2",) and r1.cycles_completed == 0 and r1.accepting.met


def test_edited_task_under_a_paper_name_gets_no_paper_value() -> None:
    spaced = "G[21,30]   (dist( p3,[0, -2] ) <= 0.10)"
    assert paper_values.lookup("scenario1", 3, spaced).label == "φ′3"
    assert paper_values.lookup("scenario1", 3, "G[21,30] (dist(p3, [0,-2]) <= 0.2)") is None
    assert paper_values.lookup("scenario1", 5, paper_values.S1_P3_FIRST) is None
    assert paper_values.lookup("other", 3, paper_values.S1_P3_FIRST) is None
    formation = ("G[10,100] (dist(p3 - p1, [-sin(th1), cos(th1)]) <= 0.1 "
                 "& angdist(th3, th1) <= 0.09)")
    assert paper_values.label("scenario3", 3, formation) == "φ3"
    assert paper_values.label("scenario3", 3, formation.replace("0.1 &", "0.2 &")) is None
    assert paper_values.label("scenario3", 2, formation) is None


def non_background_fraction(path: Path) -> float:
    image = imread(path)[..., :3]
    return float(np.mean(np.any(np.abs(image - 1.0) > 0.02, axis=-1)))


@pytest.mark.parametrize("name", ["s1", "s2", "s3"])
def test_figures_written_and_not_blank(scenarios, name) -> None:
    run_dir, report = scenarios[name]
    assert set(report.figures) >= {f"robustness_r{r}.png" for r in report.stl}
    assert sum(name.startswith("trajectories_") for name in report.figures) == 2
    for path in report.figure_paths:
        assert path.parent == run_dir and path.stat().st_size > 20_000
        assert imread(path).std() > 0.05
        assert non_background_fraction(path) > 0.03
        assert f"]({path.name})" in (run_dir / "report.md").read_text(encoding="utf-8")
    assert json.loads((run_dir / "report.json").read_text())["figures"] == list(report.figures)


def test_robustness_figure_of_a_run_shorter_than_its_subtask(tmp_path: Path) -> None:
    """A run stopped at 2 s of a G[0,20] task: the window's label lies beyond the axis; it must
    not collapse the layout (matplotlib warned and drew an empty figure before the fix)."""
    t = np.linspace(0.0, 2.0, 21)
    series = {"t": t, "rho": 0.1 - 0.05 * t, "rho_max": np.full_like(t, 0.2),
              "lower": -0.1 + 0.1 * t, "r": np.full_like(t, 0.05), "subtask": np.zeros_like(t)}
    path = tmp_path / "robustness_r2.png"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        robustness_figure(2, series, [("r2.1", 0.0, 20.0)], [RepairEvent(1.0, 1, 0, 0.05)],
                          path, t_end=2.0)
    assert non_background_fraction(path) > 0.03


def test_build_report_writes_nothing(tmp_path: Path) -> None:
    shutil.copytree(FIXTURES / "s2", tmp_path, dirs_exist_ok=True)
    before = sorted(p.name for p in tmp_path.iterdir())
    report = build_report(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == before and report.figures == ()
    assert report.ltl[2].visits["a22"] == Visits(agent=2, trajectory=2)


# -- bad input ----------------------------------------------------------------------------------

def test_missing_scenario_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(RunDirectoryError, match=r"scenario\.toml: missing"):
        build_report(tmp_path)
    with pytest.raises(RunDirectoryError, match="not a run directory"):
        build_report(tmp_path / "nope")


def test_cli_reports_a_bad_run_dir_in_one_line(tmp_path: Path, capsys) -> None:
    assert cli_main(["report", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "scenario.toml" in err


def test_cli_prints_table_and_paths(tmp_path: Path, capsys) -> None:
    write_synthetic(tmp_path)
    assert cli_main(["report", str(tmp_path), "--no-figures"]) == 0
    out = capsys.readouterr().out
    assert "r3.1" in out and "LTL r1" in out and str(tmp_path / "report.json") in out
    assert not list(tmp_path.glob("*.png"))
    assert cli_main(["report", str(tmp_path), "--json", "--no-figures"]) == 0
    assert json.loads(capsys.readouterr().out)["scenario"] == "synthetic"


def test_torn_last_event_line_is_skipped_and_reported(tmp_path: Path) -> None:
    write_synthetic(tmp_path)
    with open(tmp_path / "events.jsonl", "a") as f:
        f.write('{"t": 61.0, "source": "agent/3", "kind": "rep')
    report = write_report(tmp_path, figures=False)
    assert report.events_skipped_lines == (6,)
    assert "line(s) 6 not JSON" in render_markdown(report)
    assert report.stl[3].subtasks[0].repair_events.stage1 == 1


@pytest.mark.parametrize("content", ["", "t,x1,y1,th1,x2,y2,th2,x3,y3,th3,x4,y4,th4\n"])
def test_empty_trajectory_is_reported_not_fatal(tmp_path: Path, content: str) -> None:
    write_synthetic(tmp_path)
    (tmp_path / "trajectory.csv").write_text(content)
    report = write_report(tmp_path)
    assert report.trajectory_error
    assert "trajectory unusable" in render_markdown(report)
    assert "trajectory:" in render_table(report)
    assert report.ltl[1].accepting.met is False
    assert "no trajectory" in report.ltl[1].note
    assert all(s.robustness is None for s in report.stl[3].subtasks)
    assert all(s.paper is None for s in report.stl[3].subtasks)
    assert set(report.figures) == {"robustness_r3.png", "robustness_r4.png"}


def test_missing_trajectory_file(tmp_path: Path) -> None:
    write_synthetic(tmp_path)
    (tmp_path / "trajectory.csv").unlink()
    report = build_report(tmp_path)
    assert "cannot open" in report.trajectory_error
