"""``tlfleet agent`` / ``tlfleet router`` argument checks (no process, no socket)."""

from __future__ import annotations

import re

import pytest
from tlfleet.cli.main import main


@pytest.mark.parametrize("argv, message", [
    (["agent", "scenarios/scenario1.toml", "--robot", "9"], "has no robot 9 (robots: 1, 2, 3"),
    (["agent", "scenarios/scenario1.toml", "--robot", "3", "--stale-after", "0"],
     "--stale-after must be positive"),
    (["agent", "scenarios/scenario1.toml", "--robot", "3", "--collab-timeout", "-1"],
     "--collab-timeout must be positive"),
    (["router"], "at least one --listen endpoint"),
    (["router", "--mode", "client", "--listen", "tcp/127.0.0.1:1"], "--mode must be router"),
])
def test_bad_arguments_are_rejected_before_any_session(argv, message):
    with pytest.raises(SystemExit, match=re.escape(message)):
        main(argv)


def test_agent_needs_a_robot(capsys):
    with pytest.raises(SystemExit):
        main(["agent", "scenarios/scenario1.toml"])
    assert "--robot" in capsys.readouterr().err
