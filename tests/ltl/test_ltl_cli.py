"""``tlfleet translate`` and ``tlfleet plan`` through the real dispatcher."""

from __future__ import annotations

import json

from tlfleet.cli.main import main


def test_translate_prints_hoa_and_size(capsys):
    assert main(["translate", "G F a11 & G F a12"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("HOA: v1\n")
    assert "States: 3" in out and "Acceptance: 1 Inf(0)" in out and "acc-name: Buchi" in out
    assert out.rstrip().endswith("--END--")
    assert err.startswith("3 states, 8 edges, 1 accepting")


def test_translate_text_and_dot_formats(capsys):
    assert main(["translate", "F a & F b", "--format", "text"]) == 0
    out, _err = capsys.readouterr()
    assert out.startswith("Büchi automaton for F a & F b") and "4 states" in out
    assert main(["translate", "F a & F b", "--format", "dot"]) == 0
    out, _err = capsys.readouterr()
    assert out.startswith("digraph") and out.count("doublecircle") == 1


def test_translate_syntax_error_names_the_column(capsys):
    assert main(["translate", "G F a &"]) == 1
    _out, err = capsys.readouterr()
    assert "tlfleet translate: LTL formula 'G F a &', column 8: expected a formula after '&'" in err


def test_plan_prints_every_ltl_robot(scenarios_dir, capsys):
    assert main(["plan", str(scenarios_dir / "scenario1.toml")]) == 0
    out, _err = capsys.readouterr()
    assert out.count("robot ") == 2
    assert "robot 1: G F a11 & G F a12" in out and "robot 2: G F a21 & G F a22" in out
    assert "Büchi: 3 states" in out and "product: " in out
    assert "suffix: (" in out and "cost: " in out
    for step in ("parse", "translate", "product", "search", "total"):
        assert f"{step} " in out


def test_plan_json_for_one_robot(scenarios_dir, capsys):
    assert main(["plan", str(scenarios_dir / "scenario3.toml"), "--robot", "1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["scenario"] == "scenario3"
    (entry,) = data["plans"]
    assert entry["robot"] == 1 and entry["buchi"]["states"] == 32
    assert sorted(set(entry["prefix"] + entry["suffix"]) - {"start"}) == [
        "a1", "a2", "a3", "a4", "a5"
    ]
    assert entry["cost"] == entry["prefix_cost"] + entry["beta"] * entry["suffix_cost"]


def test_plan_rejects_a_robot_without_ltl_task(scenarios_dir, capsys):
    assert main(["plan", str(scenarios_dir / "scenario3.toml"), "--robot", "2"]) == 1
    assert "robot 2 has no LTL task" in capsys.readouterr().err
    assert main(["plan", str(scenarios_dir / "scenario3.toml"), "--robot", "9"]) == 1
    assert "has no robot 9" in capsys.readouterr().err


def test_plan_reports_unsatisfiable_tasks(tmp_path, scenarios_dir, capsys):
    text = (scenarios_dir / "scenario1.toml").read_text()
    literal = text.replace('"G F a11 & G F a12"', '"GF(a11 & a12)"')
    assert literal != text
    path = tmp_path / "literal.toml"
    path.write_text(literal)
    assert main(["plan", str(path), "--robot", "1"]) == 1
    err = capsys.readouterr().err
    assert "robot 1: task 'GF(a11 & a12)' cannot be satisfied" in err
    assert "no region carries a11 and a12 together" in err
