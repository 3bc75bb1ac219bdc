"""``tlfleet run`` end to end with stand-in router/sim/agent processes on loopback (real zenoh).

The stand-ins (``standin.py``) speak the runtime protocol minimally, so these tests exercise the
launcher, the supervisor, the recorder and the summary without the real simulator and agents.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

import pytest
from process_helpers import processes_mentioning
from tlfleet.cli import main as cli
from tlfleet.coordinator.live.supervisor import SupervisorConfig
from tlfleet.coordinator.run import RunConfig, run_fleet

STANDIN = Path(__file__).with_name("standin.py")
SCENARIO = """
name = "standin"
duration = 2.0
[[regions]]
name = "a1"
center = [-1.0, 0.0]
[[regions]]
name = "a2"
center = [1.0, 0.0]
[[robots]]
id = 1
kind = "unicycle"
pose = [0.0, -1.0, 0.0]
ltl = "G F a1 & G F a2"
[[robots]]
id = 2
kind = "omni"
pose = [0.0, 1.0, 0.0]
stl = ["G[0,2] (dist(p2, p1) <= 0.8)"]
"""

pytestmark = pytest.mark.system


def standin_argv(extra: dict[str, list[str]] | None = None, sim_duration: float = 1.0):
    def argv(spec):  # a ProcessSpec of tlfleet.coordinator.launch.plan, placed
        endpoint = (spec.links.connect or spec.links.listen)[0]
        scenario = "-" if spec.role == "router" else spec.args[1]  # the router reads none
        args = [sys.executable, str(STANDIN), spec.role, scenario, "--endpoint", endpoint]
        if spec.robot is not None:
            args += ["--robot", str(spec.robot)]
        if spec.role == "sim":
            args += ["--duration", str(sim_duration)]
        return args + (extra or {}).get(spec.name, [])
    return argv



@pytest.fixture
def scenario_path(tmp_path):
    path = tmp_path / "standin.toml"
    path.write_text(SCENARIO)
    yield path
    for proc in processes_mentioning(str(path)):  # never leave anything behind, even on failure
        proc.kill()


def test_clean_run_records_and_summarises(tmp_path, scenario_path):
    config = RunConfig(scenario_path, out=tmp_path / "run", child_argv=standin_argv())
    result = run_fleet(config)
    assert result.outcome.reason == "sim_done" and result.clean
    assert result.exit_codes == {"router": 0, "sim": 0, "agent-1": 0, "agent-2": 0}
    run = tmp_path / "run"
    for name in ("scenario.toml", "trajectory.csv", "status.csv", "events.jsonl", "run.json",
                 "summary.txt", "logs/router.log", "logs/sim.log", "logs/agent-1.log"):
        assert (run / name).exists(), name
    rows = (run / "trajectory.csv").read_text().splitlines()
    assert rows[0] == "t,x1,y1,th1,x2,y2,th2" and len(rows) == 1 + 101
    kinds = [json.loads(line)["kind"] for line in (run / "events.jsonl").read_text().splitlines()]
    assert "sim_done" in kinds
    assert "robot-wall 1" in result.summary_text
    assert result.summary.stl[2].robustness is not None
    assert processes_mentioning(str(scenario_path)) == []


def test_killed_agent_is_reported_within_one_second_and_the_run_goes_on(tmp_path,
                                                                         scenario_path):
    config = RunConfig(scenario_path, out=tmp_path / "run", duration=3.0,
                       child_argv=standin_argv(sim_duration=3.0))
    killed: dict[str, float] = {}

    def killer():
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            status = tmp_path / "run" / "status.csv"
            if status.exists() and len(status.read_text().splitlines()) > 1:  # started
                for proc in processes_mentioning(str(scenario_path)):
                    if "--robot" in proc.cmdline() and proc.cmdline()[-1] == "2":
                        killed["wall"] = time.time()
                        os.kill(proc.pid, signal.SIGKILL)
                        return
            time.sleep(0.05)

    thread = threading.Thread(target=killer)
    thread.start()
    result = run_fleet(config)
    thread.join()
    assert "wall" in killed
    assert result.outcome.reason in ("sim_done", "duration") and not result.clean
    assert result.outcome.t_end >= 3.0
    (death,) = result.outcome.deaths
    assert death.process == "agent-2" and death.wall - killed["wall"] < 1.0
    events = [json.loads(x) for x in (tmp_path / "run/events.jsonl").read_text().splitlines()]
    died = [e for e in events if e["kind"] == "process_died"]
    assert [e["data"]["process"] for e in died] == ["agent-2"]
    assert result.exit_codes["agent-1"] == 0 and result.exit_codes["agent-2"] == -9
    assert "process deaths: 1" in result.summary_text
    assert processes_mentioning(str(scenario_path)) == []


def test_stop_event_interrupts_and_cleans_up(tmp_path, scenario_path):
    config = RunConfig(scenario_path, out=tmp_path / "run",
                       child_argv=standin_argv(sim_duration=60.0))
    stop = threading.Event()
    seen = []

    def progress(t, duration):
        seen.append(t)
        if t > 0.2:
            stop.set()

    result = run_fleet(config, stop=stop, progress=progress)
    assert result.outcome.reason == "interrupted" and not result.clean
    assert max(seen) > 0.2
    assert processes_mentioning(str(scenario_path)) == []


def test_an_agent_that_never_comes_up_is_named(tmp_path, scenario_path):
    # 5 s: the other stand-ins must be up by then even on a loaded machine (with 2 s, a starved
    # sim was named too)
    config = RunConfig(scenario_path, out=tmp_path / "run",
                       supervisor=SupervisorConfig(ready_timeout=5.0),
                       child_argv=standin_argv({"agent-1": ["--no-token"]}))
    with pytest.raises(Exception, match=r"not up after 5 s .*: agent-1\n.*agent-1.log"):
        run_fleet(config)
    assert processes_mentioning(str(scenario_path)) == []


def test_invalid_scenario_exits_1_before_anything_starts(tmp_path, capsys, monkeypatch):
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENARIO.replace('kind = "omni"', 'kind = "hovercraft"'))
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", str(bad), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"tlfleet run: {bad}: robots[1].kind") or "hovercraft" in err
    assert "hovercraft" in err
    assert not (tmp_path / "runs").exists()
