"""Scheduled process faults on loopback (issue 13 §1–§2; no root needed): ``freeze:`` and
``restart:`` given to ``tlfleet run`` as fault specs, driven by the sim time the coordinator sees.

Freeze: robot 2's agent (STL) is stopped for 3 s of wall time in realtime; the watchdog stops its
robot, the coordinator notices the silence, and on SIGCONT the agent answers the newest frame
(no burst of stale commands). Restart: robot 2's agent is killed and started again with the same
argv; the run completes and the new agent drives its robot again.
"""

from __future__ import annotations

import collections
import json
import subprocess
import sys

import numpy as np
import pytest
from system_helpers import (
    HERE,
    ROOT,
    assert_restarted_agent_drove_again,
    events,
    leftover_in_groups,
    load_trajectory,
    run,
)
from tlfleet.agent.model.faults import parse_fault
from tlfleet.agent.scenario import load_scenario

pytestmark = pytest.mark.system
TWO = HERE / "two_robots.toml"


def fault_events(run_dir):
    return [e for e in events(run_dir) if e["kind"] in ("fault_start", "fault_end")]


def test_a_scheduled_freeze_stops_the_robot_and_the_agent_resumes_on_the_newest_frame(tmp_path):
    run_dir = tmp_path / "run"
    result = run(TWO, run_dir, mode="realtime", duration=8.0, rrd=False, report=True,
                 figures=False, faults=(parse_fault("freeze:robot2@1.5+3"),))
    assert result.outcome.reason in ("sim_done", "duration") and result.outcome.deaths == []
    start, end = fault_events(run_dir)
    assert (start["kind"], end["kind"]) == ("fault_start", "fault_end")
    assert start["data"]["spec"] == "freeze:robot2@1.5+3"
    assert 1.5 <= start["t"] < 1.7  # the coordinator's sim time when it froze the agent
    assert 3.0 <= end["data"]["lasted"] < 3.3  # wall time
    assert end["data"]["wall"] - start["data"]["wall"] == pytest.approx(end["data"]["lasted"],
                                                                        abs=0.05)
    assert 4.3 < end["t"] < 5.0  # realtime: sim time went on meanwhile
    stops = [e for e in events(run_dir) if e["kind"] == "watchdog_stop"
             and e["data"]["robot"] == 2]
    watchdog = load_scenario(TWO).sim.watchdog  # [s] sim time, 0.5 by default
    assert stops and start["t"] < stops[0]["t"] <= start["t"] + watchdog + 0.1
    t, states = load_trajectory(run_dir)
    held = (t > stops[0]["t"] + 0.3) & (t < end["t"] - 0.1)
    assert held.sum() > 50
    assert np.ptp(states[2][held, 0]) < 0.02 and np.ptp(states[2][held, 1]) < 0.02
    kinds = collections.Counter(e["kind"] for e in events(run_dir))
    assert kinds["agent_silent"] >= 1 and kinds["agent_back"] >= 1
    resumed = [e for e in events(run_dir) if e["kind"] == "resumed"]
    assert resumed and resumed[0]["data"]["gap"] >= 2.5
    # no burst: the simulator ignored at most the one command computed on the pre-freeze frame
    sim_stats = result.summary.deadlines.sim_stats.counters
    assert sim_stats["stale_commands"] <= 1, sim_stats
    after = (t > end["t"] + 0.5)
    assert np.ptp(states[2][after, 0]) + np.ptp(states[2][after, 1]) > 0.05  # it moves again
    assert result.verdict.label == "degraded"
    assert any(r.startswith("fault freeze:robot2@1.5+3 injected at t = 1.") for r in
               result.verdict.reasons)
    info = json.loads((run_dir / "run.json").read_text())
    assert [f["spec"] for f in info["faults"]] == ["freeze:robot2@1.5+3"]
    assert "freeze:robot2@1.5+3" in (run_dir / "report.md").read_text()
    assert leftover_in_groups(run_dir) == []


def test_a_restarted_agent_comes_back_and_the_run_completes(tmp_path):
    run_dir = tmp_path / "run"
    result = run(TWO, run_dir, mode="realtime", duration=8.0, rrd=False, report=False,
                 faults=(parse_fault("restart:robot2@2"),))
    assert result.outcome.reason in ("sim_done", "duration")
    assert result.outcome.deaths == []  # it died and came back: a recovery, not a death
    start, end = fault_events(run_dir)
    assert start["data"]["pid"] != start["data"]["new_pid"]
    assert 2.0 <= start["t"] < 2.2 and end["data"]["lasted"] < 5.0
    assert result.exit_codes["agent-2"] == 0 and result.exit_codes["sim"] == 0
    assert_restarted_agent_drove_again(run_dir, 2)
    assert result.verdict.label == "degraded"
    assert any("fault restart:robot2@2" in r for r in result.verdict.reasons)
    assert leftover_in_groups(run_dir) == []


