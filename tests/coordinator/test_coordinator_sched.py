"""OS scheduling of a run's processes (``tlfleet.cli.process_flags``): ``tlfleet run``
starts the router, the sim and the agents under Linux's ``SCHED_FIFO`` where the user may ask for
it, and elsewhere a lockstep run under ``SCHED_BATCH`` and a realtime run as the OS starts it
(``--sched``). Checked on the argv the runner builds, on the flags, on the policy a real process
ends up with (every thread it had and every thread it starts), and on a refused ``fifo`` (an
unprivileged user) falling back to ``batch``."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from tlfleet.agent.scenario import load_scenario
from tlfleet.coordinator import run as runner
from tlfleet.coordinator.run import RunConfig, child_sched, default_child_argv, fleet_plan

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "scenario1.toml"
ROLES = (("router", None), ("sim", None), ("agent", 3), ("agent", 1))


def _sched_flag(argv: list[str]) -> str | None:
    return argv[argv.index("--sched") + 1] if "--sched" in argv else None


@pytest.mark.parametrize(("mode", "sched", "permitted", "expected"), [
    ("lockstep", "auto", True, "fifo"), ("lockstep", "auto", False, "batch"),
    ("realtime", "auto", True, "fifo"), ("realtime", "auto", False, "default"),
    ("lockstep", "default", True, "default"),
    ("realtime", "batch", True, "batch"), ("lockstep", "fifo", False, "fifo")])
def test_the_runner_asks_for_fifo_where_permitted_and_batch_in_lockstep_else(
        monkeypatch, mode, sched, permitted, expected):
    monkeypatch.setattr(runner, "fifo_permitted", lambda: permitted)
    scenario = load_scenario(SCENARIO)
    config = RunConfig(SCENARIO, mode=mode, sched=sched)
    assert child_sched(config) == expected
    plan = {spec.name: spec for spec in fleet_plan(config, scenario, "tcp/127.0.0.1:7447")}
    for role, robot in ROLES:
        argv = default_child_argv(plan[role if robot is None else f"agent-{robot}"])
        assert _sched_flag(argv) == (None if expected == "default" else expected), (role, argv)


def test_fifo_is_permitted_to_root_and_to_an_rtprio_limit():
    from tlfleet.coordinator.launch.processes import fifo_permitted

    if os.geteuid() == 0:
        assert fifo_permitted()
    else:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_RTPRIO)[0]
        assert fifo_permitted() == (soft == resource.RLIM_INFINITY or soft >= 1)


def test_a_bad_sched_value_is_refused_before_anything_starts(tmp_path):
    from tlfleet.coordinator.run import run_fleet

    with pytest.raises(ValueError, match=r"RunConfig\.sched 'fast'"):
        run_fleet(RunConfig(SCENARIO, sched="fast", out=tmp_path / "run",
                            child_argv=lambda *_a: ["/nonexistent/tlfleet"]))
    assert not (tmp_path / "run").exists()


def test_the_flags_of_run_and_of_the_fleet_processes():
    from tlfleet.cli.commands import agent, router, run, sim

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
        assert parser.parse_args([*positional, "--sched", "fifo"]).sched == "fifo"
        with pytest.raises(SystemExit):
            parser.parse_args([*positional, "--sched", "rr"])


PROBE = """
import json, os, sys, threading
sys.path.insert(0, {root!r})
from tlfleet.cli.process_flags import apply_scheduling
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


