"""Which links a run's processes use (architecture.md §1): in an unsecured run
(lockstep or realtime) the simulator, the agents and the coordinator are zenoh peers linked to
each other, everything else goes through the router (``tlfleet.coordinator.run.peer_links``,
``default_child_argv``)."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.transport import DEFAULT_RUNTIME
from tlfleet.coordinator.run import (
    PEER_LISTEN,
    RunConfig,
    default_child_argv,
    fleet_plan,
    peer_links,
)

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "scenario1.toml"
ENDPOINT = "tcp/127.0.0.1:7447"
PEER_FLAGS = ["--mode", "peer", "--listen", PEER_LISTEN, "--zenoh-runtime", "minimal"]


def argv_of(config: RunConfig) -> dict[str, list[str]]:
    scenario = load_scenario(SCENARIO)
    plan = {spec.name: spec for spec in fleet_plan(config, scenario, ENDPOINT)}
    return {name: default_child_argv(plan[name]) for name in ("router", "sim", "agent-3")}


def has_peer_flags(argv: list[str]) -> bool:
    pairs = set(itertools.pairwise(argv))
    return all(pair in pairs for pair in zip(PEER_FLAGS[::2], PEER_FLAGS[1::2], strict=True))


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_an_unsecured_run_links_sim_and_agents_as_peers(mode):
    config = RunConfig(SCENARIO, mode=mode)
    assert peer_links(config)
    argv = argv_of(config)
    assert has_peer_flags(argv["sim"]) and has_peer_flags(argv["agent-3"])
    assert not has_peer_flags(argv["router"]) and "peer" not in argv["router"]
    assert "--zenoh-runtime" not in argv["router"]  # zenoh's pools: it fans out to many clients
    # still connected to the router: liveliness, control, status and events go through it
    for name in ("sim", "agent-3"):
        assert argv[name][argv[name].index("--connect") + 1] == ENDPOINT
    assert PEER_LISTEN == "tcp/127.0.0.1:0"  # loopback only, a free port


@pytest.mark.parametrize("change", [
    {"secure": Path("/keys")},  # the router enforces the access-control policy
    {"zenoh_config": Path("/zenoh.json5")},  # the user's file describes the topology
    {"direct_links": False},  # tlfleet run --via-router
], ids=["secure", "zenoh-config", "via-router"])
def test_every_other_run_goes_through_the_router(change):
    config = RunConfig(SCENARIO, **{"mode": "lockstep", **change})
    assert not peer_links(config)
    assert not any(has_peer_flags(argv) or "peer" in argv or "--zenoh-runtime" in argv
                   for argv in argv_of(config).values())


def test_a_run_with_faults_goes_through_the_router(tmp_path):
    """``run_fleet`` turns peer links off when the run has faults (their plans are made for
    the router topology): run.json says so; the stand-in children never start (bad argv)."""
    import json

    from tlfleet.agent.model.faults import parse_fault
    from tlfleet.coordinator.launch.processes import LaunchError
    from tlfleet.coordinator.run import run_fleet

    fault = parse_fault("kill:robot3@5")
    config = RunConfig(SCENARIO, mode="lockstep", out=tmp_path / "run", faults=(fault,),
                       child_argv=lambda *_args: ["/nonexistent/tlfleet"], report=False,
                       rrd=False)
    with pytest.raises(LaunchError):
        run_fleet(config)
    assert json.loads((tmp_path / "run" / "run.json").read_text())["links"] == "router"


def test_the_cli_flag_via_router_turns_peer_links_off():
    import argparse

    from tlfleet.cli.commands import run as run_command

    parser = argparse.ArgumentParser()
    run_command.add_arguments(parser)
    assert parser.parse_args([str(SCENARIO)]).direct_links is True
    assert parser.parse_args([str(SCENARIO), "--via-router"]).direct_links is False


def test_the_zenoh_runtime_flag_sets_the_transport_runtime():
    import argparse

    from tlfleet.bus.transport import DEFAULT_RUNTIME, MINIMAL_RUNTIME
    from tlfleet.cli.transport_flags import add_transport_arguments, transport_config

    parser = argparse.ArgumentParser()
    add_transport_arguments(parser)
    # zenoh's pools with RX_WORKERS receive workers
    assert transport_config(parser.parse_args([])).runtime == DEFAULT_RUNTIME
    minimal = parser.parse_args(["--zenoh-runtime", "minimal"])
    assert transport_config(minimal).runtime == MINIMAL_RUNTIME


def test_the_coordinator_joins_a_peer_link_run_as_a_peer(monkeypatch):
    import tlfleet.coordinator.run as runner

    opened = []
    monkeypatch.setattr(runner, "open_client", lambda config, *_a, **_k: opened.append(config))
    for mode in ("lockstep", "realtime"):
        runner._open_client(ENDPOINT, None, RunConfig(SCENARIO, mode=mode))
    runner._open_client(ENDPOINT, None, RunConfig(SCENARIO, direct_links=False))
    assert [(c.mode, c.listen, c.connect) for c in opened] == [
        ("peer", (PEER_LISTEN,), (ENDPOINT,)), ("peer", (PEER_LISTEN,), (ENDPOINT,)),
        ("client", (), (ENDPOINT,))]
    assert all(c.runtime == DEFAULT_RUNTIME for c in opened)  # zenoh's pools (RX_WORKERS)
