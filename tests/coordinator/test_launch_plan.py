"""One launch plan (``tlfleet.coordinator.launch.plan``): ``plan_fleet`` says what every process
of a fleet runs, ``Links.argv`` is the one serializer of the transport flags, and ``tlfleet run``,
``tlfleet compose`` (and ``run --hosts``) are placements of that plan. Checked by parsing what
the serializer writes with the very parsers of ``tlfleet sim|agent|router|supervise``, and by
reading the compose file's commands back as plans."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.transport import MINIMAL_RUNTIME
from tlfleet.cli.commands import agent, router, sim, supervise
from tlfleet.cli.conventions import merge_verbosity
from tlfleet.cli.main import add_command_arguments
from tlfleet.cli.transport_flags import transport_config
from tlfleet.coordinator.compose import ComposeConfig, compose_text
from tlfleet.coordinator.launch.plan import Links, PlanConfig, ProcessSpec, plan_fleet
from tlfleet.coordinator.run import RunConfig, fleet_plan

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "scenario1.toml"
COMMANDS = {"sim": sim, "agent": agent, "router": router, "supervise": supervise}


def parse(argv: tuple[str, ...]) -> argparse.Namespace:
    """``argv`` (``tlfleet``'s arguments) parsed by the command's own parser."""
    parser = argparse.ArgumentParser(exit_on_error=False)
    add_command_arguments(COMMANDS[argv[0]], parser)
    args = parser.parse_args(list(argv[1:]))
    merge_verbosity(args)
    return args


@pytest.mark.parametrize("links", [
    Links(),
    Links(connect=("tcp/127.0.0.1:7447", "tcp/10.0.0.2:7447")),
    Links(mode="peer", connect=("tls/a:1",), listen=("tls/b:2",), secure=Path("/k"),
          lease_ms=500, zenoh_config=Path("/z.json5"), runtime="minimal"),
])
def test_the_serializer_is_the_inverse_of_the_process_flags(links):
    args = parse(("agent", str(SCENARIO), "--robot", "3", *links.argv()))
    config = transport_config(argparse.Namespace(**{**vars(args), "secure": None}))
    assert config.mode == (links.mode or "client")
    assert config.connect == links.connect and config.listen == links.listen
    assert config.lease_ms == links.lease_ms and config.zenoh_config == links.zenoh_config
    assert (config.runtime == MINIMAL_RUNTIME) == (links.runtime == "minimal")
    assert args.secure == links.secure


def test_bad_links_and_specs_are_refused():
    with pytest.raises(ValueError, match="mode"):
        Links(mode="server")
    with pytest.raises(ValueError, match="lease_ms"):
        Links(lease_ms=0)
    with pytest.raises(ValueError, match="role"):
        ProcessSpec("x", "robot", ("agent",))
    with pytest.raises(ValueError, match="mode"):
        PlanConfig("s.toml", mode="fast")


def test_the_plan_names_every_process_once_and_each_parser_accepts_its_argv(tmp_path):
    scenario = load_scenario(SCENARIO)
    config = PlanConfig(str(SCENARIO), mode="realtime", duration=12.5, seed=7, tick_timeout=3.0,
                        max_speed=2.0, heartbeat=True, secure=tmp_path / "keys", lease_ms=500,
                        zenoh_config=tmp_path / "z.json5", sched="batch",
                        supervise=("--out", str(tmp_path / "run")), supervise_tail=("--quiet",))
    plan = plan_fleet(scenario, config)
    assert [s.name for s in plan] == ["router", "sim", *(f"agent-{r}" for r in
                                                         sorted(scenario.robot_ids)),
                                      "coordinator"]
    assert list(tmp_path.iterdir()) == []  # pure: nothing written
    for spec in plan:
        args = parse(spec.argv())
        assert args.secure == tmp_path / "keys" and args.lease_ms == 500
        assert args.zenoh_config == tmp_path / "z.json5"
        if spec.role == "sim":
            assert (args.realtime, args.duration, args.seed, args.tick_timeout,
                    args.max_speed) == (True, 12.5, 7, 3.0, 2.0)
        if spec.role == "agent":
            assert args.robot == spec.robot and args.heartbeat
        if spec.role == "coordinator":
            assert args.mode == "realtime" and args.duration == 12.5 and args.quiet
        else:
            assert args.sched == "batch"


def _without_links(argv: list[str]) -> list[str]:
    """``argv`` without the transport flags (the placement's part) and their values."""
    out, skip = [], False
    for word in argv:
        if skip:
            skip = False
        elif word in ("--mode", "--connect", "--listen", "--lease-ms", "--secure",
                      "--zenoh-config", "--zenoh-runtime", "--sched"):
            skip = True
        else:
            out.append(word)
    return out


def test_run_and_compose_are_placements_of_one_plan(tmp_path):
    """The same processes with the same own flags; only the links and the scenario's path (a
    mount point in a container) differ."""
    scenario = load_scenario(SCENARIO)
    local = fleet_plan(RunConfig(SCENARIO, duration=20.0), scenario, "tcp/127.0.0.1:7447")
    text = compose_text(ComposeConfig(SCENARIO, tmp_path / "c.yaml", duration=20.0))
    services = {}
    name = None
    for line in text.splitlines():
        if line.startswith("  ") and not line.startswith("   ") and line.endswith(":"):
            name = line.strip()[:-1]
        elif line.startswith("    command: "):
            services[name] = json.loads(line.removeprefix("    command: "))
    for spec in local:
        service = f"robot{spec.robot}" if spec.role == "agent" else spec.name
        ours = _without_links(list(spec.argv()))
        theirs = _without_links(services[service])
        assert [w.replace(str(SCENARIO.resolve()), "S") for w in ours] == \
            [w.replace("/fleet/scenario.toml", "S") for w in theirs], spec.name
    assert services["coordinator"][:3] == ["supervise", "/fleet/scenario.toml", "--lockstep"]