def _probe(policy: str, prelude: str = "") -> dict:
    done = subprocess.run([sys.executable, "-c",
                           prelude + PROBE.format(root=str(ROOT), policy=policy)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


@pytest.mark.needs_system  # fifo: root (a skip fails under TLFLEET_REQUIRE_SYSTEM=1)
@pytest.mark.skipif(not hasattr(os, "SCHED_BATCH"), reason="Linux scheduling policies")
@pytest.mark.parametrize("policy", ["batch", "default", "fifo"])
def test_the_policy_reaches_every_thread_of_the_process(policy):
    """fifo needs the right to it: root in CI, where a skip fails (tests/conftest.py)."""
    if policy == "fifo":
        from tlfleet.coordinator.launch.processes import fifo_permitted

        if not fifo_permitted():
            pytest.skip("SCHED_FIFO needs root or an RLIMIT_RTPRIO >= 1")
    out = _probe(policy)
    assert out["problem"] is None
    expected = {"batch": os.SCHED_BATCH, "fifo": getattr(os, "SCHED_FIFO", -1),
                "default": os.sched_getscheduler(0)}[policy]  # default: as started
    assert out["policies"] == {name: expected for name in ("main", "before", "after")}


@pytest.mark.needs_system
@pytest.mark.skipif(not hasattr(os, "SCHED_FIFO"), reason="Linux scheduling policies")
def test_a_refused_fifo_runs_under_batch_and_says_why():
    """An unprivileged user (root drops to nobody first, with no RLIMIT_RTPRIO): SCHED_FIFO is
    refused, the process runs under SCHED_BATCH, every thread, and the problem names both."""
    if os.geteuid() == 0:
        # everything the probe imports is loaded first: nobody may not read this checkout
        prelude = (f"import json, os, resource, sys, threading\nsys.path.insert(0, {str(ROOT)!r})"
                   "\nimport tlfleet.cli.process_flags\n"
                   "resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))\n"
                   "os.setgid(65534)\nos.setuid(65534)\n")
    else:
        import resource

        if resource.getrlimit(resource.RLIMIT_RTPRIO)[0] != 0:
            pytest.skip("this user may ask for SCHED_FIFO")
        prelude = ""
    out = _probe("fifo", prelude)
    assert out["problem"].startswith("sched_setscheduler(SCHED_FIFO) failed: "), out
    assert out["problem"].endswith("running under SCHED_BATCH instead"), out
    assert out["policies"] == {name: os.SCHED_BATCH for name in ("main", "before", "after")}


def test_an_unknown_policy_is_a_value_error():
    from tlfleet.cli.process_flags import apply_scheduling

    with pytest.raises(ValueError, match="'rr'"):
        apply_scheduling("rr")


def _policy_of_threads() -> set[tuple[int, int]]:
    """(policy without the reset-on-fork flag, priority) of every thread of this process."""
    flag = getattr(os, "SCHED_RESET_ON_FORK", 0)
    out = set()
    for tid in os.listdir("/proc/self/task"):
        try:
            policy = os.sched_getscheduler(int(tid)) & ~flag
            out.add((policy, os.sched_getparam(int(tid)).sched_priority))
        except ProcessLookupError:
            continue
    return out


@pytest.mark.needs_system
@pytest.mark.parametrize("above", [False, True])
def test_the_coordinator_shares_the_fifo_of_its_children_during_supervision(above):
    """Inside ``share_with_children("fifo")`` every thread of the coordinator (one started
    before, one started inside) runs SCHED_FIFO at the children's priority (one above in
    lockstep); afterwards all are ordinary again."""
    import threading

    from tlfleet.coordinator.launch.processes import (
        FIFO_PRIORITY,
        fifo_permitted,
        share_with_children,
    )

    if not fifo_permitted():
        pytest.skip("SCHED_FIFO is not permitted to this user (root or RLIMIT_RTPRIO)")
    release = threading.Event()
    before = threading.Thread(target=release.wait, daemon=True)
    before.start()
    inside = None
    try:
        with share_with_children("fifo", above=above) as applied:
            inside = threading.Thread(target=release.wait, daemon=True)
            inside.start()
            assert applied
            expected = FIFO_PRIORITY + 1 if above else FIFO_PRIORITY
            assert _policy_of_threads() == {(os.SCHED_FIFO, expected)}
        assert _policy_of_threads() == {(os.SCHED_OTHER, 0)}
    finally:
        release.set()
        before.join(5)
        if inside is not None:
            inside.join(5)


@pytest.mark.parametrize("sched", ["batch", "default"])
def test_no_share_unless_the_children_are_fifo(sched):
    from tlfleet.coordinator.launch.processes import share_with_children

    policies = _policy_of_threads()
    with share_with_children(sched) as applied:
        assert not applied
        assert _policy_of_threads() == policies