def test_a_restarted_ltl_agent_plans_again_from_where_its_robot_is(tmp_path):
    """The new process of LTL robot 1 (``G F a1 & G F a2``), restarted inside a1
    on its way out, finds its robot away from the start pose, plans again from there
    (``plan_ready`` with ``reason.joined``, the plan starting at a1) and goes on to a2."""
    run_dir = tmp_path / "run"
    result = run(TWO, run_dir, mode="realtime", duration=14.0, rrd=False, report=False,
                 faults=(parse_fault("restart:robot1@2.8"),))
    assert result.outcome.reason in ("sim_done", "duration") and result.outcome.deaths == []
    assert_restarted_agent_drove_again(run_dir, 1)
    evs = events(run_dir)
    recovered = next(e for e in evs if e["kind"] == "process_recovered")
    joined = [e for e in evs if e["kind"] == "plan_ready" and e["source"] == "agent/1"
              and e["data"].get("reason", {}).get("joined")]
    assert len(joined) == 1 and joined[0]["t"] >= recovered["t"] - 0.5
    assert joined[0]["data"]["reason"]["away"] > 0.1
    assert joined[0]["data"]["prefix"][0] == "a1"  # it is inside a1: the plan starts there
    visits = {e["data"]["region"] for e in evs if e["kind"] == "region_visited"
              and e["source"] == "agent/1" and e["t"] > joined[0]["t"]}
    assert "a2" in visits, visits
    assert leftover_in_groups(run_dir) == []


def test_a_frozen_agent_in_lockstep_pauses_the_fleet_and_changes_nothing(tmp_path):
    """Lockstep: the simulator waits for the frozen agent's command (tick timeout 6 s > 3 s), so
    the trajectory is byte-identical to the run without the fault; paced at 4 × wall time so the
    fault comes at a known wall time on any machine."""
    reference = run(TWO, tmp_path / "reference", duration=8.0, rrd=False, report=False)
    assert reference.clean
    run_dir = tmp_path / "run"
    result = run(TWO, run_dir, duration=8.0, rrd=False, report=False, tick_timeout=6.0,
                 sim_args=("--max-speed", "4"), faults=(parse_fault("freeze:robot2@2+3"),))
    assert result.outcome.reason in ("sim_done", "duration") and result.outcome.deaths == []
    start, end = fault_events(run_dir)
    assert end["data"]["lasted"] >= 3.0
    assert end["t"] - start["t"] < 0.1  # the fleet waited: sim time stood still
    assert (run_dir / "trajectory.csv").read_bytes() == \
        (tmp_path / "reference" / "trajectory.csv").read_bytes()
    kinds = collections.Counter(e["kind"] for e in events(run_dir))
    assert kinds["watchdog_stop"] == 0 and kinds["deadline_miss"] == 0
    assert result.verdict.label == "degraded"  # the fault, and the fleet's stale mocap
    others = [r for r in result.verdict.reasons if not r.startswith("fault ")]
    assert len(others) == 1 and "stale-mocap episode(s)" in others[0]  # the paused fleet


def test_a_killed_router_ends_the_run_with_every_file_parseable_and_flushed(tmp_path):
    from tlfleet.coordinator.record import rundir

    run_dir = tmp_path / "run"
    result = run(TWO, run_dir, mode="realtime", duration=8.0, rrd=False, report=False,
                 faults=(parse_fault("kill:router@2"),))
    assert result.outcome.reason == "router_lost"
    assert result.verdict.label == "failed"
    assert result.exit_codes["router"] == -9
    assert {n: c for n, c in result.exit_codes.items() if n != "router"} == \
        {"sim": 0, "agent-1": 0, "agent-2": 0}  # stopped by the launcher, cleanly
    files = rundir.read_run(run_dir, strict=True)  # every file parses
    (start,) = [e for e in files.events if e.kind == "fault_start"]
    assert files.trajectory is not None and files.trajectory.t[-1] >= start.t - 0.05
    assert any(e.kind == "process_died" and e.data["process"] == "router" for e in files.events)
    assert json.loads((run_dir / "run.json").read_text())["faults"][0]["spec"] == \
        "kill:router@2"
    assert leftover_in_groups(run_dir) == []


