"""OS scheduling of a run's processes (issue 17, ``cli.process_flags``): ``tlfleet run`` starts the
router, the sim and the agents of a lockstep run under Linux's ``SCHED_BATCH`` (``--sched``),
realtime runs as the OS starts them. Checked on the argv the runner builds, on the flags, and on
the policy a real process ends up with (every thread it had and every thread it starts)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from agent.scenario import load_scenario
from coordinator.runner import RunConfig, child_sched, default_child_argv

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "scenario1.toml"
ROLES = (("router", None), ("sim", None), ("agent", 3), ("agent", 1))


def _sched_flag(argv: list[str]) -> str | None:
    return argv[argv.index("--sched") + 1] if "--sched" in argv else None


@pytest.mark.parametrize(("mode", "sched", "expected"), [
    ("lockstep", "auto", "batch"), ("realtime", "auto", "default"),
    ("lockstep", "default", "default"), ("realtime", "batch", "batch")])
def test_the_runner_asks_for_batch_scheduling_in_lockstep(mode, sched, expected):
    scenario = load_scenario(SCENARIO)
    config = RunConfig(SCENARIO, mode=mode, sched=sched)
    assert child_sched(config) == expected
    for role, robot in ROLES:
        argv = default_child_argv(role, config, scenario, robot, "tcp/127.0.0.1:7447")
        assert _sched_flag(argv) == ("batch" if expected == "batch" else None), (role, argv)


def test_a_bad_sched_value_is_refused_before_anything_starts(tmp_path):
    from coordinator.runner import run_fleet

    with pytest.raises(ValueError, match=r"RunConfig\.sched 'fast'"):
        run_fleet(RunConfig(SCENARIO, sched="fast", out=tmp_path / "run",
                            child_argv=lambda *_a: ["/nonexistent/tlfleet"]))
    assert not (tmp_path / "run").exists()


def test_the_flags_of_run_and_of_the_fleet_processes():
    from cli.commands import agent, router, run, sim

    parser = argparse.ArgumentParser()
    run.add_arguments(parser)
    assert parser.parse_args([str(SCENARIO)]).sched == "auto"
    assert parser.parse_args([str(SCENARIO), "--sched", "default"]).sched == "default"
    for command, positional in ((sim, [str(SCENARIO)]), (agent, [str(SCENARIO), "--robot", "3"]),
                                (router, [])):
        parser = argparse.ArgumentParser()
        command.add_arguments(parser)
        assert parser.parse_args(positional).sched == "default"
        assert parser.parse_args([*positional, "--sched", "batch"]).sched == "batch"
        with pytest.raises(SystemExit):
            parser.parse_args([*positional, "--sched", "fifo"])


PROBE = """
import json, os, sys, threading
sys.path.insert(0, {root!r})
from cli.process_flags import apply_scheduling
release = threading.Event()
before = threading.Thread(target=release.wait)
before.start()
problem = apply_scheduling({policy!r})
after = threading.Thread(target=release.wait)
after.start()
policies = {{name: os.sched_getscheduler(tid) for name, tid in
            (("main", 0), ("before", before.native_id), ("after", after.native_id))}}
release.set()
print(json.dumps({{"problem": problem, "policies": policies}}))
"""


@pytest.mark.skipif(not hasattr(os, "SCHED_BATCH"), reason="Linux scheduling policies")
@pytest.mark.parametrize("policy", ["batch", "default"])
def test_the_policy_reaches_every_thread_of_the_process(policy):
    done = subprocess.run([sys.executable, "-c", PROBE.format(root=str(ROOT), policy=policy)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["problem"] is None
    expected = os.SCHED_BATCH if policy == "batch" else os.sched_getscheduler(0)  # as started
    assert out["policies"] == {name: expected for name in ("main", "before", "after")}


def test_an_unknown_policy_is_a_value_error():
    from cli.process_flags import apply_scheduling

    with pytest.raises(ValueError, match="'fifo'"):
        apply_scheduling("fifo")
