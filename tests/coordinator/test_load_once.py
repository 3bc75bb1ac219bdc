"""Load once: `tlfleet run --hosts N`, `tlfleet run` with link faults (namespace hosts chosen for
it) and `tlfleet compose` read the scenario file once in their process and pass the Scenario
down, as `tlfleet run` does on one machine."""

from __future__ import annotations

from pathlib import Path

import pytest
import tlfleet.agent.scenario.loader as loader
import tlfleet.coordinator.run_hosts as run_hosts
from tlfleet.cli.main import main as cli_main

SCENARIO1 = Path(__file__).resolve().parents[2] / "scenarios" / "scenario1.toml"


class Launched(Exception):
    """Raised where the fleet would start: everything before it ran."""


@pytest.fixture
def loads(monkeypatch) -> list[str]:
    """The sources of every scenario load in this process from now on."""
    seen: list[str] = []
    real = loader.parse_scenario

    def counting(data, source="<scenario>"):
        seen.append(source)
        return real(data, source)

    monkeypatch.setattr(loader, "parse_scenario", counting)
    return seen


@pytest.mark.parametrize("flags", [["--hosts", "2"], ["--fault", "cut:robot3@20+3"]])
def test_run_on_hosts_loads_the_file_once(monkeypatch, loads, tmp_path, flags) -> None:
    placed: list[object] = []

    def no_launch(scenario, hosts):
        placed.append(scenario)
        raise Launched

    monkeypatch.setattr(run_hosts, "require_root", lambda: None)
    monkeypatch.setattr(run_hosts, "place", no_launch)
    with pytest.raises(Launched):
        cli_main(["run", str(SCENARIO1), "--insecure", "-o", str(tmp_path / "run"), *flags])
    assert loads == [str(SCENARIO1)]
    assert placed and placed[0].name == "scenario1"  # the one loaded, passed down


def test_compose_loads_the_file_once(loads, tmp_path, capsys) -> None:
    assert cli_main(["compose", str(SCENARIO1), "-o", str(tmp_path), "--insecure"]) == 0
    assert loads == [str(SCENARIO1)]
    assert (tmp_path / "compose.yaml").is_file()


def test_compose_refuses_a_robot_that_could_not_launch(tmp_path, capsys) -> None:
    """Checked as `tlfleet run` checks it: a task the loader accepts (a formula with a model) but
    no run over the regions satisfies (no region is both a11 and a12) is refused before the file
    is written (it would fail in its container)."""
    text = SCENARIO1.read_text().replace('ltl = "G F a11 & G F a12"', 'ltl = "G a11 & G a12"')
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert cli_main(["compose", str(bad), "-o", str(tmp_path / "out"), "--insecure"]) == 1
    assert not (tmp_path / "out" / "compose.yaml").exists()
    assert "bad.toml" in capsys.readouterr().err