def test_a_restarted_router_is_rejoined_by_every_client_and_the_run_completes(tmp_path):
    """The router is killed and started again on the same endpoint; every token
    goes and comes back with it (link losses and restorations, not deaths), the clients
    reconnect within zenoh's retry period (250 ms in fault runs), the run completes and every
    file parses; the frames published while the coordinator had no router are backfilled."""
    from tlfleet.coordinator.record import rundir

    run_dir = tmp_path / "run"
    result = run(TWO, run_dir, mode="realtime", duration=8.0, rrd=False, report=False,
                 lease_ms=500, faults=(parse_fault("restart:router@2"),))
    assert result.outcome.reason in ("sim_done", "duration") and result.outcome.deaths == []
    assert result.exit_codes == {"router": 0, "sim": 0, "agent-1": 0, "agent-2": 0}
    files = rundir.read_run(run_dir, strict=True)  # every file parses
    (start,) = [e for e in files.events if e.kind == "fault_start"]
    assert start.data["pid"] != start.data["new_pid"]
    lost = {e.data["process"] for e in files.events if e.kind == "link_lost"}
    restored = [e for e in files.events if e.kind == "link_restored"]
    assert lost == {"sim", "agent-1", "agent-2"} == {e.data["process"] for e in restored}
    assert max(e.data["lost_for"] for e in restored) < 3.0
    assert not [e for e in files.events if e.kind == "process_died"]
    t = files.trajectory.t
    assert t[-1] == pytest.approx(8.0) and (np.diff(t) > 0).all()
    # the frames published while the coordinator had no router were backfilled:
    # one row per tick, none twice
    assert np.allclose(np.diff(t), 0.01, atol=1e-9)
    fills = [e for e in files.events if e.kind == "backfill"]
    assert all(e.data["unrecovered"] == 0 for e in fills)
    assert len(fills) == len([e for e in files.events if e.kind == "trajectory_gap"])
    assert result.verdict.label == "degraded"
    assert leftover_in_groups(run_dir) == []
    print(f"router restart: clients back after {max(e.data['lost_for'] for e in restored):.2f} "
          f"s; backfilled {[e.data['backfilled'] for e in fills]} frames")


def test_bad_fault_specs_exit_before_anything_starts(tmp_path):
    for spec, message in (("cut:robot3@x+3", "fault 'cut:robot3@x+3': time: 'x' is not a "
                                             "number of seconds"),
                          ("kill:robot9@1", "the scenario has no robot 9"),
                          ("freeze:robot1@30+1", "@30 s is not before the end of the run")):
        out = tmp_path / spec.replace(":", "_")
        done = subprocess.run([sys.executable, "-m", "tlfleet.cli", "run", str(TWO), "--out",
                               str(out), "--fault", spec], capture_output=True, text=True,
                              cwd=ROOT, timeout=60)
        assert done.returncode in (1, 2), done.stderr
        assert message in done.stderr, done.stderr
        assert not out.exists()  # nothing was written, nothing started
    assert load_scenario(TWO).faults == ()


@pytest.mark.parametrize("spec", ["freeze:sim@3+2", "freeze:router@3+2", "freeze:robot2@3+2"])
def test_with_a_short_lease_a_frozen_process_is_unreachable_and_the_run_completes(tmp_path,
                                                                                   spec):
    """README's fault examples with ``--lease-ms 500``: the frozen process's token (or, for the
    router, everybody's) lapses while its process runs — unreachable, never dead — and the run
    ends at its duration with an honest verdict: degraded, the episode listed."""
    run_dir = tmp_path / "run"
    result = run(TWO, run_dir, mode="realtime", duration=9.0, rrd=False, report=True,
                 figures=False, lease_ms=500, faults=(parse_fault(spec),))
    assert result.outcome.reason in ("sim_done", "duration") and result.outcome.deaths == []
    assert result.outcome.t_end == pytest.approx(9.0)
    assert result.verdict.label == "degraded", result.verdict.line
    kinds = collections.Counter(e["kind"] for e in events(run_dir))
    assert kinds["process_died"] == 0
    lost = {e["data"]["process"] for e in events(run_dir) if e["kind"] == "process_unreachable"}
    back = {e["data"]["process"] for e in events(run_dir) if e["kind"] == "process_reachable"}
    assert lost and lost == back, (lost, back)  # every one of them came back
    target = spec.split(":")[1].split("@")[0].replace("robot", "agent-")
    assert target in lost or target == "router"
    assert all(code == 0 for code in result.exit_codes.values()), result.exit_codes
