"""The --secure flags of the command line (no fleet is started: run_fleet is replaced)."""

from __future__ import annotations

import pytest
import tlfleet.cli.commands.run as run_command
from security_helpers import ROOT, SCENARIO1
from tlfleet.cli.main import main as cli_main


class Launched(Exception):
    pass


@pytest.fixture
def captured(monkeypatch):
    configs = []

    def fake_run_fleet(config, **_kwargs):
        configs.append(config)
        raise Launched

    monkeypatch.setattr(run_command, "run_fleet", fake_run_fleet)
    return configs


def test_run_without_secure_says_the_links_are_plain_tcp(captured, capsys):
    with pytest.raises(Launched):
        cli_main(["run", str(SCENARIO1), "--quiet"])
    assert captured[0].secure is None
    assert "plain TCP on 127.0.0.1, unauthenticated" in capsys.readouterr().err


def test_run_with_secure_passes_the_key_directory(captured, capsys, tmp_path):
    # the keys are checked before the launch (tlfleet run loads and checks the file once)
    assert cli_main(["keys", str(SCENARIO1), "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    with pytest.raises(Launched):
        cli_main(["run", str(SCENARIO1), "--quiet", "--secure", str(tmp_path)])
    assert captured[0].secure == tmp_path
    assert "plain TCP" not in capsys.readouterr().err


@pytest.mark.parametrize("command", [
    ["router", "--listen", "tcp/127.0.0.1:1"],
    ["sim", str(SCENARIO1), "--connect", "tcp/127.0.0.1:1"],
    ["agent", str(SCENARIO1), "--robot", "3", "--connect", "tcp/127.0.0.1:1"],
])
def test_a_missing_key_directory_is_a_clear_error(command, tmp_path, capsys):
    assert cli_main([*command, "--secure", str(tmp_path / "nowhere")]) == 1
    assert "no such key directory" in capsys.readouterr().err


def test_keys_of_another_fleet_are_refused_before_anything_starts(tmp_path, capsys):
    assert cli_main(["keys", str(ROOT / "tests" / "system" / "two_robots.toml"), "--out",
                     str(tmp_path)]) == 0
    capsys.readouterr()
    assert cli_main(["run", str(SCENARIO1), "--quiet", "--secure", str(tmp_path)]) == 1
    assert "missing" in capsys.readouterr().err
