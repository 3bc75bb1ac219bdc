"""HOA input (docs/ltl.md "Tools"): automata from other tools, in scenarios and on the CLI."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis_budget import examples
from ltl_helpers import automaton_accepts, formulas, lasso_words
from tlfleet.agent.ltl.buchi import translate
from tlfleet.agent.ltl.hoa import to_hoa
from tlfleet.agent.ltl.hoa_reader import HOA_TASK_PREFIX, read_hoa
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.planner import plan_robot
from tlfleet.agent.ltl.task import is_hoa_task, task_automaton
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.errors import FormulaSyntaxError, LtlError, ScenarioError, TlfleetError
from tlfleet.cli.main import main

ROOT = Path(__file__).resolve().parents[2]

# What Spot's `ltl2tgba 'G F a & G F b'` prints: one state, transition-based marks, two sets
# in a generalised condition is not Büchi — so this is `ltl2tgba -B`-like but transition-based.
SPOT_STYLE = """HOA: v1
name: "GFa"
States: 1
Start: 0
AP: 1 "a"
acc-name: Buchi
Acceptance: 1 Inf(0)
properties: trans-labels explicit-labels trans-acc complete deterministic
--BODY--
State: 0
[!0] 0
[0] 0 {0}
--END--
"""


def test_transition_based_acceptance_is_read_as_state_based():
    buchi = read_hoa(SPOT_STYLE)
    assert buchi.atoms == ("a",)
    a, e = frozenset({"a"}), frozenset()
    assert automaton_accepts(buchi, [], [a, e])
    assert not automaton_accepts(buchi, [a, a], [e])


def test_implicit_labels_and_aliases():
    text = """HOA: v1
States: 2
Start: 0
AP: 2 "p" "q"
Alias: @both 0 & 1
Acceptance: 1 Inf(0)
--BODY--
State: 0
0
0
0
1
State: 1 {0}
[@both] 1
--END--
"""
    buchi = read_hoa(text)  # state 0: letters 0..2 loop, letter 3 (p & q) → 1
    pq = frozenset({"p", "q"})
    assert automaton_accepts(buchi, [frozenset({"p"})], [pq])
    assert not automaton_accepts(buchi, [pq], [frozenset({"q"})])


@settings(max_examples=examples(150), deadline=None)
@given(formulas(), lasso_words())
def test_our_hoa_output_reads_back_to_the_same_language(f, word):
    buchi = read_hoa(to_hoa(translate(f)))
    prefix, loop = word
    assert automaton_accepts(buchi, prefix, loop) == holds(f, prefix, loop)


@pytest.mark.parametrize(("text", "message"), [
    ("States: 1\n", r"not a HOA file"),
    ("HOA: v1\nStart: 0\nAP: 0\nAcceptance: 2 Inf(0) & Inf(1)\n--BODY--\n--END--\n",
     r"line 4: acceptance .* is not supported"),
    ("HOA: v1\nStart: 0&1\nAP: 0\nAcceptance: 1 Inf(0)\n--BODY--\n--END--\n",
     r"line 2: Start: '0&1' \(alternating"),
    ("HOA: v1\nStart: 0\nAP: 1 \"a\"\nAcceptance: 1 Inf(0)\n--BODY--\nState: 0\n[3] 0\n--END--\n",
     r"line 7: AP number 3 out of range"),
    ("HOA: v1\nStart: 0\nAP: 1 \"a\"\nAcceptance: 1 Inf(0)\n", r"missing --BODY--"),
])
def test_bad_hoa_is_a_clear_error(text, message):
    with pytest.raises(LtlError, match=message):
        read_hoa(text, "task.hoa")
    assert issubclass(LtlError, TlfleetError)


def _scenario_with_hoa(tmp_path: Path, hoa_text: str) -> Path:
    source = (ROOT / "scenarios" / "scenario1.toml").read_text(encoding="utf-8")
    assert 'ltl = "G F a11 & G F a12"' in source
    (tmp_path / "task.hoa").write_text(hoa_text, encoding="utf-8")
    path = tmp_path / "scenario.toml"
    path.write_text(source.replace('ltl = "G F a11 & G F a12"', 'ltl = { hoa = "task.hoa" }'),
                    encoding="utf-8")
    return path


def test_scenario_robot_plans_with_a_hoa_automaton(tmp_path):
    """The automaton of the robot's own formula, given as a file: the same optimal plan."""
    formula = "G F a11 & G F a12"
    path = _scenario_with_hoa(tmp_path, to_hoa(translate(formula)))
    scenario = load_scenario(path)
    original = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    robot = next(r for r in original.robots if r.ltl == formula).id
    from_file = plan_robot(scenario, robot)
    expected = plan_robot(original, robot)
    assert from_file.cost == pytest.approx(expected.cost)
    assert from_file.suffix == expected.suffix and from_file.prefix == expected.prefix


def test_scenario_hoa_task_errors(tmp_path):
    path = _scenario_with_hoa(tmp_path, SPOT_STYLE.replace('"a"', '"nowhere"'))
    with pytest.raises(ScenarioError,
                       match=r"robots\[id=1\]\.ltl: proposition 'nowhere' is carried"):
        load_scenario(path)
    (tmp_path / "task.hoa").unlink()
    with pytest.raises(ScenarioError, match=r"robots\[id=1\]\.ltl\.hoa: no such HOA file"):
        load_scenario(path)


def test_cli_batch_stats_and_hoa_input(tmp_path, capsys):
    formulas_file = tmp_path / "f.ltl"
    formulas_file.write_text("G F a & G F b\n# comment\n\nF(a & F b)\na &\n", encoding="utf-8")
    assert main(["translate", "-F", str(formulas_file), "--stats"]) == 1  # one bad line
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert lines[0].startswith("line\tstates\tedges")
    assert lines[1].split("\t")[:3] == ["1", "3", "8"]
    assert lines[2].split("\t")[:3] == ["4", "3", "6"]
    assert lines[3].split("\t")[:2] == ["5", "error"]
    assert f"{formulas_file}:5: LTL formula 'a &', column 4" in err
    formulas_file.write_text("G F a & G F b\nF(a & F b)\n", encoding="utf-8")
    assert main(["translate", "-F", str(formulas_file)]) == 0
    out, _err = capsys.readouterr()
    assert out.count("HOA: v1") == 2 and out.count("--END--") == 2
    hoa = tmp_path / "a.hoa"
    hoa.write_text(SPOT_STYLE, encoding="utf-8")
    assert main(["translate", "--hoa", str(hoa), "--format", "text"]) == 0
    out, _err = capsys.readouterr()
    assert "atoms: a" in out
    assert main(["translate"]) == 1
    _out, err = capsys.readouterr()
    assert "give exactly one of FORMULA, -F FILE or --hoa FILE" in err


def test_task_automaton_reads_hoa_tasks_and_translates_formulas(tmp_path):
    path = tmp_path / "gfa.hoa"
    path.write_text(SPOT_STYLE, encoding="utf-8")
    task = HOA_TASK_PREFIX + str(path)
    assert is_hoa_task(task) and not is_hoa_task("G F a")
    from_file = task_automaton(task)
    assert from_file.atoms == ("a",) and from_file == read_hoa(SPOT_STYLE, str(path))
    assert task_automaton("G F a") == translate("G F a")
    with pytest.raises(FormulaSyntaxError):  # the translator itself reads formulas only
        translate(task)
