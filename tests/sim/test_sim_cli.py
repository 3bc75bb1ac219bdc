"""``tlfleet sim`` command line: flags, defaults from the scenario, errors before any session."""

from __future__ import annotations

import argparse

import pytest
from tlfleet.agent.scenario import load_scenario
from tlfleet.cli.commands import sim as sim_command
from tlfleet.cli.main import main


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    sim_command.add_arguments(parser)
    return parser.parse_args(list(argv))


def test_flags_and_defaults(scenarios_dir):
    path = str(scenarios_dir / "scenario1.toml")
    scenario = load_scenario(path)
    args = parse(path)
    assert (args.realtime, args.seed, args.duration, args.tick_timeout) == (False, None, None, 2.0)
    assert (args.mode, args.connect, args.listen) == ("client", [], [])
    config = sim_command.sim_config(args, scenario)
    assert (config.mode, config.seed, config.duration) == ("lockstep", 1, 90.0)
    args = parse(path, "--realtime", "--seed", "7", "--duration", "3.5", "--tick-timeout", "0.5",
                 "--mode", "peer", "--listen", "tcp/127.0.0.1:7999")
    config = sim_command.sim_config(args, scenario)
    assert (config.mode, config.seed, config.duration, config.tick_timeout) == (
        "realtime", 7, 3.5, 0.5)
    assert args.listen == ["tcp/127.0.0.1:7999"]
    with pytest.raises(SystemExit):
        parse(path, "--realtime", "--lockstep")


@pytest.mark.parametrize(("flags", "message"), [
    (("--tick-timeout", "0"), "tick_timeout = 0.0 s: must be > 0"),
    (("--duration", "-2"), "duration = -2.0 s: must be ≥ 0"),
])
def test_bad_settings_fail_before_any_session_opens(scenarios_dir, capsys, flags, message):
    assert main(["sim", str(scenarios_dir / "scenario1.toml"), *flags]) == 1
    assert message in capsys.readouterr().err
