"""``tlfleet check`` agrees with ``tlfleet run``: no file that check calls valid fails at launch.

Over a corpus of valid scenario files written the way a researcher writes them
(``tests/scenario/corpus``, the paper's three, the broken corpus's base file) and of the broken
files that once passed ``check`` and failed the run at launch (``tests/scenario/broken_corpus``:
an LTL robot in the region its task forbids, a region walled in, ``G a & G b`` on disjoint
regions, a half-plane without ``rho_opt``, a robot over the wall, bodies asked to overlap, a
window after the run) plus a few plain ones: ``check`` exits 0 ⇔ ``tlfleet run`` (a real fleet,
one second of lockstep) launches and every agent reaches its first command — a status row of
every robot in ``status.csv`` — and otherwise the run exits 1 with nothing launched.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from system_helpers import ROOT, SCENARIOS
from tlfleet.coordinator.record import rundir

pytestmark = pytest.mark.system

CORPUS = ROOT / "tests" / "scenario" / "corpus"
BROKEN = ("ltl robot starts in the region its task forbids", "ltl region walled in by obstacles",
          "ltl G a & G b on disjoint regions", "stl half-plane without rho_opt",
          "robot over the arena wall at its start", "stl bodies asked to overlap",
          "stl window beyond the duration", "ltl syntax error", "stl unknown robot")


def corpus_files(tmp: Path) -> list[tuple[str, Path]]:
    sys.path.insert(0, str(ROOT / "tests" / "scenario"))
    try:
        from broken_corpus import BASE, CASES
    finally:
        sys.path.remove(str(ROOT / "tests" / "scenario"))

    files = [(p.stem, p) for p in sorted(CORPUS.glob("*.toml"))]
    files += [(f"scenario{n}", SCENARIOS / f"scenario{n}.toml") for n in (1, 2, 3)]
    base = tmp / "base" / "scenario.toml"
    base.parent.mkdir()
    base.write_text(BASE, encoding="utf-8")
    files.append(("broken corpus base", base))
    by_name = {case.name: case for case in CASES}
    for k, name in enumerate(BROKEN):
        folder = tmp / f"broken{k}"
        folder.mkdir()
        files.append((name, by_name[name].make(folder)))
    return files


def tlfleet(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tlfleet.cli", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=240)


def test_check_exit_0_iff_the_run_starts_and_every_agent_commands(tmp_path):
    disagreements = []
    valid = 0
    for name, path in corpus_files(tmp_path):
        check = tlfleet("check", str(path))
        out = tmp_path / "runs" / name.replace(" ", "_")
        run = tlfleet("run", str(path), "--lockstep", "--duration", "1", "--out", str(out),
                      "--no-report", "--no-rrd", "--quiet")
        if check.returncode == 0:
            valid += 1
            robots = json.loads((out / "run.json").read_text())["pids"] if out.is_dir() else {}
            statuses = rundir.read_run(out).statuses if out.is_dir() else ()
            commanded = {s.robot for s in statuses}
            agents = {int(n.split("-")[1]) for n in robots if n.startswith("agent-")}
            if run.returncode not in (0, 4) or not agents or commanded != agents:
                disagreements.append((name, "check 0", run.returncode, run.stderr[-400:]))
        else:
            # a rejection names the file and a field, and the run refuses it the same way
            # before anything is launched
            first = check.stderr.strip().splitlines()[0] if check.stderr.strip() else ""
            if check.returncode != 1 or str(path) not in first or "Traceback" in check.stderr:
                disagreements.append((name, "check said", check.returncode, check.stderr))
            if run.returncode != 1 or (out / "logs").exists() or \
                    first.split(": ", 1)[-1] not in run.stderr:
                disagreements.append((name, "run", run.returncode, run.stderr[-400:]))
    assert disagreements == []
    assert valid == len(list(CORPUS.glob("*.toml"))) + 4  # every valid file ran


def test_tlfleet_run_reads_the_scenario_once(tmp_path, monkeypatch):
    """`tlfleet run` loads and checks the file once and passes the Scenario down (the fault
    plan, the launcher and the report reuse it; three loads before). The processes it starts
    load it once each, in their own process."""
    from tlfleet.agent.scenario import loader
    from tlfleet.cli.main import main

    loads: list[str] = []
    real = loader.parse_scenario

    def counting(data, source="<scenario>"):
        loads.append(source)
        return real(data, source)

    monkeypatch.setattr(loader, "parse_scenario", counting)
    out = tmp_path / "run"
    code = main(["run", str(ROOT / "tests" / "system" / "two_robots.toml"), "--lockstep",
                 "--duration", "1", "--out", str(out), "--no-report", "--no-rrd", "--quiet"])
    assert code == 0
    assert loads == [str(ROOT / "tests" / "system" / "two_robots.toml")]
    assert (out / "summary.txt").read_text().splitlines()[-1].startswith("outcome: clean")
